"""Generated requests for the services, valid ones mixed with mutations (wrong types, NaN/Infinity, huge
numbers, odd ids, deep nesting, unknown fields, duplicate keys, non-UTF-8 text, oversized strings);
shared by the fuzz tests and bench/bench_fuzz.py. ``jacobian_request`` is valid about half of the
time, ``allocate_request`` about a quarter (the rest is hostile)."""
import json

from hypothesis import strategies as st

Q = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
HOSTILE_NUMBERS = [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 5e-324, 2 ** 64, -(2 ** 63) - 1,
                   10 ** 400, True, None, "1", [], {}]
ODD_IDS = [None, True, 1.5, "", "x" * 300, "\ud800", 2 ** 64, -(2 ** 63), [1], {"a": 1}, "ü"]


def scalars():
    return st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(2 ** 70), 2 ** 70),
                     st.booleans(), st.none(), st.text(max_size=8), st.sampled_from(HOSTILE_NUMBERS))


def json_values(depth=3):
    return st.recursive(scalars(), lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                           st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                        max_leaves=depth * 4)


def ids():
    return st.one_of(st.text(max_size=12), st.integers(-(2 ** 63), 2 ** 63 - 1))


CONFIGURATION = st.lists(st.floats(-3.14, 3.14), min_size=7, max_size=7)


def valid_jacobian_request():
    """Requests the service serves for gao2023_7dof: Jacobians of one to five configurations, with or
    without bounds, and compensate requests on the nominal model (joint or pose targets)."""
    poses = st.lists(CONFIGURATION, min_size=1, max_size=3).map(
        lambda qs: [[[0.0, 0.0, 1.0, 0.05 * k], [0.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.6], [0, 0, 0, 1]]
                    for k in range(len(qs))])
    jacobian = st.fixed_dictionaries(
        {"id": ids(), "joints": st.one_of(CONFIGURATION, st.lists(CONFIGURATION, min_size=1, max_size=5))},
        optional={"robot": st.just("gao2023_7dof"), "outputs": st.sampled_from(["pose", "position"]),
                  "tolerances": st.fixed_dictionaries({"default": st.just(0), "a1": st.floats(0, 1e-3),
                                                       "theta2": st.floats(0, 1e-3)}),
                  "criteria": st.lists(st.sampled_from(["paper", "worst-case", "per-axis", "rss"]), min_size=1,
                                       max_size=4),
                  "include_jacobian": st.booleans(), "arrays": st.sampled_from(["json", "base64"])})
    compensate = st.fixed_dictionaries(
        {"id": ids(), "command": st.just("compensate"), "model": st.just("nominal")},
        optional={"match": st.sampled_from(["pose", "position"]), "arrays": st.sampled_from(["json", "base64"])}
    ).flatmap(lambda req: st.one_of(st.lists(CONFIGURATION, min_size=1, max_size=3).map(
        lambda qs: {**req, "joints": qs}), poses.map(lambda ps: {**req, "poses": ps})))
    return st.one_of(jacobian, compensate)


def valid_allocate_request():
    """Requests the allocator accepts: an allocation with a feasible limit and small options, status, or a
    cancel of some id."""
    allocation = st.fixed_dictionaries(
        {"id": ids(), "limit": st.floats(0.0008, 0.005)},
        optional={"model": st.sampled_from(["min-cost", "optimal-precision"]),
                  "criterion": st.sampled_from(["paper", "rss", "worst-case"]), "seed": st.integers(0, 100),
                  "mc_poses": st.integers(100, 500), "time_limit": st.floats(0.5, 2.0)})
    return st.one_of(allocation, st.fixed_dictionaries({"id": ids(), "command": st.just("status")}),
                     st.fixed_dictionaries({"id": ids(), "command": st.just("cancel"), "target": ids()}))


def jacobian_request():
    return st.one_of(valid_jacobian_request(), hostile_jacobian_request())


def allocate_request():
    return st.one_of(valid_allocate_request(), hostile_allocate_request(), hostile_allocate_request(),
                     hostile_allocate_request())


