"""Calibration: the identified errors of a measured robot, chosen by what predicts poses the fit did not see,
fitted robustly to the least-squares optimum and checked for plausibility.

What to identify (``parameters``): ``registration`` (nothing but the tracker and the targets),
``joint-offsets`` (each joint's zero offset), ``full`` (every parameter of the error model) or
``full+elastic`` (and a compliance per joint times its gravity load: the URDF's inertials, a ``payload``,
or a lumped point mass at the tool frame, see ``elastic.Load``); the full sets also regularised: a
Gaussian prior (``PRIOR``) on every origin error weighed against the fit's own residual noise, one on each
compliance (its deflection at the largest load of the data, ``robust.DEFLECTION``), none on the joint
offsets and none on the registration unless asked. ``auto`` cross-validates each candidate
(``crossval.validate``) and keeps the simplest whose held-out position RMS is within ``PARSIMONY`` of the
lowest: what predicts best, not what fits best.

Each fit (``robust.fit``) is converged (``identification.Convergence``: a fit stopped by its iteration cap
says so, and the command exits 3), holds a minimal set of dependent parameters at nominal (judged at
nominal and at the solution), and rejects outliers by its own residuals (never a stiffer model's), keeping
those whose removal would change what is identifiable (``suspect``). Candidates are compared on the
measurements that every candidate keeps; the chosen one is validated on every measurement, and on the
kept ones beside when it left some out. Plausibility: a calibration whose measurements do not spread like
the robot (a unit mistake), whose identified errors exceed ``PLAUSIBLE_LENGTH`` of the robot's reach or
``PLAUSIBLE_ANGLE``, or whose held-out error does not fall, is refused (``plausibility["ok"]`` False, with
the reasons).

The calibrated model is ``T = B @ T_nominal(q + c g(q), dx) @ X_k`` in the nominal base frame that the
registration defines (``B``: the identified base correction; ``X_k``: the target's frame in the tool frame);
``mechanism.calibrated_mechanism`` builds the chain part as a model of the input's own kind. Every RMS is of
the 3-D position error unless named per axis. SI throughout.
"""
from __future__ import annotations

import numpy as np

from ..accuracy import checks
from ..models.base import Mechanism
from ..accuracy.folds import pose_groups
from .crossval import Folds, kept_figures, score, validate
from .elastic import Load
from .mechanism import calibrated_mechanism, corrected_origins
from .result import Calibration, nominal_fingerprint
from ..conformity import implausible
from ..identification import PRIOR, REGISTRATIONS, FitOptions
from .robust import MODELS, FitData, estimate_sets, fit, prior_vector

__all__ = ["Calibration", "FitOptions", "MODELS", "PRIOR", "REGISTRATIONS", "calibrate", "calibrate_measurements",
           "calibrated_mechanism", "candidates", "corrected_origins", "pose_groups", "prior_vector"]

PARSIMONY = 0.01            # the simplest candidate within this share of the lowest cross-validated RMS wins
REPEATED = 0.02             # rad or m: a posture within this of a training one repeats it
INSIDE_MARGIN = 0.05        # rad or m: the training ranges widened by this are "inside"


def candidates(model: Mechanism, parameters="auto", prior=PRIOR, gravity=None) -> list:
    """[(label, parameters, prior)] to cross-validate: for 'auto' the registration alone, the joint offsets,
    the full set, the full set regularised with ``prior`` (m, rad) and, where gravity loads the joints,
    the full set with the elastostatic term (regularised too); otherwise the one given."""
    def label(which, pr):
        return which if pr is None else f"{which}, prior {pr[0] * 1e3:g} mm / {pr[1] * 1e3:g} mrad"
    if parameters != "auto":
        estimate_sets(model, parameters, gravity)
        pr = prior if parameters in ("full", "full+elastic") else None
        return [(label(parameters, pr), parameters, pr)]
    out = [("registration", "registration", None), ("joint-offsets", "joint-offsets", None), ("full", "full", None)]
    if prior is not None:
        out.append((label("full", prior), "full", prior))
    if gravity is not None:
        out.append((label("full+elastic", prior), "full+elastic", prior))
    return out


