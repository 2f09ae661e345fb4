"""A contact campaign from its file to a calibration: the rows checked as ``report`` checks measurements (joint
limits, the angle unit, a wrong robot), the targets' nominal offsets, ``contact.calibrate_contacts``, and the
``Calibration`` that the calibrated robot file, ``compensate`` and ``validate`` use (registration 'contact': no
tracker, the base frame is the robot's own; the targets are the fitted tool points). SI throughout."""
from __future__ import annotations

import numpy as np

from ..accuracy.checks import LIMIT_MARGIN, CheckError
from ..targets import Targets
from ..models.base import Mechanism
from ..conformity import PLAUSIBLE_LENGTH, implausible
from .contact import (AUTO, PLANE, ContactData, calibrate_contacts, initial_rig, not_converged_words, target_points,
                      validate_contacts)
from .elastic import ElasticJoints
from .result import Calibration, nominal_fingerprint

UNIT_SLIP_SHARE = 0.5      # beyond this share of rows outside the joint limits, the unit is wrong, not the rows
PLAUSIBLE_SPREAD = 50.0    # a plane's contacts farther from it than this many times the fit's noise: not this robot
RADIANS_AS_DEGREES = np.radians(np.pi) * (1 + 1e-9)   # rad: the largest radian number read as degrees
RENAMED = 2.0              # contacts of another id this close to a plane (times its own contacts' RMS): the same plane


def contact_data(model: Mechanism, contacts, offsets: dict) -> tuple:
    """(ContactData, (K, 3) nominal offsets, warnings) of the rows of ``contacts`` (``io.contact_csv.Contacts``)
    for ``model``: rows with a joint outside its limits are left out and said; CheckError (bad input) when most
    are (the angle unit), when a target has no nominal offset in ``offsets`` {name: (3,) m}, or when a plane or
    point is touched too few times to be fitted."""
    q = model.check_joints(contacts.joints)
    beyond = _beyond_limits(model, q)
    out = beyond.any(axis=1)
    src = contacts.source
    if out.mean() > UNIT_SLIP_SHARE:
        revolute = [j for j in range(model.dof) if model.joint_types[j] != "prismatic"]
        qq = q.copy()
        qq[:, revolute] *= np.pi / 180.0
        hint = (" (the joint values look like degrees labelled radians: read in degrees they are within)"
                if revolute and not _beyond_limits(model, qq).any(axis=1).mean() > UNIT_SLIP_SHARE else
                " (another robot, or joints in another unit?)")
        raise CheckError(f"{src}: {int(out.sum())} of {len(q)} rows have a joint outside the limits of robot "
                         f"{model.name!r}{hint}")
    warnings = []
    for i in np.flatnonzero(out):
        j = int(np.argmax(beyond[i]))
        warnings.append(f"left out before the fit: {contacts.where(i)}: joint {model.joint_names[j]} = {q[i, j]:.6g} "
                        f"lies beyond its limits [{model.joint_limits[j, 0]:.6g}, {model.joint_limits[j, 1]:.6g}] of "
                        f"{model.name!r}")
    others, other_names = _other_joints(model, contacts)
    ignored = [j for j in contacts.ignored if j not in other_names]
    if ignored:
        warnings.append(f"joint column(s) of joints outside the chain, ignored: {', '.join(ignored)}")
    keep = ~out
    names = list(dict.fromkeys(str(t) for t in contacts.target[keep]))
    missing = [t for t in names if t not in offsets]
    if missing:
        raise CheckError(f"{src}: target(s) {missing} have no nominal place on the tool: give --target NAME=X,Y,Z "
                         f"(e.g. {missing[0]}=0mm,0mm,120mm) or --target NAME=link:LINK")
    keys = list(dict.fromkeys((str(s), *str(c).split(":", 1)) for s, c in zip(contacts.session[keep],
                                                                            contacts.contact[keep])))
    index = {k: i for i, k in enumerate(keys)}
    constraint = np.array([index[(str(s), *str(c).split(":", 1))] for s, c in zip(contacts.session[keep],
                                                                                  contacts.contact[keep])], int)
    target = np.array([names.index(str(t)) for t in contacts.target[keep]], int)
    labels = np.asarray(contacts.pose[keep], dtype=object)
    data = ContactData(q[keep], target, constraint, keys, tuple(names),
                       labels if any(str(v) for v in labels) else None,
                       [contacts.where(i) for i in np.flatnonzero(keep)], contacts.stamps[keep],
                       None if others is None else others[keep], other_names)
    for c, (s, kind, i) in enumerate(keys):
        count = int(np.sum(constraint == c))
        if kind == PLANE and count < 3:
            raise CheckError(f"{src}: plane:{i} (session {s}) has {count} contact(s); a plane needs 3 or more, spread "
                             f"over it")
    nominal = np.array([offsets[t] for t in names], float).reshape(-1, 3)
    renamed = renamed_constraint(model, data, nominal)
    if renamed:
        raise CheckError(f"{src}: {renamed}")
    return data, nominal, warnings


