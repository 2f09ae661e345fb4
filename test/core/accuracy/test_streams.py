"""Streams as logs have them: repeated stamps kept once and counted, rows out of order sorted and counted, a clock
that jumps or starts again cut into epochs laid end to end, and the same on line batch by batch."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.streams import (JUMP_S, MARGIN_S, REORDER_S, SEPARATION_S, LiveOrder, Timeline,
                                                 describe_tidied, tidy)


def test_an_ordered_stream_is_kept_whole_and_nothing_is_said():
    t = np.arange(100) * 0.002
    td = tidy(t, np.arange(100.0))
    assert len(td.epochs) == 1 and np.array_equal(td.epochs[0], np.arange(100))
    assert td.describe() is None and td.summary()["kept"] == 100


def test_repeated_stamps_are_kept_once_the_first_and_counted_with_their_conflicts():
    t = np.repeat(np.arange(50) * 0.002, 2)
    v = np.repeat(np.arange(50.0), 2)
    v[7] = -1.0                                # the second copy of row 3 differs
    td = tidy(t, v)
    assert np.array_equal(td.epochs[0], np.arange(0, 100, 2))
    assert td.repeated == 50 and td.conflicting == 1
    assert "50 row(s) repeated a stamp" in td.describe() and "1 with other values" in td.describe()


def test_rows_out_of_order_are_sorted_and_counted():
    t = np.arange(200) * 0.001
    order = np.arange(200)
    order[[10, 11]] = order[[11, 10]]
    order[[50, 53]] = order[[53, 50]]
    td = tidy(t[order])
    assert np.array_equal(t[order][td.epochs[0]], t)
    assert td.reordered == 1 + 3 and "4 row(s) out of order" in td.describe()   # 10 after 11; 51, 52, 50 after 53


@pytest.mark.parametrize("jump", [1e7, JUMP_S + 1.0, -900.0, -(REORDER_S + 0.5)])
def test_a_clock_that_jumps_or_starts_again_cuts_the_stream_there(jump):
    t = np.arange(300) * 0.01
    t[120:] += jump
    td = tidy(t)
    assert [len(e) for e in td.epochs] == [120, 180] and td.jumps[0]["row"] == 120
    assert td.jumps[0]["by_s"] == pytest.approx(jump + 0.01)
    assert ("started again" if jump < 0 else "jumped") in td.describe()


def test_a_stray_stamp_is_left_out_and_non_finite_rows_are_counted():
    t = np.arange(100) * 0.01
    t[40] = 5e9                                # one corrupted stamp: a clock of its own for one row
    t[60] = np.nan
    v = np.zeros((100, 2))
    v[70, 1] = np.inf
    td = tidy(t, v)
    assert td.stray == 1 and td.not_finite == 2 and td.kept == 97
    assert len(td.epochs) == 1 and td.jumps == []      # the stray stamp cuts nothing (issue 49: it had cut two)
    assert "1 row(s) on a clock of their own" in td.describe()


@pytest.mark.parametrize("where", [0, 1, 4000, 8940, 8941])
def test_one_stamp_of_1e308_is_one_row_left_out_wherever_it_lies(where):
    t = np.arange(8942) * 0.004
    t[where] = 1e308
    td = tidy(t)
    assert td.stray == 1 and td.kept == 8941 and len(td.epochs) == 1 and td.jumps == []
    assert where not in td.epochs[0] and np.all(np.diff(t[td.epochs[0]]) > 0)


def test_a_clock_that_started_again_still_cuts_with_a_stray_stamp_in_each_epoch():
    t = np.concatenate([np.arange(300) * 0.01, np.arange(300) * 0.01])   # restarted at row 300
    t[[100, 450]] = [1e308, -1e308]
    td = tidy(t)
    assert td.stray == 2 and [len(e) for e in td.epochs] == [299, 299] and len(td.jumps) == 1
    assert td.jumps[0]["row"] == 300


def test_a_clock_that_jumps_without_end_is_refused():
    with pytest.raises(ValueError, match="jumps more than"):
        tidy(np.arange(1000) * 1e4 * np.where(np.arange(1000) % 2, 1, -1))


def test_the_summary_reads_back_into_the_same_line():
    t = np.concatenate([np.arange(50) * 0.01, 1e7 + np.arange(50) * 0.01])
    td = tidy(np.repeat(t, 2))
    assert describe_tidied("x", td.summary()) == td.describe()


def test_the_timeline_lays_epochs_end_to_end_in_memory_bounded_by_the_rows():
    """Joint states whose clock jumps by 1e7 s after 1,000 rows; the tracker's clock does not jump: its points
    after the jump belong to no joint epoch (those beyond its margin counted outside), those before keep their
    stamps."""
    tj = np.arange(2000) * 0.002 + 100.0
    tj[1000:] += 1e7
    tm = np.arange(40_000) * 0.001 + 100.0 + 3e-4
    line = Timeline(tidy(tj), tj, tidy(tm), tm)
    assert line.tj.nbytes < 1e5 and np.all(np.diff(line.tj) > 0)
    assert line.shifts[0] == 0.0 and line.tj[1000] - line.tj[999] == pytest.approx(SEPARATION_S)
    assert np.array_equal(line.tm, tm[line.im]) and line.point_slices[1].stop == line.point_slices[1].start
    assert line.outside == len(tm) - len(line.im) == np.count_nonzero(tm > tj[999] + MARGIN_S)
    assert line.covered(np.array([101.0, line.tj[999] + 1.0, line.tj[1000] + 0.5])).tolist() == [True, False, True]
    assert line.original(line.tj[1500]) == pytest.approx(tj[1500])


def test_the_timeline_pairs_epochs_when_both_clocks_start_again():
    tj = np.concatenate([1000 + np.arange(500) * 0.002, np.arange(500) * 0.002])
    tm = np.concatenate([1000.008 + np.arange(1000) * 0.001, 0.008 + np.arange(1000) * 0.001])
    line = Timeline(tidy(tj), tj, tidy(tm), tm)
    assert line.outside == 0 and len(line.im) == 2000
    second = line.point_slices[1]
    assert np.allclose(line.tm[second] - line.tj[line.joint_slices[1].start], tm[1000:] - tj[500], atol=1e-9)


def test_live_order_takes_each_batch_in_order_and_counts_what_it_leaves_out():
    live = LiveOrder("joint states")
    t = np.arange(20) * 0.002
    got = live.take(t[:10], np.arange(10.0))
    assert len(got) == 1 and np.array_equal(got[0][1], t[:10]) and not got[0][0]
    got = live.take(np.concatenate([t[9:12], t[8:9], t[12:15][::-1]]), np.zeros(7))   # a repeat, a late row
    assert np.array_equal(got[0][1], t[10:15])
    assert live.counts["repeated"] == 1 and live.counts["late"] == 1 and live.counts["reordered"] == 3
    assert live.take([], np.zeros((0, 1))) == []


def test_live_order_starts_again_on_a_jump_confirmed_and_leaves_a_stray_stamp_out():
    live = LiveOrder("tracker points")
    live.take(np.arange(10) * 0.01, np.zeros(10))
    assert live.take([1e9], [0.0]) == []                  # one stamp on a new clock: held, not yet believed
    got = live.take([0.1, 0.11], [0.0, 0.0])              # the old clock goes on: it was a stray stamp
    assert len(got) == 1 and not got[0][0] and live.counts["stray"] == 1
    got = live.take([-500.0, -499.99, -499.98], [0.0, 0.0, 0.0])
    assert got[0][0] and live.counts["jumps"] == 1 and "the clock jumped 1 time(s)" in live.describe()