def calibrate(model: Mechanism, q, T_tracker, labels=None, options: FitOptions | None = None, *, parameters="auto",
              has_orientation=True, sources=None, target_index=None, target_names=("",), stamps=None, progress=None,
              where=None, **changes) -> Calibration:
    """Calibrate from tracker readings T_tracker (n, 4, 4) at joints q (n, dof), with k-fold validation.

    labels : (n,) test-pose name of each measurement, or None (measurements at equal joints form a pose).
    options : ``FitOptions`` (default: its defaults), with ``changes`` (its fields by name) applied.
    parameters : 'auto' (of ``candidates``, the one that predicts held-out poses best) or one of ``MODELS``.
    has_orientation : whether the readings carry orientations (orientation errors are fitted and validated
    only then, with ``sigma_orientation``).  target_index, target_names : each row's target and the targets'
    names (several need registration 'base+tool').  stamps : (n,) for the rejected list.  where : (n,) where each
    row comes from ('line 23' of its file), for the rejected list (default 'row i', 0-based).  progress : called
    with (done, total) after each candidate's cross-validation and the final fit.
    """
    opts = (options or FitOptions()).updated(**changes)
    q = model.check_joints(q)
    T_tracker = np.asarray(T_tracker, float)
    n = len(q)
    if T_tracker.shape != (n, 4, 4):
        raise ValueError(f"measurements: expected ({n}, 4, 4) poses, got {T_tracker.shape}")
    names = tuple(target_names)
    idx = np.zeros(n, int) if target_index is None else np.asarray(target_index, int)
    groups, pose_names = pose_groups(q, labels)
    if len(pose_names) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (measure more poses)")
    ignored = None
    if not has_orientation and opts.sigma_orientation is not None:
        ignored = (f"the measurements are points: the orientation noise given "
                   f"({opts.sigma_orientation * 1e6:.4g} urad) has no orientation to weigh; only positions are fitted")
        opts = opts.updated(sigma_orientation=None)
    load = Load.for_model(model, opts.payload)
    gravity = load.torques(model, q) if load is not None else None
    data = FitData(q, T_tracker, idx, names, has_orientation, gravity)
    problems = _units_problems(model, q, T_tracker)
    todo = candidates(model, parameters, opts.prior, gravity)
    if problems:  # the units cannot be right: no fit beyond the registration's is worth its time
        todo = [("registration", "registration", None)]
    fits = {}
    for label, which, pr in todo:  # every candidate's robust fit of all the data: which rows it leaves out
        try:
            fits[label] = fit(model, data, which, pr, opts, analysis=False)
        except (ValueError, np.linalg.LinAlgError):
            continue
    scores, validations, errors = [], {}, {}
    folds = Folds(model, data, groups, opts)
    for step, (label, which, pr) in enumerate(todo):
        if progress is not None:
            progress(step, len(todo) + 1)
        try:
            validations[label] = validate(model, data, groups, which, pr, opts, pose_names, None, folds)
        except (ValueError, np.linalg.LinAlgError) as exc:
            errors[label] = str(exc)
    # a row is left out of the comparison only when every candidate judges it an outlier, by its fit of all the
    # data or by its prediction of the row held out: an overfitting candidate that absorbs an outlier still
    # predicts it badly, and a stiff model's misfits neither leave the flexible models' best poses unscored
    # nor favour a model
    exclude = np.zeros(n, bool)
    if validations:
        exclude[:] = True
        for label, v in validations.items():
            judged = np.zeros(n, bool)
            judged[v["outliers"]] = True
            if label in fits:
                judged |= fits[label].rejected
            exclude &= judged
    for label, which, pr in todo:
        if label in errors:
            scores.append({"label": label, "parameters": which, "prior": pr, "error": errors[label]})
            continue
        v = validations[label] = kept_figures(validations[label], exclude)
        scores.append({"label": label, "parameters": which, "prior": None if pr is None else list(pr),
                       "cv_position_rms_m": score(v), "cv_position_max_m": (v.get("after_kept") or v["after"])[
                           "position_max_m"], "unknowns": v["unknowns"], "not_converged_folds": v["not_converged"]})
    valid = [s for s in scores if "cv_position_rms_m" in s]
    if not valid:
        raise ValueError("calibration: no candidate could be fitted: " + "; ".join(s["error"] for s in scores))
    lowest = min(s["cv_position_rms_m"] for s in valid)
    best = next(s for s in valid if s["cv_position_rms_m"] <= lowest * (1 + PARSIMONY))
    chosen, chosen_prior = best["parameters"], best["prior"]
    final = fit(model, data, chosen, chosen_prior, opts)
    nominal = fits.get("registration") or fit(model, data, "registration", None, opts, analysis=False)
    if progress is not None:
        progress(len(todo) + 1, len(todo) + 1)
    cal = _result(model, data, final, nominal, opts, pose_names, sources, load, chosen)
    cal.model = {"parameters": chosen, "prior": chosen_prior, "label": best["label"],
                 "how": "chosen by the lowest cross-validated position RMS" if parameters == "auto" else "given",
                 "compared_on": "the measurements every candidate keeps" if exclude.any() else "every measurement",
                 "candidates": scores, "held_compliance": list(getattr(final.ident, "compliance_held", []))}
    cal.rejected = _row_list(final, final.rejected, stamps, labels, names, idx, "rejected", where)
    cal.suspect = _row_list(final, final.suspect, stamps, labels, names, idx, "suspect", where)
    cal.validation = kept_figures(validations[best["label"]], final.rejected)
    problems += _plausibility_problems(model, cal)
    cal.plausibility = {"ok": not problems, "problems": problems}
    cal.warnings = ([ignored] if ignored else []) + _warnings(cal, final, validations[best["label"]])
    cal.warnings += _negative_compliances(model, cal)
    cal.repeatability = repeatability(final.reg.to_base(T_tracker)[:, :3, 3], final, groups, idx, len(names))
    cal.training = {"joint_ranges": np.c_[q.min(axis=0), q.max(axis=0)].tolist(),
                    "postures": np.unique(np.round(q, 6), axis=0).tolist()}
    return cal


