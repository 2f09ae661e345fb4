"""Build mechanism models from YAML robot files (units stated in the file, converted to SI)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..resources import resolve
from ..units import UnitError, angle_scale, length_scale, parse_number
from ..geometry import transform
from ..yamlio import read_yaml
from .base import PRISMATIC, REVOLUTE, Mechanism, ModelError
from .dh import DHChain
from .urdf import URDFChain

_DH_KEYS = {"name", "kind", "convention", "units", "joints", "base", "tool", "description", "source", "notes"}
_DH_JOINT_KEYS = {"name", "type", "a", "alpha", "d", "theta", "limits", "direction", "offset"}
_URDF_KEYS = {"name", "kind", "urdf", "tip_link", "base_link", "description", "source", "notes"}


def load_robot(spec, tip_link=None, base_link=None) -> Mechanism:
    """Model from a robot YAML path, a URDF path, a shipped robot name, or an already built model.

    ``tip_link`` / ``base_link`` choose the chain of a URDF robot (overriding its YAML file's).
    """
    if isinstance(spec, Mechanism):
        if tip_link is not None or base_link is not None:
            raise ModelError("tip_link, base_link: only for a robot loaded from a URDF or its file")
        return spec
    path = resolve("robots", spec, suffixes=(".yaml", ".yml", ".urdf"))
    if _xml_kind(path) == "urdf" or path.suffix == ".urdf":
        try:
            return URDFChain(path, tip_link=tip_link, base_link=base_link).check_size()
        except ModelError as exc:  # every error names the file
            raise ModelError(str(exc) if str(path) in str(exc) else f"{path}: {exc}") from None
    data = read_yaml(path, ModelError)
    if not isinstance(data, dict):
        raise ModelError(f"{path}: expected a mapping at the top level")
    kinds = _kinds()
    kind = data.get("kind")
    if not isinstance(kind, str) or kind not in kinds:
        raise ModelError(f"{path}: kind: expected one of {sorted(kinds)}, got {kind!r:.60}")
    if tip_link is not None or base_link is not None:
        if kind != "urdf":
            raise ModelError(f"{path}: tip_link, base_link: only for URDF robots, not kind {kind!r}")
        data = {**data, **{k: v for k, v in (("tip_link", tip_link), ("base_link", base_link)) if v is not None}}
    try:
        model = kinds[kind](data, path)
    except UnitError as exc:
        raise ModelError(f"{path}: {exc}") from None
    except ModelError as exc:
        raise ModelError(f"{path}: {exc}") from None
    model.config_path = str(path)
    return model.check_size(f"{path}: ")


def _xml_kind(path: Path) -> str | None:
    """'urdf' for a file of URDF XML whatever its suffix (``robot.xml``), None for any other file; ModelError for a
    xacro file (URDF macros), which must be expanded into a URDF first."""
    with open(path, "rb") as f:
        text = f.read(1 << 24).decode("utf-8", errors="replace").lstrip("\ufeff \t\r\n")
    if path.name.endswith(".xacro") or (text.startswith("<") and "<xacro:" in text and _xacro_shapes(text)):
        urdf = path.name.removesuffix(".xacro")
        urdf = urdf if urdf.endswith(".urdf") else f"{Path(urdf).stem}.urdf"
        raise ModelError(f"{path}: a xacro file (URDF macros), not a URDF: expand it first, e.g. `xacro {path} > "
                         f"{urdf}` (xacro comes with ROS 2, or `pip install xacro`), and give the .urdf")
    return "urdf" if text.startswith("<") else None


def _xacro_shapes(text: str) -> bool:
    """Whether xacro shapes the kinematics of this XML (a macro defined or a file included, a ``${...}`` in a link or
    joint, or no joint at all): such a file must be expanded. A URDF whose links and joints are written out is read
    as it is, whatever xacro leftovers it carries elsewhere (example-robot-data's TALOS keeps macro calls in its
    transmissions)."""
    import xml.etree.ElementTree as ET
    if "<xacro:macro" in text or "<xacro:include" in text:
        return True
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return True
    joints = root.findall("joint")
    if not joints:
        return True
    return any("${" in v for el in joints + root.findall("link") for sub in el.iter() for v in sub.attrib.values())


def _kinds():
    kinds = {"dh": dh_from_dict, "urdf": urdf_from_dict}
    try:
        from .pups import pups_from_dict
        kinds["3pups"] = pups_from_dict
    except ImportError:
        pass
    return kinds


def _unknown(d: dict, allowed: set, field: str):
    extra = sorted(set(d) - allowed)
    if extra:
        raise ModelError(f"{field}: unknown key(s) {extra}; allowed: {sorted(allowed)}")


def _units(data):
    units = data.get("units", {}) or {}
    if not isinstance(units, dict):
        raise ModelError("units: expected a mapping like {length: mm, angle: rad}")
    _unknown(units, {"length", "angle"}, "units")
    return length_scale(units.get("length", "m")), angle_scale(units.get("angle", "rad"))


def frame_from_dict(value, field, lscale, ascale):
    """4x4 transform from ``{xyz: [...], rpy: [...]}`` in the file's units."""
    if value is None:
        return np.eye(4)
    if not isinstance(value, dict):
        raise ModelError(f"{field}: expected a mapping with xyz and rpy")
    _unknown(value, {"xyz", "rpy"}, field)
    xyz = _triple(value.get("xyz", [0, 0, 0]), f"{field}.xyz") * lscale
    rpy = _triple(value.get("rpy", [0, 0, 0]), f"{field}.rpy") * ascale
    return transform(xyz, rpy)


def _triple(v, field):
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise ModelError(f"{field}: expected three numbers")
    return np.array([parse_number(x, f"{field}[{i}]") for i, x in enumerate(v)])


def dh_from_dict(data: dict, path=None) -> DHChain:
    """DHChain from a parsed robot file of kind 'dh'."""
    _unknown(data, _DH_KEYS, "robot")
    lscale, ascale = _units(data)
    joints = data.get("joints")
    if not isinstance(joints, list) or not joints:
        raise ModelError("joints: expected a non-empty list")
    cols = {k: [] for k in ("a", "alpha", "d", "theta")}
    types, limits, names, direction, offset = [], [], [], [], []
    for i, j in enumerate(joints):
        field = f"joints[{i}]"
        if not isinstance(j, dict):
            raise ModelError(f"{field}: expected a mapping")
        _unknown(j, _DH_JOINT_KEYS, field)
        t = j.get("type", REVOLUTE)
        if t not in (REVOLUTE, PRISMATIC):
            raise ModelError(f"{field}.type: expected 'revolute' or 'prismatic', got {t!r}")
        types.append(t)
        names.append(str(j.get("name", f"joint{i + 1}")))
        for k, scale in (("a", lscale), ("d", lscale), ("alpha", ascale), ("theta", ascale)):
            if k not in j:
                if (k == "theta" and t == REVOLUTE) or (k == "d" and t == PRISMATIC):
                    cols[k].append(0.0)
                    continue
                raise ModelError(f"{field}.{k}: missing")
            cols[k].append(parse_number(j[k], f"{field}.{k}") * scale)
        sign = j.get("direction", 1)
        if isinstance(sign, bool) or sign not in (1, -1):
            raise ModelError(f"{field}.direction: expected 1 or -1 (the controller's sign of the joint), got {sign!r}")
        direction.append(float(sign))
        offset.append(parse_number(j.get("offset", 0), f"{field}.offset") * (ascale if t == REVOLUTE else lscale))
        lim = j.get("limits")
        if lim is None:
            if t == PRISMATIC:
                raise ModelError(f"{field}.limits: a prismatic joint needs limits")
            limits.append([-np.pi, np.pi])
        else:
            if not isinstance(lim, (list, tuple)) or len(lim) != 2:
                raise ModelError(f"{field}.limits: expected [lower, upper]")
            scale = ascale if t == REVOLUTE else lscale
            limits.append([parse_number(lim[0], f"{field}.limits[0]") * scale,
                           parse_number(lim[1], f"{field}.limits[1]") * scale])
    base = frame_from_dict(data.get("base"), "base", lscale, ascale)
    tool = frame_from_dict(data.get("tool"), "tool", lscale, ascale)
    name = data.get("name") or (Path(path).stem if path else "dh_robot")
    return DHChain(name, cols["a"], cols["alpha"], cols["d"], cols["theta"], types, limits, names,
                   convention=data.get("convention", "standard"), base=base, tool=tool, direction=direction,
                   offset=offset)


def urdf_from_dict(data: dict, path=None) -> URDFChain:
    """URDFChain from a parsed robot file of kind 'urdf' (the URDF path is relative to the file)."""
    _unknown(data, _URDF_KEYS, "robot")
    urdf = data.get("urdf")
    if not isinstance(urdf, str):
        raise ModelError("urdf: expected the path of a URDF file")
    urdf_path = Path(urdf).expanduser()
    if not urdf_path.is_absolute() and path is not None:
        urdf_path = Path(path).parent / urdf_path
    return URDFChain(urdf_path, tip_link=data.get("tip_link"), base_link=data.get("base_link"),
                     name=data.get("name"))
