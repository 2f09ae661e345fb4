"""Calibration from contact (planes and points, no tracker) on the shared FANUC URDF, against a simulated truth."""
from pathlib import Path

import numpy as np
import pytest

from tolerance_ros.core.accuracy.simulate import touch
from tolerance_ros.core.calibration.contact import (ContactData, ContactLayout, _Reference, _stack, calibrate_contacts,
                                                    fit_contacts, initial_rig, validate_contacts)
from tolerance_ros.core.models.urdf import URDFChain

URDF = Path(__file__).resolve().parents[2] / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"
TOOL = np.array([0.012, -0.006, 0.11])      # the true target on the flange, m
NOMINAL = np.array([[0.0, 0.0, 0.1]])       # what the user says it is
PLANES = [((0, 0, 1.0), 0.3), ((1.0, 0, 0), 1.7), ((0, 1.0, 0), -0.9)]
NOISE = 1e-5


@pytest.fixture(scope="module")
def fanuc():
    return URDFChain(URDF)


def planes_campaign(model, dx, planes=PLANES, n=60, seed=0, tool=TOOL, session="s1", noise=NOISE):
    qs, cons = [], []
    for c, (normal, d) in enumerate(planes):
        normal = np.array(normal) / np.linalg.norm(normal)
        qs.append(touch(model, dx, tool, "plane", (normal, d), n, seed=[seed, c], noise=noise))
        cons += [c] * n
    q = np.concatenate(qs)
    keys = [(session, "plane", f"p{c}") for c in range(len(planes))]
    return ContactData(q, np.zeros(len(q), int), cons, keys, ("A",), where=[f"line {i + 3}" for i in range(len(q))])


def free_truth(model, seed=3):
    """As-built errors on the parameters plane contact can identify (the held ones exactly nominal), so that each
    estimate can be held against its truth."""
    held = fit_contacts(model, planes_campaign(model, None), NOMINAL, "full", sigma=NOISE, robust=False).held
    rng = np.random.default_rng(seed)
    scale = np.array([1e-4 if k == "length" else 5e-4 for k in model.param_kinds])
    dx = rng.uniform(-1, 1, model.n_params) * scale
    dx[model.param_index(held)] = 0.0
    return dx, held


def test_the_jacobian_of_every_unknown_is_the_derivative_of_the_residuals(fanuc):
    dx = np.zeros(fanuc.n_params)
    data = planes_campaign(fanuc, dx, n=6)
    pts = touch(fanuc, dx, TOOL, "point", [1.6, 0.2, 0.6], 5, seed=1, noise=NOISE)
    data = ContactData(np.r_[data.q, pts], np.zeros(len(data) + 5, int), np.r_[data.constraint, [3] * 5],
                       data.constraints + (("s1", "point", "tip"),), ("A",))
    ref = _Reference(initial_rig(fanuc, data, NOMINAL))
    layout = ContactLayout(fanuc.n_params, 1, 4)
    x = np.random.default_rng(0).standard_normal(layout.n) * 1e-3
    J, r, _ = _stack(fanuc, data, x, ref, layout)
    h = 1e-7
    for j in range(layout.n):
        e = np.zeros(layout.n)
        e[j] = h
        fd = -(_stack(fanuc, data, x + e, ref, layout)[1] - _stack(fanuc, data, x - e, ref, layout)[1]) / (2 * h)
        assert np.allclose(J[:, j], fd, atol=1e-7 * max(1.0, np.abs(fd).max())), j


def test_the_fit_reaches_the_least_squares_optimum_that_scipy_finds(fanuc):
    from scipy.optimize import least_squares
    dx, _ = free_truth(fanuc)
    data = planes_campaign(fanuc, dx, n=40, seed=5)
    f = fit_contacts(fanuc, data, NOMINAL, "full", sigma=NOISE, robust=False)
    assert f.convergence.converged
    free = np.flatnonzero(~np.isin(np.arange(f.layout.n), fanuc.param_index(f.held)))

    def residuals(z):
        x = np.zeros(f.layout.n)
        x[free] = z
        return _stack(fanuc, data, x, f.reference, f.layout)[1]
    # trf: scipy 1.11's MINPACK LM stops on its step test 7e-9 above the optimum here (1.17's does not)
    ref = least_squares(residuals, np.zeros(len(free)), method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        x_scale=1e-3)
    ours = float(np.sum(residuals(f.x[free]) ** 2))
    theirs = float(np.sum(ref.fun ** 2))
    assert abs(ours - theirs) <= 1e-9 * theirs, (ours, theirs)