def _other_joints(model: Mechanism, contacts) -> tuple:
    """((n, m) readings or None, names) of the contact rows' joints outside the chain that the robot's URDF has (the
    rest of its posture, which loads its joints)."""
    pm = getattr(model, "pin_model", None)
    values = getattr(contacts, "others", None)
    if pm is None or values is None:
        return None, ()
    keep = [i for i, n in enumerate(contacts.other_names) if pm.existJointName(str(n))]
    if not keep:
        return None, ()
    return np.asarray(values, float)[:, keep], tuple(contacts.other_names[i] for i in keep)


def renamed_constraint(model: Mechanism, data: ContactData, offsets) -> str | None:
    """Why two ids of one session name one plane or point (None when none do): the contacts of one id fall between
    those of another in the file (the id changed mid-session) and lie on the other's plane (or at its point), with
    the nominal robot, as closely as the other's own contacts do (``RENAMED`` times their RMS). Contact sees one
    surface per plane: coplanar surfaces are one plane, and a plane fitted to a few renamed contacts only absorbs
    them."""
    try:
        rig = initial_rig(model, data, offsets)
    except ValueError:
        return None
    P = target_points(model, data.q, data.target, offsets)
    rows = np.arange(len(data))
    for c1, (s1, k1, i1) in enumerate(data.constraints):
        in1 = rows[data.constraint == c1]
        if len(in1) < 2:
            continue
        if k1 == PLANE:
            def off(sel):
                return P[sel] @ rig.normals[c1] - rig.d[c1]
        else:
            def off(sel):
                return np.linalg.norm(P[sel] - rig.points[c1], axis=1)
        own = float(np.sqrt(np.mean(off(in1) ** 2)))
        for c2, (s2, k2, i2) in enumerate(data.constraints):
            in2 = rows[data.constraint == c2]
            if c2 == c1 or s2 != s1 or k2 != k1 or not len(in2) or len(in2) > len(in1):
                continue
            if not (in1.min() < in2.min() and in2.max() < in1.max()):
                continue
            there = float(np.sqrt(np.mean(off(in2) ** 2)))
            if there <= RENAMED * max(own, 1e-9):
                lines = [data.where[i] for i in in2] if data.where is not None else [f"row {i}" for i in in2]
                return (f"{k2}:{i2} ({len(in2)} contact(s): {', '.join(lines[:5])}{', ...' if len(lines) > 5 else ''}) "
                        f"falls between the contacts of {k1}:{i1} of session {s1!r} and lies on it ({there * 1e3:.4g} mm "
                        f"RMS off it, its own contacts {own * 1e3:.4g} mm): one {k1} under two ids, the id changed "
                        f"mid-session? give them one id (contact sees coplanar surfaces as one plane)")
    return None


