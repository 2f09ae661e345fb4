"""ISO 9283 path characteristics against paths whose figures are known in closed form: per-cycle offsets
(AT_p, RT_p written out from the standard's formulas), rounded and overshooting corners (CR, CO), speeds
scaled and rippled (AV, RV, FV)."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy import path as P
from tolerance_ros.core.accuracy.iso_paths import trapezoid_times


def _timed(poly, speed=0.2, accel=2.0, dt=0.002, t0=0.0):
    """(t, p): the polyline driven from rest to rest, sampled every dt."""
    s = P.arc_length(poly)
    tk = trapezoid_times(s, speed, accel)
    t = t0 + np.arange(0.0, tk[-1], dt)
    t = np.append(t, t0 + tk[-1])
    ss = np.interp(t - t0, tk, s)
    return t, np.column_stack([np.interp(ss, s, poly[:, k]) for k in range(3)])


def _dense(corners, step=5e-5):
    out = [corners[:1]]
    for a, b in zip(corners[:-1], corners[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(out)


def test_at_and_rt_from_per_cycle_offsets():
    line = _dense(np.array([[0, 0, 0], [0.3, 0, 0.0]]))
    t, p = _timed(line)
    rng = np.random.default_rng(0)
    offsets = np.column_stack([np.zeros(7), rng.normal(1e-4, 5e-5, 7), rng.normal(-2e-4, 3e-5, 7)])
    cycles = [P.Cycle(t, p, P.arc_length(p), *_timed(line + o, dt=0.001)) for o in offsets]
    segs = P.path_characteristics(cycles, [0.0, 0.3], stations=50)
    assert len(segs) == 1
    d = offsets[:, 1:]
    dbar = d.mean(axis=0)
    l = np.linalg.norm(d - dbar, axis=1)
    S = np.sqrt(np.sum((l - l.mean()) ** 2) / (len(l) - 1))
    assert segs[0]["AT_p_m"] == pytest.approx(np.linalg.norm(dbar), rel=1e-6)
    assert segs[0]["RT_p_m"] == pytest.approx(l.mean() + 3 * S, rel=1e-6)
    assert [c["AT_p_m"] for c in segs[0]["per_cycle"]] == pytest.approx(np.linalg.norm(d, axis=1), rel=1e-6)
    assert segs[0]["CR_m"] is None and segs[0]["CO_m"] is None   # it starts at rest: no corner


def test_one_cycle_has_no_repeatability():
    line = _dense(np.array([[0, 0, 0], [0.2, 0, 0.0]]))
    t, p = _timed(line)
    seg = P.path_characteristics([P.Cycle(t, p, P.arc_length(p), t, p + [0, 1e-4, 0])], [0.0, 0.2], 20)[0]
    assert seg["RT_p_m"] is None and seg["RV"] is None and seg["AT_p_m"] == pytest.approx(1e-4)


def _rounded_rectangle(a, b, r, bump=0.0, bump_len=0.02):
    """The rectangle (0,0)-(a,0)-(a,b)-(0,b)-(0,0) in z = 0 with its three inner corners rounded by arcs of
    radius r, and after the corner at (a, b) a bump of height ``bump`` over ``bump_len`` on the outer side
    (the side of the incoming motion, +y)."""
    pts = [np.array([0.0, 0.0])]
    C = [np.array([a, 0.0]), np.array([a, b]), np.array([0.0, b])]
    legs = [np.array([1.0, 0]), np.array([0, 1.0]), np.array([-1.0, 0]), np.array([0, -1.0])]
    for k, c in enumerate(C):
        u_in, u_out = legs[k], legs[k + 1]
        start, end = c - r * u_in, c + r * u_out
        pts += list(_dense(np.vstack([np.append(pts[-1], 0), np.append(start, 0)]))[1:, :2])
        centre = start + r * u_out
        a0 = np.arctan2(*(start - centre)[::-1])
        a1 = np.arctan2(*(end - centre)[::-1])
        da = (a1 - a0 + np.pi) % (2 * np.pi) - np.pi
        ang = a0 + da * np.linspace(0, 1, 400)[1:]
        pts += list(centre + r * np.column_stack([np.cos(ang), np.sin(ang)]))
        if k == 1 and bump:
            x = np.linspace(0, bump_len, 800)[1:]
            pts += list(end + x[:, None] * u_out + (bump * np.sin(np.pi * x / bump_len))[:, None] * u_in)
    pts += list(_dense(np.vstack([np.append(pts[-1], 0), [0.0, 0.0, 0.0]]))[1:, :2])
    return np.column_stack([np.array(pts), np.zeros(len(pts))])


def test_corner_round_off_and_overshoot_on_a_rectangle():
    a, b, r, h = 0.2, 0.1, 3e-3, 0.4e-3
    command = _dense(np.array([[0, 0, 0], [a, 0, 0], [a, b, 0], [0, b, 0], [0, 0, 0.0]]))
    t, p = _timed(command)
    attained = _rounded_rectangle(a, b, r, bump=h)
    ta, pa = _timed(attained, dt=0.001)
    ta = ta * (t[-1] / ta[-1])        # the same start and end
    cyc = P.Cycle(t, p, P.arc_length(p), ta, pa)
    bounds = P.segment_bounds(cyc.s[-1], P.corners(p))
    assert bounds == pytest.approx([0, a, a + b, 2 * a + b, 2 * a + 2 * b], abs=2e-4)
    segs = P.path_characteristics([cyc, cyc], bounds, stations=40)
    cr = r * (np.sqrt(2) - 1)           # from a 90 degree corner to the arc tangent to both legs
    for k in (1, 2, 3):
        assert segs[k]["CR_m"] == pytest.approx(cr, rel=0.02)
    assert segs[2]["CO_m"] == pytest.approx(h, rel=0.02)   # after the corner at (a, b), beyond the leg
    assert segs[1]["CO_m"] < 1e-6 and segs[3]["CO_m"] < 1e-6  # a rounded corner stays inside
    assert segs[0]["CR_m"] is None


def test_speed_accuracy_repeatability_and_fluctuation():
    L, v, dt = 0.3, 0.2, 0.001
    line = _dense(np.array([[0, 0, 0], [L, 0, 0.0]]))
    t, p = _timed(line, speed=v, accel=4.0)
    k = np.array([1.01, 1.03, 1.02, 1.00, 1.04])
    amp, w = 2e-3, 2 * np.pi * 25.0
    cycles = []
    for kj in k:
        ta = np.arange(0, t[-1] + 0.2, dt)
        s = np.interp(ta, t, P.arc_length(p)) * kj
        ramp = np.clip(np.interp(ta, t, P.arc_length(p)) / L * 20, 0, 1) * np.clip((L - s) / L * 20, 0, 1)
        x = s + ramp * amp / w * np.sin(w * ta)
        cycles.append(P.Cycle(t, p, P.arc_length(p), ta, np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])))
    seg = P.path_characteristics(cycles, [0.0, L], stations=200, speed_window=0.002)[0]
    assert seg["v_c_m_s"] == pytest.approx(v, rel=1e-3)
    assert seg["AV"] == pytest.approx(k.mean() - 1, abs=2e-3)
    assert seg["RV"] == pytest.approx(3 * k.std(ddof=1), rel=0.1)
    assert seg["FV_m_s"] == pytest.approx(2 * amp, rel=0.1)


def test_motions_cycles_and_other_motions():
    line = _dense(np.array([[0, 0, 0], [0.1, 0, 0.0]]))
    ts, ps = [], []
    t0 = 0.0
    for k in range(3):
        for poly in (line, line[::-1]):
            t, p = _timed(poly, t0=t0)
            ts.append(t)
            ps.append(p)
            t0 = t[-1] + 0.5
            ts.append(np.arange(t[-1] + 0.002, t0, 0.002))
            ps.append(np.repeat(p[-1:], len(ts[-1]), axis=0))
    t, p = np.concatenate(ts), np.vstack(ps)
    runs = P.motions(t, p)
    assert len(runs) == 6
    cycles, others = P.cycles_of(p, runs)
    assert len(cycles) == 3 and len(others) == 3 and cycles == [0, 2, 4]