def _result(model, data, final, nominal, opts, pose_names, sources, load, chosen) -> Calibration:
    """The Calibration of the final fit (without the model choice, validation and verdicts)."""
    ident, reg = final.ident, final.reg
    keep = ~final.rejected
    rows = int(np.count_nonzero(keep)) * (6 if opts.sigma_orientation is not None and data.frames else 3)
    cal = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), ident.dx.copy(),
                      ident.std.copy(), ident.base.copy(), reg.T_tracker_base, None, ident.held,
                      ident.unidentifiable, ident.aliases, ident.condition, ident.fit_condition, ident.rank,
                      ident.n_free, ident.sigma, ident.residual_rms_before, ident.residual_rms_after, len(data),
                      len(pose_names), rows, opts.registration, sources=dict(sources or {}), targets=ident.targets,
                      targets_std=ident.targets_std, compliance=ident.compliance,
                      compliance_std=ident.compliance_std, has_orientation=data.frames)
    names = data.names
    cal.tool_offset = cal.targets.offsets[0].copy() if opts.registration == "base+tool" and len(names) == 1 else None
    cal.sources.setdefault("joint_names", list(model.joint_names))
    cal.nominal = nominal_fingerprint(model)
    cal.nominal_registration = {"T_tracker_base": nominal.reg.T_tracker_base, "targets": nominal.ident.targets,
                                "base": nominal.ident.base.copy()}
    r = ident.row_residuals[keep]
    cal.position_rms, cal.position_max = float(np.sqrt(np.mean(r ** 2))), float(r.max())
    cal.convergence = ident.convergence.to_dict()
    cal.convergence["words"] = ident.convergence.words()
    cal.convergence["held_judged_at"] = ident.held_judged_at
    cal.undetermined = dict(ident.undetermined)
    if ident.compliance is not None and load is not None:
        cal.load = load.to_dict()
        cal.load["description"] = load.describe(getattr(model, "tip_link", None) or "the tool frame")
    return cal


