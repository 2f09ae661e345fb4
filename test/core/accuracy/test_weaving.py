"""ISO 9283 weaving deviations WS, WF: the stroke and the frequency of a weave, against synthetic signals and
simulated streams."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.iso_paths import plan_path
from tolerance_ros.core.accuracy.path_report import PathOptions, path_report
from tolerance_ros.core.accuracy.simulate import path_streams
from tolerance_ros.core.accuracy.weaving import signal_figures


def test_the_stroke_and_frequency_of_a_sampled_sine():
    rng = np.random.default_rng(0)
    t = np.arange(0, 3.0, 1e-3) + 0.37e-3
    y = 0.004 * np.sin(2 * np.pi * 2.7 * t + 0.3) + 0.01 + rng.normal(0, 2e-6, len(t))
    r = signal_figures(t, y)
    assert r["stroke_m"] == pytest.approx(0.008, rel=0.005) and r["frequency_hz"] == pytest.approx(2.7, rel=1e-3)
    assert r["periods"] == 5                      # 8 periods, less the first and the last, less one partial
    assert signal_figures(t[:800], y[:800]) is None   # too few periods


@pytest.fixture(scope="module")
def weave(gao):
    return plan_path(gao, "weave", 0.1, 1.0, 0.5, 3, None, None, seed=0)


def _weaving(gao, jp, noise, settling=None):
    st = path_streams(gao, jp, None, None, 500, 1000, 0.008, noise, 3, settling=settling)
    return path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints, None, PathOptions(latency=0.008))


def test_a_robot_that_follows_its_command_weaves_as_commanded(gao, weave):
    jp, tp = weave
    w = _weaving(gao, jp, 10e-6)["weaving"]
    assert len(w["cycles"]) == 3 and w["S_c_m"] == pytest.approx(0.1 * tp.side, rel=0.02)
    assert abs(w["WS"]) < 0.005 and abs(w["WF"]) < 5e-4


def test_a_robot_near_resonance_overshoots_its_weave(gao, weave):
    jp, _ = weave
    settling = (2 * np.pi * 8, 0.2)
    noisy, exact = (_weaving(gao, jp, n, settling)["weaving"] for n in (10e-6, 0.0))
    assert exact["WS"] > 0.05                                    # the joints' resonance amplifies the stroke
    assert noisy["WS"] == pytest.approx(exact["WS"], rel=0.05)
    assert noisy["WF"] == pytest.approx(exact["WF"], abs=5e-4) and abs(exact["WF"]) < 0.005


def test_a_path_that_does_not_weave_has_no_weaving_figures(gao):
    jp, _ = plan_path(gao, "line", 0.1, 1.0, 0.5, 2, None, None, seed=0)
    assert _weaving(gao, jp, 10e-6)["weaving"] is None


def test_noise_about_the_median_at_rest_is_no_crossing():
    rng = np.random.default_rng(1)
    t = np.arange(0, 5.0, 1e-3)
    swing = (t > 0.5) & (t < 4.5)                    # at rest on the median, 4 s of a 2 Hz weave, at rest again
    y = np.where(swing, 0.004 * np.sin(2 * np.pi * 2.0 * (t - 0.5)), 0.0) + rng.normal(0, 2e-5, len(t))
    r = signal_figures(t, y)
    assert r["periods"] == 4 and r["frequency_hz"] == pytest.approx(2.0, rel=2e-3)   # 7 rises, less 2