def hostile_jacobian_request():
    joints = st.one_of(st.just(Q), st.lists(st.just(Q), min_size=1, max_size=5),
                       st.lists(st.floats(-4, 4), min_size=0, max_size=9), json_values())
    tolerances = st.one_of(st.just("current"), st.fixed_dictionaries({"default": st.just(0), "a1": st.floats(0, 1e-3)}),
                           st.dictionaries(st.sampled_from(["a1", "theta2", "tolerances", "free", "default", "zz"]),
                                           json_values(), max_size=3), json_values())
    poses = st.one_of(st.lists(st.lists(st.one_of(st.floats(-1, 1), scalars()), min_size=7, max_size=7), max_size=4),
                      st.just([[0.5, 0.1, 0.6, 0.0, 0.0, 0.0, 1.0]]), st.just([[0.4, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0]]),
                      st.just([[[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0.6], [0, 0, 0, 1]]]),
                      st.just([[[2, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0.6], [0, 0, 0, 1]]]), json_values())
    criteria = st.one_of(st.lists(st.sampled_from(["paper", "worst-case", "per-axis", "rss", "max"]), max_size=6),
                         st.lists(st.just("worst-case"), min_size=50, max_size=2000), json_values())
    return st.fixed_dictionaries({"id": st.one_of(st.text(max_size=12), st.integers(), st.sampled_from(ODD_IDS))},
                                 optional={"joints": joints, "robot": st.sampled_from(["gao2023_7dof", "ur5", 1]),
                                           "outputs": st.sampled_from(["pose", "position", "all", 3]),
                                           "tolerances": tolerances, "criteria": criteria,
                                           "allow_out_of_limits": st.one_of(st.booleans(), json_values()),
                                           "include_jacobian": st.booleans(),
                                           "arrays": st.sampled_from(["json", "base64", "xml"]),
                                           "command": st.sampled_from(["compute_error_jacobian", "compensate",
                                                                       "compensate", "x"]),
                                           "model": st.sampled_from(["nominal", "calibrated", "x"]),
                                           "poses": poses, "seed": joints,
                                           "match": st.sampled_from(["pose", "position", "x"]),
                                           "colour": json_values()})


def hostile_allocate_request():
    return st.fixed_dictionaries({"id": st.one_of(st.text(max_size=12), st.integers(), st.sampled_from(ODD_IDS))},
                                 optional={"limit": st.one_of(st.floats(0, 0.01), scalars()),
                                           "command": st.sampled_from(["allocate", "status", "cancel", "nope"]),
                                           "target": json_values(), "orientation_limit": scalars(),
                                           "model": st.sampled_from(["min-cost", "optimal-precision", "x"]),
                                           "solver": st.sampled_from(["active-set", "ga", "x"]),
                                           "criterion": st.sampled_from(["paper", "rss", "worst-case", "per-axis"]),
                                           "floors": st.one_of(st.dictionaries(st.sampled_from(["length", "angle",
                                                                                                "a1", "zz"]),
                                                                               scalars(), max_size=3), json_values()),
                                           "seed": scalars(), "mc_poses": scalars(), "ga_tol": scalars(),
                                           "ga_rounds": scalars(), "confidence": scalars(), "time_limit": scalars()})


