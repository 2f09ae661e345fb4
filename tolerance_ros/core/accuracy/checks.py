"""Checks before a verdict: what says that measurements cannot be judged against this robot as given.

One home for every path that turns measurements into a verdict -- ``report``, ``validate``, ``calibrate`` and
the accuracy monitor -- so that they cannot drift apart:

- **units**: the measured points must spread like the robot's tool (metres labelled millimetres spread a
  thousand times too little);
- **joint limits**: a row whose joints lie beyond the robot's limits (by ``LIMIT_MARGIN``) is left out and
  listed by its file line; a column beyond them in most rows is refused (degrees labelled radians?);
- **campaign**: the joints measured at a labelled test pose must be the campaign's commanded ones (the
  wrong campaign, with the same pose names, is refused naming the pose); measured poses the campaign does
  not have are listed, never dropped;
- **robust registration**: rows whose registered residual exceeds ``REJECT`` robust standard deviations are
  left out of the registration and listed, so that one bad row moves nothing else;
- **the residual**: a registered residual RMS beyond ``PLAUSIBLE_RESIDUAL`` of the robot's reach is not a
  robot error but a slip; its cause is looked for (a target off the tool frame, a joint column in the wrong
  angle unit) and named, else "another robot, or units?", against the repeat scatter where poses repeat.

Every refusal is a ``CheckError`` (a ``MeasurementError``: exit 2 on the command line) whose message names
the cause and the way out. SI throughout; every RMS is of the 3-D position error.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .io import MeasurementError
from .registration import Registration, register, spread_ratio

PLAUSIBLE_SPREAD = (0.5, 2.0)  # measured over nominal spread of the points: outside, the length unit is wrong
MIN_SPREAD = 1e-3              # m: nominal points spread less than this tell no length unit
PLAUSIBLE_RESIDUAL = 0.02      # a registered residual RMS beyond this share of the reach is a slip, not an error
LIMIT_MARGIN = 0.01            # rad or m: a joint this far beyond its limit is not a reading of this robot
LIMIT_COLUMN = 0.25            # a joint beyond its limits in more than this share of the rows: the column is wrong
CAMPAIGN_TOLERANCE = 0.01      # rad or m: a labelled pose's measured joints this far from the campaign's
EXPLAINS = 5.0                 # a cause that divides the residual by this much (and makes it plausible) explains it
CHI3_MEDIAN = 1.5382           # median of |e| for e ~ N(0, I3)
REJECT = 4.594                 # |e| / sigma beyond which a registration residual is an outlier (chi2_3, 0.9999)
MAX_REJECTED = 0.25            # at most this share of the rows is left out of a registration


class CheckError(MeasurementError):
    """Measurements that cannot be judged against the robot as given; the message names why and what to try."""


def units_problem(model, q, points) -> str | None:
    """Why the measured points (n, 3) cannot be in the units claimed (their spread against the robot's tool at
    joints q: the length unit, or the joints' angle unit when reading them in the other one explains it), or
    None."""
    q = np.asarray(q, float)
    nominal = model.fk(q)[:, :3, 3]
    if len(q) < 3 or np.sqrt(np.mean(np.sum((nominal - nominal.mean(axis=0)) ** 2, axis=1))) < MIN_SPREAD:
        return None                           # the tool hardly moves: no spread to judge the unit by
    ratio = spread_ratio(nominal, points)
    lo, hi = PLAUSIBLE_SPREAD
    if lo <= ratio <= hi:
        return None
    revolute = [j for j in range(model.dof) if model.joint_types[j] != "prismatic"]
    for factor, said in ((180.0 / np.pi, "radians labelled degrees"), (np.pi / 180.0, "degrees labelled radians")):
        qq = q.copy()
        qq[:, revolute] *= factor
        if revolute and lo <= spread_ratio(model.fk(qq)[:, :3, 3], points) <= hi:
            return (f"units: the measured points spread {ratio:.4g} times as far as the robot's tool moves at the "
                    f"joints as given, and as far as it moves when the joints are read in the other angle unit: the "
                    f"joint values look like {said}")
    hint = " (metres labelled millimetres?)" if ratio < 0.01 else " (millimetres labelled metres?)" if ratio > 100 \
        else ""
    return (f"units: the measured points spread {ratio:.4g} times as far as the robot's tool moves; the length unit "
            f"of the measurements cannot be right{hint}")


ORIENTATION_MIN_TURN = 0.01   # rad: the tool must turn this much between two measurements for their turn to count


def _turns(R) -> np.ndarray:
    """(n - 1,) angle (rad) of the rotation between consecutive rotations of ``R`` (n, 3, 3)."""
    rel = R[1:] @ np.transpose(R[:-1], (0, 2, 1))
    return np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))


ORIENTATION_MISMATCH = 0.1   # rad: a turn seen this far from the tool's (median over the pairs) is no robot error


def orientation_problem(model, q, R, T_meas=None) -> str | None:
    """Why measured orientations (n, 3, 3) cannot be in the angle unit claimed, or None: from one measurement to
    the next they must turn as the robot's tool turns at the same joints (an angle no fixed frame on either side
    changes), over the pairs where the tool turns ``ORIENTATION_MIN_TURN`` or more. Their medians must agree within
    ``PLAUSIBLE_SPREAD`` (radians labelled degrees turn 57 times too little), and each pair's turn must match the
    tool's within ``ORIENTATION_MISMATCH`` at the median (degrees labelled radians turn at random, as far as the
    tool on average over widely spread poses). None also where the tool hardly turns, and where the measured
    points of ``T_meas`` (n, 4, 4), registered with the targets' offsets, fit no better than the orientations
    (another robot's data: ``diagnose`` names it)."""
    T_tool = model.fk(np.asarray(q, float))
    tool = _turns(T_tool[:, :3, :3])
    seen = _turns(np.asarray(R, float))
    moving = tool >= ORIENTATION_MIN_TURN
    if np.count_nonzero(moving) < 3:
        return None
    ratio = float(np.median(seen[moving]) / np.median(tool[moving]))
    mismatch = float(np.median(np.abs(seen[moving] - tool[moving])))
    lo, hi = PLAUSIBLE_SPREAD
    if lo <= ratio <= hi and mismatch <= ORIENTATION_MISMATCH:
        return None
    if lo <= ratio <= hi:
        if T_meas is not None and not _points_fit(model, T_tool, T_meas):
            return None
        return (f"units: from one measurement to the next the measured orientations turn by angles unrelated to the "
                f"robot's tool's (median difference {mismatch:.3g} rad over {np.count_nonzero(moving)} pairs, "
                f"although about as far on the whole); the orientation columns cannot be right (degrees labelled "
                f"radians, or another angle convention?)")
    hint = (" (radians labelled degrees?)" if ratio < 0.1 else
            " (milliradians labelled radians, or degrees labelled radians?)" if ratio > 5 else "")
    return (f"units: from one measurement to the next the measured orientations turn {ratio:.4g} times as far as the "
            f"robot's tool does; the angle unit of the orientation columns cannot be right{hint}")


def registered_orientation_problem(R_base, R_nominal) -> str | None:
    """Why measured orientations (n, 3, 3), registered into the base frame, cannot be in the angle unit claimed,
    or None: at the median they lie more than ``ORIENTATION_MISMATCH`` from the robot's nominal ones (n, 3, 3), far
    beyond any robot's error. Catches what ``orientation_problem`` cannot see where the tool hardly turns between
    measurements (an ISO cube's poses share one orientation)."""
    from ..geometry import rotation_error
    off = np.linalg.norm(rotation_error(np.asarray(R_base, float), np.asarray(R_nominal, float)), axis=1)
    median = float(np.median(off)) if len(off) else 0.0
    if median <= ORIENTATION_MISMATCH:
        return None
    return (f"units: after the registration the measured orientations lie {median:.3g} rad (median) from the robot's, "
            f"beyond any robot's error; the orientation columns cannot be right (degrees labelled radians, or another "
            f"angle convention?)")


def _points_fit(model, T_tool, T_meas) -> bool:
    """Whether the measured points fit the tool's, registered with one target's offset (orientations ignored),
    within ``PLAUSIBLE_RESIDUAL`` of the reach."""
    try:
        reg = register(T_tool, T_meas, tool=True)
    except (ValueError, np.linalg.LinAlgError):
        return True
    return _rms(reg.residuals) <= PLAUSIBLE_RESIDUAL * model.reach()


def refuse_implausible(model, q, T_meas, idx, names, registration="base", frames=False, robust=True) -> list:
    """CheckError when measurements cannot be this robot's, as ``report`` judges them: their orientations'
    unit (``orientation_problem``), then the nominal model robustly registered onto them, its residual against
    the robot's size (``diagnose``: another robot, swapped columns, a joint column in the other angle unit);
    else the hints (a target offset). What ``calibrate`` and ``validate`` ask before any fit."""
    q = np.asarray(q, float)
    if frames:
        problem = orientation_problem(model, q, np.asarray(T_meas)[:, :3, :3], np.asarray(T_meas))
        if problem:
            raise CheckError(problem)
    if len(q) < 3:
        return []
    tool = registration == "base+tool"
    reg, out, _ = robust_register(model.fk(q), T_meas, idx, names, tool, frames, robust)
    refused, hints = diagnose(model, q, T_meas, idx, names, "base+tool" if tool else "base", frames, reg, ~out)
    if refused:
        raise CheckError(refused)
    return hints


def unused_joint_columns(model, names, joints) -> tuple:
    """(warning or None, note or None) on the joint columns ``names`` of a file (``joints`` (n, k) beside) that
    are not joints of the model's chain, so unused: a warning for those whose joints move links past the tip
    link and move over the file (the measured point moves with joints the chain does not have: a tip link
    short of the measured point), a note for the others."""
    extra = [str(n) for n in names if str(n) not in model.joint_names]
    if not extra:
        return None, None
    beyond = set(model.beyond_tip(extra)) if hasattr(model, "beyond_tip") else set()
    J = np.asarray(joints, float) if joints is not None else np.zeros((0, len(names)))
    col = {str(n): k for k, n in enumerate(names)}
    span = {n: float(np.ptp(J[:, col[n]])) if len(J) else 0.0 for n in extra}
    moving = [n for n in extra if n in beyond and span[n] > LIMIT_MARGIN * 0.1]
    chain = f"{model.name}" + (f" (from {model.base_link!r} to {model.tip_link!r})" if hasattr(model, "tip_link")
                               else "")
    warning = note = None
    if moving:
        warning = (f"joint column(s) {', '.join(moving)} move links past the tip link {model.tip_link!r} and vary "
                   f"over the file (by up to {max(span[n] for n in moving):.4g} rad or m), but are not in the chain "
                   f"of {chain}: unused, although the measured point moves with them; is --tip-link right?")
    rest = [n for n in extra if n not in moving]
    if rest:
        note = (f"joint column(s) {', '.join(rest[:10])}" + (f" and {len(rest) - 10} more" if len(rest) > 10 else "")
                + f" are not joints of the chain of {chain}: unused")
    return warning, note


def likely(problem: str, beyond: str | None) -> str:
    """A refusal's text, led by the unused joint columns past the tip (``unused_joint_columns``' warning) when
    there are any: a tip link short of the measured point explains points and orientations that do not follow
    the chain's tip."""
    return f"{beyond} ({problem})" if beyond else problem


@dataclass
class Screened:
    """Rows of a campaign that can be judged: ``keep`` (n,) mask; ``left_out`` [{row, where, reason}];
    ``notes`` what the user should know that leaves nothing out (poses the campaign does not have,
    ``unknown_poses``)."""

    keep: np.ndarray
    left_out: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    unknown_poses: list = field(default_factory=list)

    def leave_out(self, rows, reason_of, where):
        for i in np.flatnonzero(rows & self.keep):
            self.left_out.append({"row": int(i), "where": where(i), "reason": reason_of(i)})
        self.keep &= ~rows


def screen(model, q, meas=None, campaign=None, labels=None) -> Screened:
    """The rows of joints q (n, dof) that can be judged (see the module docstring): joint limits, and, with a
    campaign and pose labels, the measured joints against the campaign's. CheckError for a joint column out
    of range in most rows, or for a labelled pose whose joints are not the campaign's."""
    q = np.asarray(q, float)
    n = len(q)
    out = Screened(np.ones(n, bool))
    lo, hi = model.joint_limits[:, 0] - LIMIT_MARGIN, model.joint_limits[:, 1] + LIMIT_MARGIN
    wrapped = model.within_turn(q)
    beyond = (wrapped < lo) | (wrapped > hi)
    for j in np.flatnonzero(beyond.mean(axis=0) > LIMIT_COLUMN) if n else []:
        unit = "m" if model.joint_types[j] == "prismatic" else "rad"
        top = float(np.abs(q[:, j]).max())
        cause = ("degrees labelled radians?" if unit == "rad" and top > 2 * np.pi + 0.1 else
                 "millimetres labelled metres?" if unit == "m" and top > 10 else
                 "another robot, or the wrong column?")
        raise CheckError(f"joint {model.joint_names[j]}: {int(beyond[:, j].sum())} of {n} values lie beyond its "
                         f"limits [{model.joint_limits[j, 0]:.4g}, {model.joint_limits[j, 1]:.4g}] {unit} "
                         f"(e.g. {q[np.argmax(beyond[:, j]), j]:.4g}): {cause}")

    def limit_reason(i):
        j = int(np.argmax(beyond[i]))
        return (f"joint {model.joint_names[j]} = {q[i, j]:.6g} lies beyond its limits [{model.joint_limits[j, 0]:.6g}, "
                f"{model.joint_limits[j, 1]:.6g}]")
    out.leave_out(beyond.any(axis=1), limit_reason, lambda i: _where(meas, i))
    if campaign is not None and labels is not None:
        _check_campaign(model, q, np.asarray(labels, dtype=object), campaign, out, meas)
    return out


def _where(meas, i):
    return meas.where(i) if meas is not None else f"row {int(i)}"


def unknown_poses_text(unknown, campaign_name, labels) -> str:
    """'pose(s) C1, C2 are not in campaign X' (the first ten), or, when none of the measured poses is in it,
    that the campaign is not the one measured."""
    shown = ", ".join(unknown[:10]) + (f" and {len(unknown) - 10} more" if len(unknown) > 10 else "")
    if len(unknown) == len({str(p) for p in labels}):
        return (f"none of the {len(unknown)} poses measured ({shown}) is in campaign {campaign_name!r}: the wrong "
                f"campaign?")
    return f"pose(s) {shown} are not in campaign {campaign_name!r}"


def _check_campaign(model, q, labels, campaign, out, meas):
    table = dict(zip(campaign.names, campaign.joints_for(model)))
    named = np.array([bool(str(p)) for p in labels])
    unknown = sorted({str(p) for p in labels[named] if str(p) not in table})
    if unknown:
        out.unknown_poses = unknown
        out.notes.append(f"{unknown_poses_text(unknown, campaign.name, labels[named])}: their measurements are "
                         f"judged without a test pose (no ISO 9283 figures)")
    bad = []
    for name in table:
        sel = np.flatnonzero((labels == name) & out.keep)
        if not len(sel):
            continue
        d = np.abs(model.within_turn(q[sel] - table[name]))   # a continuous joint's a turn away is the same
        i, j = np.unravel_index(np.argmax(d), d.shape)
        if d[i, j] > CAMPAIGN_TOLERANCE:
            bad.append((name, model.joint_names[j], float(q[sel[i], j]), float(table[name][j]), sel[i]))
    if bad:
        name, joint, seen, commanded, row = bad[0]
        where = _where(meas, row)
        raise CheckError(f"campaign {campaign.name!r}: the joints measured at pose {name} ({where}) are not its "
                         f"commanded ones ({joint} = {seen:.6g} measured, {commanded:.6g} commanded)"
                         + (f"; {len(bad) - 1} more pose(s) differ" if len(bad) > 1 else "")
                         + ": the wrong campaign, or the wrong measurements?")


def outliers(r, reference, floor: float) -> tuple:
    """(rows of ``r`` (n,) m beyond the threshold, the threshold m): ``REJECT`` robust standard deviations of the
    residuals of the ``reference`` rows (a mask; their median over ``CHI3_MEDIAN``), never below ``floor`` m; at
    most ``MAX_REJECTED`` of the rows, the largest. The one rule of every robust fit (registration, calibration)."""
    n = len(r)
    sigma = np.median(r[reference]) / CHI3_MEDIAN
    threshold = REJECT * max(sigma, floor)
    new = r > threshold
    cap = int(MAX_REJECTED * n)
    if new.sum() > cap:
        new = np.zeros(n, bool)
        if cap:
            new[np.argsort(r)[-cap:]] = True
    return new, float(threshold)


def robust_register(T_tool, T_meas, idx, names, tool=False, frames=False, robust=True, targets=None):
    """(Registration on the kept rows, (n,) rows left out, threshold m): register, leave out the rows whose
    residual exceeds ``REJECT`` robust standard deviations (the median residual over that of a 3-D normal
    error; at most ``MAX_REJECTED`` of them), register again, until the set is stable. ``targets``: known
    target frames (only the tracker is fitted). The registration's residuals are those of every row."""
    n = len(T_tool)
    out = np.zeros(n, bool)
    threshold = np.inf
    kw = dict(tool=tool, frames=frames) if targets is None else dict(targets=targets)
    for _ in range(8):
        keep = ~out
        reg = register(T_tool[keep], T_meas[keep], index=idx[keep], names=names, **kw)
        r = _residuals(reg, T_tool, T_meas, idx)
        if not robust or n < 6:
            break
        new, threshold = outliers(r, keep, 1e-9)
        if np.array_equal(new, out):
            break
        out = new
    reg = Registration(reg.T_tracker_base, reg.targets, _residuals(reg, T_tool, T_meas, idx), n, reg.estimated)
    return reg, out, float(threshold)


# base+tool is chosen when its held-out RMS is lower than base's by more than this share: a target's fitted offset
# also takes up the tool-side errors of the robot (the last link's length and offset, a few per cent of the RMS on
# a reflector at the flange), which then no identification sees; a reflector off the flange gains far more
REGISTRATION_PARSIMONY = 0.10
REGISTRATION_FOLDS = 10


def choose_registration(T_tool, T_meas, idx, names, groups, frames=False, folds=REGISTRATION_FOLDS, seed=0,
                        robust=True) -> dict:
    """The registration the data choose, cross-validated by test pose as the calibration's parameters are: the
    nominal tool frames ``T_tool`` (n, 4, 4) registered onto the readings ``T_meas`` (n, 4, 4) by ``base`` (the
    tracker alone: each target at the tool frame) and by ``base+tool`` (and each target's offset on the tool),
    each fold's poses (``groups`` (n,), seeded) predicted by a robust registration without them; ``base+tool``
    when its held-out position RMS is lower than ``base``'s by more than ``REGISTRATION_PARSIMONY``, or when
    there are several targets (``base`` cannot place them). {"chosen", "how", "candidates": [{"registration",
    "cv_position_rms_m"} or {"registration", "error"}], "folds"}. Every RMS is of the 3-D position error."""
    from .folds import folds_of
    idx = np.asarray(idx, int)
    out = {"chosen": "base", "candidates": [], "folds": 0}
    if len(names) > 1:
        out.update(chosen="base+tool", how=f"{len(names)} targets: only base+tool places them")
        return out
    groups = np.asarray(groups, int)
    if len(np.unique(groups)) < 3:
        out["how"] = "fewer than 3 test poses: nothing to cross-validate, the tracker alone (base)"
        return out
    fold, k = folds_of(groups, folds, seed)
    out["folds"] = k
    for method in ("base", "base+tool"):
        sq, count = 0.0, 0
        try:
            for f in range(k):
                train, test = fold != f, fold == f
                reg, _, _ = robust_register(T_tool[train], T_meas[train], idx[train], names, method == "base+tool",
                                            frames, robust)
                r = _residuals(reg, T_tool[test], T_meas[test], idx[test])
                sq, count = sq + float(np.sum(r ** 2)), count + int(r.size)
        except (ValueError, np.linalg.LinAlgError) as exc:
            out["candidates"].append({"registration": method, "error": str(exc)})
            continue
        out["candidates"].append({"registration": method, "cv_position_rms_m": float(np.sqrt(sq / count))})
    rms = {c["registration"]: c.get("cv_position_rms_m") for c in out["candidates"]}
    if rms.get("base") is None and rms.get("base+tool") is not None:
        out["chosen"] = "base+tool"
    elif rms.get("base+tool") is not None and rms["base+tool"] < (1 - REGISTRATION_PARSIMONY) * rms["base"]:
        out["chosen"] = "base+tool"
    out["how"] = (f"chosen by the lower held-out position RMS of the nominal robot's registration ({k}-fold by test "
                  f"pose; base unless base+tool is lower by more than {REGISTRATION_PARSIMONY * 100:g} %)")
    return out


def registration_words(choice: dict) -> str:
    """'registration base+tool chosen (held-out RMS 0.052 mm against base 41.3 mm)' for a person."""
    cands = [c for c in choice.get("candidates", []) if "cv_position_rms_m" in c]
    figures = ", ".join(f"{c['registration']} {c['cv_position_rms_m'] * 1e3:.4g} mm" for c in cands)
    return (f"registration '{choice['chosen']}' chosen from the data" +
            (f" (held-out position RMS of the nominal robot: {figures})" if figures else f" ({choice['how']})"))


def _residuals(reg, T_tool, T_meas, idx) -> np.ndarray:
    """(n,) distance of each measured point from the registered model's, m."""
    P = reg.targets.poses(T_tool, idx)[:, :3, 3]
    A = reg.T_tracker_base
    return np.linalg.norm(P @ A[:3, :3].T + A[:3, 3] - np.asarray(T_meas)[:, :3, 3], axis=1)


def repeat_scatter(points, groups, idx=None) -> float | None:
    """RMS distance (m, 3-D) of a repeated measured point (``points`` (n, 3)) from its pose's mean, over the
    poses (``groups`` (n,), and target ``idx``) visited twice or more; None without repeats."""
    groups = np.asarray(groups)
    key = groups.astype(str).astype(object) + "@" + (np.zeros(len(groups), int) if idx is None else
                                                     np.asarray(idx)).astype(str).astype(object)
    sq, count = 0.0, 0
    for k in np.unique(key):
        sel = key == k
        if sel.sum() >= 2:
            d = points[sel] - points[sel].mean(axis=0)
            sq += float(np.sum(d ** 2))
            count += int(sel.sum()) - 1
    return float(np.sqrt(sq / count)) if count else None


def _rms(r) -> float:
    return float(np.sqrt(np.mean(np.asarray(r) ** 2))) if len(r) else float("nan")


def diagnose(model, q, T_meas, idx, names, registration, frames, reg, keep=None, scatter=None):
    """(refusal text or None, hints): is the registered residual of ``reg`` (every row, ``keep`` the rows
    judged) plausible for this robot? Beyond ``PLAUSIBLE_RESIDUAL`` of the reach it is refused, with the
    cause found among: a target off the tool frame (registration 'base+tool' explains it), a joint column in
    the wrong angle unit (read as radians it explains it), else another robot or units. Below it, a target
    offset that 'base+tool' would explain is a hint."""
    q = np.asarray(q, float)
    keep = np.ones(len(q), bool) if keep is None else np.asarray(keep, bool)
    rms = _rms(reg.residuals[keep])
    reach = model.reach()
    limit = PLAUSIBLE_RESIDUAL * reach
    against = f" against a repeat scatter of {scatter * 1e3:.3g} mm" if scatter is not None else ""

    def refit(qq, tool):
        T_tool = model.fk(qq[keep])
        try:
            r, _, _ = robust_register(T_tool, T_meas[keep], idx[keep], names, tool=tool, frames=frames)
        except ValueError:
            return np.inf
        return _rms(r.residuals)

    tool_rms = refit(q, True) if registration == "base" and len(q) >= 6 else np.inf
    offset = tool_rms * EXPLAINS <= rms
    if rms <= limit:
        hints = []
        if offset and (scatter is None or rms > 10 * scatter):
            hints.append(f"a target offset? the registered residual {rms * 1e3:.4g} mm{against} falls to "
                         f"{tool_rms * 1e3:.4g} mm with --registration base+tool (the targets' offsets on the tool "
                         f"fitted); the verdicts may blame the robot for it")
        return None, hints
    head = (f"the registered residual RMS is {rms * 1e3:.4g} mm{against}, {rms / reach * 100:.3g} % of the robot's "
            f"reach ({reach:.3g} m): these measurements cannot be judged against {model.name} as given")
    if offset and tool_rms <= limit:
        return head + (f"; a target offset? with --registration base+tool (the targets' offsets on the tool fitted) "
                       f"it falls to {tool_rms * 1e3:.4g} mm"), []
    revolute = [j for j in range(model.dof) if model.joint_types[j] != "prismatic"]
    for cols in [revolute] + [[j] for j in revolute]:   # every angle column, then one at a time
        for factor, said in ((180.0 / np.pi, "radians labelled degrees"), (np.pi / 180.0, "degrees labelled radians")):
            qq = q.copy()
            qq[:, cols] *= factor
            r = refit(qq, registration == "base+tool")
            if r * EXPLAINS <= rms and r <= limit:
                which = "every joint" if len(cols) > 1 else f"joint {model.joint_names[cols[0]]}"
                return head + (f"; {which}: the values look like {said} (read so, the residual falls to "
                               f"{r * 1e3:.4g} mm)"), []
    return head + "; another robot, or units? (check the robot file, the joint columns' order and units, and the "\
                  "length unit of the measurements)", []


CHANGED = 2.0  # a campaign predicted this many times worse than the calibration's own held-out figure: a change


def moved_hint(rms, rms_reregistered) -> str | None:
    """A hint that the tracker (or the robot's base) moved, when refitting the tracker's placement alone divides
    the position RMS (m) by ``EXPLAINS`` or more; None otherwise."""
    if rms_reregistered * EXPLAINS <= rms:
        return (f"the tracker (or the robot's base) moved since the calibration? with the tracker refitted "
                f"(--reregister) the position RMS falls from {rms * 1e3:.4g} mm to {rms_reregistered * 1e3:.4g} mm")
    return None


def changed_hint(rms, rms_at_calibration) -> str | None:
    """A warning that the robot changed, when a campaign is predicted ``CHANGED`` times worse (3-D position RMS,
    m) than the calibration's own cross-validated held-out figure; None otherwise."""
    if rms_at_calibration and rms > CHANGED * rms_at_calibration:
        return (f"the robot, its zeroing or the tool may have changed since the calibration: this campaign is "
                f"predicted at {rms * 1e3:.4g} mm RMS, {rms / rms_at_calibration:.3g} times the calibration's own "
                f"held-out {rms_at_calibration * 1e3:.4g} mm; calibrate again")
    return None


class StreamCheck:
    """The checks of a stream of paired measurements (the accuracy monitor): over the last ``window`` of them,
    the measured points must spread like the robot's (``units_problem``'s rule, once the robot has moved
    ``MIN_SPREAD``) and their median error must stay within ``PLAUSIBLE_RESIDUAL`` of the reach. ``add``
    returns the problem in force (text) or None; ``joint_problem`` says why a joint reading cannot be this
    robot's (beyond its limits)."""

    MIN_SAMPLES = 10
    MIN_SPREAD = 0.01  # m: the nominal points spread at least this much before their spread is compared

    def __init__(self, model, window=50):
        from collections import deque
        self.model = model
        self.reach = model.reach()
        self.points = deque(maxlen=window)
        self.problem = None

    def joint_problem(self, q) -> str | None:
        q = np.asarray(q, float).reshape(-1)
        lo, hi = self.model.joint_limits[:, 0] - LIMIT_MARGIN, self.model.joint_limits[:, 1] + LIMIT_MARGIN
        wrapped = self.model.within_turn(q)
        bad = np.flatnonzero((wrapped < lo) | (wrapped > hi))
        if not len(bad):
            return None
        j = bad[0]
        return (f"joint {self.model.joint_names[j]} = {q[j]:.6g} lies beyond its limits "
                f"[{self.model.joint_limits[j, 0]:.6g}, {self.model.joint_limits[j, 1]:.6g}]")

    def add(self, measured, nominal, error) -> str | None:
        """One paired measurement: its measured point (3,) in any fixed frame, the nominal point (3,) in the
        base frame, its position error (m)."""
        self.points.append((np.asarray(measured, float), np.asarray(nominal, float), float(error)))
        if len(self.points) < self.MIN_SAMPLES:
            return self.problem
        M = np.array([p[0] for p in self.points])
        P = np.array([p[1] for p in self.points])
        e = np.median([p[2] for p in self.points])
        problem = None
        if np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1))) >= self.MIN_SPREAD:
            ratio = spread_ratio(P, M)
            lo, hi = PLAUSIBLE_SPREAD
            if not lo <= ratio <= hi:
                hint = " (metres labelled millimetres?)" if ratio < 0.01 else \
                    " (millimetres labelled metres?)" if ratio > 100 else ""
                problem = (f"units: the measured points spread {ratio:.4g} times as far as the robot's tool moves over "
                           f"the last {len(self.points)} measurements{hint}; no verdict is given")
        limit = PLAUSIBLE_RESIDUAL * self.reach
        if problem is None and e > limit:
            problem = (f"the median position error of the last {len(self.points)} measurements is {e * 1e3:.4g} mm, "
                       f"{e / self.reach * 100:.3g} % of the robot's reach ({self.reach:.3g} m): another robot, units, "
                       f"a wrong registration (T_tracker_base) or a target offset the monitor is not given "
                       f"(target_offsets)?; no verdict is given")
        self.problem = problem
        return problem
