"""The numbers of an accuracy report: registration, errors, the budget check, ISO 9283 per test pose and
identification of a set of measurements, as a plain dict (SI): ``evaluate_file`` (all in memory) and
``stream_file`` (constant memory, large CSV files)."""
from __future__ import annotations

import numpy as np

from ..ingest import IngestError, JointOrder
from . import checks
from ..conformity import DEFAULT_RULE, DecisionRule, judged
from .accumulator import AccuracyAccumulator
from ..identification import FitOptions, Unknowns, identify
from .io import MeasurementError, read_csv
from .iso9283 import pose_characteristics
from .registration import KabschAccumulator, Registration, register
from ..targets import Targets

IDENTIFY_MAX = 20000  # up to this many measurements the nonlinear identification runs on all of them
NOT_BASE_FRAME = "the measurements are not in the robot's base frame"   # the warning of ``frame_warnings``


def evaluate_file(model, meas, budget=None, campaign=None, registration="base", keep_rows=True,
                  sigma_position=1e-5, sigma_orientation=None, robust=True, identification=True,
                  rule: DecisionRule = DEFAULT_RULE) -> dict:
    """Evaluate measurements (see the module docstring), after the checks of ``checks``: a length unit that
    cannot be right, a joint column out of range, the wrong campaign or a registered residual no robot
    error explains are refused (``checks.CheckError``); rows beyond the joint limits are listed in
    ``left_out`` and judged no further; with ``robust``, rows far off the others are left out of the
    registration only (``registration.left_out``: one bad row moves nothing else) and judged as measured.

    registration : 'base' (estimate base -> tracker), 'base+tool' (and each target's offset on the
    tool), 'auto' (the one of the two the data choose: ``checks.choose_registration``, said in
    ``registration.choice``), 'none' (measurements already in the base frame) or a Registration (its
    targets are used).
    Every error is taken at the measured target; measurements without orientation get no orientation
    figure. ``warnings`` names what the verdict should be read with (measurements in another frame than the
    one claimed, a target offset the registration does not fit, poses the campaign does not have).
    ``identification`` False: none (a caller that needs only the registered rows). ``rule``: the decision rule
    of the identified parts against the budget (``conformity``).
    """
    if len(meas) == 0:
        raise MeasurementError(f"{meas.source}: no measurements")
    q = measurement_joints(model, meas, campaign)
    names = meas.target_names
    not_registered = []
    beyond, unused = checks.unused_joint_columns(model, meas.joint_names, meas.joints)
    problem = checks.units_problem(model, q, meas.T[:, :3, 3]) or \
        (checks.orientation_problem(model, q, meas.T[:, :3, :3], meas.T) if meas.has_orientation else None)
    if problem:
        raise checks.CheckError(f"{meas.source}: {checks.likely(problem, beyond)}")
    labels = _labels(meas)
    screened = checks.screen(model, q, meas, campaign, labels)
    warnings, notes = list(screened.notes), []
    notes += [n for n in (beyond, unused) if n]
    if meas.loaded.any():
        notes.append(f"{int(meas.loaded.sum())} measurement(s) were taken under a load at the "
                     f"tool (load columns): their errors include the robot's deflection (iso9283 judges them as "
                     f"its static compliance and the unloaded ones as the pose characteristics)")
    T_tool_all = model.fk(q)
    choice = None
    if isinstance(registration, str) and registration == "auto":
        keep = screened.keep
        choice = checks.choose_registration(T_tool_all[keep], meas.T[keep], meas.target_index(names)[keep], names,
                                            _groups(q, labels)[keep], meas.has_orientation, robust=robust)
        registration = choice["chosen"]
    if isinstance(registration, Registration):
        idx_all = meas.target_index(registration.targets.names)
        residuals = np.linalg.norm(registration.to_base(meas.T)[:, :3, 3]
                                   - registration.targets.poses(T_tool_all, idx_all)[:, :3, 3], axis=1)
        reg = Registration(registration.T_tracker_base, registration.targets, residuals, len(meas),
                           registration.estimated)
    else:
        idx_all = meas.target_index(names)
        keep = screened.keep.copy()
        if registration in ("base", "base+tool"):
            if registration == "base" and len(names) > 1:
                raise ValueError(f"registration: {len(names)} targets ({', '.join(names)}) sit at different points "
                                 f"of the tool; fit their offsets with registration 'base+tool'")
            reg, out, thr = checks.robust_register(T_tool_all[keep], meas.T[keep], idx_all[keep], names,
                                                   registration == "base+tool", meas.has_orientation, robust)
            rows = np.flatnonzero(keep)
            not_registered = [{"row": int(i), "where": meas.where(i),
                               "reason": f"registered residual {r * 1e3:.4g} mm exceeds {thr * 1e3:.4g} mm "
                                         f"({checks.REJECT:g} robust standard deviations): not used by the "
                                         f"registration, judged as measured"}
                              for i, r in zip(rows[out], reg.residuals[out])]
            scatter = checks.repeat_scatter(meas.T[keep, :3, 3], _groups(q, labels)[keep], idx_all[keep])
            sel = ~out
            refused, hints = checks.diagnose(model, q[keep], meas.T[keep], idx_all[keep], names, registration,
                                             meas.has_orientation, reg, sel, scatter)
            if refused:
                raise checks.CheckError(f"{meas.source}: {checks.likely(refused, beyond)}")
            warnings += hints
            if not_registered:
                notes.append(f"{len(not_registered)} measurement(s) far off the others were not used by the "
                             f"registration (registration.left_out); they are judged as measured")
        else:
            reg = register_measurements(T_tool_all, meas, idx_all, names, registration)
            warnings += frame_warnings(T_tool_all, meas, idx_all, names, reg)
    if meas.has_orientation and not any(w.startswith(NOT_BASE_FRAME) for w in warnings):
        problem = checks.registered_orientation_problem(reg.to_base(meas.T)[:, :3, :3],
                                                        reg.targets.poses(T_tool_all, idx_all)[:, :3, :3])
        if problem:
            raise checks.CheckError(f"{meas.source}: {problem}")
    left_out = screened.left_out
    if not screened.keep.all():
        meas = meas.select(screened.keep)
        q, idx_all = q[screened.keep], idx_all[screened.keep]
        labels = None if labels is None else labels[screened.keep]
    idx = idx_all
    delta = budget.vector_for(model) if budget is not None else None
    acc = AccuracyAccumulator.from_budget(model, budget, campaign, reg.T_tracker_base, reg.targets,
                                          orientation=meas.has_orientation)
    rows = []
    for a in range(0, len(q), 5000):
        b = min(len(q), a + 5000)
        r = acc.add(meas.T[a:b], q[a:b], None if labels is None else labels[a:b], idx[a:b])
        if keep_rows:
            rows.append(r)
    method = registration if isinstance(registration, str) else "given"
    out = {"source": meas.source, "robot": model.name, "measurements": len(q), "skipped_rows": meas.skipped,
           "orientation_measured": bool(meas.has_orientation), "targets": list(reg.targets.names),
           "registration": {"method": method, **reg.to_dict(), "left_out": not_registered,
                            **({"choice": choice} if choice else {})},
           "summary": acc.summary(sigma_position, rule),
           "warnings": warnings, "notes": notes, "left_out": left_out}
    T_base = reg.to_base(meas.T)
    if campaign is not None:
        lab = labels if labels is not None else acc.label(q)
        keys = np.array([acc._key(n, k) if n else "" for n, k in zip(lab, idx)], dtype=object)
        out["per_pose"] = per_pose_statistics(list(acc.commanded()), acc.commanded(), T_base, keys,
                                              meas.has_orientation)
    if identification and len(q) <= IDENTIFY_MAX:
        ori = sigma_orientation if meas.has_orientation else None
        ident = identify(model, q, T_base, delta, FitOptions(sigma_position=sigma_position, sigma_orientation=ori),
                         Unknowns(targets=reg.targets, target_index=idx), rule=rule)
        out["identification"] = ident.to_dict()
        if delta is not None:
            out["identification"]["groups"] = aliased_groups(model, q, T_base, delta, sigma_position, ori, reg.targets,
                                                             idx, rule, _groups(q, labels))
    elif identification:
        out["identification"] = out["summary"].pop("identification", None)
    if keep_rows:
        cat = {k: np.concatenate([r[k] for r in rows]) for k in rows[0] if k not in ("dp", "dphi", "orientation_error")
               and rows[0][k] is not None}
        out["rows"] = {"stamp": meas.stamps, "joints": q, "attained": T_base, "visit_cycle": meas.cycle,
                       "pose": None if labels is None else labels, "commanded": acc.commanded(),
                       "dp": np.concatenate([r["dp"] for r in rows]),
                       "dphi": np.concatenate([r["dphi"] for r in rows]) if meas.has_orientation else None,
                       "orientation_error": (np.concatenate([r["orientation_error"] for r in rows])
                                             if meas.has_orientation else None), **cat}
    return out