def encode(request, how):
    """A request as the text a node might receive: strict JSON, JSON with NaN, duplicate keys, deep nesting,
    bytes that are not UTF-8, a truncated text, or an oversized one."""
    text = json.dumps(request, allow_nan=True, default=str, ensure_ascii=False) if how != "strict" else \
        json.dumps(request, default=str)
    if how == "duplicate":
        return text[:-1] + ', "id": "again"}' if text.endswith("}") else text
    if how == "deep":
        return '{"id": 1, "joints": ' + "[" * 5000 + "]" * 5000 + "}"
    if how == "bytes":
        return text.encode("utf-8", "surrogatepass")[:-1] + b"\xff"
    if how == "truncated":
        return text[: max(1, len(text) // 2)]
    if how == "huge":
        return text[:-1] + ', "pad": "' + "x" * 1_000_100 + '"}'
    if how == "nested_id":
        return '{"zz": {"id": "' + NESTED_ID + '"}, ' + text[1:] if text.startswith("{") and len(text) > 2 else text
    return text


ENCODINGS = ["strict", "loose", "loose", "loose", "duplicate", "deep", "bytes", "truncated", "huge", "nested_id"]
NESTED_ID = "inner-id"
"""The id of an object nested before the request's own id (``encode(..., "nested_id")``): never an answer's."""
UNKNOWN = object()


def expected_id(text):
    """The id the answer to request ``text`` must carry: the top-level id of the JSON object the service parses
    (None when it has no valid one), or UNKNOWN for text it cannot parse (its id is then recovered best-effort)."""
    from tolerance_ros.core.jsonio import loads_strict
    from tolerance_ros.services.contracts import valid_id
    try:
        doc = loads_strict(text)
    except Exception:  # not JSON for the service: no id to be sure of
        return UNKNOWN
    rid = doc.get("id") if isinstance(doc, dict) else None
    return rid if valid_id(rid) else None


# ------------------------------------------------------------------ files: every reader of the project

RAW_YAML = ["1_000", "1:30", "017", "0x1F", "0b11", ".nan", "-.inf", "~", "yes", "2001-12-14", "9" * 400,
            "!!python/object:os.system x", "!!set {a: null}", "!!binary aGk=", "*undefined", "&r [1, *r]",
            "[" * 40 + "]" * 40, "{a: 1, a: 2}", "{<<: 5}", '"\\ud800"', '"\\x00"', "'pi/2'", "'1_0.5'", "-pi/2"]
"""YAML tokens written in place of a value: the number forms readers disagree on, tags, aliases, nesting."""
HOSTILE_VALUES = [None, True, 0, -1, 1.5, 1e308, float("nan"), float("inf"), 10 ** 400, "", "x", "1_000", "pi/2",
                  "1" * 200, [], [1], [[]], {}, {"a": 1}, ["deg"], "deg"]
TEXT_EDITS = ["none"] * 6 + ["bom", "utf16", "byte", "nul", "truncate", "deep", "bomb", "recursive", "duplicate",
                            "documents", "tab", "empty", "list", "huge"]
"""What is done to a file's bytes after its document is written (``edit_bytes``)."""
XML_EDITS = ["none"] * 3 + ["swap", "limit", "origin", "axis", "type", "drop_link", "twin_joint", "two_parents",
                            "deep", "entities", "mimic"]
"""What is done to a URDF's elements (``edit_urdf``)."""
_RAW = "@@RAW{}@@"


def _paths(doc, prefix=()):
    """Every path (tuple of keys and indices) to a value in a parsed document, the root's children first."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        out.append(prefix + (k,))
        out += _paths(v, prefix + (k,))
    return out


def _set(doc, path, value, delete=False):
    import copy
    doc = copy.deepcopy(doc)
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    if delete:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    return doc


@st.composite
def mutated_document(draw, base):
    """A parsed document with one value replaced (by a hostile value or a raw YAML token), a key deleted or
    an unknown key added, or unchanged; returns (document, {placeholder: raw token})."""
    paths = _paths(base)
    action = draw(st.sampled_from(["keep", "value", "value", "raw", "raw", "delete", "unknown"]))
    raw = {}
    if action == "keep" or not paths:
        return base, raw
    path = draw(st.sampled_from(paths))
    if action == "value":
        return _set(base, path, draw(st.one_of(st.sampled_from(HOSTILE_VALUES), json_values()))), raw
    if action == "raw":
        raw[_RAW.format(0)] = draw(st.sampled_from(RAW_YAML))
        return _set(base, path, _RAW.format(0)), raw
    if action == "delete":
        return _set(base, path, None, delete=True), raw
    if isinstance(_get(base, path[:-1]), dict):
        return _set(base, path[:-1] + ("zz_unknown",), 1), raw
    return base, raw


def _get(doc, path):
    for k in path:
        doc = doc[k]
    return doc


def dump_yaml(doc, raw) -> bytes:
    import yaml
    text = yaml.safe_dump(doc, sort_keys=False, allow_unicode=True, default_flow_style=None, width=100)
    for key, token in raw.items():
        text = text.replace(f"'{key}'", token).replace(key, token)
    return text.encode("utf-8")


def dump_json(doc, raw) -> bytes:
    text = json.dumps(doc, allow_nan=True, default=str, ensure_ascii=False)
    for key, token in raw.items():
        text = text.replace(f'"{key}"', token)
    return text.encode("utf-8")


def edit_bytes(data: bytes, how: str, position: float, json_like=False) -> bytes:
    """``data`` with one edit of TEXT_EDITS at a relative ``position`` (0..1) where it needs one."""
    k = int(position * len(data))
    if how == "bom":
        return b"\xef\xbb\xbf" + data
    if how == "utf16":
        return data.decode("utf-8", "replace").encode("utf-16")
    if how == "byte":
        return data[:k] + b"\xff\xe9" + data[k:]
    if how == "nul":
        return data[:k] + b"\x00" + data[k:]
    if how == "truncate":
        return data[:k]
    if how == "deep":
        n = 33 + int(position * 100_000)
        if json_like:
            return data.rstrip()[:-1] + b', "deep": ' + b"[" * n + b"]" * n + b"}"
        return data + b"\ndeep: " + b"[" * n + b"]" * n + b"\n"
    if how == "bomb":
        lines = [b"b0: &b0 [x, x, x, x, x, x, x, x, x, x]"] + [
            f"b{i}: &b{i} [{', '.join([f'*b{i - 1}'] * 10)}]".encode() for i in range(1, 9)]
        return data + b"\n" + b"\n".join(lines) + b"\n"
    if how == "recursive":
        return data + b"\nrec: &r [1, *r]\n"
    if how == "duplicate":
        first = data.split(b"\n", 1)[0]
        return data + b"\n" + first + b"\n" if not json_like else data.rstrip()[:-1] + b", " + data.strip()[1:]
    if how == "documents":
        return data + b"\n---\nb: 1\n"
    if how == "tab":
        return data.replace(b"\n  ", b"\n\t", 1)
    if how == "empty":
        return b""
    if how == "list":
        return b"- 1\n- 2\n" if not json_like else b"[1, 2]"
    if how == "huge":
        return data + b"\npad: '" + b"x" * (4 * 1024 * 1024 + 10) + b"'\n"
    return data


@st.composite
def yaml_file(draw, base, json_like=False):
    """Bytes of a mutated YAML (or JSON) document: a structural mutation, then an edit of its bytes."""
    doc, raw = draw(mutated_document(base))
    data = (dump_json if json_like else dump_yaml)(doc, raw)
    return edit_bytes(data, draw(st.sampled_from(TEXT_EDITS)), draw(st.floats(0, 1)), json_like)


def edit_urdf(text: str, how: str, pick: int, value) -> str:
    """URDF text with one element-level edit of XML_EDITS on joint number ``pick`` (mod the joints)."""
    import copy
    import xml.etree.ElementTree as ET
    if how == "deep":
        n = 65 + pick * 997
        return text.replace("</robot>", "<link name='deep'>" + "<visual>" * n + "</visual>" * n + "</link></robot>")
    if how == "entities":
        return ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
                + "".join(f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi"))
                + "]>" + text.split("?>", 1)[-1].replace('name="ur5"', 'name="&i;"', 1))
    root = ET.fromstring(text)
    joints = root.findall("joint")
    j = joints[pick % len(joints)]
    if how == "swap":
        p, c = j.find("parent"), j.find("child")
        a, b = p.get("link"), c.get("link")
        p.set("link", b)
        c.set("link", a)
    elif how == "limit" and j.find("limit") is not None:
        j.find("limit").set("lower" if pick % 2 else "upper", str(value))
        if pick % 3 == 0:
            j.find("limit").set("lower", "1")
            j.find("limit").set("upper", "-1")
    elif how == "origin":
        org = j.find("origin")
        if org is None:
            org = ET.SubElement(j, "origin")
        org.set("xyz" if pick % 2 else "rpy", str(value))
    elif how == "axis":
        ax = j.find("axis")
        if ax is None:
            ax = ET.SubElement(j, "axis")
        ax.set("xyz", "0 0 0" if pick % 2 else str(value))
    elif how == "type":
        j.set("type", ["floating", "planar", "banana", "fixed", "continuous", ""][pick % 6])
    elif how == "drop_link":
        links = root.findall("link")
        root.remove(links[pick % len(links)])
    elif how == "twin_joint":
        root.append(copy.deepcopy(j))
    elif how == "two_parents":
        other = joints[(pick + 1) % len(joints)]
        other.find("child").set("link", j.find("child").get("link"))
    elif how == "mimic":
        ET.SubElement(j, "mimic", joint=joints[0].get("name"))
    return ET.tostring(root, encoding="unicode")


@st.composite
def urdf_text(draw, base: str):
    """Text of a mutated URDF: an element-level edit, then maybe a character-level one."""
    text = edit_urdf(base, draw(st.sampled_from(XML_EDITS)), draw(st.integers(0, 50)),
                     draw(st.sampled_from(["1 2", "nan 0 0", "1e400 0 0", "", "a b c", "1", "-1", "x", "1e-320 0 0"])))
    how = draw(st.sampled_from(["none", "none", "bom", "space", "truncate", "nul", "huge"]))
    k = int(draw(st.floats(0, 1)) * len(text))
    return {"none": text, "bom": "\ufeff" + text, "space": "\n  " + text, "truncate": text[:k],
            "nul": text[:k] + "\x00" + text[k:], "huge": text + " " * (8 * 1024 * 1024)}[how]


@st.composite
def urdf_file(draw, base: str):
    text = draw(urdf_text(base))
    data = text.encode("utf-8", "surrogatepass")
    return edit_bytes(data, draw(st.sampled_from(["none", "none", "byte", "utf16"])), draw(st.floats(0, 1)))


def csv_file(base: bytes):
    """Bytes of a mutated measurement CSV: a line repeated, dropped or cut, a cell replaced, then a byte edit."""
    @st.composite
    def make(draw):
        lines = base.split(b"\n")
        k = draw(st.integers(0, len(lines) - 1))
        how = draw(st.sampled_from(["none", "repeat", "drop", "cell", "cell", "header"]))
        if how == "repeat":
            lines.insert(k, lines[k])
        elif how == "drop":
            del lines[k]
        elif how in ("cell", "header"):
            row = lines[k if how == "cell" else next(i for i, line in enumerate(lines) if not line.startswith(b"#"))]
            cells = row.split(b",")
            cells[draw(st.integers(0, len(cells) - 1))] = draw(st.sampled_from(
                [b"nan", b"inf", b"1e400", b"", b"x", b"1_000", b'"1,2"', b"\xff", b"stamp", b"x [furlong]", b"-0"]))
            lines[lines.index(row)] = b",".join(cells)
        data = b"\n".join(lines)
        return edit_bytes(data, draw(st.sampled_from(["none", "none", "none", "bom", "byte", "nul", "truncate",
                                                      "utf16", "empty"])), draw(st.floats(0, 1)))
    return make()


# ------------------------------------------------------------------ the other entry points of the services

NAMES = ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6", "joint7"]


def joint_states():
    """(stamp, names, positions) of a joint state, valid about a third of the time: names None, repeated,
    missing or not text; positions of the wrong length, type or finiteness; stamps odd."""
    names = st.one_of(st.just(NAMES), st.permutations(NAMES), st.just(NAMES + ["joint1"]), st.just(NAMES[:-1]),
                      st.just(None), st.just([1, 2, 3, 4, 5, 6, 7]), st.just([["joint1"]] + NAMES[1:]),
                      st.lists(st.text(max_size=6), max_size=9), st.just(["x" * 5000] * 200))
    positions = st.one_of(st.just(Q), CONFIGURATION, st.lists(st.one_of(st.floats(), scalars()), max_size=9),
                          st.just(None), st.just("1234567"), st.just([[0.0] * 7]))
    stamp = st.one_of(st.floats(0, 1e6), st.floats(), st.sampled_from([None, "1", -1, 2 ** 70, True]))
    return st.tuples(stamp, names, positions)


def names_twice(names) -> bool:
    """True for joint names that name one of the arm's joints more than once (such a state must be refused)."""
    return isinstance(names, (list, tuple)) and any(list(names).count(n) > 1 for n in NAMES)


def measured_poses():
    """(stamp, frame_id, position, quaternion) of a measured pose, valid about a third of the time."""
    frame = st.one_of(st.just("tracker"), st.text(max_size=8), st.just("tracker\ud800"), st.just("\udfff"),
                      st.just("f" * 100_000), st.just(None), st.just(5))
    position = st.one_of(st.just([0.5, 0.1, 0.6]), st.lists(st.one_of(st.floats(), scalars()), max_size=4),
                         st.just([1e7, 0, 0]), st.just(None))
    quaternion = st.one_of(st.just([0.0, 0.0, 0.0, 1.0]), st.lists(st.one_of(st.floats(), scalars()), max_size=5),
                           st.just([0, 0, 0, 0]), st.just(None))
    stamp = st.one_of(st.floats(0, 1e6), st.floats(), st.sampled_from([None, "1", -1]))
    return st.tuples(stamp, frame, position, quaternion)


def budget_messages(budget_doc):
    """Texts of tolerance_budget messages: the budget (an SI dict of ``Budget.to_dict``) mutated, for the
    message's robot or another, as JSON with the request encodings."""
    body = mutated_document({"robot": "gao2023_7dof", "budget": budget_doc}).map(lambda d_raw: d_raw[0])
    return st.tuples(body, st.sampled_from(ENCODINGS)).map(lambda b: encode(b[0], b[1]))


PAYLOADS = [None, 0, 1.5, [], ["{}"], {"id": 1}, object(), b"\xff", bytearray(b'{"id": 1}'), memoryview(b"{}")]
"""Payloads a Python caller may pass where request text is expected."""


# ------------------------------------------------------------------ the readers, their inputs and their oracles

import re  # noqa: E402

_DISPUTED = re.compile(rb"(?:(?<=: )|(?<=\[)|(?<=, )|(?<=- ))(1_000|1:30|017|0x1F|0b11)(?=[,\]}\s]|$)")
_TOP_KEY = re.compile(rb"^([A-Za-z_]\w*):", re.M)


def must_refuse(data: bytes, kind: str):
    """Why a reader must refuse this input whatever else it holds (None when it may read it): a YAML 1.1
    number form as a plain scalar, a key given twice, a URDF limit whose lower is above its upper, a link
    with two parent joints or a kinematic cycle. An oracle of its own, independent of the readers."""
    if kind == "yaml":
        if _DISPUTED.search(data):
            return "a YAML 1.1 number form (1_000, 1:30, 017, 0x1F, 0b11) read as a number"
        keys = _TOP_KEY.findall(data)
        if len(keys) != len(set(keys)):
            return "a top-level key given twice"
    if kind == "json":
        def pairs(items):
            names = [k for k, _ in items]
            if len(names) != len(set(names)):
                raise KeyError("twice")
            return dict(items)
        try:
            json.loads(data.decode("utf-8-sig"), object_pairs_hook=pairs)
        except KeyError:
            return "a key given twice in one object"
        except ValueError:
            return None
    if kind == "urdf":
        import xml.etree.ElementTree as ET
        try:
            root = ET.fromstring(data.decode("utf-8-sig").lstrip())
        except (ET.ParseError, UnicodeDecodeError, ValueError):
            return None
        parent = {}
        for j in root.findall("joint"):
            lim, p, c = j.find("limit"), j.find("parent"), j.find("child")
            try:
                if j.get("type") == "revolute" and lim is not None and float(lim.get("lower", 0)) > float(
                        lim.get("upper", 0)):
                    return "a revolute limit whose lower is above its upper"
            except ValueError:
                pass
            if p is not None and c is not None:
                if c.get("link") in parent:
                    return "a link with two parent joints"
                parent[c.get("link")] = p.get("link")
        for link in parent:
            seen = set()
            while link in parent:
                if link in seen:
                    return "a kinematic cycle"
                seen.add(link)
                link = parent[link]
    return None


class Reader:
    """One file reader: ``files`` generates the bytes of its input, ``read(path)`` reads one, ``error`` is its
    own exception class (every failure must be one, naming the file), ``check(result)`` asserts that what
    it accepted is usable (finite numbers), ``refuse(data)`` says why an input must be refused (or None)."""

    def __init__(self, name, suffix, files, read, error, check, kind):
        self.name, self.suffix, self.files, self.read, self.error, self.check = name, suffix, files, read, error, check
        self.refuse = lambda data: must_refuse(data, kind)


def _calibration_doc(model):
    return {"format": "tolerance_ros.calibration/1", "robot": model.name, "units": {"length": "mm", "angle": "mrad"},
            "sources": {"robot": None}, "base_correction": {"xyz": [0.01, 0.0, 0.0], "rotation_vector": [0, 0, 0]},
            "parameters": {n: {"error": 0.001, "std": 0.0001} for n in model.param_names}, "held": [],
            "unidentifiable": [], "aliases": {}, "fit": {"rank": 28, "condition": 3.2, "noise_m": 1e-5}}


def readers() -> dict:
    """Every file reader of the project, by name (built once)."""
    global _READERS
    if _READERS is None:
        _READERS = _build_readers()
    return _READERS


_READERS = None


def _build_readers():
    import numpy as np
    import yaml

    from .example_robots import example_urdf
    from tolerance_ros.core.accuracy.io import MeasurementError, read_csv
    from tolerance_ros.core.budget import BudgetError, load_budget
    from tolerance_ros.core.calibration.calibration_file import CalibrationError, load_calibration
    from tolerance_ros.core.campaign import CampaignError, load_campaign
    from tolerance_ros.core.models import ModelError, load_robot
    from tolerance_ros.core.resources import config_dir

    cfg = config_dir()
    gao = load_robot("gao2023_7dof")
    robot_doc = yaml.safe_load((cfg / "robots" / "gao2023_7dof.yaml").read_text())
    pups_doc = yaml.safe_load((cfg / "robots" / "rong2018_3pups.yaml").read_text())
    budget_doc = yaml.safe_load((cfg / "budgets" / "gao2023_delta1.yaml").read_text())
    campaign_doc = yaml.safe_load((cfg / "campaigns" / "gao2023_iso_cube.yaml").read_text())
    ur5 = example_urdf("ur5_robot.urdf").read_text()
    csv = b"\n".join((cfg / "data" / "rong2018_pe_measurements.csv").read_bytes().split(b"\n")[:40])

    def finite_model(m):
        try:
            T = m.fk(m.joint_limits.mean(axis=1)[None])
        except ModelError:  # a parallel mechanism that does not assemble there is still a valid model
            return
        assert np.isfinite(T).all()

    def budget_ok(b):
        try:
            d = b.vector_for(gao)
        except BudgetError:
            return
        assert np.isfinite(d).all() and (d >= 0).all()

    def measurements_ok(m):
        assert np.isfinite(m.T).all() and np.isfinite(m.stamps).all()

    from tolerance_ros.core.accuracy.io.contact_csv import read_contacts, write_contacts
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        q = gao.sample_joints(6, 3)
        contact_csv = write_contacts(Path(tmp) / "c.csv", np.arange(6.0), [f"P{i}" for i in range(6)], ["s1"] * 6,
                                     ["A", "B"] * 3, ["plane:t", "point:p"] * 3, q, gao.joint_names,
                                     gao.joint_types, ["contacts"]).read_bytes()

    def contacts_ok(c):
        assert np.isfinite(c.joints).all() and np.isfinite(c.stamps).all() and c.joints.shape[1] == gao.dof

    def campaign_ok(c):
        try:
            q = c.joints_for(gao)
        except CampaignError:
            return
        assert np.isfinite(q).all() and not gao.out_of_limits(q).any()

    return {r.name: r for r in [
        Reader("robot YAML", ".yaml", st.one_of(yaml_file(robot_doc), yaml_file(pups_doc)), load_robot, ModelError,
               finite_model, "yaml"),
        Reader("URDF file", ".urdf", urdf_file(ur5), lambda p: load_robot(p, tip_link="tool0"), ModelError,
               finite_model, "urdf"),
        Reader("budget YAML", ".yaml", yaml_file(budget_doc), lambda p: load_budget(p, gao), BudgetError, budget_ok,
               "yaml"),
        Reader("budget JSON", ".json", yaml_file(budget_doc, json_like=True), lambda p: load_budget(p, gao),
               BudgetError, budget_ok, "json"),
        Reader("campaign", ".yaml", yaml_file(campaign_doc), lambda p: load_campaign(p, gao), CampaignError,
               campaign_ok, "yaml"),
        Reader("calibration", ".yaml", yaml_file(_calibration_doc(gao)),
               lambda p: load_calibration(p, gao).mechanism(gao), CalibrationError, finite_model, "yaml"),
        Reader("measurement CSV", ".csv", csv_file(csv), read_csv, MeasurementError, measurements_ok, "csv"),
        Reader("contact CSV", ".csv", csv_file(contact_csv),
               lambda p: read_contacts(p, gao.joint_names, gao.joint_types), MeasurementError, contacts_ok, "csv"),
    ]}
