"""Cycles from repetition: the period of a command that loops without a stop found from its geometry (the FFT lag
profile equal to its direct sums, the period equal to a bounded scipy search of the same objective and to the
program's), cusps where a line turns back, and the cycles cut there."""
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from path_runs import Q_CENTER
from tolerance_ros.core.accuracy import path as P
from tolerance_ros.core.accuracy.iso_paths import plan_path
from tolerance_ros.core.accuracy.path_report import command_points
from tolerance_ros.core.accuracy.repeats import cusps, lag_profile, period, split_runs


@pytest.fixture(scope="module")
def programs(gao):
    """(kind, dwell) -> (JointPath, joint stamps at 500 Hz, command points)."""
    out = {}
    for kind in ("line", "circle", "rectangle"):
        for dwell in (0.0, 0.5):
            jp, _ = plan_path(gao, kind, speed=0.2, accel=1.0, cycles=6, q_center=Q_CENTER, dwell=dwell)
            t = np.arange(int(jp.duration * 500) + 1) / 500
            out[kind, dwell] = jp, t, command_points(gao, jp.at(t))
    return out


def test_the_lag_profile_is_the_mean_squared_difference_at_each_lag():
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.standard_normal((300, 3)), axis=0)
    D = lag_profile(x)
    direct = [np.mean(np.sum((x[L:] - x[:len(x) - L]) ** 2, axis=1)) for L in range(len(x))]
    assert D == pytest.approx(direct, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("kind", ["line", "circle", "rectangle"])
def test_the_period_of_a_loop_without_a_stop_is_the_programs(programs, kind):
    jp, t, p = programs[kind, 0.0]
    found = period(t, p)
    assert found == pytest.approx(jp.period, abs=1e-3)

    def D(T):                                     # the same objective, continuous in T, evaluated directly
        a = t[t <= t[-1] - T]
        return float(np.mean(np.sum((P.interp_columns(a + T, t, p) - P.interp_columns(a, t, p)) ** 2, axis=1)))
    ref = minimize_scalar(D, bounds=(0.9 * jp.period, 1.1 * jp.period), method="bounded", options={"xatol": 1e-6})
    assert found == pytest.approx(ref.x, abs=2e-3)


def test_one_cycle_has_no_period(programs):
    jp, t, p = programs["circle", 0.5]
    one = t <= jp.period
    assert period(t[one], p[one]) is None


def test_a_line_driven_back_and_forth_has_a_cusp_at_each_end_and_a_rectangle_none(programs):
    jp, t, p = programs["line", 0.0]
    c = cusps(t, p, 0.002)
    turns = np.arange(1, 2 * jp.cycles) * jp.period / 2       # every end of a stroke but the first and last
    assert len(c) == len(turns) and np.abs(t[c] - turns).max() < 0.02
    for kind in ("rectangle", "circle"):
        assert len(cusps(*programs[kind, 0.0][1:], 0.002)) == 0


@pytest.mark.parametrize("kind", ["line", "circle", "rectangle"])
def test_cycles_are_cut_where_the_command_repeats_as_where_it_rests(programs, kind):
    jp, t, p = programs[kind, 0.0]
    pieces, how = split_runs(t, p, P.motions(t, p), 0.002)
    assert how["method"] == "repetition" and how["period_s"] == pytest.approx(jp.period, abs=1e-3)
    picked, others = P.cycles_of(p, pieces)
    assert len(picked) == jp.cycles and len(others) == (jp.cycles if kind == "line" else 0)
    starts = np.array([t[pieces[k][0]] for k in picked])
    assert np.abs(starts - np.arange(jp.cycles) * jp.period).max() < 0.01
    rested = programs[kind, 0.5]
    r_pieces, r_how = split_runs(rested[1], rested[2], P.motions(rested[1], rested[2]), 0.002)
    r_picked, _ = P.cycles_of(rested[2], r_pieces)
    assert r_how["method"] == "rests" and len(r_picked) == jp.cycles
    a = [P.arc_length(p[pieces[k][0]:pieces[k][1] + 1])[-1] for k in picked]
    b = [P.arc_length(rested[2][r_pieces[k][0]:r_pieces[k][1] + 1])[-1] for k in r_picked]
    assert np.median(a) == pytest.approx(np.median(b), rel=2e-3)


def test_a_given_period_cuts_the_cycles_at_its_multiples(programs):
    jp, t, p = programs["circle", 0.0]
    pieces, how = split_runs(t, p, P.motions(t, p), 0.002, jp.period, 0.0)
    assert how == {"method": "trajectory", "period_s": jp.period}
    cuts = np.array([t[a] for a, _ in pieces[1:]])
    assert np.abs(cuts - np.arange(1, jp.cycles) * jp.period).max() <= 0.001