def _warnings(cal, final, validation) -> list:
    out = []
    if not final.converged:
        out.append(f"the final fit did not converge: {final.ident.convergence.words()}")
    if validation.get("not_converged"):
        out.append(f"the fits of fold(s) {validation['not_converged']} of the cross-validation stopped at their "
                   f"iteration cap")
    if cal.suspect:
        out.append(f"{len(cal.suspect)} measurement(s) beyond the rejection threshold were kept: leaving them out "
                   f"would change which parameters are identifiable (see suspect)")
    if cal.undetermined:
        out.append(f"{len(cal.undetermined)} estimated parameter(s) the data cannot tell (set by the prior, or "
                   f"near-copies of another; see undetermined): {', '.join(cal.undetermined)}")
    return out


def calibrate_measurements(model, meas, campaign=None, options: FitOptions | None = None, *, parameters="auto",
                           progress=None, registration=None, **changes) -> Calibration:
    """``calibrate`` for a ``Measurements`` (joints from its columns or from the campaign's test poses), after the
    checks ``report`` makes (``checks``: the units of the points and of the orientations, the joint limits, the
    campaign of labelled poses, the nominal robot registered onto them): CheckError (bad input, exit 2) for
    measurements that cannot be this robot's, before any fit; the rows it leaves out and rejects are named by
    their place in the file (``Measurements.where``). ``registration`` 'auto': base or base+tool chosen from the
    data (``checks.choose_registration``, cross-validated by test pose; ``model["registration"]`` says how)."""
    from ..accuracy.evaluation import measurement_joints
    q = measurement_joints(model, meas, campaign)
    beyond, unused = checks.unused_joint_columns(model, meas.joint_names, meas.joints)
    problem = checks.units_problem(model, q, meas.T[:, :3, 3])
    if problem:
        raise checks.CheckError(f"{meas.source}: {checks.likely(problem, beyond)}")
    labels = meas.pose if meas.pose is not None and any(str(p) for p in meas.pose) else None
    screened = checks.screen(model, q, meas, campaign, labels)   # beyond the limits: left out, said; wrong campaign
    if not screened.keep.all():
        meas, q = meas.select(screened.keep), q[screened.keep]
    labels = meas.pose if meas.pose is not None and any(str(p) for p in meas.pose) else None
    opts = (options or FitOptions()).updated(**changes)
    choice = None
    if registration == "auto":
        choice = checks.choose_registration(model.fk(q), meas.T, meas.target_index(), meas.target_names,
                                            pose_groups(q, labels)[0], meas.has_orientation, opts.folds, opts.seed,
                                            opts.robust)
        opts = opts.updated(registration=choice["chosen"])
    elif registration is not None:
        opts = opts.updated(registration=registration)
    try:
        checks.refuse_implausible(model, q, meas.T, meas.target_index(), meas.target_names, opts.registration,
                                  meas.has_orientation)
    except checks.CheckError as exc:
        raise checks.CheckError(f"{meas.source}: {checks.likely(str(exc), beyond)}") from None
    cal = calibrate(model, q, meas.T, labels, opts, parameters=parameters, has_orientation=meas.has_orientation,
                    sources={"measurements": meas.source}, target_index=meas.target_index(),
                    target_names=meas.target_names, stamps=meas.stamps, progress=progress,
                    where=[meas.where(i) for i in range(len(meas))])
    cal.warnings = [f"left out before the fit: {r['where']}: {r['reason']}" for r in screened.left_out] + cal.warnings
    cal.model["registration"] = choice or {"chosen": opts.registration, "how": "given"}
    cal.warnings[:0] = [n for n in (beyond, unused) if n]
    if screened.unknown_poses:
        named = [p for p in meas.pose if str(p)]
        cal.warnings.insert(0, f"{checks.unknown_poses_text(screened.unknown_poses, campaign.name, named)}: the "
                               f"campaign gives their measurements nothing; they are fitted at their own joint "
                               f"columns")
    return cal


def _units_problems(model, q, T_tracker) -> list:
    """Reasons the measurements cannot be in the units claimed (``checks.units_problem``)."""
    problem = checks.units_problem(model, q, T_tracker[:, :3, 3])
    return [problem] if problem else []


