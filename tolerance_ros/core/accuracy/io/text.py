"""Reading a text file line by line, bounded: long lines are never held, bytes that are not UTF-8 are
named with their position. Shared by the CSV and campaign-log readers."""
from __future__ import annotations

import re

from .measurements import MeasurementError

_UNDECODED = re.compile("[\udc80-\udcff]")       # a byte that is not UTF-8, as surrogateescape decodes it

MAX_LINE = 1 << 20  # characters in one line of a CSV file or a campaign log


def _show(text, n=40):
    """repr of ``text``, cut to about ``n`` characters."""
    return repr(text) if len(text) <= n else repr(text[:n]) + f"... ({len(text)} characters)"


def _cut(text, n=40):
    return text if len(text) <= n else text[:n] + "..."


def _lines(fh):
    """(line number, text) of each line of a text file opened with ``errors="surrogateescape"``; the text
    is None for a line longer than MAX_LINE characters, which is not kept in memory."""
    lineno = 0
    while True:
        line = fh.readline(MAX_LINE + 1)
        if not line:
            return
        lineno += 1
        if len(line) > MAX_LINE:
            while line and line[-1] not in "\r\n":
                line = fh.readline(MAX_LINE)
            yield lineno, None
            continue
        if lineno == 1 and line.startswith("\ufeff"):
            line = line[1:]
        yield lineno, line


def _check_text(line):
    """Index of the first character of ``line`` that stands for a byte that is not UTF-8, or None;
    MeasurementError for a line that was too long (None)."""
    if line is None:
        raise MeasurementError(f"line longer than {MAX_LINE} characters")
    if not line.isascii():
        bad = _UNDECODED.search(line)
        if bad:
            return bad.start()
    return None


def _not_utf8(line, pos):
    return f"byte 0x{ord(line[pos]) - 0xdc00:02x} at character {pos + 1} is not UTF-8"

