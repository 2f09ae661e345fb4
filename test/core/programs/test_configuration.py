"""An arm's configuration signs and the nominal inverse kinematics in a configuration, on the FANUC R-2000iC URDF and
the UR5: the signs against pinocchio's joint frames, every solution of a pose found in its own configuration, the
solution against scipy's least squares."""
import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import least_squares

from tolerance_ros.core.geometry import rotation_error
from tolerance_ros.core.models import ModelError, load_robot
from tolerance_ros.core.programs.configuration import ArmGeometry
from tolerance_ros.testing.programs import FANUC_URDF, robot


@pytest.fixture(scope="module")
def fanuc():
    return load_robot(str(FANUC_URDF))


@pytest.fixture(scope="module")
def geometry(fanuc):
    return ArmGeometry(fanuc)


def _reference_signs(model, q):
    """The signs from pinocchio's joint placements (the axes' points and directions, an independent path)."""
    pm = model.pin_model
    data = pm.createData()
    out = []
    for row in q:
        pin.forwardKinematics(pm, data, model.pinocchio_configuration(row))
        ids = [pm.getJointId(n) for n in model.joint_names]
        pts = [data.oMi[i].translation.copy() for i in ids]
        pin.computeJointJacobians(pm, data, model.pinocchio_configuration(row))
        dirs = [_axis(pm, data, i) for i in ids]
        p4, d4, p5, d5 = pts[3], dirs[3], pts[4], dirs[4]
        # the point of joint 5's axis nearest joint 4's
        w0 = p5 - p4
        b = d5 @ d4
        t = (b * (d4 @ w0) - d5 @ w0) / (1 - b * b) if abs(1 - b * b) > 1e-12 else 0.0
        wc = p5 + t * d5
        a1 = dirs[0]
        f0 = np.array([1.0, 0, 0]) - a1[0] * a1
        f0 /= np.linalg.norm(f0)
        f = pin.exp3(a1 * row[0]) @ f0
        c2 = pts[1] + ((wc - pts[1]) @ dirs[1]) * dirs[1]
        c3 = pts[2] + ((wc - pts[2]) @ dirs[2]) * dirs[2]
        shoulder = np.sign((wc - pts[0]) @ f)
        elbow = np.sign(np.cross(c3 - c2, wc - c3) @ np.cross(a1, f))
        out.append([shoulder, elbow, 1 if row[4] >= 0 else -1])
    return np.array(out, int)


def _axis(pm, data, i):
    """(3,) joint i's axis in the world frame: the angular part of its column of the joint Jacobian (every
    pinocchio version from the floor up gives it; the joint model's own axis is not exposed the same way)."""
    J = pin.getJointJacobian(pm, data, i, pin.ReferenceFrame.WORLD)
    return np.asarray(J[3:, pm.joints[i].idx_v], float)


def test_signs_are_the_arms_geometry(fanuc, geometry):
    q = fanuc.sample_joints(300, 4)
    signs, margin = geometry.flags(q)
    ref = _reference_signs(fanuc, q)
    clear = np.all(margin > 1e-6, axis=1)
    assert clear.mean() > 0.99 and np.array_equal(signs[clear], ref[clear])
    home = geometry.flags(np.radians([[0, 0, 0, 0, -90, 0]]))[0][0]
    assert home.tolist() == [1, 1, -1]      # front, elbow in front of the lower arm, joint 5 negative
    back = geometry.flags(np.radians([[0, -60, 60, 0, -90, 0]]))[0][0]
    assert back[0] == -1                    # the wrist centre behind joint 1's axis


def test_every_solution_is_found_in_its_own_configuration(fanuc, geometry):
    """Poses of random joints solved back in the signs and turns of those joints: the same joints, away from the
    singularities (within a centimetre of one the solution is ill-conditioned: 1e-9 m of residual is up to 1e-6 rad)."""
    q = fanuc.sample_joints(3000, 5)
    q[:, 1:3] *= 0.6
    signs, margin = geometry.flags(q)
    windows = np.full((len(q), 6, 2), np.nan)
    for j in (3, 4, 5):
        turn = np.floor((q[:, j] + np.pi) / (2 * np.pi))
        windows[:, j] = np.stack([np.pi * (2 * turn - 1), np.pi * (2 * turn + 1)], axis=1)
    found, ok, why = geometry.solve(fanuc.fk(q), signs, windows)
    clear = np.all(margin > [1e-2, 1e-2, 1e-2], axis=1) & (np.abs(np.abs(q[:, 4]) - np.pi) > 1e-2)
    assert ok[clear].all()
    assert np.abs(found[clear] - q[clear]).max() < 1e-7
    # and each of the other configurations of a pose reaches the same pose
    pose = fanuc.fk(q[:1])
    for s in ([1, 1, 1], [1, 1, -1], [1, -1, 1], [-1, 1, -1], [-1, -1, 1]):
        sol, ok, why = geometry.solve(pose, np.array([s]))
        if ok[0]:
            assert geometry.flags(sol)[0][0].tolist() == s
            np.testing.assert_allclose(fanuc.fk(sol), pose, atol=1e-9)


def test_the_solution_is_the_least_squares_one(fanuc, geometry):
    q = fanuc.sample_joints(20, 6)
    q[:, 1:3] *= 0.5
    signs, _ = geometry.flags(q)
    T = fanuc.fk(q)
    found, ok, _ = geometry.solve(T, signs)
    for k in np.flatnonzero(ok):
        def residual(x):
            F = fanuc.fk(x[None])[0]
            return np.r_[F[:3, 3] - T[k, :3, 3], rotation_error(F[None, :3, :3], T[k, None, :3, :3])[0]]
        ref = least_squares(residual, found[k] + 1e-3, xtol=1e-15, ftol=1e-15, gtol=1e-15)
        assert np.abs(ref.x - found[k]).max() < 1e-8


def test_unreachable_and_impossible_configurations_say_why(fanuc, geometry):
    T = fanuc.fk(np.radians([[0, 20, -10, 0, -60, 0]]))
    far = T.copy()
    far[0, :3, 3] *= 5
    _, ok, why = geometry.solve(far)
    assert not ok[0] and "reach" in why[0]
    _, ok, why = geometry.solve(T, windows=np.array([[[np.nan] * 2] * 5 + [[10.0, 11.0]]]))
    assert not ok[0] and "turns" in why[0]


def test_a_seven_joint_arm_has_no_configuration(gao):
    with pytest.raises(ModelError, match="6-joint"):
        ArmGeometry(gao)


def test_the_ur5_signs_and_solutions():
    ur5 = robot("ur5")
    g = ArmGeometry(ur5)
    assert not g.spherical
    q = ur5.sample_joints(200, 2)
    signs, margin = g.flags(q)
    found, ok, _ = g.solve(ur5.fk(q), signs, near=q + 0.05)
    clear = np.all(margin > [1e-2, 1e-2, 5e-2], axis=1)
    assert ok[clear].mean() > 0.95
    np.testing.assert_allclose(ur5.fk(found[ok]), ur5.fk(q[ok]), atol=1e-8)
