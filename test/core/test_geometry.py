"""Rotations and transforms against scipy's independent implementation (scipy.spatial.transform)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tolerance_ros.core import geometry as G

RNG = np.random.default_rng(7)
ROT = Rotation.random(200, random_state=11)


def test_rpy_is_extrinsic_xyz():
    rpy = RNG.uniform(-np.pi, np.pi, (200, 3))
    ref = Rotation.from_euler("xyz", rpy).as_matrix()
    np.testing.assert_allclose(G.rpy_to_matrices(rpy), ref, atol=1e-14)
    np.testing.assert_allclose(G.rpy_to_matrix(rpy[0]), ref[0], atol=1e-14)
    np.testing.assert_allclose(np.moveaxis(G.rpy_matrix(*rpy.T), 2, 0), ref, atol=1e-14)


def test_rpy_from_matrix_inverts_within_the_principal_range():
    rpy = np.column_stack([RNG.uniform(-np.pi, np.pi, 200), RNG.uniform(-1.5, 1.5, 200), RNG.uniform(-np.pi, np.pi, 200)])
    R = Rotation.from_euler("xyz", rpy).as_matrix()
    np.testing.assert_allclose(G.rpy_from_matrix(R), rpy, atol=1e-12)


@pytest.mark.parametrize("pitch", [np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-7, 1.57079632679, -np.pi / 2 + 3e-4])
def test_rpy_from_matrix_rebuilds_the_rotation_at_and_near_gimbal_lock(pitch):
    """Near pitch = +-pi/2 roll and yaw are ill-defined one by one, but the three angles must rebuild the
    rotation to rounding error (a calibrated URDF origin is written as such angles)."""
    rpy = np.column_stack([RNG.uniform(-np.pi, np.pi, 50), np.full(50, pitch), RNG.uniform(-np.pi, np.pi, 50)])
    R = Rotation.from_euler("xyz", rpy).as_matrix()
    back = G.rpy_from_matrix(R)
    np.testing.assert_allclose(G.rpy_to_matrices(back), R, atol=2e-15)
    np.testing.assert_allclose(back[:, 1], pitch, atol=1e-15)


def test_axis_angle_and_base_axis_rotations():
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    angles = RNG.uniform(-4, 4, 50)
    ref = Rotation.from_rotvec(angles[:, None] * axis).as_matrix()
    np.testing.assert_allclose(np.moveaxis(G.axis_angle_matrix(axis, angles), 2, 0), ref, atol=1e-14)
    for k in range(3):
        ref_k = Rotation.from_rotvec(angles[:, None] * np.eye(3)[k]).as_matrix()
        np.testing.assert_allclose(G.axis_rotations(k, angles), ref_k, atol=1e-14)
    assert G.axis_rotations(2, np.zeros((4, 3))).shape == (4, 3, 3, 3)


@pytest.mark.parametrize("scale", [1.0, 1e-5, 1e-9, 0.0])
def test_exp_and_log_against_rotation_vectors(scale):
    w = ROT.as_rotvec() * scale
    np.testing.assert_allclose(G.exp_so3(w), Rotation.from_rotvec(w).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(G.matrix_log_vec(Rotation.from_rotvec(w).as_matrix()), w, atol=1e-12)


def test_log_near_pi():
    axis = np.array([[1.0, 2.0, -2.0]]) / 3.0
    for angle in (np.pi - 1e-7, np.pi - 1e-5, np.pi):
        R = Rotation.from_rotvec(axis * angle).as_matrix()
        w = G.matrix_log_vec(R)
        np.testing.assert_allclose(Rotation.from_rotvec(w).as_matrix(), R, atol=1e-9)
        assert abs(np.linalg.norm(w) - angle) < 1e-9


def test_rotation_error_is_the_left_small_rotation():
    R0 = ROT.as_matrix()
    dphi = RNG.normal(0, 1e-3, (len(R0), 3))
    R1 = Rotation.from_rotvec(dphi).as_matrix() @ R0
    np.testing.assert_allclose(G.rotation_error(R1, R0), dphi, atol=1e-14)


def test_quaternions_both_ways():
    q = ROT.as_quat()  # scipy: (x, y, z, w)
    np.testing.assert_allclose(G.quat_to_matrices(q * 3.0), ROT.as_matrix(), atol=1e-14)
    back = G.matrices_to_quat(ROT.as_matrix())
    ref = np.where(q[:, 3:] < 0, -q, q)
    np.testing.assert_allclose(back, ref, atol=1e-14)
    assert np.all(back[:, 3] >= 0)
    # each of Shepperd's four branches: rotations by pi about x, y, z and the identity
    special = Rotation.from_rotvec(np.vstack([np.eye(3) * np.pi, np.zeros(3)]))
    np.testing.assert_allclose(np.abs(G.matrices_to_quat(special.as_matrix())), np.abs(special.as_quat()), atol=1e-14)
    with pytest.raises(ValueError, match="zero"):
        G.quat_to_matrices([0.0, 0.0, 0.0, 0.0])
    for bad in ([np.nan, 0.0, 0.0, 1.0], [0.0, 0.0, 0.5, np.nan], [np.inf, 0.0, 0.0, 1.0], [[0, 0, 1, np.nan]] * 2):
        with pytest.raises(ValueError):
            G.quat_to_matrices(bad)


def test_one_quaternion_takes_the_same_rotation_as_a_batch():
    q = ROT.as_quat()[:50] * RNG.uniform(1e-3, 1e3, (50, 1))
    batch = G.quat_to_matrices(q)
    for i in range(len(q)):
        np.testing.assert_array_equal(G.quat_to_matrices(q[i]), batch[i:i + 1])


@pytest.mark.parametrize("scale", [1e-5, 1e200, 1e307])
def test_quaternions_of_any_finite_length_give_their_direction_without_overflow(scale):
    q = ROT.as_quat()[:20]
    with np.errstate(all="raise"):
        R = G.quat_to_matrices(q * scale)
    np.testing.assert_allclose(R, ROT.as_matrix()[:20], atol=1e-14)


def test_transforms_and_cross():
    T = G.transform([1.0, 2.0, 3.0], [0.1, 0.2, 0.3])
    np.testing.assert_allclose(T[:3, :3], Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_matrix(), atol=1e-15)
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    P = G.pose_matrices(np.ones((2, 3)), ROT.as_matrix()[:2])
    np.testing.assert_array_equal(P[:, :3, 3], np.ones((2, 3)))
    np.testing.assert_array_equal(P[:, 3], [[0, 0, 0, 1]] * 2)
    a, b = RNG.normal(size=(3, 5)), RNG.normal(size=(3, 5))
    np.testing.assert_allclose(G.cross3(a, b), np.cross(a.T, b.T).T, atol=1e-15)
