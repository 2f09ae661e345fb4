"""Tolerance budgets: a tolerance per kinematic parameter plus the design limits, saved as YAML or JSON.

File format (YAML or JSON; ``units`` applies to every length and angle in the file)::

    robot: gao2023_7dof              # the robot the budget belongs to
    units: {length: mm, angle: rad}  # SI when omitted
    limit: {position: 1.4}           # design limit(s); orientation in the angle unit, optional
    criterion: paper                 # how the limit was judged: paper | worst-case | rss
    tolerances: {a1: 0.0996, d1: 0.0506, alpha1: 0.0003, ...}   # +- limits per parameter
    free: [alpha7, theta7]           # optional: parameters with no effect on the limited errors
    default: 0                       # optional: tolerance of parameters not listed
    source: "..."                    # free text; other keys under `meta:` are kept as they are

Every parameter of the robot must be listed (in ``tolerances`` or ``free``) unless ``default`` is given,
so nothing is silently zero. ``free`` parameters count as 0 in error bounds: they do not move what
the limits constrain (e.g. the last joint's angle errors for a position limit).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import LIMIT_CRITERIA
from .resources import resolve
from .units import UnitError, angle_scale, length_scale, parse_number, parse_quantity
from .yamlio import dump_yaml, read_json, read_yaml

_KEYS = {"robot", "units", "limit", "criterion", "tolerances", "free", "default", "source", "meta"}


MAX_TOLERANCE = {"length": 1.0, "angle": 3.141592653589793}  # m, rad: the largest tolerance a budget may give
PLAUSIBLE_SHARE = 0.05   # of the robot's reach: the largest design limit or length tolerance believed for it
PLAUSIBLE_ANGLE = 0.1    # rad: the largest orientation limit or angle tolerance believed


class BudgetError(ValueError):
    """An invalid budget file or a budget that does not fit the robot; the message names the field."""


@dataclass
class Budget:
    """Tolerances (SI, +- limits) by parameter name, and the design limits (m, rad)."""

    tolerances: dict
    robot: str | None = None
    limit_position: float | None = None
    limit_orientation: float | None = None
    criterion: str = "paper"
    source: str | None = None
    meta: dict = field(default_factory=dict)
    default: float | None = None
    free: tuple = ()
    path: str | None = None

    def vector_for(self, model) -> np.ndarray:
        """(p,) tolerances in the model's parameter order (SI). Unknown or missing names raise."""
        where = f"{self.path}: " if self.path else ""
        unknown = sorted((set(self.tolerances) | set(self.free)) - set(model.param_names))
        if unknown:
            raise BudgetError(f"{where}tolerances: unknown parameter name(s) {unknown} for robot {model.name!r}")
        missing = [n for n in model.param_names if n not in self.tolerances and n not in self.free]
        if missing and self.default is None:
            raise BudgetError(f"{where}tolerances: no tolerance for {missing}; list them, mark them `free`, "
                              f"or set `default`")
        return np.array([0.0 if n in self.free else self.tolerances.get(n, self.default)
                         for n in model.param_names], dtype=float)

    def problem_for(self, model, where="") -> str | None:
        """Why this budget cannot be meant for ``model`` (``limits_problem``: a limit or tolerance implausible for
        its size), or None."""
        return limits_problem(model, self.limit_position, self.limit_orientation, self.tolerances, where)

    @classmethod
    def from_vector(cls, model, delta, free=None, **kw) -> "Budget":
        """Budget from a (p,) SI tolerance vector in the model's order; ``free`` is a (p,) bool mask."""
        free = np.zeros(model.n_params, bool) if free is None else np.asarray(free, bool)
        return cls(tolerances={n: float(v) for n, v, f in zip(model.param_names, delta, free) if not f},
                   robot=model.name, free=tuple(n for n, f in zip(model.param_names, free) if f), **kw)

    def to_dict(self, units=None, kinds=None) -> dict:
        """Plain dict; SI unless ``units`` ({length:, angle:}) and the per-name ``kinds`` are given."""
        units = units or {"length": "m", "angle": "rad"}
        ls, as_ = length_scale(units["length"]), angle_scale(units["angle"])
        kinds = kinds or {}

        def conv(name, v):
            return _clean(float(v) / (as_ if kinds.get(name, _guess_kind(name)) == "angle" else ls))

        out = {"robot": self.robot, "units": dict(units), "criterion": self.criterion, "limit": {}}
        if self.limit_position is not None:
            out["limit"]["position"] = _clean(self.limit_position / ls)
        if self.limit_orientation is not None:
            out["limit"]["orientation"] = _clean(self.limit_orientation / as_)
        out["tolerances"] = {n: conv(n, v) for n, v in self.tolerances.items()}
        if self.free:
            out["free"] = list(self.free)
        if self.default is not None:
            out["default"] = self.default
        if self.source:
            out["source"] = self.source
        if self.meta:
            out["meta"] = self.meta
        return out

    def save(self, path, units=None, kinds=None) -> Path:
        """Write YAML (``.yaml``/``.yml``) or JSON (anything else)."""
        path = Path(path)
        data = self.to_dict(units, kinds)
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix in (".yaml", ".yml"):
            path.write_text(dump_yaml(data, sort_keys=False))
        else:
            path.write_text(json.dumps(data, indent=2) + "\n")
        return path


