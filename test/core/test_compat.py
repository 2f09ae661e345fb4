"""The compatibility calls: the same results on the oldest declared versions as on the latest."""
from types import SimpleNamespace

import numpy as np

from tolerance_ros.core import compat


def test_vecdot_fallback_is_numpys_vecdot():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(4, 3, 5)) + 1j * rng.normal(size=(4, 3, 5))
    b = rng.normal(size=(4, 3, 5))
    expected = np.einsum("nip,nip->np", a.conj(), b)
    np.testing.assert_allclose(compat._vecdot(a, b, axis=1), expected, rtol=1e-14)
    np.testing.assert_allclose(compat.vecdot(a, b, axis=1), expected, rtol=1e-14)
    assert compat.vecdot is getattr(np, "vecdot", compat._vecdot)


def test_frame_joint_reads_either_pinocchio_name():
    assert compat.frame_joint(SimpleNamespace(parent=3, previousFrame=1)) == 3
    assert compat.frame_joint(SimpleNamespace(parentJoint=0, parent=7)) == 0
