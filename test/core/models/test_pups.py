"""The 3-PUPS model: kinematics, the completed error transfer G, variants, sampling, file validation."""
import copy
import re

import numpy as np
import pytest
import yaml
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from helpers import fd_jacobian, pose_difference
from tolerance_ros.core import analysis
from tolerance_ros.core.campaign import load_campaign
from tolerance_ros.core.models import ModelError, load_robot
from tolerance_ros.core.geometry import exp_so3, transform
from tolerance_ros.core.geometry import axis_rotations as axis_rotation
from tolerance_ros.core.models.pups import PUPS3, pups_from_dict
from tolerance_ros.core.resources import config_dir

DEG = np.pi / 180


@pytest.fixture(scope="module")
def model():
    return load_robot("rong2018_3pups")


@pytest.fixture(scope="module")
def raw():
    return yaml.safe_load((config_dir() / "robots" / "rong2018_3pups.yaml").read_text())


@pytest.fixture(scope="module")
def pe(model):
    camp = load_campaign("rong2018_pe", model)
    return np.array([tp.pose for tp in camp.poses]), camp.joints_for(model)


@pytest.fixture(scope="module")
def ws(model):
    return model.sample_poses(150, seed=11)


def test_loaded_model(model):
    assert isinstance(model, PUPS3) and model.variant == "3-PUPS"
    assert model.joint_names == ("a1", "a2", "a3", "psi1", "psi2", "psi3", "l1", "l2", "l3")
    assert model.param_names[:9] == ("a1.x", "a1.y", "a1.z", "b1.x", "b1.y", "b1.z", "l1.x", "l1.y", "l1.z")
    assert model.n_params == 27 and not model.nominal.any()
    # Units converted from the file's mm and deg.
    assert model.c == pytest.approx(0.09)
    np.testing.assert_allclose(model.joint_limits[0], [0.2, 0.3])
    np.testing.assert_allclose(model.joint_limits[3], [-np.pi / 4, np.pi / 4])


def test_ik_then_fk_round_trip(model, pe, ws):
    T = np.concatenate([pe[0], ws[1]])
    q, theta = model.inverse_kinematics(T, passive=True)
    np.testing.assert_allclose(model.fk(q), T, atol=1e-12)
    np.testing.assert_allclose(model.passive_angles(q), theta, atol=1e-10)
    np.testing.assert_allclose(q[:, :3], 0.25)  # the redundancy rule: free sliders at mid-travel
    # The test poses can be reached with the sliders anywhere in their travel.
    a = np.random.default_rng(1).uniform(0.2, 0.3, (len(pe[0]), 3))
    q2 = model.inverse_kinematics(pe[0], a=a)
    np.testing.assert_allclose(q2[:, :3], a)
    np.testing.assert_allclose(model.fk(q2), pe[0], atol=1e-12)


def test_pe_joints_by_hand(model, pe):
    """PE1 is symmetric: every leg reaches from A_i (250 mm from O) to C_i (90 mm from the axis)."""
    q = pe[1][0]
    np.testing.assert_allclose(q[6:], np.hypot(1.3, 0.25 - 0.09))
    np.testing.assert_allclose(q[3:6], 0.0, atol=1e-15)


def _random_dx(rng, n, scale=1e-6):
    return rng.uniform(-scale, scale, (n, 27))


def test_G_against_the_nonlinear_loops(model, pe, ws):
    q = np.concatenate([pe[1], ws[0]])
    G = model.error_jacobian(q).J
    rng = np.random.default_rng(7)
    dx = _random_dx(rng, len(q))
    T0 = model.fk(q)
    d1 = pose_difference(model.fk(q, dx), T0)
    lin = np.einsum("nrp,np->nr", G, dx)
    scale = np.abs(lin).max(axis=1, keepdims=True)
    assert np.max(np.abs(d1 - lin) / scale) < 1e-4
    # The remainder is of second order: halving the errors quarters it.
    d2 = pose_difference(model.fk(q, dx / 2), T0)
    r1, r2 = np.abs(d1 - lin).max(), np.abs(d2 - lin / 2).max()
    assert r2 < 0.3 * r1


def test_G_against_central_differences(model, pe, ws):
    q = np.concatenate([pe[1], ws[0][:10]])
    G = model.error_jacobian(q).J
    fd = fd_jacobian(lambda p: model.fk(q, p), np.zeros(27), h=1e-6)
    assert np.abs(G - fd).max() < 1e-6 * np.abs(G).max()