def budget_from_dict(data, kinds=None, field_prefix="") -> Budget:
    """Budget from a parsed file; ``kinds`` maps parameter name -> 'length' | 'angle' (needed for units)."""
    f = field_prefix
    if not isinstance(data, dict):
        raise BudgetError(f"{f or 'budget'}: expected a mapping")
    extra = sorted(set(data) - _KEYS)
    if extra:
        raise BudgetError(f"{f}budget: unknown key(s) {extra}; allowed: {sorted(_KEYS)}")
    units = data.get("units") or {}
    if not isinstance(units, dict):
        raise BudgetError(f"{f}units: expected a mapping like {{length: mm, angle: rad}}")
    try:
        ls = length_scale(units.get("length", "m"), f"{f}units.length")
        as_ = angle_scale(units.get("angle", "rad"), f"{f}units.angle")
    except UnitError as exc:
        raise BudgetError(str(exc)) from None
    tol = data.get("tolerances")
    if tol is None and data.get("free"):
        tol = {}
    if not isinstance(tol, dict) or (not tol and not data.get("free")):
        raise BudgetError(f"{f}tolerances: expected a mapping of parameter name -> tolerance")
    kinds = kinds or {}
    scaled_units = ls != 1.0 or as_ != 1.0
    tolerances = {}
    for name, value in tol.items():
        try:
            v = parse_number(value, f"{f}tolerances.{name}")
        except UnitError as exc:
            raise BudgetError(str(exc)) from None
        if v < 0:
            raise BudgetError(f"{f}tolerances.{name}: must be >= 0, got {v}")
        kind = kinds.get(name, _guess_kind(name))
        if scaled_units and kind is None:
            raise BudgetError(f"{f}tolerances.{name}: cannot tell whether it is a length or an angle")
        tolerances[str(name)] = v * (as_ if kind == "angle" else ls)
        top = MAX_TOLERANCE["angle" if kind == "angle" else "length"]
        if tolerances[str(name)] > top:
            raise BudgetError(f"{f}tolerances.{name}: {value!r} is beyond {top:g} {'rad' if kind == 'angle' else 'm'}; "
                              f"no part is made that loosely (a unit mistake?)")
    limit = data.get("limit") or {}
    if not isinstance(limit, dict):
        raise BudgetError(f"{f}limit: expected a mapping like {{position: 1.4}}")
    bad = sorted(set(limit) - {"position", "orientation"})
    if bad:
        raise BudgetError(f"{f}limit: unknown key(s) {bad}; allowed: position, orientation")
    lp = lo = None
    try:
        if limit.get("position") is not None:
            lp = parse_number(limit["position"], f"{f}limit.position") * ls
        if limit.get("orientation") is not None:
            lo = parse_number(limit["orientation"], f"{f}limit.orientation") * as_
    except UnitError as exc:
        raise BudgetError(str(exc)) from None
    for nm, v in (("position", lp), ("orientation", lo)):
        if v is not None and v <= 0:
            raise BudgetError(f"{f}limit.{nm}: must be > 0")
    criterion = data.get("criterion", "paper")
    if criterion not in LIMIT_CRITERIA:
        raise BudgetError(f"{f}criterion: expected one of {LIMIT_CRITERIA}, got {criterion!r}")
    free = data.get("free") or []
    if not isinstance(free, list) or not all(isinstance(n, str) for n in free):
        raise BudgetError(f"{f}free: expected a list of parameter names")
    both = sorted(set(free) & set(tolerances))
    if both:
        raise BudgetError(f"{f}free: {both} also have a tolerance; a parameter is either free or toleranced")
    default = data.get("default")
    if default is not None:
        try:
            default = parse_number(default, f"{f}default")
        except UnitError as exc:
            raise BudgetError(str(exc)) from None
        if default != 0:
            raise BudgetError(f"{f}default: only 0 is allowed (a unit-free default would be ambiguous)")
    return Budget(tolerances=tolerances, robot=data.get("robot"), limit_position=lp, limit_orientation=lo,
                  criterion=criterion, source=data.get("source"), meta=data.get("meta") or {}, default=default,
                  free=tuple(free))


