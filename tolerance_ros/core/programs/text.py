"""A program's text as its controller reads it: bytes kept as they are, comments and strings told apart from
code, numbers found with their place in the file, and numbers written back with the digits they need.

A program file is read as bytes and decoded so that every byte comes back on writing (UTF-8 with
``surrogateescape``: a Latin-1 comment, CRLF line ends and a missing last newline survive a round trip). Parsers
search a *masked* copy of the text, in which comments (and, with ``strings=True``, string literals) are blanked
with spaces of the same length, so that a position found there is the same position in the text.
"""
from __future__ import annotations

import bisect
import math
import re
from dataclasses import dataclass
from pathlib import Path

ENCODING = "utf-8"
ERRORS = "surrogateescape"

NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
NUMBER_RE = re.compile(NUMBER)

# Decimals written for a corrected value (at least; never fewer than the value had). The rounding they leave is at
# most half a unit of the last digit: 0.05 um for mm and m; 5e-6 deg (0.26 um at 3 m) for degrees; 5e-8 rad
# (0.15 um at 3 m) for radians; 5e-9 of a quaternion component (1e-8 rad, 0.03 um at 3 m).
DECIMALS = {"mm": 4, "m": 7, "deg": 5, "rad": 7, "quat": 8}


class ProgramError(ValueError):
    """A program that cannot be read as its controller would: the message names the file and the line."""


MAX_BYTES = 64 << 20     # a program file's size: 64 MiB holds some 400,000 targets


def read_text(path) -> str:
    """The file's text, every byte kept (see the module docstring); ProgramError for a file over ``MAX_BYTES``."""
    size = Path(path).stat().st_size
    if size > MAX_BYTES:
        raise ProgramError(f"{path}:1: {size / 2 ** 20:.0f} MiB: a program file is read whole, up to "
                           f"{MAX_BYTES >> 20} MiB")
    return Path(path).read_bytes().decode(ENCODING, ERRORS)


def to_bytes(text: str) -> bytes:
    return text.encode(ENCODING, ERRORS)


class Lines:
    """Line numbers (1-based) of offsets in a text."""

    def __init__(self, text: str):
        self.starts = [0] + [m.end() for m in re.finditer(r"\r\n|\r|\n", text)]

    def line(self, offset: int) -> int:
        return bisect.bisect_right(self.starts, offset)

    def start(self, line: int) -> int:
        return self.starts[line - 1]


def newline(text: str) -> str:
    """The text's line end (CRLF, CR or LF: the first one found; LF for a text of one line)."""
    m = re.search(r"\r\n|\r|\n", text)
    return m.group() if m else "\n"


def mask(text: str, comment: str, strings: str = "\"", keep_strings: bool = False) -> str:
    """The text with comments (``comment``: the characters that start one, to the end of the line) and string
    literals (quoted by any character of ``strings``; blanked unless ``keep_strings``) replaced with spaces, line ends
    kept; an unclosed string runs to the end of its line."""
    alternatives = [f"{re.escape(q)}[^{re.escape(q)}\\r\\n]*(?:{re.escape(q)}|(?=[\\r\\n])|\\Z)" for q in strings]
    if comment:
        alternatives.append(f"[{re.escape(comment)}][^\\r\\n]*")
    out, last = [], 0
    for m in re.finditer("|".join(alternatives), text):
        if keep_strings and m.group()[0] in strings:
            continue
        out.append(text[last:m.start()])
        out.append(" " * (m.end() - m.start()))
        last = m.end()
    out.append(text[last:])
    return "".join(out)


@dataclass
class Number:
    """A number in a file: its span [start, end) in the text and the text there."""

    start: int
    end: int
    text: str

    @property
    def value(self) -> float:
        return float(self.text)


def number_at(text: str, start: int, end: int, where: str) -> Number:
    """The number that is the whole of ``text[start:end]`` (spaces around it allowed); ProgramError naming
    ``where`` otherwise."""
    chunk = text[start:end]
    m = re.fullmatch(r"\s*(" + NUMBER + r")\s*", chunk)
    if m is None:
        raise ProgramError(f"{where}: expected a number, got {chunk.strip()!r}")
    value = float(m.group(1))
    if not math.isfinite(value):
        raise ProgramError(f"{where}: {chunk.strip()!r} is not a finite number")
    return Number(start + m.start(1), start + m.end(1), m.group(1))


def decimals(text: str) -> int:
    """Digits after the decimal point of a number as written (0 for an integer or an exponent form)."""
    if "e" in text.lower() or "." not in text:
        return 0
    return len(text.split(".", 1)[1])


def formatted(value: float, old: str, unit: str) -> str:
    """``value`` written in the style of ``old`` (a leading zero below 1 or not, no negative zero) with at least
    ``DECIMALS[unit]`` decimals and at least as many as ``old`` had; ``old`` itself when it already reads as
    ``value`` to that many decimals (a value that did not change keeps its text, byte for byte)."""
    d = max(decimals(old), DECIMALS[unit])
    text = f"{value:.{d}f}"
    if float(text) == 0.0:
        text = text.lstrip("-")
    if float(text) == float(old):
        return old
    bare = old.lstrip("+-")
    if bare.startswith(".") and text.lstrip("-").startswith("0."):
        text = text.replace("0.", ".", 1)
    if old.startswith("+") and not text.startswith("-"):
        text = "+" + text
    return text


def replaced(text: str, edits) -> str:
    """``text`` with each (start, end, new) edit made; edits must not overlap."""
    out, last = [], 0
    for start, end, new in sorted(edits):
        if start < last:
            raise ValueError(f"overlapping edits at offset {start}")
        out.append(text[last:start])
        out.append(new)
        last = end
    out.append(text[last:])
    return "".join(out)


def matching(text: str, start: int, open_: str, close: str, where: str) -> int:
    """Offset just past the bracket that closes the one at ``start`` (``text`` masked of comments and strings)."""
    depth = 0
    for i in range(start, len(text)):
        c = text[i]
        if c == open_:
            depth += 1
        elif c == close:
            depth -= 1
            if depth == 0:
                return i + 1
    raise ProgramError(f"{where}: {open_!r} is never closed")


def split_top(text: str, start: int, end: int, sep: str = ",", brackets: str = "([{", closers: str = ")]}"):
    """[(start, end)] of the parts of ``text[start:end]`` separated by ``sep`` outside brackets."""
    parts, depth, last = [], 0, start
    for i in range(start, end):
        c = text[i]
        if c in brackets:
            depth += 1
        elif c in closers:
            depth -= 1
        elif c == sep and depth == 0:
            parts.append((last, i))
            last = i + 1
    parts.append((last, end))
    return parts