def aliased_groups(model, q, T_base, delta, sigma_position=1e-5, sigma_orientation=None, targets=None,
                   target_index=None, rule: DecisionRule = DEFAULT_RULE, visits=None) -> dict:
    """What the data can see of each parameter, against the budget, and what it decides: the fit without a prior
    that holds a minimal set of dependent parameters at nominal, its covariance scaled by the residual noise; each
    estimated parameter measures the combination of itself and the held parameters it absorbs
    (``conformity.parameter_groups``), decided within, out or undecided by ``rule`` from its estimate and
    standard uncertainty (the noise the larger of the measurements' and of the means of the visits of each test
    pose, ``visits`` (n,) their group: an error the model lacks repeats at every visit). A fault in a held
    parameter shows in its group, or is absorbed by the registration's base frame. SI.

    Keys: those of ``conformity.judged`` (groups, rule, rule_words, counts, out_of_tolerance);
    ``absorbed_by_registration``: the held
    parameters the base correction absorbs (a registration takes them: no campaign sees them); ``not_seen``: the
    held parameters these measurements do not see at all (no effect on what was measured).
    """
    ident = identify(model, q, T_base, None, FitOptions(sigma_position=sigma_position,
                                                        sigma_orientation=sigma_orientation),
                     Unknowns(targets=targets, target_index=target_index), hold="dependent", noise_from_residuals=True,
                     clusters=visits)
    out = judged(model.param_names, model.param_kinds, ident.dx, ident.std, ident.held, ident.aliases, delta, rule,
                 ident.undetermined, model.reach())
    base = {h for b, a in ident.aliases.items() if b.startswith("base.") for h, c in a.items() if abs(c) > 1e-6}
    grouped = {h for g in out["groups"] for h in g["parameters"]}
    return {**out, "absorbed_by_registration": [h for h in ident.held if h in base],
            "not_seen": [h for h in ident.held if h not in base and h not in grouped]}