def test_G_contains_the_papers_projected_equations(model, pe):
    """Rows of eq. 8: w_i dp - (w_i x R c_i) dphi = w_i (da_i + R_Ai db_i + R_Ai R_Bi dl_i)."""
    T, q = pe
    G = model.error_jacobian(q).J
    theta = model.passive_angles(q)
    for n in range(len(q)):
        R, p = T[n, :3, :3], T[n, :3, 3]
        for i in range(3):
            RA = axis_rotation(2, model.slider_angles[i])
            A = -q[n, i] * RA[:, 0]
            Rc = R @ model.c_local[i]
            w = (p + Rc - A) / q[n, 6 + i]
            RB = axis_rotation(0, q[n, 3 + i]) @ axis_rotation(1, theta[n, i])
            lhs = w @ G[n, :3] - np.cross(w, Rc) @ G[n, 3:]
            rhs = np.zeros(27)
            rhs[9 * i:9 * i + 3], rhs[9 * i + 3:9 * i + 6], rhs[9 * i + 6:9 * i + 9] = w, w @ RA, w @ RA @ RB
            np.testing.assert_allclose(lhs, rhs, atol=1e-12)


def test_passive_joint_absorbs_the_lateral_leg_error(model, ws):
    """li.x moves C_i along the passive joint's tangent: no first-order effect."""
    G = model.error_jacobian(ws[0]).J
    idx = model.param_index(["l1.x", "l2.x", "l3.x"])
    assert np.abs(G[:, :, idx]).max() < 1e-12 * np.abs(G).max()


@settings(deadline=None, max_examples=20)
@given(x=st.floats(-0.5, 0.5), y=st.floats(-0.5, 0.5), z=st.floats(1.2, 1.5), roll=st.floats(-15, 15),
       pitch=st.floats(-15, 15), yaw=st.floats(-35, 35))
def test_limb_symmetry(model, x, y, z, roll, pitch, yaw):
    """Turning the whole configuration by 120 deg about z moves limb i's role to limb i + 1."""
    T = transform([x, y, z], np.array([roll, pitch, yaw]) * DEG)
    try:
        q = model.inverse_kinematics(T)
    except ModelError:
        assume(False)
    Rz = axis_rotation(2, 2 * np.pi / 3)
    S = np.eye(4)
    S[:3, :3] = Rz
    T2 = S @ T @ S.T
    perm = np.array([2, 0, 1])
    q2 = model.inverse_kinematics(T2)
    np.testing.assert_allclose(q2, q[:, np.concatenate([perm, perm + 3, perm + 6])], atol=1e-12)
    G, G2 = model.error_jacobian(q).J[0], model.error_jacobian(q2).J[0]
    Q = np.kron(np.eye(2), Rz)
    for j in range(3):
        old, new = 9 * perm[j], 9 * j
        np.testing.assert_allclose(G2[:, new:new + 3], Q @ G[:, old:old + 3] @ Rz.T, atol=1e-10)
        np.testing.assert_allclose(G2[:, new + 3:new + 9], Q @ G[:, old + 3:old + 9], atol=1e-10)


@pytest.mark.parametrize("xyz, rpy, reason", [
    ([0, 0, 2000], [0, 0, 0], "leg l1 = "),
    ([0, 0, 1000], [0, 0, 0], "leg l1 = "),
    # Limb 1 (A_1 at x = -250 mm, C_1 at x + 90 mm): theta1 = asin(1160 / hypot(1160, 1000)) = 49.24 deg.
    ([1000, 0, 1000], [0, 0, 0], "passive U-joint angle theta1 = 49.236"),
    # Sideways for limb 1: psi1 = -atan(1100 / 1000) = -47.73 deg.
    ([0, 1100, 1000], [0, 0, 0], "U-joint angle psi1 = -47.726"),
])
def test_unreachable_poses_name_the_pose_and_the_reason(model, xyz, rpy, reason):
    T = transform(np.array(xyz) * 1e-3, np.array(rpy) * DEG)
    with pytest.raises(ModelError) as exc:
        model.inverse_kinematics(T)
    msg = str(exc.value)
    assert reason in msg and "outside" in msg
    assert f"xyz = {[float(v) for v in xyz]} mm" in msg