def _beyond_limits(model: Mechanism, q) -> np.ndarray:
    """(n, dof) joints beyond their limits by more than ``checks.LIMIT_MARGIN`` (a joint read at its stop, a few
    encoder counts past the URDF's limit, is a reading of this robot, as ``checks.screen`` judges it)."""
    wrapped = model.within_turn(np.atleast_2d(q))
    return (wrapped < model.joint_limits[:, 0] - LIMIT_MARGIN) | (wrapped > model.joint_limits[:, 1] + LIMIT_MARGIN)


def refuse_implausible(model: Mechanism, data: ContactData, offsets):
    """CheckError when the contacts cannot be this robot's: every revolute joint reads within +-pi degrees (the
    numbers of radians read as degrees: ``RADIANS_AS_DEGREES``) and the same numbers read as radians move the robot
    within its limits; the nominal robot (its rig fitted) puts them farther off their planes and points than
    ``PLAUSIBLE_LENGTH`` of its reach, or ten times farther than it does with the revolute joints read in the other
    angle unit (degrees labelled radians, or the reverse), as a share of how far the contacts spread."""
    def misfit(q):
        d = data if q is data.q else ContactData(q, data.target, data.constraint, data.constraints, data.target_names)
        try:
            rig = initial_rig(model, d, offsets)
        except ValueError:
            return np.inf
        P = target_points(model, q, data.target, offsets)
        sq = []
        for c, (s, kind, i) in enumerate(data.constraints):
            sel = data.constraint == c
            e = P[sel] @ rig.normals[c] - rig.d[c] if kind == PLANE else np.linalg.norm(P[sel] - rig.points[c], axis=1)
            sq.append(e ** 2)
        return float(np.sqrt(np.mean(np.concatenate(sq)))) if sq else 0.0

    def relative(q):
        """The misfit as a share of how far the contacts spread: a robot that hardly moves fits any plane."""
        P = target_points(model, q, data.target, offsets)
        spread = float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1))))
        return misfit(q) / spread if spread > 0 else np.inf
    try:
        initial_rig(model, data, offsets)
    except ValueError as exc:
        raise CheckError(f"{exc}") from None
    rms = misfit(data.q)
    revolute = [j for j in range(model.dof) if model.joint_types[j] != "prismatic"]
    if revolute and len(data) > 1:
        top = float(np.abs(data.q[:, revolute]).max())
        q = data.q.copy()
        q[:, revolute] *= 180.0 / np.pi
        if top <= RADIANS_AS_DEGREES and not _beyond_limits(model, q).any() and np.ptp(q[:, revolute]) > 10 * top:
            raise CheckError(f"units: every revolute joint reads within +-{np.degrees(top):.4g} degrees, as if its "
                             f"numbers, all within +-pi, were radians labelled degrees (read as radians they span "
                             f"{np.ptp(q[:, revolute]):.3g} rad within the limits): check the unit of the joint columns")
    for factor, said in ((180.0 / np.pi, "radians labelled degrees"), (np.pi / 180.0, "degrees labelled radians")):
        q = data.q.copy()
        q[:, revolute] *= factor
        if revolute and not model.out_of_limits(q).any() and relative(q) * 10 < relative(data.q):
            raise CheckError(f"units: the nominal robot puts the contacts {rms * 1e3:.4g} mm RMS off their planes and "
                             f"points, {misfit(q) * 1e3:.4g} mm with the joints read in the other angle unit: the joint "
                             f"values look like {said}")
    limit = PLAUSIBLE_LENGTH * model.reach()
    if rms > limit:
        raise CheckError(f"the nominal robot puts the contacts {rms * 1e3:.4g} mm RMS off their planes and points, more "
                         f"than {PLAUSIBLE_LENGTH * 100:g} % of its reach ({model.reach():.3g} m): not this robot's "
                         f"contacts, or joints in another unit")


def _refuse(model, data, offsets, source):
    """``refuse_implausible``, its CheckError naming the file."""
    try:
        refuse_implausible(model, data, offsets)
    except CheckError as exc:
        raise CheckError(f"{source}: {exc}") from None


