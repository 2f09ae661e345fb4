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


EXCEEDED = ("position bound", "orientation bound", "position limit", "orientation limit")
_EXCEEDED_BITS = 1 << np.arange(len(EXCEEDED))
_EXCEEDED_TEXT = np.array([", ".join(w for k, w in enumerate(EXCEEDED) if code >> k & 1) for code in range(16)],
                          dtype=object)


def budget_check(err_pos, bound_pos=None, limit=None, err_ori=None, bound_ori=None, limit_ori=None) -> dict:
    """Per-measurement verdicts, what each one exceeded, and margins (bound - error, negative when over;
    NaN without a bound).

    'within': within every predicted bound given; 'over bound': above one but within the design limits;
    'over limit': above a design limit (position ``limit`` m, ``limit_ori`` rad); 'no budget': no
    predicted bound to check against (``bound_pos`` None) and within the limits. ``exceeded`` names,
    for each measurement, the bounds and limits it is above (``EXCEEDED``, joined by ', '; '' if none),
    and ``over`` the same as an (n, 4) boolean array in the order of ``EXCEEDED``.
    """
    e = np.asarray(err_pos, float)
    b = np.full(e.shape, np.nan) if bound_pos is None else np.asarray(bound_pos, float)
    eo = None if err_ori is None else np.asarray(err_ori, float)
    over = {"position bound": e > b if bound_pos is not None else np.zeros(e.shape, bool),
            "orientation bound": np.zeros(e.shape, bool),
            "position limit": e > limit if limit is not None else np.zeros(e.shape, bool),
            "orientation limit": eo > limit_ori if eo is not None and limit_ori is not None else np.zeros(e.shape, bool)}
    out = {"error": e, "bound": b, "margin": b - e}
    if eo is not None and bound_ori is not None:
        bo = np.asarray(bound_ori, float)
        out.update(orientation_error=eo, orientation_bound=bo, orientation_margin=bo - eo)
        over["orientation bound"] = eo > bo
    verdict = np.full(e.shape, "within" if bound_pos is not None else "no budget", dtype=object)
    verdict[over["position bound"] | over["orientation bound"]] = "over bound"
    verdict[over["position limit"] | over["orientation limit"]] = "over limit"
    flags = np.empty(e.shape + (len(EXCEEDED),), bool)
    for k, what in enumerate(EXCEEDED):
        flags[..., k] = over[what]
    out["verdict"] = verdict
    out["over"] = flags
    out["exceeded"] = _EXCEEDED_TEXT[flags @ _EXCEEDED_BITS]
    return out


def describe(verdicts: dict, exceeded: dict) -> str:
    """One line of verdict counts that names what was exceeded, e.g. '145 within the predicted bound,
    5 over it, 0 over the design limit; exceeded: orientation bound 5' (a measurement may exceed several)."""
    text = []
    if verdicts.get("no budget"):
        text.append(f"{verdicts['no budget']} without a budget to check against")
    if verdicts.get("within") or verdicts.get("over bound") or not verdicts.get("no budget"):
        text.append(f"{verdicts.get('within', 0)} within the predicted bound, {verdicts.get('over bound', 0)} over it")
    text.append(f"{verdicts.get('over limit', 0)} over the design limit")
    parts = [f"{k} {n}" for k, n in exceeded.items() if n]
    return ", ".join(text) + (f"; exceeded: {', '.join(parts)}" if parts else "")