def _plausibility_problems(model, cal) -> list:
    """Reasons the identified model cannot be right: errors beyond a fraction of the robot's reach or a
    plausible angle, elastic deflections beyond it, a held-out error that does not fall."""
    reach = model.reach()
    out = [f"{n}: {why}" for n, why in implausible(cal.names, cal.kinds, cal.dx, reach).items()]
    far = np.linalg.norm(cal.targets.offsets, axis=1)
    for name, d in zip(cal.targets.names, far):
        if d > max(reach, 1.0):
            out.append(f"target {name or '(unnamed)'}: {d:.4g} m from the tool frame, farther than the robot reaches")
    v = cal.validation
    if v["after"]["position_rms_m"] >= v["before"]["position_rms_m"]:
        out.append(f"hold-out validation: the calibrated model does not reduce the position error RMS "
                   f"({v['before']['position_rms_m'] * 1e3:.4f} mm before, {v['after']['position_rms_m'] * 1e3:.4f} "
                   f"mm after)")
    return out


def _negative_compliances(model, cal) -> list:
    """Warnings for compliances fitted negative beyond three standard uncertainties: no joint bends against its
    load, so the term takes up another gravity-dependent error there; it predicts at the loads of the data, and
    must not be carried to another payload."""
    if cal.compliance is None:
        return []
    std = np.zeros_like(cal.compliance) if cal.compliance_std is None else np.abs(cal.compliance_std)
    bad = np.flatnonzero(cal.compliance + 3 * std < 0)
    if not bad.size:
        return []
    which = ", ".join(f"{model.joint_names[j]} {cal.compliance[j]:.4g} +- {std[j]:.2g}" for j in bad)
    return [f"compliance fitted negative ({which}; rad/(N m), m/N for a prismatic joint): not a physical compliance, "
            f"since no joint bends against its load; the term takes up another gravity-dependent error there "
            f"(backlash, a counterbalance, a cable), which predicts at the loads of these data but must not be carried "
            f"to another payload"]


def _row_list(fitted, mask, stamps, labels, names, idx, kind, where=None) -> list:
    """The measurements of ``mask`` with their residuals and the reason: rejected (beyond the threshold) or
    suspect (beyond it, kept: their removal would change what is identifiable)."""
    out = []
    r, limit = fitted.ident.row_residuals, fitted.row_thresholds
    for i in np.flatnonzero(mask):
        reason = (f"position residual {r[i] * 1e3:.4g} mm exceeds {limit[i] * 1e3:.4g} mm ({checks.REJECT:g} robust "
                  f"standard deviations of the fit, at this row)")
        if kind == "suspect":
            reason += "; kept, because leaving it out would change which parameters are identifiable"
        entry = {"row": int(i), "where": where[i] if where is not None else f"row {int(i)}", "target": names[idx[i]],
                 "residual_m": float(r[i]), "threshold_m": float(limit[i]), "reason": reason}
        if stamps is not None:
            entry["stamp"] = float(stamps[i])
        if labels is not None:
            entry["pose"] = str(labels[i])
        out.append(entry)
    return out


def repeatability(points, fitted, groups, idx, n_targets) -> dict:
    """The residual of a fit beside the scatter of repeated visits of one pose (same pose and target):
    ``scatter_m`` is the RMS distance of a repeated measured point (``points`` (n, 3), m) from its pose's
    mean, ``residual_rms_m`` the fit's (3-D), ``unexplained_m`` sqrt(residual^2 - scatter^2), what noise does not
    explain (0 when it explains all); None without repeats. Rejected measurements are left out."""
    keep = ~fitted.rejected
    res = float(np.sqrt(np.mean(fitted.ident.row_residuals[keep] ** 2)))
    key = np.asarray(groups, int) * max(n_targets, 1) + np.asarray(idx, int)
    sq, count = 0.0, 0
    for k in np.unique(key[keep]):
        sel = keep & (key == k)
        if sel.sum() >= 2:
            d = points[sel] - points[sel].mean(axis=0)
            sq += float(np.sum(d ** 2))
            count += int(sel.sum()) - 1
    if not count:
        return {"repeated_measurements": 0, "scatter_m": None, "residual_rms_m": res, "unexplained_m": None}
    scatter = float(np.sqrt(sq / count))
    return {"repeated_measurements": count, "scatter_m": scatter, "residual_rms_m": res,
            "unexplained_m": float(np.sqrt(max(res ** 2 - scatter ** 2, 0.0)))}
