"""D-H chains: forward kinematics and the analytic parameter-error Jacobian."""
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import fd_jacobian, random_dh
from tolerance_ros.core.models import DHChain, ModelError


def _fd_check(model, q):
    T, EJ = model.fk_and_jacobian(q)
    ref = fd_jacobian(lambda p: model.fk(q, p - model.nominal), model.nominal.copy())
    scale = np.abs(ref).max() + 1.0
    assert np.abs(EJ.J - ref).max() / scale < 1e-7
    return EJ


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["standard", "modified"]))
def test_jacobian_matches_central_differences(seed, convention):
    rng = np.random.default_rng(seed)
    model = random_dh(rng, convention=convention)
    q = model.sample_joints(5, rng)
    _fd_check(model, q)


def test_jacobian_with_per_pose_parameter_errors_matches_differences():
    rng = np.random.default_rng(7)
    model = random_dh(rng, dof=6)
    q = model.sample_joints(4, rng)
    dx = rng.normal(0, 1e-3, (4, model.n_params))
    J = model.error_jacobian(q, dx).J
    for k in range(4):
        ref = fd_jacobian(lambda p: model.fk(q[k:k + 1], p - model.nominal), model.nominal + dx[k])
        assert np.allclose(J[k], ref[0], atol=1e-7)