def test_literal_eq2_axes_make_pe1_singular(raw, pe):
    """With eq. 2's axes taken literally (psi about y, theta about x) the symmetric pose PE1 is a
    forward-kinematic singularity: the passive joints let the platform turn about z."""
    data = dict(raw, u_joint_axes=["y", "x"])
    lit = pups_from_dict(data)
    with pytest.raises(ModelError, match="J1 is singular"):
        lit.inverse_kinematics(pe[0][0])
    # Its forward kinematics has other assemblies close by (at PE4 and PE5 the start leads to one with
    # the same joints and another orientation), so G is checked where the assembly is the commanded one.
    T = pe[0][1:3]
    q = lit.inverse_kinematics(T)
    np.testing.assert_allclose(lit.fk(q), T, atol=1e-12)
    G = lit.error_jacobian(q).J
    fd = fd_jacobian(lambda p: lit.fk(q, p), np.zeros(27), h=1e-6)
    assert np.abs(G - fd).max() < 1e-6 * np.abs(G).max()


def test_joints_that_cannot_close_the_loop(model, ws):
    bad = np.array([0.3, 0.2, 0.3, 0.26, np.pi / 4, -np.pi / 4, 1.1, 1.6, 1.6])
    with pytest.raises(ModelError, match="cannot close the platform triangle"):
        model.fk(bad)
    q = np.vstack([ws[0][:2], bad])
    T, J = model.tolerant().fk_and_jacobian(q)
    assert np.isnan(T[2]).all() and np.isnan(J.J[2]).all()
    np.testing.assert_allclose(T[:2], ws[1][:2], atol=1e-12)


@pytest.mark.parametrize("joint", [0, 7])
def test_joints_far_outside_their_range_fail_alone_with_the_reason(model, ws, joint):
    """A slider or leg at 1e10 m made the start's normal equations singular: LinAlgError for the whole batch."""
    far = ws[0][0].copy()
    far[joint] = 1e10
    with pytest.raises(ModelError, match=r"joints\[0\] = .*: the legs cannot close the platform triangle"):
        model.fk(far)
    T, _ = model.tolerant().fk_and_jacobian(np.vstack([ws[0][:2], far]))
    assert np.isnan(T[2]).all()
    np.testing.assert_allclose(T[:2], ws[1][:2], atol=1e-12)


def test_sample_joints_deterministic_and_reachable(model):
    q = model.sample_joints(300, seed=5)
    np.testing.assert_array_equal(q, model.sample_joints(300, seed=5))
    assert not np.array_equal(q, model.sample_joints(300, seed=6))
    assert not model.out_of_limits(q).any()
    T = model.fk(q)
    x = np.concatenate([T[:, :3, 3], np.array([[0, 0, 0]] * len(T))], axis=1)
    lo, hi = model.workspace[:, 0], model.workspace[:, 1]
    assert np.all((x[:, :3] >= lo[:3]) & (x[:, :3] <= hi[:3]))
    np.testing.assert_allclose(model.inverse_kinematics(T), q, atol=1e-10)
    th = model.passive_angles(q)
    assert np.all(np.abs(th) <= model.theta_range[1])


def test_analysis_runs_unchanged(model):
    sens = analysis.sensitivity(model, 300, seed=1)
    assert sens.salience.sum() == pytest.approx(1.0)
    delta = np.full(27, 5e-6)
    lin = analysis.monte_carlo(model, delta, n=300, distribution="uniform", seed=2, method="linear")
    non = analysis.monte_carlo(model, delta, n=300, distribution="uniform", seed=2, method="nonlinear")
    np.testing.assert_allclose(non.position, lin.position, rtol=3e-4, atol=1e-12)   # second order of 5 um errors
    np.testing.assert_allclose(non.orientation, lin.orientation, rtol=1e-4, atol=1e-12)


# ------------------------------------------------------------------ metamorphic variants


