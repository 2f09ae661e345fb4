"""One bounded reader of the project's YAML and JSON files (robot, budget, campaign, calibration).

``read_yaml(path, error)`` reads a file with PyYAML's C parser (libyaml) and builds the Python values
from its event stream in one loop, so nothing recursive sees the document and every bound is checked
as the events arrive:

- at most ``MAX_FILE_BYTES`` bytes (checked before reading), UTF-8 text (a byte-order mark is allowed);
- nesting at most ``MAX_DEPTH`` collections deep;
- at most ``MAX_NODES`` values, counting every value an alias repeats (so alias bombs stop early);
  an alias to a collection that contains it is refused (no recursive values);
- one document; mapping keys are text (a plain key is taken as written, never as a number or a
  boolean) and a key given twice in one mapping is refused; merge keys (``<<``) are honoured;
- plain scalars read as in YAML 1.1 (null ``~``, booleans ``true``/``yes``/``on``..., ``.inf``), except
  the number forms YAML readers disagree on, which are refused with the line: digit separators
  (``1_000``), sexagesimal numbers (``1:30``), octal with a leading zero (``017``), ``0x``/``0b``
  numbers. Decimal numbers read as ints and floats (``1e3`` too); dates stay text;
- tags other than the core ones (``!!str``, ``!!int``, ``!!float``, ``!!bool``, ``!!null``,
  ``!!seq``, ``!!map``) are refused.

Every failure raises ``error`` (the reader's own exception class) with a message that names the file
and, where there is one, the line. ``read_json`` applies the same size, encoding, depth and
duplicate-key rules to JSON files.
"""
from __future__ import annotations

import json
import math
import os
import re
import stat
from pathlib import Path

import yaml
from yaml.events import (AliasEvent, DocumentEndEvent, DocumentStartEvent, MappingEndEvent, MappingStartEvent,
                         ScalarEvent, SequenceEndEvent, SequenceStartEvent, StreamEndEvent, StreamStartEvent)

try:
    from yaml import CSafeLoader as _Loader
except ImportError:  # pragma: no cover - PyYAML without libyaml: the pure-Python parser, same events
    from yaml import SafeLoader as _Loader

MAX_FILE_BYTES = 4 * 1024 * 1024  # 4 MiB
MAX_DEPTH = 32                     # collections inside collections
MAX_NODES = 500_000                # values (a campaign of about 40,000 poses), every alias counting as what it repeats

_CORE = "tag:yaml.org,2002:"
_MISSING = object()
_MERGE = object()
_WORDS = {"": None, "~": None, "null": None, "Null": None, "NULL": None,
          **{w: True for w in ("true", "True", "TRUE", "yes", "Yes", "YES", "on", "On", "ON")},
          **{w: False for w in ("false", "False", "FALSE", "no", "No", "NO", "off", "Off", "OFF")},
          **{s + w: v for s, v0 in (("", 1.0), ("+", 1.0), ("-", -1.0)) for w, v in
             ((w, v0 * math.inf) for w in (".inf", ".Inf", ".INF"))},
          ".nan": math.nan, ".NaN": math.nan, ".NAN": math.nan}
_INT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)")
_FLOAT = re.compile(r"[-+]?(?:(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?|[0-9]+[eE][-+]?[0-9]+)")
_YAML11_NUMBER = re.compile(  # PyYAML's (YAML 1.1) int and float forms
    r"[-+]?0b[0-1_]+|[-+]?0[0-7_]+|[-+]?(?:0|[1-9][0-9_]*)|[-+]?0x[0-9a-fA-F_]+|[-+]?[1-9][0-9_]*(?::[0-5]?[0-9])+"
    r"|[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+][0-9]+)?|\.[0-9_]+(?:[eE][-+][0-9]+)?"
    r"|[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*")


