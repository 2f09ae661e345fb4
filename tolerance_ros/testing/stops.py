"""Stops with a known truth, for the tests and the benchmark of ``core.accuracy.settling``: a command moving by
a speed profile, a robot that rings at its stops, a tracker that reads it with noise (SI)."""
import numpy as np

from ..core.accuracy.iso_paths import profile_distance, profile_duration
from ..core.accuracy.simulate import settle


def profile_run(profile, noise=2e-6, seed=0, speed=0.5, accel=5.0):
    """Two moves of 100 mm along x (out and back, ``speed`` m/s and ``accel`` m/s^2 by ``profile``), each followed by
    a rest of 1.5 s, the command's joint states at 500 Hz; a robot ringing at 8 Hz (damping 0.2) follows it and a
    tracker reads it at 1 kHz with ``noise``. Returns (tracker stamps, points, joint stamps, command points, the exact instants each
    move ends, (the 10 kHz grid, the noise-free points on it))."""
    L, v, a, rest = 0.1, speed, accel, 1.5
    T = profile_duration(L, v, a, profile)
    starts = np.array([0.5, 0.5 + T + rest])
    fine = np.arange(0.0, starts[-1] + T + rest, 1e-4)

    def x(t):
        return profile_distance(t - starts[0], L, v, a, profile) - profile_distance(t - starts[1], L, v, a, profile)
    P = np.c_[x(fine), np.zeros_like(fine), np.zeros_like(fine)] + [0.6, 0.1, 0.4]
    robot = settle(P, 1e-4, 2 * np.pi * 8, 0.2)
    tm = fine[::10]
    pm = robot[::10] + np.random.default_rng(seed).normal(0, noise, (len(tm), 3))
    tj = fine[::20]
    return tm, pm, tj, P[::20], starts + T, (fine, robot)


def entered(t, p, t_end, band, rest=1.5):
    """(s) the closed-form truth of the stabilisation time: from the command's rest at ``t_end`` to the instant the
    noise-free points ``p`` (on the 10 kHz grid ``t``) enter the band about their attained pose for good."""
    sel = (t >= t_end) & (t <= t_end + rest)
    ts, ps = t[sel], p[sel]
    d = np.linalg.norm(ps - ps[ts >= t_end + 0.8 * rest].mean(axis=0), axis=1)
    out = np.flatnonzero(d > band)
    if not out.size:
        return 0.0
    k = out[-1]
    return ts[k] + (d[k] - band) / (d[k] - d[k + 1]) * (ts[k + 1] - ts[k]) - t_end