def test_3ups_sliders_locked(model, ws):
    ups = model.with_locked(a=[0.22, 0.25, 0.28])
    assert ups.variant == "3-UPS"
    np.testing.assert_allclose(ups.joint_limits[:3], [[0.22, 0.22], [0.25, 0.25], [0.28, 0.28]])
    q = ups.inverse_kinematics(ws[1])
    np.testing.assert_allclose(q[:, :3], np.broadcast_to([0.22, 0.25, 0.28], (len(q), 3)))
    np.testing.assert_allclose(ups.fk(q), ws[1], atol=1e-12)
    with pytest.raises(ModelError, match="a1 is locked at 0.22"):
        ups.fk(model.inverse_kinematics(ws[1][:1]))
    qs = ups.sample_joints(50, seed=3)
    np.testing.assert_allclose(qs[:, :3], np.broadcast_to([0.22, 0.25, 0.28], (50, 3)))


@pytest.mark.parametrize("locked, variant", [({"psi": [0.0] * 3}, "3-PRPS"),
                                             ({"a": [0.25] * 3, "psi": [0.0] * 3}, "3-RPS"),
                                             ({"psi": [0.05, None, None]}, "asymmetric")])
def test_locked_u_joints_confine_the_platform(model, locked, variant):
    v = model.with_locked(**locked)
    assert v.variant == variant
    q, T = v.sample_poses(40, seed=4)
    np.testing.assert_allclose(v.fk(q), T, atol=1e-12)
    for i, psi in enumerate(locked["psi"]):
        if psi is None:
            continue
        np.testing.assert_allclose(q[:, 3 + i], psi)
        # C_i stays in the plane through the slider axis turned by psi_i about it.
        RA = axis_rotation(2, v.slider_angles[i])
        n = RA @ axis_rotation(0, psi)[:, 1]
        C = T[:, :3, 3] + np.einsum("nij,j->ni", T[:, :3, :3], v.c_local[i])
        np.testing.assert_allclose(C @ n, 0.0, atol=1e-12)
    # Moving only the free actuators keeps the mobility: 6 for free sliders alone would be too many.
    free = [j for j in range(9) if v.joint_limits[j, 0] < v.joint_limits[j, 1]]
    J = np.stack([pose_difference(v.fk(q[:1] + e), v.fk(q[:1] - e))[0] / 2e-7
                  for e in np.eye(9)[free] * 1e-7], axis=1)
    assert np.linalg.matrix_rank(J, tol=1e-6) == 6 - len([p for p in locked["psi"] if p is not None])
    with pytest.raises(ModelError, match="off the plane of limb 1"):
        v.inverse_kinematics(transform([0.1, 0.05, 1.3], [0.1, 0.05, 0.2]))


def test_locked_variant_from_the_file(raw, tmp_path):
    path = tmp_path / "ups.yaml"
    path.write_text(yaml.safe_dump(dict(raw, name="rong_3ups", locked={"a": [250, 250, 250]})))
    ups = load_robot(path)
    assert ups.variant == "3-UPS" and ups.name == "rong_3ups"
    np.testing.assert_allclose(ups.joint_limits[:3], 0.25)


# ------------------------------------------------------------------ invalid files


@pytest.mark.parametrize("change, field", [
    ({"platform_radius": None}, "platform_radius"),
    ({"platform_radius": -90}, "platform_radius"),
    ({"leg_length": [1600, 1100]}, "leg_length"),
    ({"leg_length": [1100]}, "leg_length"),
    ({"slider_travel": [200, "wide"]}, "slider_travel[1]"),
    ({"u_joint_axes": ["x", "z"]}, "u_joint_axes"),
    ({"units": {"length": "furlong"}}, "units.length"),
    ({"workspace": {"x": [-1, 1]}}, "workspace"),
    ({"workspace_box": {}}, "unknown key"),
    ({"locked": {"l": [1300, 1300, 1300]}}, "locked.l"),
    ({"locked": {"a": [250, 350, 250]}}, "locked.a[1]"),
    ({"locked": {"a": [250, 250]}}, "locked.a"),
    ({"redundancy": {"a": [250, 250, 100]}}, "redundancy.a"),
    ({"slider_angles": [0, 120]}, "slider_angles"),
])
def test_invalid_fields_are_named(raw, tmp_path, change, field):
    data = copy.deepcopy(raw)
    for k, v in change.items():
        if v is None:
            data.pop(k)
        else:
            data[k] = v
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ModelError) as exc:
        load_robot(path)
    assert field in str(exc.value) and str(path) in str(exc.value)


