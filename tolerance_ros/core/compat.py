"""The few calls whose name differs between the oldest declared versions and the latest ones.

numpy: ``np.vecdot`` exists from numpy 2.0; on 1.26 ``vecdot`` is the same sum of products (chosen once,
at import). pinocchio: a frame's joint is ``Frame.parentJoint`` from pinocchio 3 (where ``Frame.parent`` is
deprecated) and ``Frame.parent`` in 2.7.
"""
from __future__ import annotations

import numpy as np


def _vecdot(a, b, axis=-1):
    """``np.vecdot`` of numpy 2: the sum over ``axis`` of ``conj(a) * b``."""
    return np.sum(np.conjugate(a) * b, axis=axis)


vecdot = getattr(np, "vecdot", _vecdot)


def frame_joint(frame) -> int:
    """Id of the joint that moves a pinocchio ``Frame`` (0 for the universe)."""
    joint = getattr(frame, "parentJoint", None)
    return frame.parent if joint is None else joint