def test_a_probe_tip_touching_one_point_from_20_orientations_gives_the_tool_point(fanuc):
    c = np.array([1.6, 0.2, 0.6])
    q = touch(fanuc, np.zeros(fanuc.n_params), TOOL, "point", c, 20, seed=2, noise=NOISE)
    data = ContactData(q, np.zeros(20, int), np.zeros(20, int), [("s1", "point", "tip")], ("A",))
    f = fit_contacts(fanuc, data, NOMINAL, "rig", sigma=NOISE)
    rig = f.rig
    assert f.convergence.converged and not f.rejected.any()
    assert np.all(np.abs(rig.offsets[0] - TOOL) <= 3 * rig.offsets_std[0]), (rig.offsets[0], rig.offsets_std[0])
    assert np.all(rig.offsets_std[0] < 5 * NOISE)
    assert np.all(np.abs(rig.points[0] - c) <= 3 * rig.points_std[0])
    assert 0.5 * NOISE < f.noise < 1.5 * NOISE                 # per axis, from the residuals


def test_three_planes_recover_the_joint_offsets_and_lengths_within_their_uncertainties(fanuc):
    dx, held = free_truth(fanuc)
    data = planes_campaign(fanuc, dx, seed=7)
    f = fit_contacts(fanuc, data, NOMINAL, "full", sigma=NOISE)
    assert f.convergence.converged and f.held == held and f.held_judged_at == "nominal and solution"
    est = np.flatnonzero(~np.isin(fanuc.param_names, held))
    z = (f.dx[est] - dx[est]) / f.std[est]
    assert np.abs(z).max() < 3.5, dict(zip(np.array(fanuc.param_names)[est], z.round(2)))
    names = [fanuc.param_names[j] for j in est]
    assert {"joint_2.offset", "joint_3.offset", "joint_4.offset", "joint_5.offset"} <= set(names)
    assert any(fanuc.param_kinds[j] == "length" for j in est)
    assert np.all(np.abs(f.rig.offsets[0] - TOOL) <= 3.5 * f.rig.offsets_std[0])


def test_what_contact_cannot_see_is_held_and_said(fanuc):
    f = fit_contacts(fanuc, planes_campaign(fanuc, None, n=30), NOMINAL, "full", sigma=NOISE)
    why = f.held_why
    scale = [n for n, w in why.items() if w.startswith("the overall scale")]
    assert scale == ["joint_4.x"]      # the longest nominal length (the upper arm) fixes the scale
    # joint 1 turns about the normal of the horizontal plane and moves along the two vertical ones: a motion of the rig
    assert why["joint_1.offset"].startswith("a motion of the rig")
    assert why["joint_6.offset"].startswith("a motion of the rig")   # the target turned about the flange's axis


def test_a_fit_free_to_shrink_the_robot_is_not_offered(fanuc):
    """Every length scaled with the rig meets the same contacts at scaled distances: without the scale held the fit
    would shrink the residuals toward zero; with it the residual stays at the noise."""
    dx, _ = free_truth(fanuc)
    f = fit_contacts(fanuc, planes_campaign(fanuc, dx, seed=9), NOMINAL, "full", sigma=NOISE)
    assert 0.7 * NOISE < f.rms() < 1.3 * NOISE


def test_cross_validation_falls_from_the_nominal_and_another_session_validates(fanuc):
    dx, _ = free_truth(fanuc, seed=4)
    train = planes_campaign(fanuc, dx, n=40, seed=11)
    cc = calibrate_contacts(fanuc, train, NOMINAL, sigma=NOISE, folds=5)
    v = cc.validation
    assert cc.which == "full" and v["rows_scored"] == len(train)
    assert v["after"]["contact_rms_m"] < 2 * NOISE < v["before"]["contact_rms_m"]
    moved = [((0, 0.1, 1.0), 0.25), ((1.0, 0.05, 0), 1.65), ((0, 1.0, 0.02), -0.8)]
    other = planes_campaign(fanuc, dx, moved, n=30, seed=12, session="s2")
    res = validate_contacts(fanuc, other, cc.fit.dx, cc.fit.rig.offsets, cc.nominal.rig.offsets, sigma=NOISE)
    assert res["after"]["contact_rms_m"] < 2 * NOISE < res["before"]["contact_rms_m"]
    assert [p["session"] for p in res["rig"]["planes"]] == ["s2"] * 3


def test_one_bad_contact_is_rejected_and_named(fanuc):
    dx, _ = free_truth(fanuc)
    data = planes_campaign(fanuc, dx, n=40, seed=13)
    data.q[17] = data.q[57]                      # a contact with the second plane logged as one with the first
    cc = calibrate_contacts(fanuc, data, NOMINAL, parameters="full", prior=None, sigma=NOISE, folds=4)
    assert [r["where"] for r in cc.rejected] == ["line 20"]
    assert cc.fit.rms() < 1.5 * NOISE