def limits_problem(model, position=None, orientation=None, tolerances=None, where="") -> str | None:
    """Why design limits (``position`` m, ``orientation`` rad) or ``tolerances`` ({parameter: SI}) cannot be meant
    for ``model``: a limit or a length tolerance beyond ``PLAUSIBLE_SHARE`` of its reach, an orientation limit or
    an angle tolerance beyond ``PLAUSIBLE_ANGLE`` (no part is made, no robot designed, that loosely: a unit
    off); None when they can."""
    reach = model.reach()
    cap = PLAUSIBLE_SHARE * reach
    size = f"{model.name}'s reach is {reach:.3g} m"
    if position is not None and not position <= cap:
        return (f"{where}the position limit {position * 1e3:.6g} mm is {position / reach * 100:.3g} % of the robot's size "
                f"({size}); no design limit is that loose (a length unit off: m written for mm?)")
    if orientation is not None and not orientation <= PLAUSIBLE_ANGLE:
        return (f"{where}the orientation limit {orientation:.6g} rad is beyond {PLAUSIBLE_ANGLE:g} rad; no design limit is "
                f"that loose (an angle unit off: rad written for mrad, or degrees?)")
    kinds = dict(zip(model.param_names, model.param_kinds))
    for name, value in (tolerances or {}).items():
        if kinds.get(name) == "angle" and not value <= PLAUSIBLE_ANGLE:
            return (f"{where}tolerances.{name}: {value:.6g} rad is beyond {PLAUSIBLE_ANGLE:g} rad; no part is made that "
                    f"loosely (an angle unit off?)")
        if kinds.get(name) == "length" and not value <= cap:
            return (f"{where}tolerances.{name}: {value * 1e3:.6g} mm is {value / reach * 100:.3g} % of the robot's size "
                    f"({size}); no part is made that loosely (a length unit off: m written for mm?)")
    return None


def _guess_kind(name: str):
    """Kind from a parameter name when the robot is not known: D-H and URDF names are unambiguous."""
    base = name.split(".")[-1] if "." in name else name.rstrip("0123456789")
    if base in ("a", "d", "x", "y", "z", "b", "l"):
        return "length"
    if base in ("alpha", "theta", "roll", "pitch", "yaw"):
        return "angle"
    return None


def load_budget(spec, model=None) -> Budget:
    """Budget from a YAML/JSON path or a shipped budget name; with ``model``, units follow its parameters."""
    path = resolve("budgets", spec, suffixes=(".yaml", ".yml", ".json"))
    data = read_json(path, BudgetError) if path.suffix == ".json" else read_yaml(path, BudgetError)
    kinds = dict(zip(model.param_names, model.param_kinds)) if model is not None else None
    robot = data.get("robot") if isinstance(data, dict) else None
    if model is not None and robot and str(robot) != model.name:  # before its fields: they are another robot's
        raise BudgetError(f"{path}: this budget is for robot {str(robot)[:80]!r}, not {model.name!r}")
    try:
        budget = budget_from_dict(data, kinds)
    except BudgetError as exc:
        raise BudgetError(f"{path}: {exc}") from None
    budget.path = str(path)
    problem = budget.problem_for(model) if model is not None else None
    if problem:
        raise BudgetError(f"{path}: {problem}")
    return budget


def _clean(x: float) -> float:
    """``x`` to 15 significant digits: a unit conversion's last-bit noise (1e-5 m is 0.009999999999999998 mm)
    removed, every digit a tolerance can carry kept."""
    return float(f"{x:.15g}")


def tolerance_vector(spec: str, model) -> np.ndarray:
    """(p,) tolerances (m, rad) of ``model``'s parameters from a budget (a file or a shipped name) or
    ``uniform:LENGTH,ANGLE`` (each with its unit: ``uniform:0.1mm,0.5mrad``, every length and every angle);
    BudgetError naming the spec."""
    if str(spec).startswith("uniform:"):
        parts = str(spec)[len("uniform:"):].split(",")
        if len(parts) != 2:
            raise BudgetError(f"tolerances: expected uniform:LENGTH,ANGLE (e.g. uniform:0.1mm,0.5mrad), got {spec!r}")
        try:
            length, angle = parse_quantity(parts[0], "length", "tolerances"), parse_quantity(parts[1], "angle",
                                                                                              "tolerances")
        except UnitError as exc:
            raise BudgetError(str(exc)) from None
        if not (length > 0 and angle > 0):
            raise BudgetError(f"tolerances: uniform lengths and angles must be > 0, got {spec!r}")
        return np.array([length if k == "length" else angle for k in model.param_kinds])
    return load_budget(spec, model).vector_for(model)