def test_sampled_poses_lie_in_the_workspace_box_read_with_rep103_angles(model):
    """The workspace box is in R = Rz(yaw) Ry(pitch) Rx(roll) angles: scipy's extrinsic 'xyz' Euler
    angles of the sampled platform rotations fall inside it."""
    from scipy.spatial.transform import Rotation
    _, T = model.sample_poses(200, seed=3)
    rpy = Rotation.from_matrix(T[:, :3, :3]).as_euler("xyz")
    box = model.workspace
    assert np.all(T[:, :3, 3] >= box[:3, 0] - 1e-12) and np.all(T[:, :3, 3] <= box[:3, 1] + 1e-12)
    assert np.all(rpy >= box[3:, 0] - 1e-9) and np.all(rpy <= box[3:, 1] + 1e-9)


# ------------------------------------------------------------------ the compiled kernel against the numpy reference
# The compiled path (pups_kernels) and the numpy reference run the same algorithm; they differ by rounding, and by
# where the start's Gauss-Newton stops (pose by pose, against batch-wide in the numpy code). In the workspace J1 is
# well conditioned (cond <= 3) and T and G agree to 1e-12 absolute. Elsewhere G's sensitivity to rounding grows
# like cond(J1)^2 |G|, T's and theta's like cond(J1): there the numpy reference does not reproduce itself better
# (one pose alone and in a batch differ as much), and the checks are |dT|, |dtheta| <= 1e-12 cond and
# |dG| <= 1e-12 cond^2 max(1, |G|) per pose.

ATOL = 1e-12


def _backend(model, name):
    out = copy.copy(model)
    out.backend = name
    return out


def _pair(model):
    return _backend(model, "numba"), _backend(model, "numpy")


def _assert_agree(model, q, dx=None):
    """The compiled and the numpy path agree on the failing rows (NaN in both, tolerant), T, G and theta."""
    fast, ref = (m.tolerant() for m in _pair(model))
    (T1, G1), (T2, G2) = fast.fk_and_jacobian(q, dx), ref.fk_and_jacobian(q, dx)
    bad = np.isnan(T2[:, 0, 0])
    np.testing.assert_array_equal(np.isnan(T1), np.broadcast_to(bad[:, None, None], T1.shape))
    np.testing.assert_array_equal(np.isnan(G1.J), np.broadcast_to(bad[:, None, None], G1.J.shape))
    ok = ~bad
    s = ref._solve(q, dx)
    cond = s["cond"][ok]
    assert np.all(np.abs(T1[ok] - T2[ok]).max(axis=(1, 2), initial=0.0) <= ATOL * cond)
    dG = np.abs(G1.J[ok] - G2.J[ok]).max(axis=(1, 2), initial=0.0)
    assert np.all(dG <= ATOL * cond ** 2 * np.maximum(1.0, np.abs(G2.J[ok]).max(axis=(1, 2), initial=0.0)))
    th1, th2 = fast.passive_angles(q, dx), np.where(s["ok"][:, None], s["theta"], np.nan)  # ref.passive_angles
    np.testing.assert_array_equal(np.isnan(th1), np.isnan(th2))
    assert np.all(np.abs(th1[ok] - th2[ok]).max(axis=1, initial=0.0) <= ATOL * cond)
    return ok, cond, dG


def test_the_compiled_path_is_the_default_and_the_numpy_one_the_reference(model):
    assert model.compiled and model.backend == "numba"
    assert _backend(model, "numpy")._kernels() is None
    assert model.warm_up() >= 0.0 and _backend(model, "numpy").warm_up() < 0.1


