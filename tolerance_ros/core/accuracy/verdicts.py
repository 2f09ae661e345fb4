"""Measured against nominal and against the budget: pose errors, predicted bounds, and the verdict of
every measurement (this module is the one place verdicts are decided). SI; errors in the base frame."""
from __future__ import annotations

import numpy as np

from ..errors import criterion_bound
from ..geometry import rotation_error

VERDICTS = ("within", "over bound", "over limit", "no budget")


def pose_errors(T_nominal, T_actual):
    """(dp (n, 3) m, dphi (n, 3) rad): position and small-rotation errors of actual vs nominal poses."""
    Tn, Ta = np.asarray(T_nominal, float), np.asarray(T_actual, float)
    dp = Ta[:, :3, 3] - Tn[:, :3, 3]
    dphi = rotation_error(Ta[:, :3, :3], Tn[:, :3, :3])
    return dp, dphi


def predicted_bounds(model, q, delta, criterion="paper", k_sigma=3.0, EJ=None):
    """(position (n,) m, orientation (n,) rad) bounds of the budget at configurations q."""
    EJ = EJ if EJ is not None else model.error_jacobian(q)
    return (criterion_bound(EJ.position, delta, criterion, k_sigma),
            criterion_bound(EJ.orientation, delta, criterion, k_sigma))


def budget_check(err_pos, bound_pos=None, limit=None, err_ori=None, bound_ori=None, limit_ori=None) -> dict:
    """Per-measurement verdicts and margins (bound - error, negative when over; NaN without a bound).

    'within': within every predicted bound given; 'over bound': above one but within the design limits;
    'over limit': above a design limit (position ``limit`` m, ``limit_ori`` rad); 'no budget': no
    predicted bound to check against (``bound_pos`` None) and within the limits.
    """
    e = np.asarray(err_pos, float)
    b = np.full(e.shape, np.nan) if bound_pos is None else np.asarray(bound_pos, float)
    if bound_pos is None:
        verdict = np.full(e.shape, "no budget", dtype=object)
    else:
        verdict = np.where(e <= b, "within", "over bound").astype(object)
    out = {"error": e, "bound": b, "margin": b - e, "verdict": verdict}
    if err_ori is not None and bound_ori is not None:
        eo, bo = np.asarray(err_ori, float), np.asarray(bound_ori, float)
        out.update(orientation_error=eo, orientation_bound=bo, orientation_margin=bo - eo)
        verdict[(eo > bo) & (verdict == "within")] = "over bound"
    if limit is not None:
        verdict[e > limit] = "over limit"
    if err_ori is not None and limit_ori is not None:
        verdict[np.asarray(err_ori, float) > limit_ori] = "over limit"
    return out
