"""The one ingestion path: stamps, joint order, measured poses and pairing by stamp."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tolerance_ros.core.ingest import (IngestError, JointOrder, StateBuffer, nearest_indices, pair_by_stamp,
                                       pose_from_values, stamp_seconds)


def test_stamps():
    assert stamp_seconds(SimpleNamespace(sec=12, nanosec=500_000_000)) == 12.5
    assert stamp_seconds(3) == 3.0
    for bad in (SimpleNamespace(sec="x", nanosec=0), object(), float("nan"), SimpleNamespace(sec=10 ** 400, nanosec=0),
                SimpleNamespace(sec=1, nanosec=1_000_000_000), SimpleNamespace(sec=1, nanosec=2 ** 32 - 1),
                SimpleNamespace(sec=1, nanosec=-1), SimpleNamespace(sec=1, nanosec=float("nan"))):
        with pytest.raises(IngestError, match="stamp"):
            stamp_seconds(bad)


def test_joint_order_reorders_ignores_extras_and_names_what_is_missing():
    order = JointOrder(["j1", "j2", "j3"])
    np.testing.assert_array_equal(order(["gripper", "j3", "j1", "j2"], [9.0, 3.0, 1.0, 2.0]), [1.0, 2.0, 3.0])
    first = order.index(["gripper", "j3", "j1", "j2"])
    assert order.index(("gripper", "j3", "j1", "j2")) is first          # the same names reuse the index
    with pytest.raises(IngestError, match=r"no value for joint\(s\) \['j3'\]"):
        order(["j1", "j2"], [1.0, 2.0])
    with pytest.raises(IngestError, match="and 990 more") as exc:               # hostile names, a bounded message
        order(["x" * 5000] * 1000, [0.0] * 1000)
    assert len(str(exc.value)) < 1000
    with pytest.raises(IngestError, match="2 values for 3 joint names"):
        order(["j1", "j2", "j3"], [1.0, 2.0])
    with pytest.raises(IngestError, match="'j2': not a finite number"):
        order(["j1", "j2", "j3"], [1.0, np.inf, 2.0])
    with pytest.raises(IngestError, match="expected numbers"):
        order(["j1", "j2", "j3"], ["a", "b", "c"])
    np.testing.assert_array_equal(order.rows(["j3", "j2", "j1"], [[3, 2, 1], [6, 5, 4]]), [[1, 2, 3], [4, 5, 6]])


def test_a_joint_named_twice_or_names_that_are_not_a_list_are_refused():
    order = JointOrder(["j1", "j2", "j3"])
    with pytest.raises(IngestError, match=r"joint\(s\) \['j1'\] named more than once in one joint state"):
        order(["j1", "j2", "j3", "j1"], [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(order(["x", "j1", "j2", "j3", "x"], [0, 1, 2, 3, 0]), [1, 2, 3])  # extras may repeat
    with pytest.raises(IngestError, match="name: expected a list of joint names, got NoneType"):
        order(None, [1.0, 2.0, 3.0])
    with pytest.raises(IngestError, match="name: expected joint names"):
        order([["j1"], "j2", "j3"], [1.0, 2.0, 3.0])


def test_poses_from_position_and_quaternion():
    R = Rotation.from_euler("xyz", [0.1, 0.2, 0.3])
    T = pose_from_values([1.0, 2.0, 3.0], R.as_quat() * 2.0)
    np.testing.assert_allclose(T[:3, :3], R.as_matrix(), atol=1e-15)
    np.testing.assert_array_equal(T[:3, 3], [1, 2, 3])
    for pos, quat, needle in [([0, 0, 0], [0, 0, 0, 0], "zero quaternion"),
                              ([0, 0, np.nan], [0, 0, 0, 1], "non-finite"),
                              ([0, 0, 1e154], [0, 0, 0, 1], "beyond 1e\\+06 m"),
                              ([0, 0], [0, 0, 0, 1], "3 position and 4 quaternion"),
                              ([0, 0, 0], [0, 0, 1], "3 position and 4 quaternion"),
                              (["x", 0, 0], [0, 0, 0, 1], "expected numbers")]:
        with pytest.raises(IngestError, match=needle):
            pose_from_values(pos, quat)


def test_nearest_stamp_rule():
    s = [0.0, 1.0, 2.0]
    assert nearest_indices(s, [0.4, 0.5, 0.6, 2.05, 3.0], 0.1).tolist() == [-1, -1, -1, 2, -1]
    assert nearest_indices(s, [0.5, 0.95, 1.04], 0.5).tolist() == [0, 1, 1]   # a tie goes to the earlier stamp
    assert nearest_indices([], [1.0], 1.0).tolist() == [-1]
    assert pair_by_stamp([0.0, 2.0], [2.01, 0.02, 1.0], 0.05).tolist() == [1, 0]  # states in any order


def test_state_buffer_keeps_order_and_the_newest_states():
    buf = StateBuffer(dof=2, capacity=4)
    for t in (1.0, 3.0, 2.0, 0.5):                     # out of order: inserted at their place
        buf.add(t, [t, -t])
    np.testing.assert_array_equal(buf.stamps[:len(buf)], [0.5, 1.0, 2.0, 3.0])
    stamp, q = buf.nearest(2.1, 0.2)
    assert stamp == 2.0 and q.tolist() == [2.0, -2.0]
    assert buf.nearest(2.5, 0.2) is None and buf.distance(2.4) == pytest.approx(0.4)
    for t in np.arange(4.0, 20.0):
        buf.add(t, [t, -t])
    assert len(buf) >= 4 and buf.newest == 19.0
    np.testing.assert_array_equal(np.diff(buf.stamps[:len(buf)]) > 0, True)
    assert buf.nearest(19.0, 0.0)[1].tolist() == [19.0, -19.0]
    assert StateBuffer(dof=1).newest == -np.inf


def _stream(rate, seconds, jitter=0.0, seed=0):
    """Stamps (s) of a stream at ``rate`` Hz for ``seconds``, each off its tick by up to ``jitter`` periods."""
    rng = np.random.default_rng(seed)
    n = int(rate * seconds)
    return 100.0 + (np.arange(n) + rng.uniform(-jitter, jitter, n)) / rate


def test_stamp_gaps_counts_the_messages_lost_from_a_regular_stream_one_at_a_time_or_in_batches():
    from tolerance_ros.core.ingest import StampGaps
    t = _stream(1000, 3.0, jitter=0.2)
    lost = np.r_[1200:2400, 2500:2510]          # a 1.2 s backlog lost, then ten messages
    kept = np.delete(t, lost)
    for batches in ([kept], np.array_split(kept, 37), [kept[i:i + 1] for i in range(len(kept))]):
        g = StampGaps()
        found = sum(g.add(b) for b in batches)
        s = g.summary()
        assert found == s["gaps"] == 2
        assert abs(s["missing"] - len(lost)) <= 0.01 * len(lost)   # "about": the period is estimated
        assert abs(s["longest_gap_s"] - 1.201) < 1e-3
        assert abs(s["period_s"] - 1e-3) < 5e-5 and s["regular"]
        assert s["last_gap_end_s"] == kept[2500 - 1200]
        assert "2 gap(s)" in g.describe("joint_states") and f"{s['missing']:,} message(s)" in g.describe("joint_states")


def test_stamp_gaps_finds_nothing_in_a_jittery_but_complete_stream_nor_in_an_irregular_one():
    from tolerance_ros.core.ingest import StampGaps
    g = StampGaps()
    g.add(_stream(1000, 2.0, jitter=0.45))
    assert g.summary()["gaps"] == 0 and g.describe("joint_states") is None
    single = StampGaps()                        # one measurement now and then: nothing to judge
    single.add(np.cumsum(np.random.default_rng(1).exponential(2.0, 200)))
    assert not single.summary()["regular"] and single.summary()["gaps"] == 0


def test_stamp_gaps_judges_the_learning_intervals_and_starts_again_after_a_clock_restart():
    from tolerance_ros.core.ingest import StampGaps
    t = _stream(100, 1.0)
    g = StampGaps()
    g.add(np.delete(t, np.r_[5:15]))            # ten lost before the period was known
    assert g.summary()["gaps"] == 1 and g.summary()["missing"] == 10
    g.add(t[:50] - 50.0)                         # a clock that restarted: not a gap, not a negative interval
    assert g.summary()["restarts"] == 1 and g.summary()["gaps"] == 1
    g.add(t[60:70] - 50.0)
    assert g.summary()["gaps"] == 2 and g.summary()["missing"] == 20
    assert g.add([np.nan]) == 0 and g.add([]) == 0


def test_stamp_gaps_shorter_than_min_gap_are_a_late_timer_not_counted():
    from tolerance_ros.core.ingest import StampGaps
    t = _stream(50, 10.0)
    late = np.concatenate([t[:100], t[105:300], t[350:]])    # a timer 0.1 s late, then 1 s of messages lost
    strict, lenient = StampGaps(), StampGaps(min_gap=0.5)
    strict.add(late)
    lenient.add(late)
    assert strict.summary()["gaps"] == 2 and strict.summary()["missing"] == 55
    assert lenient.summary()["gaps"] == 1 and lenient.summary()["missing"] == 50
    assert lenient.hole(late[95:110]) is None and strict.hole(late[95:110]) == pytest.approx(0.12)


def _reader(t, stall_from, stall_s, depth, latency=2e-4, clock_offset=0.0):
    """What a reader with a keep-last queue of ``depth`` takes of a live stream stamped ``t`` (s) when its callbacks
    stop from ``stall_from`` (s) for ``stall_s``: (stamps taken, the reader's clock when it took each)."""
    taken, received, queue, now = [], [], [], 0.0
    for k, stamp in enumerate(t):
        queue.append(stamp)
        queue = queue[-depth:]                      # DDS keep-last drops the oldest without a word
        now = stamp + latency
        if not stall_from <= now < stall_from + stall_s:
            while queue:                            # the reader takes its backlog, quickly
                taken.append(queue.pop(0))
                received.append(now + clock_offset)
                now += 1e-6
    return np.array(taken), np.array(received)


def test_stamp_gaps_shorter_than_min_gap_are_counted_when_the_reader_was_behind_and_its_queue_overflowed():
    """A 1 kHz stream, a queue of 1,000, a reader stalled for 1.3 s: 300 messages dropped, a 0.3 s hole, under
    ``min_gap``; the message after it was 1 s old when taken, so the hole is counted (and said to be the reader's),
    in any clock offset and in batches alike. The same hole from a publisher that paused is not."""
    from tolerance_ros.core.ingest import StampGaps
    t = _stream(1000, 4.0, jitter=0.1)
    taken, received = _reader(t, 101.0, 1.3, 1000)
    assert abs(len(t) - len(taken) - 300) <= 1
    for offset in (0.0, -1.7e9, 3.5):                 # the reader's clock: ROS time, or any other time base
        for split in (1, 7, len(taken)):
            g = StampGaps(min_gap=0.5)
            found = sum(g.add(a, b) for a, b in zip(np.array_split(taken, split), np.array_split(received + offset, split)))
            s = g.summary()
            assert found == s["gaps"] == 1 and s["behind"] == 1 and abs(s["missing"] - 300) <= 3, (offset, split, s)
            assert "while this reader was behind" in g.describe("joint_states")
    hole = int(np.argmax(np.diff(taken)))             # the last message before the hole
    partly = received.copy()
    partly[hole % 10::10] = np.nan                    # a clock that failed now and then, just before the hole too:
    for split in (1, len(taken)):                     # the lag rose over the latest one known
        g = StampGaps(min_gap=0.5)
        for a, b in zip(np.array_split(taken, split), np.array_split(partly, split)):
            g.add(a, b)
        assert g.summary()["gaps"] == 1 and g.summary()["behind"] == 1, split
    without = StampGaps(min_gap=0.5)                  # no reader's clock: the hole is under min_gap
    without.add(taken)
    assert without.summary()["gaps"] == 0
    paused = np.delete(t, np.r_[1000:1300])           # the publisher sent nothing for 0.3 s; the reader kept up
    g = StampGaps(min_gap=0.5)
    for stamp in paused:
        g.add(stamp, stamp + 2e-4)
    assert g.summary()["gaps"] == 0 and g.summary()["behind"] == 0
    g.add(paused[-1] + 0.8, paused[-1] + 0.8 + 2e-4)  # a 0.8 s pause is a gap by min_gap, not the reader's
    assert g.summary()["gaps"] == 1 and g.summary()["behind"] == 0
    assert "behind" not in g.describe("joint_states")


def test_stamp_gaps_without_a_finite_readers_clock_still_takes_every_stamp():
    from tolerance_ros.core.ingest import StampGaps
    t = _stream(1000, 1.0)
    kept = np.delete(t, np.r_[500:520])
    for received in (np.full(kept.size, np.nan), np.full(kept.size, np.inf)):
        one, batch = StampGaps(), StampGaps()
        for a, b in zip(kept, received):
            one.add(float(a), float(b))
        batch.add(kept, received)
        assert one.summary() == batch.summary() and one.summary()["gaps"] == 1 and one.summary()["behind"] == 0
        assert one.summary()["missing"] == 20 and one.seen == batch.seen == kept.size - 1