def calibration_of(model: Mechanism, data: ContactData, nominal, cc, sources=None) -> Calibration:
    """The ``Calibration`` of a ``contact.ContactCalibration``: the identified errors with their uncertainties, the
    fitted targets as the tool points, registration 'contact', and the contact figures (``contact`` in ``sources``
    is not used; the rig, the candidates and the validation go in ``model`` and ``validation``)."""
    f = cc.fit
    rig = f.rig
    p = model.n_params
    targets = Targets.from_offsets(list(data.target_names), list(rig.offsets))
    rows = int(np.sum(np.where(data.kind == PLANE, 1, 3)[~f.rejected]))
    held = [n for n in f.held if n in model.param_names]
    held_compliance = [n for n in f.held if n not in model.param_names]
    cal = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), f.dx[:p].copy(),
                      f.std[:p].copy(), np.zeros(6), np.eye(4), None, held, [], {}, float("nan"), f.condition, f.rank,
                      int(p - len(held)), f.noise, float("nan"), float("nan"), len(data),
                      len(set(map(str, data.labels))) if data.labels is not None else len(np.unique(data.q, axis=0)),
                      rows, "contact", sources=dict(sources or {}), targets=targets, targets_std=rig.offsets_std,
                      has_orientation=False)
    elastic = None
    if cc.load is not None:
        cal.compliance, cal.compliance_std, cal.load = f.dx[p:].copy(), f.std[p:].copy(), cc.load.to_dict()
        elastic = {"load": cc.load.describe(), "base_link": getattr(model, "base_link", None),
                   "posture_from": list(data.other_names), "deflection_prior_rad": cc.deflection,
                   "joints": [{"joint": j, "compliance": float(c), "std": float(s), "largest_load": float(g),
                               "deflection_rad": float(c * g), "deflection_std_rad": float(s * g)}
                              for j, c, s, g in zip(model.joint_names, cal.compliance, cal.compliance_std,
                                                    cc.largest_loads)]}
    cal.nominal = nominal_fingerprint(model)
    cal.sources.setdefault("joint_names", list(model.joint_names))
    cal.model = {"parameters": cc.which, "prior": None if cc.prior is None else list(cc.prior), "label": cc.label,
                 "tikhonov": cc.tikhonov, "deflection": cc.deflection, "how": cc.how, "candidates": cc.scores,
                 "held_why": dict(f.held_why), "held_compliance": held_compliance,
                 "rig": rig.to_dict(), "targets_why": dict(f.targets_why),
                 "noise": {"rig_only_m": f.noise_rig, "after_parameters_m": f.noise_robust, "residual_m": f.noise,
                           "given": f.noise_given, "prior_weighed_at_m": f.prior_weight},
                 "nominal_targets": {n: list(map(float, o)) for n, o in zip(data.target_names, nominal)},
                 "nominal_fit_targets": {n: list(map(float, o)) for n, o in zip(data.target_names,
                                                                                cc.nominal.rig.offsets)},
                 "undetermined_rig": list(f.undetermined_rig), "rig_held": list(f.rig_held), "elastic": elastic}
    cal.validation = cc.validation
    cal.rejected = list(cc.rejected)
    cal.warnings = list(cc.warnings)
    cal.position_rms = f.rms()
    cal.position_max = float(f.distances[~f.rejected].max())
    cal.convergence = f.convergence.to_dict()
    cal.convergence["words"] = (f.convergence.words() if f.convergence.converged else
                                f"did not converge: {not_converged_words(f.convergence)}")
    cal.convergence["held_judged_at"] = f.held_judged_at
    cal.training = {"joint_ranges": np.c_[data.q.min(axis=0), data.q.max(axis=0)].tolist()}
    reach = model.reach()
    problems = [f"{n}: {why}" for n, why in implausible(cal.names, cal.kinds, cal.dx, reach).items()]
    moved = np.linalg.norm(rig.offsets - nominal, axis=1)
    for name, m in zip(data.target_names, moved):
        if m > PLAUSIBLE_LENGTH * reach:
            problems.append(f"target {name}: fitted {m * 1e3:.4g} mm from its nominal place on the tool, more than "
                            f"{PLAUSIBLE_LENGTH * 100:g} % of the reach (its nominal place wrong, or the contacts)")
    v = cc.validation
    if v["after"]["contact_rms_m"] >= v["before"]["contact_rms_m"]:
        problems.append(f"hold-out validation: the calibrated model does not reduce the contact RMS "
                        f"({v['before']['contact_rms_m'] * 1e3:.4f} mm before, {v['after']['contact_rms_m'] * 1e3:.4f} mm"
                        f" after)")
    cal.plausibility = {"ok": not problems, "problems": problems}
    return cal


