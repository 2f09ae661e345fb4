"""The calibration file: its format, written and read, and every check a calibration passes when it is loaded.

Calibration file (YAML; ``units`` applies to ``parameters``, ``base_correction``, ``registration`` and
``aliases``; the ``fit`` and ``validation`` blocks name their unit in each key, ``_m`` or ``_rad``)::

    format: tolerance_ros.calibration/1
    robot: gao2023_7dof
    units: {length: mm, angle: mrad}
    sources: {robot: .../gao2023_7dof.yaml, measurements: m.csv, campaign: null,
              calibrated_robot: gao2023_7dof_calibrated.yaml}     # relative to this file, or absolute
    provenance:                                    # who made it, from what (all optional but content_sha256)
      id: 3f0c9a...                                # a uuid4 (hex) of this calibration
      request_id: k1                               # the calibrate request's id (calibrations made by the service)
      time: 2026-12-01T08:15:00Z                   # when it was made (UTC), and unix_time_s: 1796199300.0
      log: .../campaigns/gao2023_7dof_20261201_081200.jsonl   # the measurement log it was fitted to
      log_sha256: 9d2e...                          # SHA-256 of that log's bytes (of the snapshot fitted)
      made_by: /arm/tolerance_accuracy_monitor     # the node (full name) or `tolerance-ros calibrate`
      content_sha256: 51b7...                      # SHA-256 of this document's content (see provenance.py)
    registration:
      method: base                                 # base | base+tool
      T_tracker_base: {xyz: [...], rpy: [...]}     # nominal base frame -> tracker frame
      tool_offset: null                            # [x, y, z], tool frame (base+tool, one target)
    targets:                                       # what the tracker measured, in the tool frame
      frames: false                                # false: points; true: measured frames (with rpy)
      by_name: {A: {xyz: [...], rpy: [0, 0, 0], std: [...]}}   # one per target ('' for the one unnamed)
    compliance: {arm_2_joint: {value: ..., std: ...}, ...}   # rad/(N m) or m/N; null without the elastic term
    nominal_registration: {T_tracker_base: {...}, base: {...}, targets: {...}}   # the registration-only fit
    model: {parameters: full, prior: [0.005, 0.005], how: ..., candidates: [...]}  # what was identified, and why
    base_correction: {xyz: [...], rotation_vector: [...]}   # on the left of the model: T = B T(q, dx)
    parameters:                                    # identified - nominal, standard uncertainty
      a1: {error: 0.0123, std: 0.0011}
      d1: {error: 0, std: 0}                       # held at nominal (listed under held)
    held: [d1, theta1]                             # not identifiable from these poses: left at nominal
    unidentifiable: [d1, theta1, base.z, base.rz]  # the identifiability analysis of `report`
    aliases: {a6: {theta6: -91.12}}                # estimate = own error + c * held error (file units)
    fit: {measurements: 90, poses: 30, rows: 270, unknowns: 30, rank: 28, condition: 25.2, fit_condition: 21.3,
          noise_per_axis_m: 1.0e-05, position_rms_m: ..., position_max_m: ...,    # 3-D, in-sample, kept rows
          per_axis_rms_before_m: ..., per_axis_rms_after_m: ...}
    convergence: {iterations: 9, stop: gradient, converged: true, gradient_cosine: ..., decrement: ..., words: ...}
    undetermined: {joint_1.rx: "set by the prior: ..."}   # estimated, but not told by the data
    suspect: [{row: 7, ...}]                       # beyond the threshold, kept (their removal loses identifiability)
    warnings: [...]
    load: {model: point-mass, mass_kg: 1.0, point_m: [0, 0, 0], description: ...}   # of the elastostatic term
    validation: {method: ..., before: {position_rms_m: ...}, after: {...}, improvement: 0.93, per_pose: {...}}
    rejected: [{row: 12, target: A, residual_m: ..., threshold_m: ..., reason: ...}]   # outliers left out
    plausibility: {ok: true, problems: []}
    repeatability: {repeated_measurements: 60, scatter_m: ..., residual_rms_m: ..., unexplained_m: ...}
    training: {joint_ranges: [[lo, hi], ...], postures: [[...], ...]}   # SI: to group another campaign's poses
    signature: {algorithm: ed25519, key_id: 0a1b2c3d4e5f6071, value: <base64>}   # optional, last

``provenance.content_sha256`` is the SHA-256 of the document as read back, without itself and without
``signature``, in canonical JSON (``provenance.canonical``): every reader computes it, refuses a document whose
declared hash differs (its content was changed after it was made), and reports the calibration by it. The
``signature`` (written with a signing key, ``calibration_text(..., signing_key=...)``) is Ed25519 over that
hash; a node with trusted keys refuses a calibration without one, or with another key's, or a false one.
The calibrate service saves exactly the text it publishes (SI), so its file and the topic's text have the
same hash. Files without ``provenance`` (made before it existed) are read; their hash is computed. A file
edited by hand no longer matches its hash and is refused: delete its ``content_sha256`` line (its ``signature``
too, which the edit has made false) and the readers compute the hash of the edited content.

``tolerance_ros.calibration/1`` files (one tool offset, no targets, no elastic term) are read too, and
``tolerance_ros.calibration/2`` files, whose compliances were signed against the potential energy's gradient
(a joint that yields had a negative one): they are read with their sign turned (format 3: ``c > 0`` yields,
``elastic``).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..identification import BASE_NAMES
from ..geometry import rpy_from_matrix
from ..models.base import Mechanism, ModelError
from ..models.loader import frame_from_dict, load_robot
from ..resources import ConfigNotFound, not_a_file
from ..units import UnitError, angle_scale, length_scale, parse_number
from ..targets import Targets
from ..yamlio import Dumper, dump_yaml, loads_yaml, read_yaml
from .elastic import Load
from .provenance import ProvenanceError, check_blocks, signature, stamped, verified_provenance
from .result import NOMINAL_TOLERANCE, Calibration

FORMAT = "tolerance_ros.calibration/3"
FORMATS = ("tolerance_ros.calibration/1", "tolerance_ros.calibration/2", FORMAT)
GRADIENT_SIGNED = ("tolerance_ros.calibration/2",)   # formats whose compliances multiply +dV/dq
UNITS = {"length": "mm", "angle": "mrad"}


class CalibrationError(ValueError):
    """An invalid calibration file, or one that does not fit the robot; the message names the field."""


# ------------------------------------------------------------------ the calibration file


def _name_scales(names, kinds, ls, as_) -> dict:
    """SI value of one file unit for every parameter name and base-correction component."""
    out = {n: ls if k == "length" else as_ for n, k in zip(names, kinds)}
    out.update({b: ls if b in BASE_NAMES[:3] else as_ for b in BASE_NAMES})
    return out


def save_calibration(cal: Calibration, path, units=None, signing_key=None) -> Path:
    """Write the calibration file (format in the module docstring); lengths and angles in ``units``; signed
    with ``signing_key`` when given."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(calibration_text(cal, units, signing_key))
    return path