def test_planned_contacts_are_better_determined_than_random_ones_and_touch_their_rig(fanuc):
    from tolerance_ros.core.calibration.contact_planning import plan_contacts
    specs = [("plane", f"p{c}", (np.array(n), d)) for c, (n, d) in enumerate(PLANES)]
    pl = plan_contacts(fanuc, specs, {"A": NOMINAL[0]}, 30, candidates=600, seed=1)
    assert pl.planned["rank"] == pl.planned["unknowns"] == len(pl.columns)
    assert pl.planned["O1"] > pl.random["O1"] and pl.planned["condition"] < pl.random["condition"]
    assert "joint_4.x" in pl.held and "joint_1.offset" in pl.held     # the scale; a motion of the rig
    T = fanuc.fk(pl.q)
    P = T[:, :3, 3] + T[:, :3, :3] @ NOMINAL[0]
    for (kind, cid, (n, d)) in specs:
        rows = [i for i, c in enumerate(pl.contact) if c == f"plane:{cid}"]
        assert rows and np.abs(P[rows] @ n - d).max() < 1e-9


def test_fingertips_flush_on_a_table_keep_their_places_along_it():
    """Three fingertips touching a table at once (the form of a humanoid's real set): their places along the table
    cannot be seen and are held where given, said (their std at the noise far beyond a share of their lever arm);
    free, the fit moved them onto one point and fitted every contact exactly (a degenerate calibration); the fit
    stays at the noise and predicts held-out poses better than the nominal robot."""
    from tolerance_ros.testing.example_robots import example_urdf
    talos = URDFChain(example_urdf("talos_reduced.urdf"), tip_link="gripper_left_base_link", base_link="left_sole_link")
    fingers = np.array([[0, 0, -0.1], [0.03, 0, -0.1], [0, 0.03, -0.1]])
    dx = np.random.default_rng(5).uniform(-1, 1, talos.n_params) * np.where(
        np.array(talos.param_kinds) == "length", 2e-4, 1e-3)
    q = touch(talos, dx, fingers, "plane", (np.array([0, 0, 1.0]), 0.9), 40, seed=6, noise=NOISE)
    n = len(q)
    data = ContactData(np.repeat(q, 3, axis=0), np.tile([0, 1, 2], n), np.zeros(3 * n, int),
                       [("s1", "plane", "table")], ("F1", "F2", "F3"), np.repeat([f"P{i}" for i in range(n)], 3))
    f = fit_contacts(talos, data, fingers, "full", sigma=NOISE)
    assert {f"target F{k}.{a}" for k in (1, 2, 3) for a in "xy"} <= set(f.rig_held)
    assert np.allclose(f.rig.offsets[:, :2], fingers[:, :2]) and f.convergence.converged
    assert 0.5 * NOISE < f.rms() < 1.5 * NOISE
    cc = calibrate_contacts(talos, data, fingers, sigma=NOISE, folds=5)
    assert cc.validation["after"]["contact_rms_m"] < 0.5 * cc.validation["before"]["contact_rms_m"]
    said = cc.fit.targets_why
    assert all(not said[f"F{k}.{a}"]["fitted"] and said[f"F{k}.{a}"]["kind"] in ("copy", "unseen")
               for k in (1, 2, 3) for a in "xy")


def test_the_noise_comes_from_the_rows_and_the_plane_is_always_fitted(fanuc):
    """Contact rows of 0.5 mm noise: the noise is estimated from them (robust, after the rig alone, then after the
    parameters), not the tracker's 10 um; a noise given overrides the first estimate, and whatever it is the planes
    are fitted (with 1 mm given, every rig unknown had been held, the planes included)."""
    dx, _ = free_truth(fanuc)
    data = planes_campaign(fanuc, dx, n=40, seed=21, noise=5e-4)
    f = fit_contacts(fanuc, data, [TOOL], "joint-offsets")
    assert not f.noise_given and 0.35e-3 < f.noise_robust < 0.7e-3 and f.noise_rig >= f.noise_robust
    from tolerance_ros.core.calibration.contact import TARGET_SHARE
    lever = np.linalg.norm(TOOL)
    assert f.convergence.converged and all(w["fitted"] == (w["std_m"] <= TARGET_SHARE * lever)
                                           for w in f.targets_why.values())
    for sigma in (1e-5, 1e-3):
        g = fit_contacts(fanuc, data, [TOOL], "joint-offsets", sigma=sigma)
        rig = g.rig
        assert g.noise_given and g.noise_rig == sigma
        assert np.all(rig.d_std > 0) and np.all(np.isfinite(rig.normals_std)) and np.all(rig.normals_std > 0)
        assert np.allclose(rig.d, f.rig.d, atol=5e-4)        # the same planes, fitted