def contact_fit(cal: Calibration) -> dict:
    """The ``fit`` block of a contact calibration: the calibration's, its distances named as contact figures (m)."""
    out = cal.fit_dict()
    out.pop("position_rms_m", None)
    out.pop("position_max_m", None)
    out.update(contact_rms_m=cal.position_rms, contact_max_m=cal.position_max, noise_m=cal.sigma)
    return out


def calibrate_campaign(model: Mechanism, contacts, offsets: dict, parameters="auto", prior=None, sigma=None,
                       folds=10, seed=0, robust=True, progress=None, targets=AUTO, target_prior=None) -> Calibration:
    """``calibration_of`` the contact campaign ``contacts`` after the checks of ``contact_data`` and
    ``refuse_implausible`` (CheckError: bad input). ``sigma``: the contact noise (m), None to estimate it from the
    rows; ``targets``, ``target_prior``: see ``contact.fit_contacts``."""
    from .contact import PRIOR
    data, nominal, warnings = contact_data(model, contacts, offsets)
    _refuse(model, data, nominal, contacts.source)
    cc = calibrate_contacts(model, data, nominal, parameters, PRIOR if prior is None else prior, sigma, folds, seed,
                            robust, progress, targets, target_prior)
    cal = calibration_of(model, data, nominal, cc, {"measurements": contacts.source})
    cal.warnings = warnings + cal.warnings
    return cal


def validate_campaign(cal: Calibration, model: Mechanism, contacts, robust=True) -> dict:
    """Score a contact calibration on another campaign or session (``contact.validate_contacts``): its targets
    are the calibration's (by name), only the planes and points of the rows are fitted; 'before' is the nominal
    robot with the targets its own rig-only fit found on the calibration's rows (else the nominal targets)."""
    names = list(cal.targets.names)
    doc = cal.model or {}
    nominal_doc = doc.get("nominal_fit_targets") or doc.get("nominal_targets") or {}
    offsets = {n: o for n, o in zip(names, cal.targets.offsets)}
    data, nominal, warnings = contact_data(model, contacts, offsets)
    fitted = np.array([offsets[t] for t in data.target_names])
    nominal = np.array([nominal_doc.get(t, offsets[t]) for t in data.target_names], float)
    _refuse(model, data, nominal, contacts.source)
    dx, chain = cal.dx, None
    if cal.compliance is not None and np.any(cal.compliance):
        chain = ElasticJoints(model, cal.joint_load(model), data.posture)
        dx = np.r_[cal.dx, cal.compliance]
        fitted_with = (doc.get("elastic") or {}).get("posture_from") or []
        missing = [j for j in fitted_with if j not in data.other_names]
        if missing:
            warnings.append(f"the calibration's compliances were fitted with the rest of the posture recorded; these "
                            f"rows have no column for {len(missing)} of its joints ({', '.join(missing[:6])}"
                            f"{', ...' if len(missing) > 6 else ''}): their loads take those joints at their neutral "
                            f"values (write every joint's column)")
    res = validate_contacts(model, data, dx, fitted, nominal, robust=robust, chain=chain)
    res["measurements"] = len(data)
    res["warnings"] = warnings
    return res