SI = {"length": "m", "angle": "rad"}
MAX_TEXT = 4 << 20  # characters of a calibration received as text


def calibration_text(cal: Calibration, units=None, signing_key=None) -> str:
    """The calibration file's content (``units``, default mm and mrad; ``SI`` for the graph's
    ``tolerance_calibration`` topic), its content hash stamped, signed with ``signing_key`` (an Ed25519
    private key, ``provenance.load_signing_key``) when one is given."""
    head = (f"# Calibration of {cal.robot} by tolerance-ros calibrate; format: "
            f"tolerance_ros/core/calibration/calibration_file.py\n")
    doc = stamped(_document(cal, units), lambda d: loads_yaml(_dump(d), "calibration", CalibrationError))
    if signing_key is not None:
        doc["signature"] = signature(doc["provenance"]["content_sha256"], signing_key)
    return head + _dump(doc)


_BLOCK = ("provenance", "signature")   # written one key a line: an edit by hand deletes a line (content_sha256)


class _BlockMapping(dict):
    """A mapping written one key a line."""


class _Dumper(Dumper):
    pass


_Dumper.add_representer(_BlockMapping, lambda dumper, data: dumper.represent_mapping("tag:yaml.org,2002:map", data,
                                                                                     flow_style=False))


def _dump(doc) -> str:
    """The document as YAML: short mappings of numbers inline, the provenance and signature one key a line."""
    doc = {k: _BlockMapping(v) if k in _BLOCK and isinstance(v, dict) else v for k, v in doc.items()}
    return dump_yaml(doc, Dumper=_Dumper, sort_keys=False, default_flow_style=None, width=110)


