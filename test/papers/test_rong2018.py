"""Reproduction of Rong et al. (2018): Fig. 3 study, ISO 286 grades, Table 3 and the example campaign."""

import numpy as np
import pytest

from helpers import pose_difference
from tolerance_ros.papers import rong2018
from tolerance_ros.core.accuracy.io import read_csv
from tolerance_ros.core.geometry import rpy_from_matrix
from tolerance_ros.core.campaign import load_campaign
from tolerance_ros.core.errors import rss_bound
from tolerance_ros.core.models import load_robot
from tolerance_ros.core.resources import config_dir

DEG = np.pi / 180


@pytest.fixture(scope="module")
def model():
    return load_robot(rong2018.ROBOT)


@pytest.fixture(scope="module")
def campaign(model):
    return load_campaign(rong2018.CAMPAIGN, model)


@pytest.fixture(scope="module")
def fig3(model, campaign):
    return rong2018.fig3_study(model, campaign, m=600, seed=3)


def test_campaign_is_table2(campaign):
    assert campaign.names == ["PE1", "PE2", "PE3", "PE4", "PE5", "PE6"] and campaign.cycles == 30
    for tp in campaign.poses:
        x, y, z, a, b, g = rong2018.PUBLISHED_TABLE2[tp.name]
        np.testing.assert_allclose(tp.pose[:3, 3], np.array([x, y, z]) * 1e-3)
        np.testing.assert_allclose(rpy_from_matrix(tp.pose[:3, :3])[0], np.array([a, b, g]) * DEG, atol=1e-12)


def test_fig3_errors_grow_with_the_source(fig3):
    mags = fig3["magnitudes_m"]
    np.testing.assert_allclose(mags[[0, -1]], [1e-6, 1e-5])
    for g, s in fig3["sweep"].items():
        for key in ("position_m", "orientation_rad"):
            assert np.all(np.diff(s[key], axis=1) > 0), (g, key)
            # Re-solved loops against the linear model: equal to first order.
            np.testing.assert_allclose(s[key], s[key.replace("_m", "_linear_m").replace("_rad", "_linear_rad")],
                                       rtol=1e-4)
        # Linear in the magnitude: ten times the source, ten times the error.
        np.testing.assert_allclose(s["position_m"][:, -1], 10 * s["position_m"][:, 0], rtol=1e-4)


def test_fig3_conclusion_depends_on_the_direction(fig3):
    """All three vectors of a limb displace its sphere centre: along their worst directions (and in
    the rms over random directions) they act alike, so the paper's ranking cannot hold there; along
    the x axis of its leg frame dl is taken up by the passive joint, so there it holds everywhere."""
    assert fig3["facts"]["worst_direction_relative_spread"] < 1e-9
    assert fig3["facts"]["max_abs_difference_da_db_columns"] == 0.0
    worst = fig3["sweep"]
    np.testing.assert_allclose(worst["l"]["position_m"], worst["a"]["position_m"], rtol=1e-4)
    assert fig3["verdict"]["worst"] == "fails" and fig3["verdict"]["rms"] == "fails"
    assert fig3["verdict"]["x"] == "holds"
    for name, entry in fig3["checks"]["worst"]["test_poses"].items():
        assert not entry["position"] and not entry["orientation"], name
        assert entry["dl_over_min_da_db"] == pytest.approx([1.0, 1.0], abs=1e-9)


def test_fig3_salience(fig3, model):
    for rows in ("position", "orientation"):
        sal = fig3["salience"][rows]
        assert sum(sal["all_limbs"].values()) == pytest.approx(1.0)
        assert sal["limb1"]["a"] == pytest.approx(sal["limb1"]["b"])
        for i in (1, 2, 3):
            assert sal["salience"][f"l{i}.x"] < 1e-12


def test_paper_tolerances_from_iso286():
    """IT6 at 6-10 mm is 9 um, IT7/IT8 at 10-18 mm 18/27 um, IT8 at 6-10 mm 22 um, IT9 at 18-30 mm 52 um."""
    d = dict(zip(load_robot(rong2018.ROBOT).param_names, rong2018.paper_tolerances() * 1e6))
    assert d["a2.y"] == pytest.approx(4.5) and d["b3.z"] == pytest.approx(4.5)
    assert d["l1.z"] == pytest.approx((18 + 27 + 22) / 2)
    assert d["l2.x"] == pytest.approx((52 + 22) / 2)


@pytest.fixture(scope="module")
def grades(model):
    """A lighter workspace search than the command's (checked below on fresh poses)."""
    return rong2018.grades(model, samples=1500, n_mc=400, solver_options={"n_check": 5000, "n_starts": 4})


