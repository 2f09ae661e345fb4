"""The calibrated robot's files, in the input's own form.

Calibrated robot files: a D-H robot YAML with the identified values written in the file's own units
(other keys and unchanged values kept as written; the base correction becomes ``base``), or a URDF
whose corrected joints' ``<origin xyz rpy>`` attributes carry the identified errors, zero offsets
and the base correction folded in exactly; every other byte of the file is kept.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..identification import base_matrix
from ..geometry import rpy_from_matrix
from ..models.base import Mechanism
from ..models.dh import DHChain
from ..models.urdf import URDFChain
from ..units import angle_scale, length_scale
from ..yamlio import dump_yaml, read_yaml
from .calibration_file import CalibrationError, plain_floats
from .mechanism import calibrated_mechanism, corrected_origins
from .result import Calibration


def write_calibrated_robot(model: Mechanism, cal: Calibration, out_dir) -> dict:
    """Write the calibrated robot in the input's own form into ``out_dir``; {kind: path}.

    D-H: ``<name>_calibrated.yaml``. URDF: ``<stem>_calibrated.urdf``, and ``<name>_calibrated.yaml`` of
    kind urdf pointing at it with the chain's tip and base links (the robot YAML it came from, edited).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if isinstance(model, DHChain):
        path = out_dir / f"{model.name}_calibrated.yaml"
        path.write_text(calibrated_dh_yaml(model, cal.dx, cal.base))
        return {"robot": str(path)}
    if isinstance(model, URDFChain):
        if model.source == "<string>":
            raise CalibrationError("calibrated URDF: the robot was built from a string; give it a file")
        stem = Path(model.source).stem
        urdf = out_dir / f"{stem}_calibrated.urdf"
        base, files = cal.base, {}
        if model._reversed[0] and np.any(base):
            # a chain from a sensor's link against its first joint: no joint origin holds a correction of where the
            # chain starts; it belongs with the sensor's placement on that link, which the calibration file carries
            base = np.zeros(6)
            files["note"] = (f"the calibrated URDF carries the joints' errors; the base correction (where the chain "
                             f"starts on {model.base_link!r}: with the measuring frame's placement, the sensor's mount) "
                             f"stays in the calibration file")
        urdf.write_text(calibrated_urdf_text(model, Path(model.source).read_text(), cal.dx, base))
        files["urdf"] = str(urdf)
        cfg = getattr(model, "config_path", None)
        data = read_yaml(cfg, CalibrationError) if cfg and Path(cfg).suffix in (".yaml", ".yml") else \
            {"name": model.name, "kind": "urdf"}
        data.update(urdf=urdf.name, tip_link=model.tip_link, base_link=model.base_link)
        path = out_dir / f"{model.name}_calibrated.yaml"
        path.write_text(_header(model) + dump_yaml(data, sort_keys=False, default_flow_style=None))
        files["robot"] = str(path)
        return files
    raise CalibrationError(f"calibration: robot {model.name!r} is a {type(model).__name__}; calibrated files are "
                           f"written for D-H and URDF chains")


def _header(model):
    return f"# {model.name}, calibrated by tolerance-ros calibrate (the calibration file lists what changed)\n"


