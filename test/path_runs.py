"""Simulated path runs (shared by the tests of the path report, the command line and the monitor) with known truth, and
``feed``, which gives them to an on-line monitor in batches: the paper's arm as built within gao2023_delta2 (seed 3), driving an
ISO 9283 test path 10 times at 0.2 m/s, seen by a 1 kHz tracker 8 ms late with 10 um of noise, its joints
off by a 0.1 mrad offset drawn per cycle (so that the cycles differ), against 500 Hz joint states; each cycle
starts with a rest of ``dwell`` s (0: a program that loops without a stop)."""
import numpy as np

from tolerance_ros.core.accuracy.iso_paths import plan_path
from tolerance_ros.core.accuracy.simulate import as_built_errors, path_streams
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.geometry import transform

Q_CENTER = np.radians([0, 45, 0, 60, 0, 30, 0])   # P1 of gao2023_iso_cube
T_TB = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


def run(model, kind, cycles=10, latency=0.008, noise=10e-6, repeatability=1e-4, seed=1, dwell=0.5):
    dx = as_built_errors(load_budget("gao2023_delta2", model).vector_for(model), 3)
    jp, _ = plan_path(model, kind, speed=0.2, accel=1.0, cycles=cycles, q_center=Q_CENTER, dwell=dwell)
    return path_streams(model, jp, dx, T_TB, latency=latency, noise=noise, seed=seed, repeatability=repeatability)


def feed(mon, st, batch=0.05):
    """The streams in time order, ``batch`` s at a time (joint states then the tracker's points of each)."""
    reports = []
    t0 = min(st.joint_stamps[0], st.stamps[0])
    end = max(st.joint_stamps[-1], st.stamps[-1])
    for a in np.arange(t0, end + batch, batch):
        j = (st.joint_stamps >= a) & (st.joint_stamps < a + batch)
        m = (st.stamps >= a) & (st.stamps < a + batch)
        reports += mon.add_joint_states(st.joint_stamps[j], st.joints[j])
        reports += mon.add_points(st.stamps[m], st.points[m])
        assert len(mon.tm) < 20_000 and len(mon.tj) < 10_000       # bounded: about one motion at a time
    return reports + mon.finish()