def test_grades(grades, model):
    assert grades["success"] and grades["criterion"] == "rss"
    assert sorted(grades["free"]) == ["l1.x", "l2.x", "l3.x"]
    assert [f["size_mm"] for f in grades["fits"]] == [10, 8, 12, 15, 30, 8]
    assert [f["paper_grade"] for f in grades["fits"]] == [6, 6, 7, 8, 9, 8]
    tol = grades["tolerances"]
    for f in grades["fits"]:
        shares = [tol[f"{s[0]}{i}.{s[2]}"] / sum(s in g["sources"] for g in rong2018.FITS)
                  for s in f["sources"] for i in (1, 2, 3) if tol[f"{s[0]}{i}.{s[2]}"] is not None]
        assert f["tolerance_m"] == pytest.approx(min(shares))
        assert isinstance(f["grade"], int) and 1 <= f["grade"] <= 18
    # Independent check of the allocation on fresh workspace poses.
    delta = np.array([0.0 if tol[n] is None else tol[n] for n in model.param_names])
    J = model.error_jacobian(model.sample_joints(1000, seed=99))
    assert rss_bound(J.position, delta).max() <= grades["limits"]["position_m"] * 1.02
    assert rss_bound(J.orientation, delta).max() <= grades["limits"]["orientation_rad"] * 1.02


def _generate(**kw):
    return rong2018.generate_example_measurements(**kw)


def test_table3_of_a_perfect_robot_is_zero(model, campaign):
    data = _generate(delta=np.zeros(27), tracker_noise={"position_m": 0, "orientation_rad": 0},
                     joint_repeatability={"a": 0, "psi": 0, "l": 0})
    tab = rong2018.table3(campaign, model, rong2018.measured_by_pose(data))
    for row in tab["rows"]:
        assert row["n"] == 30
        assert max(abs(v) for v in row["mean_error"].values()) < 1e-12
        assert row["iso9283"]["RP_l"] < 1e-12


def test_table3_recovers_the_as_built_error(model, campaign):
    """Without noise every visit lands on the as-built pose: the mean error is that pose's deviation."""
    data = _generate(seed=5, tracker_noise={"position_m": 0, "orientation_rad": 0},
                     joint_repeatability={"a": 0, "psi": 0, "l": 0})
    tab = rong2018.table3(campaign, model, rong2018.measured_by_pose(data))
    q = campaign.joints_for(model)
    T_nom, T_built = model.fk(q), model.fk(q, data["dx"])
    dev = pose_difference(T_built, T_nom)
    drpy = rpy_from_matrix(T_built[:, :3, :3]) - rpy_from_matrix(T_nom[:, :3, :3])
    for k, row in enumerate(tab["rows"]):
        me = row["mean_error"]
        np.testing.assert_allclose([me["dX"], me["dY"], me["dZ"]], dev[k, :3], atol=1e-12)
        np.testing.assert_allclose([me["dalpha"], me["dbeta"], me["dgamma"]], drpy[k], atol=1e-10)
        assert row["iso9283"]["AP_p"] == pytest.approx(np.linalg.norm(dev[k, :3]))
    assert tab["rows"][2]["published"]["dZ"] == pytest.approx(0.038e-3)
    assert tab["rows"][4]["published"]["dgamma"] == pytest.approx(0.044 * DEG)


def test_shipped_measurements_are_reproducible(model, campaign):
    """The shipped file is what the documented generator writes, and the project's reader reads it."""
    path = config_dir() / "data" / rong2018.EXAMPLE_CSV
    data = _generate(seed=rong2018.EXAMPLE_SEED)
    comments = [ln[2:] for ln in path.read_text().splitlines() if ln.startswith("# ")]
    assert comments == rong2018.example_comments(data, model)
    meas = read_csv(path)
    assert len(meas) == 180 and list(meas.pose) == list(data["pose"]) and list(meas.cycle) == list(data["cycle"])
    assert np.all(np.diff(meas.stamps) > 0)
    np.testing.assert_allclose(meas.T[:, :3, 3], data["T"][:, :3, 3], atol=1e-9)
    np.testing.assert_allclose(rpy_from_matrix(meas.T[:, :3, :3]), rpy_from_matrix(data["T"][:, :3, :3]), atol=2e-9)
    tab = rong2018.table3(campaign, model, {n: meas.T[meas.pose == n] for n in campaign.names})
    ref = rong2018.table3(campaign, model, rong2018.measured_by_pose(data))
    for a, b in zip(tab["rows"], ref["rows"]):
        for k in rong2018.TABLE3_KEYS:
            assert a["mean_error"][k] == pytest.approx(b["mean_error"][k], abs=2e-9)


def test_generation_is_seeded(model):
    a, b, c = _generate(seed=1), _generate(seed=1), _generate(seed=2)
    np.testing.assert_array_equal(a["T"], b["T"])
    assert not np.allclose(a["T"], c["T"])
    assert np.all(np.abs(a["dx"]) <= a["delta"])
    counts = {n: int(np.sum(a["pose"] == n)) for n in rong2018.PUBLISHED_TABLE2}
    assert set(counts.values()) == {30}
