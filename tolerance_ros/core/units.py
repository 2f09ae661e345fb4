"""Unit parsing and conversion to SI (metres, radians).

Configuration files state their units; everything inside the core is SI. Human reports may print
millimetres, but only where they say so.
"""
from __future__ import annotations

import ast
import math
import operator
import re

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "um": 1e-6, "µm": 1e-6, "in": 0.0254}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3, "urad": 1e-6, "µrad": 1e-6,
               "arcsec": math.pi / 648000.0}

MAX_EXPRESSION_CHARS = 100  # a number written as a small arithmetic string, e.g. '-pi/2'
_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
        ast.USub: operator.neg, ast.UAdd: operator.pos}


class UnitError(ValueError):
    """A unit name or a quantity string could not be understood."""


def length_scale(unit: str, field: str = "units.length") -> float:
    """Factor that converts a length in ``unit`` to metres."""
    try:
        return LENGTH_UNITS[str(unit).strip()]
    except KeyError:
        raise UnitError(f"{field}: unknown length unit {unit!r}; expected one of {sorted(LENGTH_UNITS)}") from None


def angle_scale(unit: str, field: str = "units.angle") -> float:
    """Factor that converts an angle in ``unit`` to radians."""
    try:
        return ANGLE_UNITS[str(unit).strip()]
    except KeyError:
        raise UnitError(f"{field}: unknown angle unit {unit!r}; expected one of {sorted(ANGLE_UNITS)}") from None


def scale_for(kind: str, units: dict, field: str = "units") -> float:
    """SI factor for a parameter of ``kind`` ('length' or 'angle') given a ``{length:, angle:}`` dict."""
    if kind == "length":
        return length_scale(units.get("length", "m"), f"{field}.length")
    if kind == "angle":
        return angle_scale(units.get("angle", "rad"), f"{field}.angle")
    raise UnitError(f"{field}: unknown quantity kind {kind!r}")


def _eval_node(node, field):
    if isinstance(node, ast.Expression):
        return _eval_node(node.body, field)
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.Name) and node.id == "pi":
        return math.pi
    if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
        return _OPS[type(node.op)](_eval_node(node.left, field), _eval_node(node.right, field))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _OPS:
        return _OPS[type(node.op)](_eval_node(node.operand, field))
    raise UnitError(f"{field}: only numbers, 'pi' and + - * / are allowed")


_TIMESTAMP = re.compile(r"^\d{4}-\d{1,2}-\d{1,2}([Tt ].*)?$")  # a YAML date or timestamp, not arithmetic


def parse_number(value, field: str) -> float:
    """A finite float from a number or a small arithmetic string (at most ``MAX_EXPRESSION_CHARS``) such as
    ``'-pi/2'``; digit separators (``'1_000'``) are refused, since YAML readers disagree on them."""
    if isinstance(value, bool):
        raise UnitError(f"{field}: expected a number, got {value!r}")
    if isinstance(value, (int, float)):
        try:
            out = float(value)
        except OverflowError:
            raise UnitError(f"{field}: value must be finite, got an integer of {value.bit_length()} bits") from None
    elif isinstance(value, str):
        if len(value) > MAX_EXPRESSION_CHARS:
            raise UnitError(f"{field}: a number written in more than {MAX_EXPRESSION_CHARS} characters: "
                            f"{value[:40]!r}...")
        if "_" in value:
            raise UnitError(f"{field}: {value[:40]!r}: digit separators '_' are not accepted in a number; write it "
                            f"without them")
        if _TIMESTAMP.match(value.strip()):
            raise UnitError(f"{field}: {value[:40]!r} is a date (YAML reads it as one), not a number")
        try:
            tree = ast.parse(value.strip(), mode="eval")
        except (SyntaxError, ValueError):
            raise UnitError(f"{field}: cannot parse {value!r} as a number") from None
        try:
            out = _eval_node(tree, field)
        except ZeroDivisionError:
            raise UnitError(f"{field}: division by zero in {value!r}") from None
    else:
        raise UnitError(f"{field}: expected a number, got {type(value).__name__}")
    if not math.isfinite(out):
        raise UnitError(f"{field}: value must be finite, got {value!r}")
    return out