@pytest.mark.parametrize("dx", ["none", "shared", "per pose"])
def test_compiled_equals_the_numpy_reference_to_1e12_in_the_workspace(model, pe, ws, dx):
    q = np.concatenate([pe[1], ws[0]])
    rng = np.random.default_rng(21)
    d = {"none": None, "shared": rng.uniform(-1e-4, 1e-4, 27), "per pose": rng.uniform(-1e-4, 1e-4, (len(q), 27))}[dx]
    fast, ref = _pair(model)
    (T1, G1), (T2, G2) = fast.fk_and_jacobian(q, d), ref.fk_and_jacobian(q, d)
    assert np.abs(T1 - T2).max() <= ATOL and np.abs(G1.J - G2.J).max() <= ATOL
    assert G1.names == G2.names and G1.units == G2.units
    np.testing.assert_array_equal(fast.fk(q, d), T1)
    assert np.abs(fast.passive_angles(q, d) - ref.passive_angles(q, d)).max() <= ATOL
    # One pose at a time: the same numbers, bit for bit (each pose is computed on its own), and the reference's.
    for i in (0, 7, len(q) - 1):
        one = None if d is None or d.ndim == 1 else d[i]
        T, G = fast.fk_and_jacobian(q[i], d if one is None else one)
        np.testing.assert_array_equal(T[0], T1[i])
        np.testing.assert_array_equal(G.J[0], G1.J[i])
        Tr, Gr = ref.fk_and_jacobian(q[i], d if one is None else one)
        assert np.abs(T[0] - Tr[0]).max() <= ATOL and np.abs(G.J[0] - Gr.J[0]).max() <= ATOL
    assert fast.fk_and_jacobian(q, d, jacobian=False)[1] is None


@pytest.mark.parametrize("axes", [("x", "y"), ("y", "x")])
def test_compiled_equals_the_numpy_reference_on_random_joints_in_and_out_of_limits(raw, axes):
    """Uniform joints within the limits and within the limits widened by 30 %: most cannot close the loop; the
    ones that do are mostly outside the workspace, some with cond(J1) above 5."""
    model = pups_from_dict(dict(raw, u_joint_axes=list(axes)))
    rng = np.random.default_rng(5)
    lo, hi = model.joint_limits.T
    q = np.concatenate([lo + (hi - lo) * rng.random((600, 9)),
                        lo - 0.3 * (hi - lo) + 1.6 * (hi - lo) * rng.random((600, 9))])
    ok, cond, _ = _assert_agree(model, q)
    assert 8 < ok.sum() < 300 and cond.max() > 5 and model.out_of_limits(q[ok]).any()
    some = np.concatenate([q[ok], q[~ok][:30]])
    _assert_agree(model, some, rng.uniform(-1e-3, 1e-3, 27))
    _assert_agree(model, some, rng.uniform(-1e-3, 1e-3, (len(some), 27)))


def test_compiled_equals_the_numpy_reference_near_a_singularity(raw, pe):
    """With eq. 2's literal axes PE1 is singular: poses 1e-1 ... 1e-8 from it (cond 10 ... 1e10) are assembled
    alike, and singular alike beyond the condition-number limit, with the same message."""
    lit = pups_from_dict(dict(raw, u_joint_axes=["y", "x"]))
    rng = np.random.default_rng(0)
    u = rng.normal(size=(32, 6))
    u *= np.repeat(10.0 ** -np.arange(1, 9), 4)[:, None] / np.linalg.norm(u, axis=1, keepdims=True)
    T = np.repeat(pe[0][:1], len(u), axis=0)
    T[:, :3, 3] += u[:, :3]
    T[:, :3, :3] = exp_so3(u[:, 3:]) @ T[:, :3, :3]
    q, _, _ = lit._ik(T)
    q = np.asarray(q, dtype=float)
    ok, cond, _ = _assert_agree(lit, q)
    assert cond.max() > 1e5 and 0 < ok.sum() < len(q)
    fast, ref = _pair(lit)
    for i in np.flatnonzero(~ok)[:3]:
        msgs = []
        for m in (fast, ref):
            with pytest.raises(ModelError, match="J1 is singular") as exc:
                m.fk_and_jacobian(np.vstack([q[ok][:2], q[i]]))
            msgs.append(str(exc.value))
        # The same text; the condition number (beyond 1e6, computed at poses that differ by cond x 1e-14) to 1 %.
        number = r"condition number ([0-9.e+]+) >"
        conds = [float(re.search(number, m).group(1)) for m in msgs]
        assert re.sub(number, "", msgs[0]) == re.sub(number, "", msgs[1]) and msgs[0].startswith("joints[2] = ")
        assert conds[1] == pytest.approx(conds[0], rel=1e-2)