def calibrated_dh_yaml(model: DHChain, dx, base) -> str:
    """Text of the calibrated D-H robot file: the input file's keys and units with the identified values
    (a value whose error is 0 stays as written), ``base := B @ base``; SI when the model has no file."""
    cal = calibrated_mechanism(model, dx, base)
    dx = np.asarray(dx, float)
    cfg = getattr(model, "config_path", None)
    if cfg:
        data = read_yaml(cfg, CalibrationError)
    else:
        data = {"name": model.name, "kind": "dh", "convention": model.convention,
                "units": {"length": "m", "angle": "rad"},
                "joints": [{"name": n, "type": t, "limits": [float(lo), float(hi)]}
                           for n, t, (lo, hi) in zip(model.joint_names, model.joint_types, model.joint_limits)]}
        data["tool"] = {"xyz": plain_floats(model.tool[:3, 3]), "rpy": plain_floats(rpy_from_matrix(model.tool[None, :3, :3])[0])}
    units = data.get("units") or {}
    ls, as_ = length_scale(units.get("length", "m")), angle_scale(units.get("angle", "rad"))
    n = model.dof
    p = cal.nominal
    for i, joint in enumerate(data["joints"]):
        for k, key in enumerate(("a", "d", "alpha", "theta")):
            j = k * n + i
            if dx[j] != 0 or key not in joint and p[j] != 0 or not cfg:
                joint[key] = float(p[j] / (ls if key in ("a", "d") else as_))
    if not np.array_equal(cal.base, model.base) or not cfg:
        data["base"] = {"xyz": plain_floats(cal.base[:3, 3] / ls),
                        "rpy": plain_floats(rpy_from_matrix(cal.base[None, :3, :3])[0] / as_)}
    return _header(model) + dump_yaml(data, sort_keys=False, default_flow_style=None, width=120)


_COMMENT = re.compile(r"<!--.*?-->", re.S)
_JOINT = re.compile(r"<joint\b[^>]*>")
_ATTR = r"\b{}\s*=\s*([\"'])(.*?)\1"


def calibrated_urdf_text(model: URDFChain, text: str, dx, base) -> str:
    """The URDF text with the corrected joints' ``<origin xyz rpy>`` values (``corrected_origins``).

    Only those attribute values change (an absent attribute or ``<origin>`` element is added); a
    component equal to its written value keeps its text. Comments are not touched.
    """
    values, changed = corrected_origins(model, dx, base_matrix(np.asarray(base, float)))
    wanted = {model.joint_names[k]: values[k] for k in np.flatnonzero(changed)}
    masked = _COMMENT.sub(lambda m: " " * len(m.group()), text)
    edits = []
    found = set()
    for m in _JOINT.finditer(masked):
        tag = m.group()
        name = re.search(_ATTR.format("name"), tag)
        if name is None or name.group(2) not in wanted or re.search(_ATTR.format("type"), tag) is None:
            continue
        jname = name.group(2)
        if tag.endswith("/>"):
            raise CalibrationError(f"urdf: joint {jname!r} is an empty element; it needs its <origin> and <axis>")
        end = masked.find("</joint>", m.end())
        body = masked[m.end():end]
        xyz, rpy = wanted[jname][:3], wanted[jname][3:]
        om = re.search(r"<origin\b[^>]*?/?>", body)
        if om is None:
            line_start = masked.rfind("\n", 0, m.start()) + 1
            indent = re.match(r"[ \t]*", masked[line_start:]).group() + "  "
            edits.append((m.end(), m.end(), f"\n{indent}<origin xyz=\"{_fmt(xyz)}\" rpy=\"{_fmt(rpy)}\"/>"))
        else:
            start = m.end() + om.start()
            edits += _origin_edits(masked[start:m.end() + om.end()], start, xyz, rpy)
        found.add(jname)
    lost = sorted(set(wanted) - found)
    if lost:
        raise CalibrationError(f"urdf: joint(s) {lost} not found in the text")
    out = text
    for a, b, new in sorted(edits, reverse=True):
        out = out[:a] + new + out[b:]
    return out


def _origin_edits(tag, offset, xyz, rpy):
    edits = []
    for attr, vals in (("xyz", xyz), ("rpy", rpy)):
        m = re.search(_ATTR.format(attr), tag)
        if m is None:
            close = len(tag) - (2 if tag.endswith("/>") else 1)
            edits.append((offset + close, offset + close, f" {attr}=\"{_fmt(vals)}\""))
            continue
        old = m.group(2).split()
        try:
            old_vals = [float(t) for t in old]
        except ValueError:
            old_vals = []
        tokens = [o if len(old) == 3 and old_vals[i] == v else repr(float(v)) for i, (o, v) in
                  enumerate(zip(old if len(old) == 3 else [""] * 3, vals))]
        edits.append((offset + m.start(2), offset + m.end(2), " ".join(tokens)))
    return edits


def _fmt(vals):
    return " ".join(repr(float(v)) for v in vals)
