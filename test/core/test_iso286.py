"""ISO 286 grades."""
import pytest

from tolerance_ros.core.iso286 import IT_UM, coarsest_grade, it_tolerance


def test_known_values():
    assert it_tolerance(7, 25) == pytest.approx(21e-6)       # 18-30 mm, IT7 = 21 um
    assert it_tolerance(6, 10) == pytest.approx(9e-6)        # 6-10 mm (10 is in that range), IT6 = 9 um
    assert it_tolerance(9, 177) == pytest.approx(100e-6)     # 120-180 mm, IT9 = 100 um


def test_grades_follow_the_iso_formula_for_it5_to_it18():
    # IT = k * i, i = 0.45 D^(1/3) + 0.001 D (um), D the geometric mean of the range: checked loosely,
    # the standard rounds its values.
    factors = {5: 7, 6: 10, 7: 16, 8: 25, 9: 40, 10: 64, 11: 100, 12: 160, 13: 250, 14: 400}
    steps = [(3, 6), (18, 30), (120, 180), (400, 500)]
    for lo, hi in steps:
        D = (lo * hi) ** 0.5
        i = 0.45 * D ** (1 / 3) + 0.001 * D
        for g, k in factors.items():
            assert it_tolerance(g, hi) * 1e6 == pytest.approx(k * i, rel=0.1)


def test_rows_increase_with_grade_and_size():
    for g in range(1, 18):
        assert all(a <= b for a, b in zip(IT_UM[g], IT_UM[g + 1]))
        assert all(a <= b for a, b in zip(IT_UM[g], IT_UM[g][1:]))


def test_coarsest_grade():
    # +-0.05 mm on a 177 mm length: zone 100 um = IT9 at 120-180 mm.
    assert coarsest_grade(0.05e-3, 177) == 9
    assert coarsest_grade(0.0499e-3, 177) == 8
    assert coarsest_grade(1e-9, 177) is None
    with pytest.raises(ValueError):
        coarsest_grade(1e-4, 0)