_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*((?:[a-zA-Zµ][a-zA-Zµ/^2]*)?)\s*$",
                       re.ASCII)
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
DURATION_UNITS = {**TIME_UNITS, "min": 60.0, "h": 3600.0}  # a duration on the command line; stamps take TIME_UNITS
MASS_UNITS = {"kg": 1.0, "g": 1e-3, "t": 1e3}
SPEED_UNITS = {"m/s": 1.0, "mm/s": 1e-3}
ACCEL_UNITS = {"m/s^2": 1.0, "mm/s^2": 1e-3}
FREQUENCY_UNITS = {"Hz": 1.0, "kHz": 1e3}
FORCE_UNITS = {"N": 1.0, "kN": 1e3}
TORQUE_UNITS = {"Nm": 1.0, "kNm": 1e3}
ANGULAR_SPEED_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
ANGULAR_ACCEL_UNITS = {"rad/s^2": 1.0, "deg/s^2": math.pi / 180.0}
STIFFNESS_UNITS = {"Nm/rad": 1.0, "kNm/rad": 1e3}  # of a revolute joint
_EXAMPLES = {"length": "1.4mm or 0.0014m", "angle": "0.3mrad, 0.02deg or 0.0003rad", "time": "1s, 250ms or 1h",
             "mass": "165kg or 0.5t", "speed": "0.2m/s or 200mm/s", "acceleration": "1m/s^2",
             "frequency": "1000Hz or 1kHz", "force": "200N or 0.2kN", "torque": "20Nm", "stiffness": "50kNm/rad",
             "angular speed": "0.5rad/s or 30deg/s", "angular acceleration": "2.5rad/s^2"}
_TABLES = {"time": DURATION_UNITS, "mass": MASS_UNITS, "speed": SPEED_UNITS, "acceleration": ACCEL_UNITS,
           "frequency": FREQUENCY_UNITS, "force": FORCE_UNITS, "torque": TORQUE_UNITS, "stiffness": STIFFNESS_UNITS,
           "angular speed": ANGULAR_SPEED_UNITS, "angular acceleration": ANGULAR_ACCEL_UNITS}


def parse_quantity(text, kind: str = "length", field: str = "value") -> float:
    """SI value of a length, angle, time, mass, speed, acceleration or frequency written with its unit:
    ``'1.4mm'``, ``'0.3 mrad'``, ``'2 s'``, ``'165kg'``, ``'0.2m/s'``, ``'1m/s^2'``, ``'1kHz'``.

    A number without a unit is an error (a bare 1.4 could be metres or millimetres), as is an unknown
    unit or a non-finite value; the UnitError names ``field`` and shows the accepted forms.
    """
    units = {"length": LENGTH_UNITS, "angle": ANGLE_UNITS, **_TABLES}[kind]
    forms = f"write it with its unit, e.g. {_EXAMPLES[kind]} ({kind} units: {', '.join(sorted(units))})"
    m = _QUANTITY.match(str(text)) if isinstance(text, str) else None
    if not m:
        raise UnitError(f"{field}: cannot read {text!r} as {'an' if kind[0] in 'aeiou' else 'a'} {kind}; {forms}")
    number, unit = float(m.group(1)), m.group(2)
    if not unit:
        raise UnitError(f"{field}: {text!r} has no unit; {forms}")
    if kind in _TABLES:
        if unit not in _TABLES[kind]:
            raise UnitError(f"{field}: unknown {kind} unit {unit!r}; {forms}")
        scale = _TABLES[kind][unit]
    else:
        scale = length_scale(unit, field) if kind == "length" else angle_scale(unit, field)
    value = number * scale
    if not math.isfinite(value):
        raise UnitError(f"{field}: value must be finite, got {text!r}")
    return value