def read_bytes(path, error=ValueError, limit: int = MAX_FILE_BYTES, what: str = "file") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (checked before and while reading)."""
    path = Path(path)
    try:
        info = os.stat(path)
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{path}: not a regular file")
    if info.st_size > limit:
        raise error(f"{path}: {info.st_size} bytes; a {what} may have at most {limit} bytes")
    try:
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise error(f"{path}: more than {limit} bytes; a {what} may have at most {limit} bytes")
    return data


def decode_utf8(data: bytes, source, error=ValueError) -> str:
    """UTF-8 text of ``data`` without a leading byte-order mark; a byte that is not UTF-8 raises ``error``
    naming ``source``, the line and the column."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise error(f"{source}, line {line}, column {column}: not UTF-8 text (byte 0x{data[exc.start]:02x})") from None


def read_yaml(path, error=ValueError):
    """The value of a YAML file (see the module docstring); ``error`` is raised for anything wrong."""
    data = read_bytes(path, error, what="YAML file")
    return loads_yaml(decode_utf8(data, path, error), path, error)


def read_json(path, error=ValueError):
    """The value of a JSON file: the size, UTF-8, depth and duplicate-key rules of ``read_yaml``."""
    text = decode_utf8(read_bytes(path, error, what="JSON file"), path, error)

    def pairs(items):
        out = {}
        for k, v in items:
            if k in out:
                raise error(f"{path}: key {k[:60]!r} given twice in one object")
            out[k] = v
        return out

    try:
        doc = json.loads(text, object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        raise error(f"{path}, line {exc.lineno}, column {exc.colno}: not valid JSON: {exc.msg}") from None
    except RecursionError:
        raise error(f"{path}: nested deeper than {MAX_DEPTH} levels") from None
    depth = nesting_depth(doc)
    if depth > MAX_DEPTH:
        raise error(f"{path}: nested {depth} levels deep; at most {MAX_DEPTH} are allowed")
    return doc


def nesting_depth(value) -> int:
    """Depth of nested lists and dicts in a parsed value (a scalar is 0), found without recursion."""
    deepest, todo = 0, [(value, 1)]
    while todo:
        v, d = todo.pop()
        children = v.values() if isinstance(v, dict) else v if isinstance(v, list) else None
        if children is None:
            continue
        deepest = max(deepest, d)
        todo.extend((c, d + 1) for c in children if isinstance(c, (dict, list)))
    return deepest


def loads_yaml(text: str, source="<text>", error=ValueError):
    """The value of YAML text (see the module docstring); ``source`` names it in the errors."""
    if len(text) > MAX_FILE_BYTES:
        raise error(f"{source}: more than {MAX_FILE_BYTES} characters; a YAML file may have at most "
                    f"{MAX_FILE_BYTES} bytes")
    loader = _Loader(text)
    try:
        return _build(loader, source, error)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        if "maximum nesting depth" in str(exc.problem):   # PyYAML >= 6.0.3 scans ahead and stops deep nesting itself
            raise error(f"{source}, line {mark.line + 1 if mark is not None else 1}: nested deeper than {MAX_DEPTH} "
                        f"levels") from None
        where = f", line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        what = "; ".join(str(p) for p in (exc.context, exc.problem) if p)
        raise error(f"{source}{where}: not valid YAML: {what}") from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        raise error(f"{source}, line {line}: not valid YAML: character {_shown(exc.character)} is not "
                    f"allowed") from None
    except yaml.YAMLError as exc:
        raise error(f"{source}: not valid YAML: {str(exc)[:200]}") from None
    finally:
        loader.dispose()


def _scalar(value, ev, source, error):
    """A plain, untagged scalar as YAML 1.1 reads it, or ``error`` for the number forms readers disagree on."""
    v = _WORDS.get(value, _MISSING)
    if v is not _MISSING:
        return v
    if value[0] in "0123456789+-.":
        if _INT.fullmatch(value):
            try:
                return int(value)
            except ValueError:  # more digits than Python converts
                raise error(f"{source}, line {_line(ev)}: a number of {len(value)} digits") from None
        if _FLOAT.fullmatch(value):
            return float(value)
        if _YAML11_NUMBER.fullmatch(value):
            kind = ("a number with digit separators ('_')" if "_" in value else "a sexagesimal (base 60) number"
                    if ":" in value else "a binary number" if "0b" in value else "a hexadecimal number" if "0x" in value
                    else "an octal number (leading zero)")
            read = f" (YAML 1.1 reads {yaml.load(value, _Loader)!r})" if len(value) <= 40 else ""
            raise error(f"{source}, line {_line(ev)}: {value[:40]!r} is {kind}, which YAML readers read "
                        f"differently{read}; write a plain decimal number, or quote it if it is text")
    return value


def _plain_misread(text: str) -> bool:
    """Whether ``text``, written as a plain scalar, would be read back by ``loads_yaml`` as something else (a
    number, a word such as ``yes`` or ``null``) or refused: ``1e5`` or a hexadecimal id such as ``2e89134567890123``
    is a number to YAML 1.2's readers and ours, though PyYAML writes it plain."""
    if text in _WORDS:
        return True
    return bool(text) and text[0] in "0123456789+-." and bool(
        _INT.fullmatch(text) or _FLOAT.fullmatch(text) or _YAML11_NUMBER.fullmatch(text))


class Dumper(yaml.SafeDumper):
    """PyYAML's safe dumper, quoting every string ``loads_yaml`` would not read back as that string."""


Dumper.add_representer(str, lambda dumper, data: dumper.represent_scalar(
    "tag:yaml.org,2002:str", data, style="'" if _plain_misread(data) else None))


def dump_yaml(doc, **options) -> str:
    """``doc`` as YAML text (``yaml.dump`` options: ``sort_keys``, ``default_flow_style``, ``width``...) that
    ``loads_yaml`` reads back as written."""
    return yaml.dump(doc, Dumper=options.pop("Dumper", Dumper), **options)


def _shown(character) -> str:
    return f"#x{character:04x}" if isinstance(character, int) else repr(character)


def _line(ev) -> int:
    return ev.start_mark.line + 1


def _tagged(tag, value, ev, source, error):
    """A scalar with an explicit core tag."""
    line = _line(ev)
    if tag in ("!", _CORE + "str"):
        return value
    want = {_CORE + "int": int, _CORE + "float": float, _CORE + "bool": bool, _CORE + "null": type(None)}.get(tag)
    if want is None:
        raise error(f"{source}, line {line}: tag {tag[:60]!r} is not supported (only the core tags str, int, "
                    f"float, bool, null, seq, map)")
    v = _scalar(value, ev, source, error) if value else None
    if want is float and type(v) is int:
        v = float(v)
    if type(v) is not want:
        raise error(f"{source}, line {line}: {value[:40]!r} is not a valid {tag[len(_CORE):]}")
    return v


def _build(loader, source, error):
    """Python values from the loader's events, bounded (see the module docstring)."""
    get = loader.get_event
    stack = []        # open collections: [container, is_mapping, pending key, anchor, nodes at start, merges]
    anchors = {}      # name -> (value, nodes it stands for)
    nodes = 0
    documents = 0
    root = _MISSING
    while True:
        ev = get()
        kind = type(ev)
        if kind is ScalarEvent:
            nodes += 1
            top = stack[-1] if stack else None
            if top is not None and top[1] and top[2] is _MISSING:  # a mapping key: text as written
                if ev.tag is not None and ev.tag not in ("!", _CORE + "str"):
                    raise error(f"{source}, line {_line(ev)}: a mapping key with tag {ev.tag[:60]!r}; keys are text")
                key = _MERGE if (ev.value == "<<" and ev.implicit[0] and ev.tag is None) else ev.value
                if key is not _MERGE and key in top[0]:
                    raise error(f"{source}, line {_line(ev)}: key {key[:60]!r} given twice in one mapping")
                top[2] = key
                if ev.anchor is not None:
                    anchors[ev.anchor] = (ev.value, 1)
                continue
            if ev.tag is None and ev.implicit[0]:
                value = _scalar(ev.value, ev, source, error)
            elif ev.tag is None:
                value = ev.value
            else:
                value = _tagged(ev.tag, ev.value, ev, source, error)
            if ev.anchor is not None:
                anchors[ev.anchor] = (value, 1)
        elif kind is SequenceStartEvent or kind is MappingStartEvent:
            mapping = kind is MappingStartEvent
            if ev.tag is not None and ev.tag not in ("!", _CORE + ("map" if mapping else "seq")):
                raise error(f"{source}, line {_line(ev)}: tag {ev.tag[:60]!r} is not supported (only the core "
                            f"tags str, int, float, bool, null, seq, map)")
            if stack and stack[-1][1] and stack[-1][2] is _MISSING:
                raise error(f"{source}, line {_line(ev)}: a mapping key that is a collection; keys are text")
            if len(stack) >= MAX_DEPTH:
                raise error(f"{source}, line {_line(ev)}: nested deeper than {MAX_DEPTH} levels")
            nodes += 1
            if nodes > MAX_NODES:
                raise error(f"{source}, line {_line(ev)}: more than {MAX_NODES} values")
            stack.append([{} if mapping else [], mapping, _MISSING, ev.anchor, nodes, None])
            continue
        elif kind is SequenceEndEvent or kind is MappingEndEvent:
            value, mapping, _, anchor, start, merges = stack.pop()
            if merges:
                merged = {}
                for m in reversed(merges):
                    merged.update(m)
                merged.update(value)
                value = merged
            if anchor is not None:
                anchors[anchor] = (value, nodes - start + 1)
        elif kind is AliasEvent:
            line = _line(ev)
            found = anchors.get(ev.anchor)
            if found is None:
                open_ = any(frame[3] == ev.anchor for frame in stack)
                raise error(f"{source}, line {line}: alias *{ev.anchor[:60]} " + (
                    "refers to a collection that contains it (a recursive value)" if open_ else
                    "refers to no anchor before it"))
            value, count = found
            top = stack[-1] if stack else None
            if top is not None and top[1] and top[2] is _MISSING:
                if not isinstance(value, str):
                    raise error(f"{source}, line {line}: alias *{ev.anchor[:60]} as a mapping key is not text")
                if value in top[0]:
                    raise error(f"{source}, line {line}: key {value[:60]!r} given twice in one mapping")
                top[2] = value
                continue
            nodes += count
            if nodes > MAX_NODES:
                raise error(f"{source}, line {line}: more than {MAX_NODES} values (counting what the aliases "
                            f"repeat)")
        elif kind is DocumentStartEvent:
            documents += 1
            if documents > 1:
                raise error(f"{source}, line {_line(ev)}: more than one YAML document")
            continue
        elif kind is StreamEndEvent or ev is None:
            return None if root is _MISSING else root
        elif kind is StreamStartEvent or kind is DocumentEndEvent:
            continue
        else:  # pragma: no cover - libyaml emits no other events
            raise error(f"{source}: unexpected YAML event {kind.__name__}")
        if nodes > MAX_NODES:
            raise error(f"{source}, line {_line(ev)}: more than {MAX_NODES} values")
        if not stack:
            root = value
            continue
        top = stack[-1]
        if not top[1]:
            top[0].append(value)
            continue
        key = top[2]
        top[2] = _MISSING
        if key is _MERGE:
            parts = value if isinstance(value, list) else [value]
            if not all(isinstance(p, dict) for p in parts):
                raise error(f"{source}, line {_line(ev)}: a merge key '<<' needs a mapping or a list "
                            f"of mappings")
            top[5] = (top[5] or []) + parts
        else:
            top[0][key] = value