def _labels(meas):
    """(n,) test-pose labels of the rows, or None when no row names its pose."""
    if meas.pose is not None and any(str(p) for p in meas.pose):
        return np.array([str(p) for p in meas.pose], dtype=object)
    return None


def _groups(q, labels):
    """(n,) pose group of each row: by label, else by equal joints."""
    keys = labels if labels is not None else [tuple(r) for r in np.round(np.asarray(q, float), 9)]
    lookup = {}
    return np.array([lookup.setdefault(k, len(lookup)) for k in keys], int)


def register_measurements(T_tool, meas, idx, names, registration) -> Registration:
    """The Registration of ``meas`` by method: 'base', 'base+tool' or 'none'."""
    if registration == "none":
        tg = Targets.at_tool(names, meas.has_orientation)
        return Registration(np.eye(4), tg, np.linalg.norm(meas.T[:, :3, 3] - tg.poses(T_tool, idx)[:, :3, 3], axis=1),
                            len(T_tool))
    if registration not in ("base", "base+tool"):
        raise ValueError(f"registration: expected 'base', 'base+tool' or 'none', got {registration!r}")
    if registration == "base" and len(names) > 1:
        raise ValueError(f"registration: {len(names)} targets ({', '.join(names)}) sit at different points of the "
                         f"tool; fit their offsets with registration 'base+tool'")
    return register(T_tool, meas.T, tool=registration == "base+tool", index=idx, names=names,
                    frames=meas.has_orientation)


