"""RViz marker geometry: the ellipsoid against the Jacobian, the sphere against the worst case, the arrows
against the measurements; stable ids and DELETE_ALL after a budget change."""
import numpy as np
import pytest

from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.errors import rss_bound, worst_case_bound
from tolerance_ros.core.geometry import quat_to_matrices
from tolerance_ros.services import markers
from tolerance_ros.services.monitor import MonitorLogic

Q = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6])


@pytest.fixture(scope="module")
def delta(gao):
    return load_budget("gao2023_delta2", gao).vector_for(gao)


def test_the_rss_ellipsoid_is_the_covariance_of_the_position_error(gao, delta):
    J = gao.error_jacobian(Q[None]).position[0]
    axes, semi = markers.rss_ellipsoid(J, delta)
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) == pytest.approx(1.0)
    cov = J @ np.diag((delta / 3) ** 2) @ J.T
    np.testing.assert_allclose(axes @ np.diag((semi / 3) ** 2) @ axes.T, cov, atol=1e-18)
    assert np.sqrt(np.sum(semi ** 2)) == pytest.approx(rss_bound(J[None], delta)[0])


def test_bound_markers_at_the_tool_point(gao, delta):
    sphere, ellipsoid, text = markers.bound_markers(gao, Q, delta, scale=100.0)
    p = gao.fk(Q[None])[0, :3, 3]
    worst = worst_case_bound(gao.error_jacobian(Q[None]).position, delta)[0]
    assert sphere["type"] == "sphere" and sphere["position"] == pytest.approx(p.tolist())
    assert sphere["scale"] == pytest.approx([200.0 * worst] * 3)
    axes, semi = markers.rss_ellipsoid(gao.error_jacobian(Q[None]).position[0], delta)
    np.testing.assert_allclose(quat_to_matrices(ellipsoid["orientation"])[0], axes, atol=1e-12)
    assert ellipsoid["scale"] == pytest.approx((200.0 * semi).tolist())
    assert (sphere["ns"], sphere["id"], ellipsoid["id"], text["id"]) == ("bound", 0, 1, 2)
    assert "x100" in text["text"] and f"{worst * 1e3:.3f} mm" in text["text"]


def test_measurement_arrows_go_from_nominal_to_measured_and_say_the_margin(gao):
    dp = np.array([1e-4, -2e-4, 5e-5])
    recent = [{"seq": 3, "joints": Q, "dp": dp, "bound": 5e-4, "margin": 2.5e-4},
              {"seq": 25, "joints": Q, "dp": dp, "bound": 1e-4, "margin": -1.3e-4},
              {"seq": 26, "joints": Q, "dp": dp, "bound": np.nan, "margin": np.nan}]
    out = markers.measurement_markers(gao, recent, scale=100.0, slots=20)
    arrows = [m for m in out if m["ns"] == "measurements"]
    texts = [m for m in out if m["ns"] == "margins"]
    p = gao.fk(Q[None])[0, :3, 3]
    np.testing.assert_allclose(arrows[0]["points"][0], p)
    np.testing.assert_allclose(arrows[0]["points"][1], p + 100.0 * dp)
    assert [a["id"] for a in arrows] == [3, 5, 6] and arrows[0]["color"] == list(markers.GREEN)
    assert arrows[1]["color"] == list(markers.RED) and texts[1]["text"] == "-0.130 mm"
    assert texts[0]["text"] == "+0.250 mm" and texts[2]["text"] == "no budget"


def test_the_monitor_clears_markers_when_its_budget_changes(gao, tmp_path):
    budget = load_budget("gao2023_delta2", gao)
    mon = MonitorLogic(gao, budget, slop=0.01, clock=lambda: 0.0)
    first = mon.markers()
    assert first[0]["type"] == "delete_all" and len(first) == 1          # no joint state yet: nothing to draw
    mon.on_joint_state(1.0, gao.joint_names, Q)
    again = mon.markers()
    assert [m["type"] for m in again] == ["sphere", "sphere", "text"]
    mon.set_budget(load_budget("gao2023_delta1", gao))
    assert mon.markers()[0]["type"] == "delete_all"
    mon.set_budget(None)
    assert [m["type"] for m in mon.markers()] == ["delete_all"]