@pytest.mark.parametrize("q, dx, match", [
    (lambda q: np.where(np.arange(9) == 4, np.nan, q), None, r"joints\[0\]\[4\] \(psi2\): not a finite number"),
    (lambda q: np.where(np.arange(9) == 0, np.inf, q), None, r"joints\[0\]\[0\] \(a1\): not a finite number"),
    (lambda q: q[:8], None, r"expected shape \(n, 9\)"),
    (lambda q: [["a"] * 9], None, "expected numbers"),
    (lambda q: q, np.full(27, np.nan), "dx: parameter errors must be finite"),
    (lambda q: q, np.zeros(26), r"dx: expected shape \(27,\) or \(1, 27\)"),
    (lambda q: np.where(np.arange(9) == 7, 1e10, q), None, r"joints\[0\] = .*: the legs cannot close"),
    (lambda q: np.array([0.3, 0.2, 0.3, 0.26, np.pi / 4, -np.pi / 4, 1.1, 1.6, 1.6]), None, "cannot close the"),
])
def test_bad_input_gives_the_same_clean_error_on_both_paths(model, ws, q, dx, match):
    msgs = []
    for m in _pair(model):
        with pytest.raises(ModelError, match=match) as exc:
            m.fk_and_jacobian(q(ws[0][0].copy()), dx)
        msgs.append(str(exc.value))
    assert msgs[0] == msgs[1]


def test_compiled_locked_variant_and_turned_over_platforms(model, ws):
    ups = model.with_locked(a=[0.22, 0.25, 0.28])
    q = ups.inverse_kinematics(ws[1][:20])
    _assert_agree(ups, q)
    for m in _pair(ups):
        with pytest.raises(ModelError, match="a1 is locked at 0.22"):
            m.fk(model.inverse_kinematics(ws[1][:1]))
    # Joints far outside the ranges whose only assembly found has the platform turned over (R_zz <= 0).
    over = np.array([[0.2958, 0.1822, 0.3108, 2.0914, -1.7586, 1.719, 0.6892, 1.1712, 1.2447],
                     [0.1189, 0.337, 0.1087, 1.9712, -1.7084, -1.2616, 0.9739, 1.0897, 0.7888],
                     [0.1514, 0.2418, 0.2776, -0.508, -1.0588, -2.0682, 1.247, 1.4951, 1.56]])
    ok, _, _ = _assert_agree(model, np.concatenate([ws[0][:3], over]))
    np.testing.assert_array_equal(ok, [True] * 3 + [False] * 3)
    for i in range(3):
        msgs = []
        for m in _pair(model):
            with pytest.raises(ModelError, match="the only assembly found has the platform turned over") as exc:
                m.fk(over[i])
            msgs.append(str(exc.value))
        assert msgs[0] == msgs[1]


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_G_against_central_differences_on_both_paths(model, pe, ws, backend):
    m = _backend(model, backend)
    q = np.concatenate([pe[1], ws[0][10:20]])
    G = m.error_jacobian(q).J
    fd = fd_jacobian(lambda p: m.fk(q, p), np.zeros(27), h=1e-6)
    assert np.abs(G - fd).max() < 1e-6 * np.abs(G).max()
    # And with parameter errors: G at dx is the derivative there.
    dx0 = np.random.default_rng(2).uniform(-1e-3, 1e-3, 27)
    G = m.error_jacobian(q, dx0).J
    fd = fd_jacobian(lambda p: m.fk(q, p), dx0, h=1e-6)
    assert np.abs(G - fd).max() < 1e-6 * np.abs(G).max()


def test_without_numba_the_numpy_path_runs(model, ws, monkeypatch):
    from tolerance_ros.core.models import kernels
    monkeypatch.setattr(kernels, "_unavailable", True)  # as when numba cannot be imported
    fresh = load_robot("rong2018_3pups")
    assert fresh.backend == "numpy" and fresh._kernels() is None
    with pytest.raises(ModelError, match="numba cannot be imported"):
        fresh.backend = "numba"
    T, G = fresh.fk_and_jacobian(ws[0][:5])
    np.testing.assert_array_equal(G.J, _backend(model, "numpy").fk_and_jacobian(ws[0][:5])[1].J)


def test_no_poses_give_empty_answers_on_both_paths(model):
    """(0, 9) joints: empty T, G and theta (the numpy start's max over no poses raised a bare ValueError)."""
    for m in _pair(model):
        T, G = m.fk_and_jacobian(np.zeros((0, 9)), np.zeros(27))
        assert T.shape == (0, 4, 4) and G.J.shape == (0, 6, 27) and m.passive_angles(np.zeros((0, 9))).shape == (0, 3)