def test_the_one_standard_error_rule_takes_the_fewest_parameters_within_one_standard_error_of_the_best():
    from tolerance_ros.core.calibration.contact import one_standard_error

    def score(label, estimated, rms, se, bad=()):
        return {"label": label, "estimated": estimated, "cv_contact_rms_m": rms, "standard_error_m": se,
                "not_converged_folds": list(bad)}
    scores = [score("rig", 0, 14e-3, 2e-3), score("joint-offsets", 15, 5.9e-3, 1e-3),
              score("joint-offsets, Tikhonov 0.01", 15, 5.5e-3, 1e-3), score("full, prior", 105, 5.2e-3, 0.4e-3),
              score("full", 105, 4.0e-3, 1e-3, bad=[3])]
    chosen, why = one_standard_error(scores)
    assert chosen["label"] == "joint-offsets, Tikhonov 0.01"   # within 5.2 + 0.4 mm; of the 15, the lower RMS
    assert "5.2 mm" in why and "not chosen" in why             # 'full' did not converge in a fold: not the best
    scores[3]["standard_error_m"] = 0.2e-3                     # the best's scatter smaller: nothing simpler within
    assert one_standard_error(scores)[0]["label"] == "full, prior"


def test_the_cross_validation_gives_each_folds_rms_and_their_standard_error(fanuc):
    from tolerance_ros.core.calibration.contact import Candidate, cross_validate
    from tolerance_ros.core.accuracy.folds import folds_of, pose_groups
    dx, _ = free_truth(fanuc)
    data = planes_campaign(fanuc, dx, n=20, seed=22, noise=5e-4)
    cv = cross_validate(fanuc, data, Candidate("joint-offsets", tikhonov=1e-2), folds=5, offsets=NOMINAL)
    fold, k = folds_of(pose_groups(data.q, data.labels)[0], 5, 0)
    d = cv["distances_m"]
    per = np.array([np.sqrt(np.mean(d[fold == f] ** 2)) for f in range(k)])
    assert np.allclose(cv["fold_rms_m"], per) and cv["rows_scored"] == len(data)
    assert cv["standard_error_m"] == pytest.approx(np.std(per, ddof=1) / np.sqrt(k))
    assert cv["after"]["contact_rms_m"] == pytest.approx(np.sqrt(np.mean(d ** 2)))
    assert not cv["not_converged"] and 0 < cv["effective_unknowns"]


def test_the_candidates_state_their_regularisation():
    from tolerance_ros.core.calibration.contact import TIKHONOV, candidates
    labels = [c.label for c in candidates((0.005, 0.005))]
    assert labels[:2] == ["rig", "joint-offsets"] and TIKHONOV[0] == 1e-3       # FIGAROH's weight on TALOS first
    assert "joint-offsets, Tikhonov 0.001" in labels and "full, prior 5 mm / 5 mrad" in labels
    assert [c.label for c in candidates(None)].count("full, prior 5 mm / 5 mrad") == 0


@pytest.fixture(scope="module")
def standing():
    """A humanoid standing on its left sole, the left fingertips flush on a table: its hip roll and knee yield under
    the weight they carry (2e-4, 1e-4 rad/(N m): 30-45 mrad), the right leg and arm recorded beside the chain."""
    from tolerance_ros.testing import standing as st
    model = st.chain()
    rng = np.random.default_rng(3)
    dx = np.zeros(model.n_params)
    dx[model.joint_columns()] = rng.normal(0, 5e-3, model.dof)
    c = np.zeros(model.dof)
    c[model.joint_names.index("leg_left_2_joint")], c[model.joint_names.index("leg_left_4_joint")] = 2e-4, 1e-4
    normal = np.array([0.05, 0.02, 1.0]) / np.linalg.norm([0.05, 0.02, 1.0])
    q, names, others = st.campaign(model, dx, c, (normal, 0.72), 30, seed=4, encoder=2e-4)
    n = len(q)
    data = ContactData(np.repeat(q, 3, axis=0), np.tile([0, 1, 2], n), np.zeros(3 * n, int),
                       [("s1", "plane", "table")], ("F1", "F2", "F3"), np.repeat([f"P{i}" for i in range(n)], 3),
                       others=np.repeat(others, 3, axis=0), other_names=names)
    return model, dx, c, data