def calibration_from_text(text, model: Mechanism, source="tolerance_calibration") -> Calibration:
    """A Calibration from the content of a calibration file (as ``calibration_text`` writes it), checked
    against ``model``; CalibrationError naming ``source`` and the field."""
    if not isinstance(text, str):
        raise CalibrationError(f"{source}: expected the calibration file's text")
    if len(text) > MAX_TEXT:
        raise CalibrationError(f"{source}: longer than {MAX_TEXT} characters")
    doc = loads_yaml(text, source, CalibrationError)
    _check_document(doc, source)
    try:
        return _calibration_from_dict(doc, Path("."), model)
    except (UnitError, ModelError, CalibrationError, KeyError, TypeError, ValueError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        raise CalibrationError(f"{source}: {msg}") from None


def _document(cal: Calibration, units=None) -> dict:
    units = dict(units or UNITS)
    ls, as_ = length_scale(units["length"]), angle_scale(units["angle"])
    kind_scale = {"length": ls, "angle": as_}
    T = cal.T_tracker_base
    scale_of = _name_scales(cal.names, cal.kinds, ls, as_)
    doc = {
        "format": FORMAT,
        "robot": cal.robot,
        "units": units,
        "sources": {k: ([str(x) for x in v] if isinstance(v, (list, tuple)) else str(v) if v is not None else None)
                    for k, v in cal.sources.items()},
        "provenance": {k: v for k, v in (cal.provenance or {}).items() if k != "content_sha256"},
        "registration": {"method": cal.registration,
                         "T_tracker_base": {"xyz": plain_floats(T[:3, 3] / ls),
                                            "rpy": plain_floats(rpy_from_matrix(T[None, :3, :3])[0] / as_)},
                         "tool_offset": None if cal.tool_offset is None else plain_floats(np.asarray(cal.tool_offset) / ls)},
        "base_correction": {"xyz": plain_floats(cal.base[:3] / ls), "rotation_vector": plain_floats(cal.base[3:] / as_)},
        "parameters": {n: {"error": float(v / kind_scale[k]), "std": float(s / kind_scale[k])}
                       for n, k, v, s in zip(cal.names, cal.kinds, cal.dx, cal.std)},
        "held": list(cal.held),
        "unidentifiable": list(cal.unidentifiable),
        "aliases": {n: {h: float(c * scale_of[h] / scale_of[n]) for h, c in a.items()} for n, a in cal.aliases.items()},
        "fit": {k: v for k, v in _plain(cal.fit_dict()).items() if k != "convergence" and v is not None},
        "convergence": _plain(cal.convergence),
        "undetermined": _plain(cal.undetermined),
        "suspect": _plain(cal.suspect),
        "warnings": _plain(cal.warnings),
        "load": _plain(cal.load),
        "validation": _plain(_without_samples(cal.validation)),
        "targets": _targets_doc(cal.targets, cal.targets_std, ls, as_),
        "compliance": None if cal.compliance is None else {
            n: {"value": float(c), "std": float(s)}
            for n, c, s in zip(cal.sources.get("joint_names") or [f"joint{i + 1}" for i in range(len(cal.compliance))],
                               cal.compliance, cal.compliance_std)},
        "nominal_registration": None if cal.nominal_registration is None else {
            "T_tracker_base": _frame_doc(cal.nominal_registration["T_tracker_base"], ls, as_),
            "base": {"xyz": plain_floats(cal.nominal_registration["base"][:3] / ls),
                     "rotation_vector": plain_floats(cal.nominal_registration["base"][3:] / as_)},
            "targets": _targets_doc(cal.nominal_registration["targets"], None, ls, as_)},
        "model": _plain(cal.model),
        "rejected": _plain(cal.rejected),
        "plausibility": _plain(cal.plausibility),
        "repeatability": _plain(cal.repeatability),
        "training": _plain(cal.training),
        "nominal": _plain(cal.nominal),
    }
    return doc


def _frame_doc(T, ls, as_) -> dict:
    return {"xyz": plain_floats(T[:3, 3] / ls), "rpy": plain_floats(rpy_from_matrix(T[None, :3, :3])[0] / as_)}


def _targets_doc(targets, std, ls, as_) -> dict:
    by_name = {}
    for k, (name, X) in enumerate(zip(targets.names, targets.X)):
        entry = _frame_doc(X, ls, as_)
        if std is not None:
            entry["std"] = plain_floats(np.asarray(std[k]) / ls)
        by_name[name] = entry
    return {"frames": bool(targets.frames), "by_name": by_name}


def _targets_from(doc, field, ls, as_):
    """(Targets, std (K, 3) m or None) of a targets block."""
    if not isinstance(doc, dict) or not isinstance(doc.get("frames", False), bool) or \
            not isinstance(doc.get("by_name"), dict):
        raise CalibrationError(f"{field}: expected frames: true|false and by_name: {{target: {{xyz, rpy}}}}")
    names, X, std = [], [], []
    for name, entry in doc["by_name"].items():
        if not isinstance(entry, dict):
            raise CalibrationError(f"{field}.{name}: expected {{xyz, rpy}}")
        names.append("" if name is None else str(name))
        X.append(frame_from_dict({"xyz": entry.get("xyz"), "rpy": entry.get("rpy", [0, 0, 0])}, f"{field}.{name}",
                                 ls, as_))
        s = entry.get("std")
        std.append(None if s is None else [parse_number(v, f"{field}.{name}.std[{i}]") * ls for i, v in enumerate(s)])
    if not names:
        raise CalibrationError(f"{field}: no target")
    stds = None if any(s is None for s in std) else np.array(std, float)
    return Targets(tuple(names), np.array(X), bool(doc.get("frames", False))), stds


def load_calibration(path, model: Mechanism | None = None) -> Calibration:
    """Calibration from its file, checked against ``model`` (the nominal robot; by default
    ``calibration_robot(path)``)."""
    doc = _read(path)
    model = model if model is not None else calibration_robot(path)
    try:
        return _calibration_from_dict(doc, Path(path), model)
    except (UnitError, ModelError, CalibrationError, KeyError, TypeError, ValueError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        raise CalibrationError(f"{path}: {msg}") from None


def load_calibrated_model(path, model: Mechanism | None = None) -> Mechanism:
    """The calibrated Mechanism of a calibration file (what the error-model service serves)."""
    model = model if model is not None else calibration_robot(path)
    return load_calibration(path, model).mechanism(model)


_COUNTS = ("measurements", "poses", "rows", "unknowns", "rank")  # the whole numbers of the fit block
_SECTIONS = {"units": dict, "sources": dict, "registration": dict, "base_correction": dict, "parameters": dict,
             "held": list, "unidentifiable": list, "aliases": dict, "fit": dict, "validation": dict, "targets": dict,
             "compliance": dict, "nominal_registration": dict, "model": dict, "rejected": list, "plausibility": dict,
             "repeatability": dict, "training": dict, "convergence": dict, "undetermined": dict, "suspect": list,
             "warnings": list, "load": dict, "provenance": dict, "signature": dict, "nominal": dict}


def _read(path):
    """The calibration file's document (bounded reader, ``core.yamlio``), its format and the type of each
    section checked."""
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"calibration {str(path)!r}: {not_a_file(path)}")
    doc = read_yaml(path, CalibrationError)
    _check_document(doc, path)
    return doc


def _check_document(doc, path):
    """The format and the type of each section of a calibration document; CalibrationError naming ``path``."""
    if not isinstance(doc, dict) or doc.get("format") not in FORMATS:
        raise CalibrationError(f"{path}: format: expected {FORMAT!r}")
    for key, kind in _SECTIONS.items():
        if doc.get(key) is not None and not isinstance(doc[key], kind):
            raise CalibrationError(f"{path}: {key}: expected {'a mapping' if kind is dict else 'a list'}, got "
                                   f"{type(doc[key]).__name__}")
    for key in ("parameters", "aliases"):
        for name, entry in (doc.get(key) or {}).items():
            if not isinstance(entry, dict):
                raise CalibrationError(f"{path}: {key}.{name}: expected a mapping")
    numbers = [(f"fit.{k}", v) for k, v in (doc.get("fit") or {}).items()] + [
        (f"aliases.{n}.{h}", c) for n, a in (doc.get("aliases") or {}).items() for h, c in a.items()]
    for field, value in numbers:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise CalibrationError(f"{path}: {field}: expected a number, got {type(value).__name__}")
        if isinstance(value, int) and abs(value) > 2 ** 53:
            raise CalibrationError(f"{path}: {field}: an integer of {len(str(abs(value)))} digits is too large")
        if field.split(".")[-1] in _COUNTS and field.startswith("fit.") and not float(value).is_integer():
            raise CalibrationError(f"{path}: {field}: expected a whole number, got {value!r}")
    if not isinstance(doc.get("robot"), str):
        raise CalibrationError(f"{path}: robot: expected the robot's name")
    bad = _not_finite(doc)
    if bad:
        raise CalibrationError(f"{path}: {bad}: not a finite number (a calibration file holds none)")
    try:
        check_blocks(doc, path)
    except ProvenanceError as exc:
        raise CalibrationError(str(exc)) from None
    return doc


def calibration_robot_name(path) -> str:
    """The name of the robot a calibration file is for (the file read and checked as ``load_calibration`` does)."""
    return _read(path)["robot"]


def calibration_robot(path) -> Mechanism:
    """The nominal robot of a calibration file: its ``sources.robot`` (relative to the file) when that
    file exists, else its robot name (a shipped robot)."""
    doc = _read(path)
    sources = doc.get("sources") or {}
    src = sources.get("robot")
    if src:
        cand = Path(src) if Path(src).is_absolute() else Path(path).parent / src
        if cand.is_file():
            chain = {k: sources.get(k) for k in ("tip_link", "base_link")} if cand.suffix == ".urdf" else {}
            return load_robot(cand, **chain)
    try:
        return load_robot(str(doc.get("robot")))
    except (ConfigNotFound, ModelError, OSError):
        if not src:
            raise
        where = "relative to the calibration file" if not Path(src).is_absolute() else "absolute"
        raise CalibrationError(f"calibration {str(path)!r}: its robot file {src!r} ({where}) does not exist "
                               f"(was the calibration folder moved?), and {doc.get('robot')!r} is not a shipped "
                               f"robot; give the robot with --robot (and --tip-link for a URDF)") from None


def _calibration_from_dict(doc, path, model):
    robot = doc.get("robot")
    sources = doc.get("sources") or {}
    if robot != model.name:
        raise CalibrationError(f"robot: the calibration is for {robot!r}, not {model.name!r}")
    units = doc.get("units") or {}
    ls, as_ = length_scale(units.get("length", "m")), angle_scale(units.get("angle", "rad"))
    kind_scale = {"length": ls, "angle": as_}
    params = doc.get("parameters")
    if not isinstance(params, dict):
        raise CalibrationError("parameters: expected a mapping of parameter -> {error, std}")
    unknown = sorted(set(params) - set(model.param_names))
    missing = [n for n in model.param_names if n not in params]
    if unknown or missing:
        raise CalibrationError(f"parameters: unknown {unknown}, missing {missing} for robot {model.name!r}")
    dx = np.empty(model.n_params)
    std = np.empty(model.n_params)
    for j, (n, k) in enumerate(zip(model.param_names, model.param_kinds)):
        entry = params[n]
        if not isinstance(entry, dict):
            raise CalibrationError(f"parameters.{n}: expected {{error, std}}")
        dx[j] = parse_number(entry.get("error"), f"parameters.{n}.error") * kind_scale[k]
        std[j] = parse_number(entry.get("std", 0), f"parameters.{n}.std") * kind_scale[k]
    bc = doc.get("base_correction") or {}
    base = np.r_[[parse_number(v, f"base_correction.xyz[{i}]") * ls for i, v in enumerate(bc.get("xyz", [0] * 3))],
                 [parse_number(v, f"base_correction.rotation_vector[{i}]") * as_
                  for i, v in enumerate(bc.get("rotation_vector", [0] * 3))]]
    if base.shape != (6,):
        raise CalibrationError("base_correction: expected xyz and rotation_vector of three numbers each")
    reg = doc.get("registration") or {}
    T = frame_from_dict(reg.get("T_tracker_base"), "registration.T_tracker_base", ls, as_)
    tool = reg.get("tool_offset")
    tool = None if tool is None else np.array([parse_number(v, f"registration.tool_offset[{i}]") * ls
                                               for i, v in enumerate(tool)])
    fitd = doc.get("fit") or {}
    held = [str(h) for h in doc.get("held") or []]
    bad = sorted(set(held) - set(model.param_names))
    if bad:
        raise CalibrationError(f"held: unknown parameter(s) {bad}")
    scale_of = _name_scales(model.param_names, model.param_kinds, ls, as_)
    aliases = {n: {h: float(c) * scale_of[n] / scale_of[h] for h, c in a.items()}
               for n, a in (doc.get("aliases") or {}).items()}
    targets, targets_std = (None, None) if doc.get("targets") is None else _targets_from(doc["targets"], "targets",
                                                                                          ls, as_)
    compliance = compliance_std = None
    if doc.get("compliance") is not None:
        comp = doc["compliance"]
        if not isinstance(comp, dict) or sorted(comp) != sorted(model.joint_names) or \
                not all(isinstance(v, dict) for v in comp.values()):
            raise CalibrationError(f"compliance: expected {{value, std}} for each joint of {model.name!r} "
                                   f"({', '.join(model.joint_names)})")
        compliance = np.array([parse_number(comp[j].get("value"), f"compliance.{j}.value") for j in model.joint_names])
        compliance_std = np.array([parse_number(comp[j].get("std", 0), f"compliance.{j}.std")
                                   for j in model.joint_names])
        if doc.get("format") in GRADIENT_SIGNED:
            compliance = -compliance
    nominal = None
    nr = doc.get("nominal_registration")
    if nr is not None:
        if not isinstance(nr, dict):
            raise CalibrationError("nominal_registration: expected a mapping")
        nb = nr.get("base") or {}
        nominal = {"T_tracker_base": frame_from_dict(nr.get("T_tracker_base"), "nominal_registration.T_tracker_base",
                                                     ls, as_),
                   "base": np.r_[[parse_number(v, "nominal_registration.base.xyz") * ls
                                  for v in nb.get("xyz", [0] * 3)],
                                 [parse_number(v, "nominal_registration.base.rotation_vector") * as_
                                  for v in nb.get("rotation_vector", [0] * 3)]],
                   "targets": _targets_from(nr.get("targets"), "nominal_registration.targets", ls, as_)[0]}
    cal = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), dx, std, base, T, tool, held,
                      list(doc.get("unidentifiable") or []), aliases, float(fitd.get("condition", np.nan)),
                      float(fitd.get("fit_condition", np.nan)), int(fitd.get("rank", 0)),
                      int(fitd.get("unknowns", 0)), float(fitd.get("noise_per_axis_m", fitd.get("noise_m", np.nan))),
                      float(fitd.get("per_axis_rms_before_m", fitd.get("residual_rms_before_m", np.nan))),
                      float(fitd.get("per_axis_rms_after_m", fitd.get("residual_rms_after_m", np.nan))),
                      int(fitd.get("measurements", 0)),
                      int(fitd.get("poses", 0)), int(fitd.get("rows", 0)), str(reg.get("method", "base")),
                      doc.get("validation"), dict(sources), targets=targets, targets_std=targets_std,
                      compliance=compliance, compliance_std=compliance_std, nominal_registration=nominal,
                      model=doc.get("model") or {}, rejected=list(doc.get("rejected") or []),
                      plausibility=doc.get("plausibility") or {"ok": True, "problems": []},
                      repeatability=doc.get("repeatability"), training=doc.get("training"),
                      has_orientation=bool(targets.frames) if targets is not None else True,
                      convergence=doc.get("convergence"), undetermined=dict(doc.get("undetermined") or {}),
                      suspect=list(doc.get("suspect") or []), warnings=[str(w) for w in doc.get("warnings") or []],
                      position_rms=None if fitd.get("position_rms_m") is None else float(fitd["position_rms_m"]),
                      position_max=None if fitd.get("position_max_m") is None else float(fitd["position_max_m"]))
    try:  # last: a document that is wrong is said so by its field first
        cal.provenance, cal.signature = verified_provenance(doc), doc.get("signature")
    except ProvenanceError as exc:
        raise CalibrationError(str(exc)) from None
    if doc.get("load") is not None:
        try:
            Load.from_dict(doc["load"])
        except (TypeError, ValueError) as exc:
            raise CalibrationError(f"load: {exc}") from None
        cal.load = dict(doc["load"])
    if compliance is not None and cal.load is None:
        cal.load = Load.for_model(model).to_dict() if Load.for_model(model) else None
    cal.nominal = doc.get("nominal")
    check_calibration(cal, model)
    return cal