def frame_warnings(T_tool, meas, idx, names, reg) -> list:
    """What says that measurements claimed to be in the base frame are not: a registration would shrink the
    error many times over."""
    if len(T_tool) < 3:
        return []
    try:
        best = register(T_tool, meas.T, index=idx, names=names, targets=reg.targets)
    except ValueError:
        return []
    if reg.rms > 10 * best.rms and reg.rms > 1e-3:
        return [f"{NOT_BASE_FRAME}: their RMS error is {reg.rms * 1e3:.4g} mm as "
                f"given and {best.rms * 1e3:.4g} mm after a registration; use registration 'base' (or 'base+tool')"]
    return []


def stream_file(model, path, budget=None, campaign=None, chunk_rows=5000, registration="base",
                rule: DecisionRule = DEFAULT_RULE) -> dict:
    """Constant-memory evaluation of a large CSV file of one target: pass 1 registers the base (position
    sums), pass 2 feeds the accumulator chunk by chunk. Identification is the linearised one, its parts decided
    by ``rule``."""
    T_tb = np.eye(4)
    if registration == "base":
        kab = KabschAccumulator()
        for m in read_csv(path, chunk_rows=chunk_rows):
            _one_target(m)
            kab.add(model.fk(measurement_joints(model, m, campaign))[:, :3, 3], m.T[:, :3, 3])
        T_tb = kab.result()
    elif registration != "none":
        raise ValueError("stream_file: registration must be 'base' or 'none'")
    acc = None
    skipped = []
    for m in read_csv(path, chunk_rows=chunk_rows):
        _one_target(m)
        if acc is None:
            acc = AccuracyAccumulator.from_budget(model, budget, campaign, T_tb, orientation=m.has_orientation)
        labels = np.array([str(p) for p in m.pose], dtype=object) if m.pose is not None and any(m.pose) else None
        acc.add(m.T, measurement_joints(model, m, campaign), labels)
        skipped += m.skipped
    return {"source": str(path), "robot": model.name, "measurements": acc.n, "skipped_rows": skipped,
            "orientation_measured": acc.orientation, "T_tracker_base": T_tb, "summary": acc.summary(rule=rule)}


def _one_target(m):
    if len(m.target_names) > 1:
        raise MeasurementError(f"{m.source}: streaming takes one target; this file has {len(m.target_names)} "
                               f"({', '.join(m.target_names)}): evaluate it without streaming")


def per_pose_statistics(names, T_commanded: dict, T_measured, labels, orientation=True) -> dict:
    """ISO 9283 characteristics for each test pose key (measured poses grouped by ``labels``)."""
    out = {}
    labels = np.asarray(labels, dtype=object)
    for name in names:
        sel = labels == name
        if sel.sum() >= 2:
            out[name] = pose_characteristics(T_commanded[name], np.asarray(T_measured)[sel], orientation).to_dict()
        else:
            out[name] = {"n": int(sel.sum()), "note": "fewer than 2 measurements"}
    return out


def measurement_joints(model, meas, campaign=None) -> np.ndarray:
    """(n, dof) joints of each measurement in the model's order: from the joint columns, or from the
    campaign's test pose named in the ``pose`` column."""
    if meas.joints is not None and len(meas.joint_names):
        try:
            return JointOrder(model.joint_names).rows(meas.joint_names, meas.joints)
        except IngestError as exc:
            raise MeasurementError(f"{meas.source}: joint columns: {exc}") from None
    if campaign is None or meas.pose is None:
        raise ValueError(f"{meas.source}: measurements carry no joints; give a campaign and label each row with "
                         f"its test pose")
    table = dict(zip(campaign.names, campaign.joints_for(model)))
    unknown = sorted({str(p) for p in meas.pose if p not in table})
    if unknown:
        raise ValueError(f"{meas.source}: test pose(s) {unknown} are not in campaign {campaign.name!r} "
                         f"({campaign.names})")
    return np.array([table[p] for p in meas.pose])