def test_a_standing_robots_yielding_joints_are_found_by_the_elastic_candidate(standing):
    """The folds choose the joint offsets with every joint's compliance under the whole weight on the sole (not the
    root link held, not a geometric candidate); the yielding joints' compliances are found, the others near 0."""
    from tolerance_ros.core.calibration.contact import ELASTIC
    from tolerance_ros.testing.standing import TIPS
    model, dx, c, data = standing
    cc = calibrate_contacts(model, data, TIPS, folds=5)
    assert cc.which == ELASTIC and cc.load.kind == "standing" and cc.fit.convergence.converged
    p = model.n_params
    found = cc.fit.dx[p:]
    yielding = c > 0
    assert found[yielding] == pytest.approx(c[yielding], rel=0.1)
    assert np.all(np.abs(found[~yielding] * cc.largest_loads[~yielding]) < 5e-3)     # under 5 mrad at their loads,
    assert np.all(np.abs(found[yielding] * cc.largest_loads[yielding]) > 25e-3)      # the yielding ones 30-45
    assert cc.validation["after"]["contact_rms_m"] < 0.15 * cc.validation["before"]["contact_rms_m"]
    geometric = min(s["cv_contact_rms_m"] for s in cc.scores if s["parameters"] in ("joint-offsets", "full"))
    assert cc.validation["after"]["contact_rms_m"] < 0.2 * geometric


def test_the_rest_of_the_posture_loads_the_joints(standing):
    """The right leg and arm move the centre of mass: without their readings the elastic fit predicts worse."""
    from tolerance_ros.core.calibration.contact import DEFLECTIONS, ELASTIC, ELASTIC_TIKHONOV, Candidate, cross_validate
    from tolerance_ros.testing.standing import TIPS
    model, _, _, data = standing
    blind = ContactData(data.q, data.target, data.constraint, data.constraints, data.target_names, data.labels)
    cand = Candidate(ELASTIC, tikhonov=ELASTIC_TIKHONOV, deflection=DEFLECTIONS[0], load="standing")
    seen, unseen = (cross_validate(model, d, cand, folds=5, offsets=TIPS)["after"]["contact_rms_m"] for d in (data, blind))
    assert seen < 0.5 * unseen


def test_an_elastic_calibration_predicts_another_table_from_the_command_line(capsys, standing, tmp_path):
    """calibrate reads the other joints' columns of the CSV, the calibration file keeps the compliances and their
    load, and validate on another table (its plane alone refitted) applies them at that session's postures."""
    import json
    from helpers import run_cli as run
    from tolerance_ros.testing import standing as st
    model, dx, c, _ = standing
    a = st.write_campaign(tmp_path / "a.csv", *st.campaign(model, dx, c, (np.array([0.0, 0.0, 1.0]), 0.72), 30, seed=4,
                                                           encoder=2e-4), "A")
    normal = np.array([-0.04, 0.06, 1.0]) / np.linalg.norm([-0.04, 0.06, 1.0])
    b = st.write_campaign(tmp_path / "b.csv", *st.campaign(model, dx, c, (normal, 0.78), 20, seed=9, encoder=2e-4), "B")
    code, out, err = run(capsys, "calibrate", *st.robot_args(), "--measurements", a, *st.target_args(), "--folds", "5",
                         "--out", tmp_path / "cal", "--json", "--quiet")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["model"]["parameters"] == "joint-offsets+elastic"
    assert sorted(doc["model"]["elastic"]["posture_from"]) == sorted(st.OTHERS)
    assert not any("ignored" in w for w in doc["warnings"])
    code, out, err = run(capsys, "validate", "--calibration", tmp_path / "cal" / "calibration.yaml", "--measurements",
                         b, "--json")
    assert code == 0, err
    v = json.loads(out)
    assert v["after"]["contact_rms_m"] < 0.1 * v["before"]["contact_rms_m"] and v["after"]["contact_rms_m"] < 1e-3
    assert not v["warnings"]
    lines = b.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("stamp"))
    keep = [k for k, h in enumerate(lines[header].split(",")) if "right" not in h]
    (tmp_path / "chain_only.csv").write_text("\n".join(",".join(line.split(",")[k] for k in keep) if i >= header else
                                                        line for i, line in enumerate(lines)) + "\n")
    code, out, err = run(capsys, "validate", "--calibration", tmp_path / "cal" / "calibration.yaml", "--measurements",
                         tmp_path / "chain_only.csv", "--json")
    blind = json.loads(out)
    assert code == 0 and any("no column for 13 of its joints" in w for w in blind["warnings"])
    assert blind["after"]["contact_rms_m"] > v["after"]["contact_rms_m"]
