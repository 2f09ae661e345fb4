"""Validation on another campaign: a calibration predicts measurements it has never seen, with its own
registration and target offsets (nothing refitted), beside the nominal robot with the registration-only
fit of the same training data: the protocol that scores a calibration (fit one day, predict another).

``reregister`` refits the tracker alone (both models keep their targets and parameters), for a tracker
that moved between the campaigns. Postures are grouped against the training campaign: a posture within
``REPEATED`` of a training one repeats it; otherwise it is inside the training ranges (each joint within
the range the training covered, widened by ``INSIDE_MARGIN``) or outside them. SI throughout.
"""
from __future__ import annotations

import numpy as np

from ..identification import base_matrix
from ..accuracy import checks
from ..accuracy.verdicts import pose_errors
from ..models.base import Mechanism
from .calibrate import INSIDE_MARGIN, REPEATED, Calibration, pose_groups

GROUPS = ("repeated training posture", "new, inside the training ranges", "new, outside the training ranges")


def posture_groups(cal: Calibration, q) -> np.ndarray | None:
    """(n,) group of each configuration (an index into ``GROUPS``), or None without the training's record."""
    tr = cal.training
    if not tr or not tr.get("postures"):
        return None
    q = np.asarray(q, float)
    postures = np.asarray(tr["postures"], float)
    ranges = np.asarray(tr["joint_ranges"], float)
    d = np.abs(q[:, None, :] - postures[None]).max(axis=2).min(axis=1)
    inside = np.all((q >= ranges[:, 0] - INSIDE_MARGIN) & (q <= ranges[:, 1] + INSIDE_MARGIN), axis=1)
    return np.where(d <= REPEATED, 0, np.where(inside, 1, 2))


def predict_campaign(cal: Calibration, model: Mechanism, q, T_tracker, target_index=None, labels=None,
                     has_orientation=True, reregister=False, meas=None, robust=True) -> dict:
    """Before (nominal robot, registration-only fit) and after (calibrated robot) errors of a campaign of
    tracker readings T_tracker (n, 4, 4) at joints q (n, dof); a plain dict, SI.

    The campaign is checked first (``accuracy.checks``): a length or angle unit that cannot be right, a
    joint column out of range, or measurements the nominal robot cannot be registered onto (another robot,
    swapped columns: ``checks.refuse_implausible``) are refused; rows beyond the joint limits are left out and listed (``meas``
    names their file lines). With ``reregister`` the tracker's placement is refitted for each model,
    robustly: rows beyond ``checks.REJECT`` robust sigmas are left out of it and of the figures, and listed.

    Keys: measurements, reregistered, before / after {position_rms_m, position_max_m, orientation_rms_rad,
    orientation_max_rad} (3-D, over the kept rows), improvement, per_pose {pose: {n, group, before_rms_m,
    after_rms_m}}, by_group {group: {n, poses, before_rms_m, after_rms_m}}, by_target, position_error_m
    {before, after}, left_out [{row, where, reason}], warnings (what says the verdict is off: the tracker
    moved, the robot changed), notes (what is not scored).
    """
    q = model.check_joints(q)
    T_tracker = np.asarray(T_tracker, float)
    n = len(q)
    idx = np.zeros(n, int) if target_index is None else np.asarray(target_index, int)
    problem = checks.units_problem(model, q, T_tracker[:, :3, 3])
    if problem:
        raise checks.CheckError(problem)
    screened = checks.screen(model, q, meas)
    checks.refuse_implausible(model, q[screened.keep], T_tracker[screened.keep], idx[screened.keep], cal.targets.names,
                              "base+tool" if len(cal.targets.names) > 1 or cal.registration == "base+tool" else "base",
                              bool(has_orientation), robust)
    ori = bool(has_orientation and cal.has_orientation)
    notes = []
    if has_orientation and not cal.has_orientation:
        notes.append("the campaign measured orientations, but the calibration fitted positions only: orientation is "
                     "not scored")
    nominal = cal.nominal_registration or {"T_tracker_base": cal.T_tracker_base, "targets": cal.targets,
                                           "base": np.zeros(6)}
    T_after_tool = cal.B @ cal.mechanism_chain(model).fk(q, cal.dx)
    T_before_tool = base_matrix(nominal["base"]) @ model.fk(q)
    models = {"before": (T_before_tool, nominal["targets"], nominal["T_tracker_base"]),
              "after": (T_after_tool, cal.targets, cal.T_tracker_base)}
    placements = {}
    keep = screened.keep.copy()
    for label in ("after", "before"):  # the calibrated model's outliers first: they are left out of both
        T_tool, targets, A = models[label]
        if reregister:
            reg, out, thr = checks.robust_register(T_tool[keep], T_tracker[keep], idx[keep], targets.names,
                                                   robust=robust, targets=targets)
            A = reg.T_tracker_base
            far = np.zeros(n, bool)
            far[np.flatnonzero(keep)[out]] = True
            resid = dict(zip(np.flatnonzero(keep), reg.residuals))
            screened.leave_out(far, lambda i: f"residual {resid[i] * 1e3:.4g} mm after the tracker was refitted to the "
                               f"{label} model exceeds {thr * 1e3:.4g} mm ({checks.REJECT:g} robust standard "
                               f"deviations)", lambda i: meas.where(i) if meas is not None else f"row {int(i)}")
            keep = screened.keep.copy()
        placements[label] = A
    out = {"measurements": int(n), "scored": int(keep.sum()), "reregistered": bool(reregister),
           "orientation_measured": ori, "left_out": screened.left_out, "notes": notes}
    errs = {}
    for label, (T_tool, targets, _) in models.items():
        A = placements[label]
        T_pred = targets.poses(T_tool[keep], idx[keep])
        T_seen = np.linalg.inv(A) @ T_tracker[keep]
        dp, dphi = pose_errors(T_pred, T_seen)
        ep, eo = np.linalg.norm(dp, axis=1), np.linalg.norm(dphi, axis=1)
        errs[label] = (ep, eo)
        out[label] = {"position_rms_m": _rms(ep), "position_max_m": float(ep.max()),
                      "orientation_rms_rad": _rms(eo) if ori else None,
                      "orientation_max_rad": float(eo.max()) if ori else None,
                      "T_tracker_base": A}
    out["improvement"] = 1.0 - out["after"]["position_rms_m"] / out["before"]["position_rms_m"]
    out["warnings"] = _warnings(cal, out, T_after_tool[keep], T_tracker[keep], idx[keep], reregister)
    q, idx = q[keep], idx[keep]
    labels = None if labels is None else np.asarray(labels, dtype=object)[keep]
    groups, names = pose_groups(q, labels)
    posture = posture_groups(cal, q)
    per_pose = {}
    for g, name in enumerate(names):
        sel = groups == g
        per_pose[name] = {"n": int(sel.sum()), "group": None if posture is None else GROUPS[int(posture[sel][0])],
                          "before_rms_m": _rms(errs["before"][0][sel]), "after_rms_m": _rms(errs["after"][0][sel])}
    out["per_pose"] = per_pose
    if posture is not None:
        out["by_group"] = {GROUPS[k]: {"n": int((posture == k).sum()),
                                       "poses": int(len({groups[i] for i in np.flatnonzero(posture == k)})),
                                       "before_rms_m": _rms(errs["before"][0][posture == k]),
                                       "after_rms_m": _rms(errs["after"][0][posture == k])}
                           for k in range(len(GROUPS)) if np.any(posture == k)}
    out["by_target"] = {t: {"n": int((idx == k).sum()), "before_rms_m": _rms(errs["before"][0][idx == k]),
                            "after_rms_m": _rms(errs["after"][0][idx == k])}
                        for k, t in enumerate(cal.targets.names) if np.any(idx == k)}
    out["position_error_m"] = {"before": errs["before"][0], "after": errs["after"][0]}
    return out


