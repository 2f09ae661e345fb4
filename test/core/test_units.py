"""Unit parsing."""
import math

import pytest

from tolerance_ros.core.units import UnitError, parse_number, parse_quantity


@pytest.mark.parametrize("text, kind, si", [("1.4mm", "length", 1.4e-3), ("1.4 mm", "length", 1.4e-3),
                                            ("0.0014m", "length", 0.0014), ("2um", "length", 2e-6),
                                            ("-1.4mm", "length", -1.4e-3), ("+3 deg", "angle", math.pi / 60),
                                            ("0.3mrad", "angle", 3e-4), ("1deg", "angle", math.pi / 180),
                                            (".5m", "length", 0.5), ("1e-3m", "length", 1e-3)])
def test_parse_quantity(text, kind, si):
    assert parse_quantity(text, kind) == pytest.approx(si)


@pytest.mark.parametrize("text", ["1.4 furlong", "mm", "abc", "1.4mm mm", "nan", "inf", "1e400m", "١.٤mm", 1.4])
def test_parse_quantity_rejects(text):
    with pytest.raises(UnitError, match="--limit"):
        parse_quantity(text, "length", field="--limit")


@pytest.mark.parametrize("text, kind", [("1.4", "length"), ("-0.5", "angle"), ("3e-3", "length")])
def test_a_bare_number_is_an_error_that_shows_the_accepted_forms(text, kind):
    with pytest.raises(UnitError, match="has no unit; write it with its unit, e.g.") as exc:
        parse_quantity(text, kind, field="--x")
    assert ("1.4mm" if kind == "length" else "0.3mrad") in str(exc.value)


@pytest.mark.parametrize("text, value", [("pi/2", math.pi / 2), ("-pi", -math.pi), (" 2*pi/3 ", 2 * math.pi / 3),
                                         (3, 3.0), ("1e-3", 1e-3)])
def test_parse_number(text, value):
    assert parse_number(text, "f") == pytest.approx(value)


@pytest.mark.parametrize("text", ["__import__('os')", "pi/0", "e", True, None, "1/", float("nan"), 10 ** 400,
                                  "9" * 101, "1+" * 30000 + "1", "-" * 100000 + "1", "1\x00"])
def test_parse_number_rejects_everything_else(text):
    with pytest.raises(UnitError, match="f"):
        parse_number(text, "f")


@pytest.mark.parametrize("text", ["1_000", "1_0.5", "2*1_0"])
def test_digit_separators_in_a_number_string_are_refused(text):
    with pytest.raises(UnitError, match=r"tolerances.a1: .*digit separators '_' are not accepted"):
        parse_number(text, "tolerances.a1")


def test_a_yaml_date_is_not_arithmetic():
    """YAML reads 2001-12-14 as a date; as arithmetic it would be 1975: refused, naming the field."""
    from tolerance_ros.core.units import UnitError, parse_number
    for text in ("2001-12-14", "2001-12-14T10:00:00", "2001-1-4 10:00"):
        with pytest.raises(UnitError, match="limit: .* is a date"):
            parse_number(text, "limit")
    assert parse_number("2001 - 12 - 14", "x") == 1975.0   # spaced, it is arithmetic and reads as written