def plain_floats(v) -> list:
    """The numbers of ``v`` (any shape) as a flat list of Python floats."""
    return [float(x) for x in np.asarray(v, float).ravel()]


SAMPLES = ("position_error_m", "orientation_error_rad")   # per-measurement arrays: the report's (.json), not the file's


def _without_samples(validation):
    """The validation block without its per-measurement arrays (``SAMPLES``): the calibration file stays the size
    of the model, whatever the number of measurements."""
    if not validation:
        return validation
    return {k: v for k, v in validation.items() if k not in SAMPLES}


def _plain(obj):
    """YAML-safe copy (numpy scalars and arrays to Python; a number that is not finite, not known, to None:
    a calibration file holds no NaN or infinity, and its readers refuse one)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return _plain(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _not_finite(doc, where="") -> str | None:
    """The field (dotted path) of the first number in ``doc`` that is not finite, or None."""
    if isinstance(doc, dict):
        items = doc.items()
    elif isinstance(doc, list):
        items = ((f"[{i}]", v) for i, v in enumerate(doc))
    else:
        return where if isinstance(doc, float) and not math.isfinite(doc) else None
    for k, v in items:
        found = _not_finite(v, f"{where}{k}" if str(k).startswith("[") or not where else f"{where}.{k}")
        if found:
            return found
    return None


def check_calibration(cal: Calibration, model: Mechanism) -> None:
    """The checks a calibration passes when it is loaded, whoever loads it (the commands and the nodes alike):
    the robot given is the one it was made for (its ``nominal`` tool points, ``result.nominal_fingerprint``);
    an elastostatic term has a load this robot can compute. CalibrationError naming the field otherwise."""
    nominal = cal.nominal
    if nominal is not None:
        try:
            q = np.asarray(nominal["joints"], float)
            points = np.asarray(nominal["tool_points_m"], float)
            ok = q.ndim == 2 and q.shape[1] == model.dof and points.shape == (len(q), 3) and len(q) > 0
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise CalibrationError(f"nominal: expected joints ({model.dof} a posture) and tool_points_m (3 a posture)")
        off = float(np.linalg.norm(model.fk(q)[:, :3, 3] - points, axis=1).max())
        if off > NOMINAL_TOLERANCE:
            raise CalibrationError(f"nominal: {model.name} as given is not the robot this calibration was made for: at "
                                   f"the calibration's check postures its tool lies up to {off * 1e3:.4g} mm from where "
                                   f"that robot's did (another version of its robot file?)")
    if cal.compliance is not None and np.any(cal.compliance):
        load = cal.joint_load(model)
        if load is None:
            raise CalibrationError(f"compliance: an elastostatic term needs the gravity load of each joint, which "
                                   f"{model.name} ({type(model).__name__}) cannot give (a URDF chain can; no `load` "
                                   f"block names one)")
        try:
            load.torques(model, model.sample_joints(1, 0))
        except (ModelError, ValueError) as exc:
            raise CalibrationError(f"load: {exc}") from None