def _warnings(cal, out, T_tool, T_tracker, idx, reregistered) -> list:
    """What says the verdict is off: the tracker moved (refitting it alone explains the error), or the robot
    changed (far beyond the calibration's own held-out figure)."""
    warnings = []
    rms = out["after"]["position_rms_m"]
    if not reregistered and len(T_tool) >= 3:
        try:
            reg, _, _ = checks.robust_register(T_tool, T_tracker, idx, cal.targets.names, targets=cal.targets)
            hint = checks.moved_hint(rms, float(np.sqrt(np.mean(reg.residuals ** 2))))
        except ValueError:
            hint = None
        if hint:
            return [hint]
    v = cal.validation or {}
    held_out = (v.get("after_kept") or v.get("after") or {}).get("position_rms_m")
    hint = checks.changed_hint(rms, held_out)
    if hint:
        warnings.append(hint)
    return warnings


def predict_measurements(cal: Calibration, model: Mechanism, meas, reregister=False, campaign=None,
                         robust=True) -> dict:
    """``predict_campaign`` of a ``Measurements`` (its targets must be among the calibration's)."""
    from ..accuracy.evaluation import measurement_joints
    q = measurement_joints(model, meas, campaign)
    idx = meas.target_index(cal.targets.names)
    labels = meas.pose if meas.pose is not None and any(str(p) for p in meas.pose) else None
    try:
        out = predict_campaign(cal, model, q, meas.T, idx, labels, meas.has_orientation, reregister, meas, robust)
    except checks.CheckError as exc:
        raise checks.CheckError(f"{meas.source}: {exc}") from None
    out["source"] = meas.source
    out["notes"][:0] = [n for n in checks.unused_joint_columns(model, meas.joint_names, meas.joints) if n]
    return out


def _rms(e) -> float:
    e = np.asarray(e, float)
    return float(np.sqrt(np.mean(e ** 2))) if e.size else float("nan")
