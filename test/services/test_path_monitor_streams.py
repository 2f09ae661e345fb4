"""The on-line monitors on the streams cells really record: every joint state published twice, rows out of order,
a clock that jumps or starts again, NaN, empty and malformed batches. The path monitor reports the figures of the
clean stream where nothing was lost, says what it left out, never raises, and judges again once the streams are
whole; the accuracy monitor never raises either."""
import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from path_runs import T_TB, feed, run
from tolerance_ros.core.geometry import transform
from tolerance_ros.services.monitor import MonitorLogic
from tolerance_ros.services.path_monitor import WARN, PathMonitor

TS = get_typestore(Stores.ROS2_JAZZY)


@pytest.fixture(scope="module")
def rect(gao):
    return run(gao, "rectangle", cycles=4)


def _time(t):
    ns = int(round(t * 1e9))
    return TS.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def _header(t):
    return TS.types["std_msgs/msg/Header"](stamp=_time(t), frame_id="tracker")


def _joint_msg(t, names, q):
    return TS.types["sensor_msgs/msg/JointState"](header=_header(t), name=list(names), position=np.asarray(q, float),
                                                  velocity=np.zeros(0), effort=np.zeros(0))


def _point_msg(t, p):
    return TS.types["geometry_msgs/msg/PointStamped"](
        header=_header(t), point=TS.types["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2])))


def feed_messages(mon, st, names, twice=False, period=0.1):
    """The streams as messages in arrival order, each joint state published ``twice`` with one stamp; flushed
    every ``period`` s of stream time, as the node's timer does."""
    events = sorted([(t, 0, k) for k, t in enumerate(st.joint_stamps)] + [(t, 1, k) for k, t in enumerate(st.stamps)])
    reports, next_flush = [], events[0][0] + period
    for t, kind, k in events:
        if t >= next_flush:
            reports += mon.flush()
            next_flush += period
        if kind == 0:
            for _ in range(2 if twice else 1):
                mon.on_joint_state_msg(_joint_msg(t, names, st.joints[k]))
        else:
            mon.on_point_msg(_point_msg(t, st.points[k]))
    return reports + mon.flush()


def test_every_joint_state_published_twice_gives_the_clean_figures_and_says_so(gao, rect):
    clean = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    twice = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    a = feed_messages(clean, rect, gao.joint_names)
    b = feed_messages(twice, rect, gao.joint_names, twice=True)
    assert [r["cycles"] for r in b] == [r["cycles"] for r in a] == [1, 2, 3, 4]
    for on, off in zip(b[-1]["segments"], a[-1]["segments"]):
        assert on["AT_p_m"] == off["AT_p_m"] and on["RT_p_m"] == off["RT_p_m"]
    assert twice.live["joints"].counts["repeated"] == len(rect.joint_stamps)
    assert twice.counts["errors"] == 0 and twice.counts["rejected"] == 0
    assert f"{len(rect.joint_stamps):,} repeated stamp(s) left out" in twice.status()[1]
    assert twice.diagnostic()["values"]["joint_states_repeated"] == str(len(rect.joint_stamps))


def test_a_clock_that_starts_again_is_said_and_the_next_cycles_are_judged(gao, rect):
    """Both clocks restart at 0 after the second cycle (a simulation restarted): the motion under way is not
    judged, the status warns, and the cycles after it are judged with the same latency and placement."""
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    cut = rect.joint_stamps[0] + 2 * 4.56 + 0.3
    reports = []
    for lo, hi, shift in ((-np.inf, cut, 0.0), (cut, np.inf, -1000.0)):
        j = (rect.joint_stamps >= lo) & (rect.joint_stamps < hi)
        m = (rect.stamps >= lo) & (rect.stamps < hi)
        for a in np.arange(0, j.sum(), 25):
            idx = np.flatnonzero(j)[a:a + 25]
            reports += mon.add_joint_states(rect.joint_stamps[idx] + shift, rect.joints[idx])
            idm = np.flatnonzero(m & (rect.stamps < rect.joint_stamps[idx[-1]] + 0.05) &
                                 (rect.stamps >= (rect.joint_stamps[idx[0]] if a else lo)))
            reports += mon.add_points(rect.stamps[idm] + shift, rect.points[idm])
    judged = [r for r in reports if r["judged"]]
    skipped = [r for r in reports if not r["judged"]]
    assert len(judged) >= 3 and judged[-1]["cycles"] >= 3
    assert any("clock jumped" in r["reason"] for r in skipped)
    level, words = mon.status()
    assert level == WARN and "the clock jumped" in words
    assert mon.counts["errors"] == 0


def _mutations(st, rng, batch=0.01, rate=0.2):
    """The streams in batches of ``batch`` s, each batch mutated with probability ``rate``: rows repeated, shuffled,
    a clock that jumps (for the rest of that stream), a NaN stamp or value, an empty batch, one stray stamp, a
    batch with a column or a stamp missing."""
    t0, end = min(st.joint_stamps[0], st.stamps[0]), max(st.joint_stamps[-1], st.stamps[-1])
    shift = {"joints": 0.0, "points": 0.0}
    for a in np.arange(t0, end + batch, batch):
        for kind, T, V in (("joints", st.joint_stamps, st.joints), ("points", st.stamps, st.points)):
            sel = (T >= a) & (T < a + batch)
            t, v = T[sel] + shift[kind], V[sel].copy()
            r = rng.random() / rate if rate else np.inf
            if r < 0.2:
                t, v = np.repeat(t, 2), np.repeat(v, 2, axis=0)
            elif r < 0.35 and len(t) > 1:
                order = rng.permutation(len(t))
                t, v = t[order], v[order]
            elif r < 0.4:
                shift[kind] += rng.choice([1e7, -900.0, 1e5, -2.0, 61.0])
                t = T[sel] + shift[kind]
            elif r < 0.5 and len(t):
                t = t.copy()
                t[rng.integers(len(t))] = np.nan
            elif r < 0.6 and len(v):
                v[rng.integers(len(v))] = rng.choice([np.nan, np.inf, 1e300])
            elif r < 0.7:
                t, v = t[:0], v[:0]
            elif r < 0.8 and len(t):
                t = t.copy()
                t[0] += rng.choice([1e9, -1e9])
            elif r < 0.9:
                v = v[:, :-1]
            elif r < 1.0:
                t = t[:-1]
            yield kind, t, v


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("given", [True, False])
def test_the_path_monitor_never_raises_on_mutated_streams_and_judges_again_when_they_are_whole(gao, rect, seed,
                                                                                                given):
    """About 4,000 mutated batches; then the same run on a new clock, whole: its cycles are judged."""
    rng = np.random.default_rng(seed)
    mon = PathMonitor(gao, latency=0.008 if given else None, T_tracker_base=T_TB if given else None, step=0.002)
    batches = 0
    for kind, t, v in _mutations(rect, rng):
        (mon.add_joint_states if kind == "joints" else mon.add_points)(t, v)
        batches += 1
        if batches % 500 == 0:
            mon.diagnostic()
            assert len(mon.tm) < 200_000 and len(mon.tj) < 100_000
    assert batches > 3000 and mon.counts["errors"] == 0
    reports = []
    for kind, t, v in _mutations(rect, np.random.default_rng(seed), rate=0.0):
        reports += (mon.add_joint_states if kind == "joints" else mon.add_points)(t + 5e8, v)
    judged = [r for r in reports if r["judged"]]
    assert judged and judged[-1]["cycles_seen"] >= 3, [r.get("reason") for r in reports]
    assert mon.counts["errors"] == 0


def test_the_path_monitor_never_raises_on_messages_of_any_shape(gao, rect):
    """Messages whose fields are missing, of the wrong type or absurd, between flushes: counted as rejected."""
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)

    class Odd:
        def __getattr__(self, name):
            raise RuntimeError("a field that cannot be read")

    names = list(gao.joint_names)
    bad = [None, Odd(), _joint_msg(1.0, names[:3], [0.0] * 3), _joint_msg(1.0, names, [np.nan] * gao.dof),
           _joint_msg(1.0, names * 2, [0.0] * 2 * gao.dof), _point_msg(1.0, [0, 0, 0]),
           _point_msg(1.0, [1e308, -1e308, 0])]
    bad[5].header.stamp = TS.types["builtin_interfaces/msg/Time"](sec=1, nanosec=2_000_000_000)   # out of range
    for msg in bad:
        mon.on_joint_state_msg(msg)
        mon.on_point_msg(msg)
        mon.flush()
    assert mon.counts["rejected"] >= len(bad) and mon.counts["errors"] == 0
    assert feed_messages(mon, rect, names)[-1]["cycles"] == 4


def test_the_accuracy_monitor_never_raises_on_mutated_streams(gao, rect):
    logic = MonitorLogic(gao, T_tracker_base=transform([0, 0, 0], [0, 0, 0]))
    rng = np.random.default_rng(7)
    names = list(gao.joint_names)
    for kind, t, v in _mutations(rect, rng, batch=0.05, rate=0.5):
        for k in range(len(t)):
            if kind == "joints":
                logic.on_joint_state(t[k], names, v[k])
            else:
                logic.on_pose(t[k], "tracker", v[k], (0.0, 0.0, 0.0, 1.0), target="")
    logic.resolve(now=1e12)
    assert logic.counts["paired"] > 0 and logic.diagnostic()["level"] in (0, 1, 2)


@pytest.mark.parametrize("kind", ["rectangle", "line"])
def test_a_program_that_loops_without_a_stop_is_judged_on_line_cycle_by_cycle(gao, kind):
    """No rest between the cycles: each is judged as its repetition (or its stroke, before the line's cusp) is
    complete, not after the run; the figures within 2 % of the offline report's on the same log."""
    from tolerance_ros.core.accuracy.path_report import PathOptions, path_report
    st = run(gao, kind, cycles=5, dwell=0.0)
    offline = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints,
                          options=PathOptions(latency=0.008, T_tracker_base=T_TB, step=0.002))
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    reports = feed(mon, st, batch=0.1)
    test_path = [r for r in reports if r["judged"] and r["path"] == 0]
    assert [r["cycles"] for r in test_path] == [1, 2, 3, 4, 5] and all(r["judged"] for r in reports)
    for on, off in zip(test_path[-1]["segments"], offline["segments"]):
        assert on["AT_p_m"] == pytest.approx(off["AT_p_m"], rel=0.02) and on["RT_p_m"] == pytest.approx(off["RT_p_m"],
                                                                                                       rel=0.02)
