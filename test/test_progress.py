"""Progress that moves: the pose selection of plan-campaign reports progress at least every 2 s, in chunks
that give the same answer as the whole; a progress line is written on a long step."""
import io
import time

import numpy as np


def test_plan_reports_progress_at_least_every_2_s():
    from tolerance_ros.core.calibration.planning import PROGRESS_STEPS, plan
    from tolerance_ros.core.models import load_robot
    model = load_robot("gao2023_7dof")
    model.warm_up()
    times, done = [time.perf_counter()], []

    def progress(d, total):
        assert total == PROGRESS_STEPS
        times.append(time.perf_counter())
        done.append(d)

    pl = plan(model, 24, "observability", 1500, 0, progress=progress)
    times.append(time.perf_counter())
    assert len(pl.q) == 24 and len(done) >= 10
    assert done == sorted(done) and 0 <= done[0] and done[-1] <= PROGRESS_STEPS
    assert np.diff(times).max() <= 2.0


def test_chunked_pose_blocks_and_gains_equal_the_whole():
    from tolerance_ros.core.calibration.planning import _gains, pose_blocks
    from tolerance_ros.core.models import load_robot
    model = load_robot("gao2023_7dof")
    q = model.sample_joints(50, 3)
    ticks = []
    G, cols, held = pose_blocks(model, q, tick=ticks.append, chunk=7)
    G1, cols1, held1 = pose_blocks(model, q)
    assert np.array_equal(G, G1) and cols == cols1 and np.array_equal(held, held1) and len(ticks) >= 7
    M = np.einsum("kri,krj->ij", G, G) + 1e-9 * np.eye(G.shape[2])
    whole = np.linalg.slogdet(np.eye(G.shape[1]) + np.einsum("kri,ij,ksj->krs", G, np.linalg.inv(M), G))[1]
    assert np.allclose(_gains(M, G, "O1", 1.0, chunk=8), whole, rtol=0, atol=1e-12)


def test_progress_writes_a_line_at_least_every_few_seconds_on_a_long_step(monkeypatch):
    from tolerance_ros.render.text import Progress
    stream = io.StringIO()
    prog = Progress("x", stream=stream)
    monkeypatch.setattr(Progress, "EVERY", 30.0)  # the heartbeat (every EVERY / 4) stays out of this test
    prog(0, 100)
    prog(1, 100)  # same 10 % step, too soon: nothing
    prog.written -= 31.0  # the last line is older than EVERY
    prog(2, 100)  # same step, but EVERY has passed: a line
    assert len(stream.getvalue().splitlines()) == 2
    prog(100, 100)  # done: the heartbeat ends


def test_the_progress_beats_through_a_step_that_does_not_call_it_and_stops_at_the_end(monkeypatch):
    """A step that calls nothing for 0.5 s, with EVERY 0.05 s: the line is written again several times, the
    elapsed time moving; once done, nothing more is written."""
    from tolerance_ros.render.text import Progress
    stream = io.StringIO()
    monkeypatch.setattr(Progress, "EVERY", 0.05)
    prog = Progress("x", stream=stream)
    prog(1, 10)
    time.sleep(0.5)
    lines = stream.getvalue().splitlines()
    assert len(lines) >= 5 and all(line.startswith("x: 10% (") for line in lines)
    elapsed = [float(line.split("(")[1].rstrip("s)")) for line in lines]
    assert elapsed == sorted(elapsed) and elapsed[-1] >= 0.4   # the elapsed time moves
    prog(10, 10)
    n = len(stream.getvalue().splitlines())
    time.sleep(0.2)
    assert len(stream.getvalue().splitlines()) == n and stream.getvalue().splitlines()[-1].startswith("x: 100%")