def _paper_link(a, alpha, d, theta):
    """Gao et al. eq. 1 written out: the standard D-H link matrix."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def test_paper_arm_fk_is_the_product_of_eq1_matrices(gao):
    q = gao.sample_joints(10, 11)
    T = gao.fk(q)
    for k in range(10):
        ref = np.eye(4)
        for i in range(7):
            ref = ref @ _paper_link(gao.a[i], gao.alpha[i], gao.d[i], q[k, i])
        assert np.allclose(T[k], ref, atol=1e-14)


def test_paper_arm_jacobian_columns(gao):
    EJ = _fd_check(gao, gao.sample_joints(20, 3))
    assert EJ.J.shape == (20, 6, 28)
    assert EJ.names[:2] == ("a1", "a2") and EJ.names[14] == "alpha1" and EJ.names[-1] == "theta7"
    assert EJ.units[0] == "m" and EJ.units[-1] == "rad"
    # alpha7 and theta7 do not move the tool point (Fig. 2: zero salience).
    assert np.abs(EJ.position[:, :, [20, 27]]).max() < 1e-12


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_fk_and_joint_columns_match_pinocchio(seed):
    rng = np.random.default_rng(seed)
    model = random_dh(rng, dof=6)
    pm, fid = model.to_pinocchio()
    data = pm.createData()
    q = model.sample_joints(5, rng)
    T, EJ = model.fk_and_jacobian(q)
    for k in range(5):
        pin.computeJointJacobians(pm, data, q[k])
        pin.updateFramePlacements(pm, data)
        assert np.allclose(data.oMf[fid].homogeneous, T[k], atol=1e-12)
        Jp = pin.getFrameJacobian(pm, data, fid, pin.LOCAL_WORLD_ALIGNED)
        for i in range(model.dof):
            # The joint's own motion equals its zero-offset error: theta_i (revolute) or d_i (prismatic).
            name = ("theta" if model.joint_types[i] == "revolute" else "d") + str(i + 1)
            col = EJ.J[k, :, EJ.names.index(name)]
            assert np.allclose(Jp[:, i], col, atol=1e-12)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_small_and_large_batches_agree(backend, convention):
    """Few poses and many poses take different code paths (on numpy: 4x4 link products against a walk on axis
    arrays); both give the same poses and columns."""
    rng = np.random.default_rng(12)
    model = random_dh(rng, dof=6, convention=convention)
    model.backend = backend
    q = model.sample_joints(300, rng)
    T, J = model.fk_and_jacobian(q)
    pieces = [model.fk_and_jacobian(q[a:a + 7]) for a in range(0, 300, 7)]
    assert np.allclose(T, np.concatenate([t for t, _ in pieces]), rtol=0, atol=1e-14)
    assert np.allclose(J.J, np.concatenate([j.J for _, j in pieces]), rtol=0, atol=1e-14)


def test_perturbed_pinocchio_model_matches_perturbed_fk():
    rng = np.random.default_rng(9)
    model = random_dh(rng, dof=5)
    dx = rng.normal(0, 1e-2, model.n_params)
    pm, fid = model.to_pinocchio(dx)
    data = pm.createData()
    q = model.sample_joints(3, rng)
    T = model.fk(q, dx)
    for k in range(3):
        pin.framesForwardKinematics(pm, data, q[k])
        assert np.allclose(data.oMf[fid].homogeneous, T[k], atol=1e-12)


def test_prismatic_joint_moves_along_z():
    model = DHChain("p", a=[0.0], alpha=[0.0], d=[0.1], theta=[0.0], joint_types=["prismatic"],
                    joint_limits=[[0.0, 0.5]])
    T = model.fk([[0.2]])
    assert T[0, :3, 3] == pytest.approx([0, 0, 0.3])


@pytest.mark.parametrize("kwargs, field", [
    (dict(a=[0, np.nan], alpha=[0, 0], d=[0, 0], theta=[0, 0]), "joints[1].a"),
    (dict(a=[0, 0], alpha=[0], d=[0, 0], theta=[0, 0]), "alpha"),
    (dict(a=[0], alpha=[0], d=[0], theta=[0], joint_types=["helical"]), "joints[0].type"),
    (dict(a=[0], alpha=[0], d=[0], theta=[0], joint_limits=[[1, -1]]), "joints[0].limits"),
    (dict(a=[0], alpha=[0], d=[0], theta=[0], convention="craig"), "convention"),
    (dict(a=[0], alpha=[0], d=[0], theta=[0], base=np.ones((4, 4))), "base"),
    (dict(a=[0], alpha=[0], d=[0], theta=[0], joint_types=["prismatic"]), "limits"),
])
def test_invalid_tables_name_the_field(kwargs, field):
    with pytest.raises(ModelError, match=field.replace("[", r"\[").replace("]", r"\]")):
        DHChain("bad", **kwargs)


def test_bad_joints_are_rejected_with_the_joint_name(gao):
    with pytest.raises(ModelError, match=r"shape \(n, 7\)"):
        gao.fk(np.zeros((2, 6)))
    with pytest.raises(ModelError, match=r"joints\[0\]\[3\] \(joint4\)"):
        gao.fk([[0, 0, 0, np.nan, 0, 0, 0]])
    with pytest.raises(ModelError, match="outside the joint limits"):
        gao.check_joints([[4.0, 0, 0, 0, 0, 0, 0]], allow_out_of_limits=False)
    with pytest.raises(ModelError, match="dx"):
        gao.fk(np.zeros(7), dx=np.zeros(5))


def test_controller_directions_and_zero_offsets_map_the_joints_a_controller_logs(tmp_path, gao):
    """``q_model = direction * q + offset``: a controller that counts joint 2 the other way round and joint 3
    from 0.1 rad gives its own joints; the model, its Jacobian and the compensation take them as they are."""
    import yaml

    from tolerance_ros.core.calibration.calibrate import calibrated_mechanism
    from tolerance_ros.core.calibration.compensate import compensate
    from tolerance_ros.core.models import load_robot
    from tolerance_ros.core.resources import resolve
    data = yaml.safe_load(resolve("robots", "gao2023_7dof", suffixes=(".yaml",)).read_text())
    data["joints"][1]["direction"] = -1
    data["joints"][2]["offset"] = 100.0 / 1000 if data["units"]["angle"] == "rad" else 0.1
    (tmp_path / "ctrl.yaml").write_text(yaml.safe_dump(data))
    ctrl = load_robot(tmp_path / "ctrl.yaml")
    q = gao.sample_joints(5, 1)
    q_model = q.copy()
    q_model[:, 1] *= -1
    q_model[:, 2] += 0.1
    T, EJ = ctrl.fk_and_jacobian(q)
    T0, EJ0 = gao.fk_and_jacobian(q_model)
    assert np.allclose(T, T0, atol=1e-12) and np.allclose(EJ.J, EJ0.J, atol=1e-12)
    ctrl.backend = "numpy"
    assert np.allclose(ctrl.fk(q), T0, atol=1e-12)
    dx = np.random.default_rng(2).normal(0, 1e-4, gao.n_params)
    comp = compensate(calibrated_mechanism(ctrl, dx), ctrl, joints=q)
    assert np.all(comp.reached) and comp.residual_position.max() < 1e-9
    data["joints"][0]["direction"] = 2
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(Exception, match=r"joints\[0\]\.direction: expected 1 or -1"):
        load_robot(tmp_path / "bad.yaml")
