"""The ISO 9283 report's figures against the truth of simulated robots (backlash, warm-up, several robots of a
type), each within 5 % or within the noise floor of its mean."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.iso9283_report import ISOOptions, ISOReportError, iso9283_report
from tolerance_ros.core.accuracy.simulate import as_built_errors, backlash, measure_targets, thermal_expansion
from tolerance_ros.core.accuracy.iso9283 import iso_cube_joints
from tolerance_ros.core.calibration.planning import iso9283_campaign
from tolerance_ros.core.campaign import campaign_from_dict
from tolerance_ros.core.geometry import transform

NOISE = 3e-6
T_TRACKER = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


@pytest.fixture(scope="module")
def cube(gao):
    q, _ = iso_cube_joints(gao, gao.sample_joints(400, 0))
    return q


def _run(model, campaign, seed=0, play=0.0, growth=None, tracker=T_TRACKER, noise=NOISE):
    """(measurements, noise-free attained positions in the base frame, pose names) of one simulated robot."""
    dx = as_built_errors(np.where(np.array(model.param_kinds) == "length", 5e-5, 2e-4), seed)
    steps, pose, cycle, via = campaign.steps(model)
    visit = ~via
    names = np.array(campaign.names, object)[pose[visit]]
    q = steps[visit]
    stamps = np.flatnonzero(visit) * campaign.dwell_s
    d = backlash(steps, play, np.ones(model.dof, bool))[visit]
    g = None if growth is None else thermal_expansion(stamps, *growth)
    meas = measure_targets(model, q, dx, None, noise, 1e-6, tracker, seed + 1, stamps, names,
                           points=False, deflection=d, growth=g)
    meas.cycle = cycle[visit]
    true = model.fk(q + d, dx)[:, :3, 3] * (1.0 if g is None else 1.0 + g[:, None])
    return meas, true, names


def test_vap_and_ad_against_a_robot_with_backlash(gao, cube):
    camp = campaign_from_dict(iso9283_campaign(gao, cube, 0.1, cycles=30, dwell=1.0), model=gao)
    meas, true, names = _run(gao, camp, play=1e-3)
    r = iso9283_report(gao, meas, camp)
    assert set(r["multidirectional"]) == {"P1", "P2", "P3", "P4", "P5"}
    for pose, v in r["multidirectional"].items():
        bary = [true[names == f"{pose}{d}"].mean(axis=0) for d in ("+x", "+y", "+z")]
        truth = max(np.linalg.norm(a - b) for a in bary for b in bary)
        assert truth > 20 * NOISE                             # the backlash shows, well above the noise
        assert v["vAP_p"] == pytest.approx(truth, rel=0.05)
    D = np.linalg.norm(true[names == "P2"] - true[names == "P4"], axis=1)
    C = gao.fk(np.array([camp.joints_for(gao)[camp.names.index(p)] for p in ("P2", "P4")]))
    truth = D.mean() - np.linalg.norm(C[0, :3, 3] - C[1, :3, 3])
    floor = 3 * NOISE * np.sqrt(2 / 30)                      # three standard deviations of the mean distance
    assert r["distance"]["between"] == ["P2", "P4"]
    assert abs(r["distance"]["AD_p"] - truth) <= max(0.05 * abs(truth), floor)
    assert r["distance"]["RD_p"] == pytest.approx(3 * np.sqrt(np.var(D) + 2 * NOISE ** 2), rel=0.35)   # n = 30
    assert "vAP (multi-directional pose accuracy variation)" not in {m["characteristic"] for m in r["missing"]}


def test_drift_of_a_robot_warming_up_for_eight_hours(gao, cube):
    camp = campaign_from_dict(iso9283_campaign(gao, cube[[0, 1, 3]], cycles=960, dwell=10.0), model=gao)   # 8 h
    meas, true, names = _run(gao, camp, growth=(3e-4, 7200.0))
    r = iso9283_report(gao, meas, camp, ISOOptions(drift_window=3600.0))
    for pose in ("P1", "P2"):
        t = meas.stamps[names == pose]
        p = true[names == pose]
        truth = np.linalg.norm(p[t < 3600].mean(axis=0) - p[t >= 7 * 3600].mean(axis=0))
        assert truth > 10 * NOISE
        assert r["drift"][pose]["dAP_p"] == pytest.approx(truth, rel=0.05)
        assert len(r["drift"][pose]["windows"]) == 8


def test_exchangeability_of_three_robots_of_a_type(gao, cube):
    camp = campaign_from_dict(iso9283_campaign(gao, cube, cycles=10), model=gao)
    runs = [_run(gao, camp, seed=s, tracker=None) for s in (0, 10, 20)]
    r = iso9283_report(gao, runs[0][0], camp, ISOOptions(registration="none"), others=[m for m, _, _ in runs[1:]])
    for pose in camp.names:
        bary = np.array([t[n == pose].mean(axis=0) for _, t, n in runs])
        truth = np.linalg.norm(bary.max(axis=0) - bary.min(axis=0))
        assert r["exchangeability"][pose]["E"] == pytest.approx(truth, rel=0.05)


def test_what_the_data_do_not_allow_is_named(gao, cube):
    camp = campaign_from_dict(iso9283_campaign(gao, cube, cycles=3), model=gao)
    r = iso9283_report(gao, _run(gao, camp)[0], camp)
    missing = {m["characteristic"]: m["needs"] for m in r["missing"]}
    assert "--approach" in missing["vAP (multi-directional pose accuracy variation)"]
    assert "--other" in missing["E (exchangeability)"]
    assert "two windows" in missing["dAP, dRP (drift of pose characteristics)"]
    assert r["multidirectional"] == {} and r["exchangeability"] == {} and r["drift"] == {}
    assert set(r["pose"]) == set(camp.names) and r["distance"]["n"] == 3


def test_approaches_commanding_different_poses_are_refused(gao, cube):
    doc = iso9283_campaign(gao, cube, 0.05, cycles=3)
    doc["poses"][5]["joints"] = doc["poses"][6]["joints"] = list(doc["poses"][1]["joints"])   # P1+x, P1+y at P2
    doc["poses"][5]["joints"][0] += 1.0
    camp = campaign_from_dict(doc, model=gao)
    with pytest.raises(ISOReportError, match="approaches of P1 .* must command one pose"):
        iso9283_report(gao, _run(gao, camp)[0], camp)


def test_a_distance_between_unknown_poses_is_refused(gao, cube):
    camp = campaign_from_dict(iso9283_campaign(gao, cube, cycles=3), model=gao)
    with pytest.raises(ISOReportError, match=r"\['P9'\] are not in campaign"):
        iso9283_report(gao, _run(gao, camp)[0], camp, ISOOptions(distance=("P1", "P9")))


def test_static_compliance_against_the_joints_stiffness(gao, cube):
    from tolerance_ros.core.accuracy.simulate import joint_compliance
    camp = campaign_from_dict(iso9283_campaign(gao, cube, cycles=3), model=gao)
    dx = as_built_errors(np.where(np.array(gao.param_kinds) == "length", 5e-5, 2e-4), 0)
    axes = [s * v * np.eye(6)[k] for k, v in zip(range(6), [300.0] * 3 + [30.0] * 3) for s in (1, -1)]
    steps = np.vstack([np.zeros(6), *axes])                 # unloaded, then +-300 N and +-30 N m along each axis
    q = np.repeat(camp.joints_for(gao), 3 * len(steps), axis=0)
    W = np.tile(steps, (len(q) // len(steps), 1))
    K = np.full(gao.dof, 4e4)
    meas = measure_targets(gao, q, dx, None, NOISE, 1e-6, T_TRACKER, 1, np.arange(len(q), dtype=float),
                           np.repeat(np.array(camp.names, object), 3 * len(steps)), points=False,
                           deflection=joint_compliance(gao, q, dx, W, K))
    meas.load = W
    r = iso9283_report(gao, meas, camp)
    for i, pose in enumerate(camp.names):
        _, EJ = gao.fk_and_jacobian(camp.joints_for(gao)[i:i + 1], dx)
        J = EJ.J[0][:, gao.joint_columns()]
        truth = J @ np.diag(1 / K) @ J.T                        # at the tool: J K^-1 J^T (m/N, rad/N m, ...)
        C = np.array(r["compliance"][pose]["C"], dtype=float)
        assert np.allclose(np.diag(C), np.diag(truth), rtol=0.05)
        for block in (slice(0, 3), slice(3, 6)):              # forces on the point, torques on the turn
            assert np.abs(C[block, block] - truth[block, block]).max() < 0.05 * np.abs(truth[block, block]).max()
        v = r["compliance"][pose]
        assert v["compliance_rad_per_Nm"]["z"] == pytest.approx(truth[5, 5], rel=0.05)
    assert r["pose"]["P1"]["n"] == 3                            # the pose figures take the unloaded visits
    assert "static compliance" not in {m["characteristic"] for m in r["missing"]}
