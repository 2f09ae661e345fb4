"""A path report from two streams: the tracker's points and the commanded joints.

0. The streams as logged (``streams.tidy``): repeated stamps kept once, rows out of order sorted, a clock that
   jumps or starts again cut into epochs laid end to end (``streams.Timeline``); each said in ``streams``.
1. The command path: the nominal tool point of the commanded joints at their stamps (``model.fk``); joint
   states sparser than ``MAX_COMMAND_INTERVAL`` (a static campaign) are not a path.
2. Time alignment: the tracker's latency against the joint states (``latency.estimate_latency``), unless
   given; of any size (a coarse search over the streams' whole overlap, ``latency.coarse_offset``, then the
   fine one about it) unless a window is given; its points are then taken at ``stamp - latency``.
3. Registration: the tracker's placement by Kabsch over every point paired at the aligned stamps
   (``base``), or none (``none``: the points are in the base frame).
4. Cycles and segments: the motions between rests (``path.motions``) cut into the repetitions of the command
   and at its cusps (``repeats.split_runs``: a program that loops without a stop, a line driven back and
   forth), or at a trajectory file's period; the test path is the most frequent (``path.cycles_of``), cut at
   its corners (``path.corners``, or the trajectory's knots) into segments; the ISO 9283 figures
   (``path.path_characteristics``).
5. Checks before any figure (``checks``): the length and angle units of the streams, joint states beyond the
   limits, a registered residual beyond 2 % of the robot's reach: refused with the cause (ValueError).
6. With a budget: its predicted bound (its criterion) at every station of the first cycle, the tube the
   barycentres should stay in, and two verdicts: the path accuracy against the design limit, and the
   latency's uncertainty against it (refused when ``2 u(tau) v_max`` exceeds ``LATENCY_SHARE`` of the limit:
   the time alignment alone could then move the path by that much).

Nothing measured is dropped silently: the points outside the test path's cycles are counted by why (the
robot at rest, another motion, a cycle not judged, outside the joint states' time span, left out as a
repeated stamp). A cycle with a gap in its joint states or in the tracker's points across it
(``ingest.StampGaps``: messages lost, or never sent) is not judged, its reason in ``not_judged``:
interpolated across the gap, its figures would be wrong. SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import path as P
from ..ingest import StampGaps
from .latency import FINE_WINDOW_S, coarse_offset, estimate_latency
from .repeats import split_runs
from .settling import stops
from .weaving import weaving
from .streams import Timeline, tidy
from .checks import PLAUSIBLE_RESIDUAL, units_problem
from .registration import kabsch
from ..targets import at_point

LATENCY_SHARE = 0.1   # of the design limit: the most the latency's uncertainty (2 u x speed) may move the path


def command_points(model, joints, chunk: int = 100_000, offset=None) -> np.ndarray:
    """(k, 3) nominal points (m) of joints (k, dof): the tool point, or the point ``offset`` (3,) m of the tool
    frame (a target's)."""
    target = at_point(model, offset)
    out = np.empty((len(joints), 3))
    for i in range(0, len(joints), chunk):
        out[i:i + chunk] = target.fk(joints[i:i + chunk])[:, :3, 3]
    return out


def _cycles(t_c, p_c, ta, a, runs, picked):
    out = []
    for k in picked:
        i0, i1 = runs[k]
        j0, j1 = np.searchsorted(ta, [t_c[i0], t_c[i1]], side="left")
        tc, pc = t_c[i0:i1 + 1], p_c[i0:i1 + 1]
        out.append(P.Cycle(tc, pc, P.arc_length(pc), ta[j0:j1], a[j0:j1]))
    return out


@dataclass
class PathOptions:
    """How ``path_report`` judges two streams. ``registration``: 'base' (fit the tracker's placement) or 'none'
    (base-frame points); ``T_tracker_base`` (4, 4): the placement, given instead. ``latency`` (s): given instead
    of estimated; ``window`` (s): the estimate looked for within ``center +- window`` only (None: any size, a
    coarse search over the two streams' whole overlap first). ``stations`` per segment, ``speed_window`` (s) of
    the speeds, ``rest_speed`` (m/s) and ``step`` (s) of the motions (``path.motions``). ``offset`` (3,) m: the
    tracked target on the tool frame (None: its origin); along a path of constant orientation (the standard's)
    an offset is a translation the registration absorbs, elsewhere it must be given. ``trajectory``
    (``iso_paths.JointPath``): the program the joint states follow (their stamps its run time), whose period
    cuts the cycles and whose knots place the corners. ``reverse``: judge the motion that drives the test path
    backwards (a line's return strokes) instead. ``band`` (m) and ``smooth`` (s): the stabilisation band and the
    points' smoothing of the stabilisation time and overshoot at each stop (``settling.stops``)."""

    registration: str = "base"
    latency: float | None = None
    window: float | None = None
    center: float = 0.0
    stations: int = 100
    speed_window: float = 0.01
    rest_speed: float = 1e-3
    T_tracker_base: object = None
    step: float | None = None
    offset: object = None
    trajectory: object = None
    reverse: bool = False
    band: float = 1e-4
    smooth: float = 0.04


MAX_COMMAND_INTERVAL = 0.1   # s: joint states further apart than this (median) do not sample a path
MIN_CYCLE_POINTS = 10        # tracker points a cycle needs to be judged


def path_report(model, stamps, points, joint_stamps, joints, budget=None, options: PathOptions | None = None,
                source: str = "") -> dict:
    """The path report (a JSON-ready dict, SI) of the tracker's ``points`` (n, 3) m stamped ``stamps`` (n,) s
    against the commanded ``joints`` (k, dof) stamped ``joint_stamps`` (k,) s, both as logged: repeated stamps,
    rows out of order and a clock that jumps are put in order and said (``streams.tidy``). ValueError when they
    cannot be judged (the cause in its message)."""
    o = options or PathOptions()
    tm, pm = np.asarray(stamps, float), np.asarray(points, float)
    tj, qj = np.asarray(joint_stamps, float), np.asarray(joints, float)
    if o.registration not in ("base", "none"):
        raise ValueError(f"registration: expected base or none, got {o.registration!r}")
    if pm.ndim != 2 or pm.shape[1] != 3 or len(pm) != len(tm):
        raise ValueError(f"points: expected (n, 3) with n stamps, got {pm.shape} and {tm.shape}")
    if len(tj) < 3 or qj.shape != (len(tj), model.dof):
        raise ValueError(f"joint states: expected (k >= 3, {model.dof}) joints with k stamps, got {qj.shape}")
    offset = None
    if o.offset is not None:
        offset = np.asarray(o.offset, float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f"offset: expected 3 finite lengths in m, got {offset.tolist()}")
    tidied = {"joint_states": tidy(tj, qj, "joint states"), "points": tidy(tm, pm, "tracker points")}
    line = Timeline(tidied["joint_states"], tj, tidied["points"], tm)
    n_points = len(tm)
    tj, qj, tm, pm = line.tj, qj[line.ij], line.tm, pm[line.im]
    if len(tm) == 0:
        raise ValueError("no tracker point lies within the joint states' time span: the two streams do not overlap")
    interval = float(np.median(np.diff(tj))) if len(tj) > 1 else np.inf
    if interval > MAX_COMMAND_INTERVAL:
        raise ValueError(f"not a path: the joint states are {interval:.3g} s apart (median), too sparse to sample a "
                         f"motion (a static campaign's measurements? judge those with `report`)")
    p_c = command_points(model, qj, offset=offset)
    reg = o.registration == "base"
    step = o.step
    runs = _within_epochs(P.motions(tj, p_c, o.rest_speed, step=step), line.joint_slices)
    jp = o.trajectory
    runs, how = split_runs(tj, p_c, runs, step if step is not None else interval,
                           None if jp is None else jp.period, None if jp is None else 0.0)
    picked, others = P.cycles_of(p_c, runs, reverse=o.reverse)
    if not picked:
        raise ValueError("the command never moves: no path to judge (joint states at rest)")
    _check(model, tm, pm, tj, qj, line.covered(tm))
    latency, window, center = o.latency, o.window, o.center
    if latency is None and (window is None or jp is not None):
        # a latency of any size (and a trajectory's run time against the tracker's clock, always): the coarse
        # search first, on the clock of the epoch with the most points
        k = int(np.argmax([s.stop - s.start for s in line.point_slices]))
        js, ps = line.joint_slices[k], line.point_slices[k]
        center = coarse_offset(tm[ps], pm[ps], tj[js], p_c[js])
        window = window or FINE_WINDOW_S
    tm_c = tm - center                      # the tracker's stamps about aligned (before the latency is known)
    gaps = {"joint_states": StampGaps(), "points": StampGaps()}
    for name, t, slices in (("joint_states", tj, line.joint_slices), ("points", tm, line.point_slices)):
        for sl in slices:                   # each epoch on its own: no gap across a cut
            gaps[name].add(t[sl])
            gaps[name].cut()
    spans = {k: np.searchsorted(tm_c, [tj[runs[k][0]], tj[runs[k][1]]]) for k in picked}   # each cycle's points
    holes = {}
    for k in picked:
        why = P.hole_in_motion(gaps, tj, runs[k][0], runs[k][1], tm, int(spans[k][0]), int(spans[k][1]))
        if why is None and spans[k][1] - spans[k][0] < MIN_CYCLE_POINTS:
            why = (f"the motion from {line.original(tj[runs[k][0]]):.3f} s to {line.original(tj[runs[k][1]]):.3f} s "
                   f"(joint states' clock) was not judged: {spans[k][1] - spans[k][0]} tracker point(s) along it (the "
                   f"tracker was not recording, or its clock jumped)")
        if why is not None:
            holes[k] = why
    if len(holes) == len(picked):
        raise ValueError(f"every cycle of the path has a gap in its streams: {holes[picked[0]]}")
    picked = [k for k in picked if k not in holes]
    groups = [np.arange(*spans[k]) for k in picked]
    i0, i1 = runs[picked[0]]
    s_ref = P.arc_length(p_c[i0:i1 + 1])
    corner_s = P.corners(p_c[i0:i1 + 1]) if jp is None else \
        trajectory_corners(model, jp, tj[i0:i1 + 1], s_ref, offset)
    bounds = P.segment_bounds(s_ref[-1], corner_s)
    cuts = bounds if len(bounds) > 2 else np.linspace(0.0, bounds[-1], 5)   # one segment: its quarters
    parts = [[] for _ in range(len(cuts) - 1)]
    for k in picked:
        a, b = runs[k]
        s_k = P.arc_length(p_c[a:b + 1])
        t_b = np.interp(cuts * s_k[-1] / cuts[-1], s_k, tj[a:b + 1])
        for j in range(len(cuts) - 1):
            parts[j].append(np.arange(*np.searchsorted(tm_c, [t_b[j], t_b[j + 1]])))
    parts = [np.concatenate(p) for p in parts]
    if latency is None:
        lat = estimate_latency(tm, pm, tj, p_c, window, center, reg, groups, parts, line.covered,
                               geometry=error_columns(model, tj, qj, offset))
        tau, lat_doc = lat.latency_s, dict(lat.to_dict(), center_s=center, coarse=o.window is None)
    else:
        tau, lat_doc = float(latency), {"latency_s": float(latency), "std_s": 0.0, "given": True}
    registration = "given" if o.T_tracker_base is not None else o.registration

    def aligned(tau):
        """(stamps on the command's clock, covered, R, t, points in the base frame, residual RMS) at ``tau``."""
        ta = tm - tau
        inside = line.covered(ta)
        if not inside.any():
            raise ValueError("no tracker point lies within the joint states' time span: the two streams do not "
                             "overlap")
        pc_a = P.interp_columns(ta[inside], tj, p_c)
        if o.T_tracker_base is not None:
            R, t = np.asarray(o.T_tracker_base, float)[:3, :3], np.asarray(o.T_tracker_base, float)[:3, 3]
        elif reg:
            R, t, _ = kabsch(pc_a, pm[inside])
        else:
            R, t = np.eye(3), np.zeros(3)
        a = (pm - t) @ R                  # base frame
        return ta, inside, R, t, a, float(np.sqrt(np.mean(np.sum((pc_a - a[inside]) ** 2, axis=1))))

    def at_p(tau) -> float:
        """The overall AT_p (m) were the latency ``tau``."""
        ta, _, _, _, a, _ = aligned(tau)
        return P.overall(P.path_characteristics(_cycles(tj, p_c, ta, a, runs, picked), bounds, o.stations,
                                                o.speed_window))["AT_p_m"]
    ta, inside, R, t, a, rms = aligned(tau)
    reach = model.reach()
    if rms > PLAUSIBLE_RESIDUAL * reach:
        raise ValueError(f"the registered residual RMS is {rms * 1e3:.4g} mm, {rms / reach * 100:.3g} % of the robot's "
                         f"reach ({reach:.3g} m): these streams cannot be judged against {model.name} as given "
                         f"(another robot, the wrong joint states, or points not in the base frame with "
                         f"--registration none?)")
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    cycles = _cycles(tj, p_c, ta, a, runs, picked)
    ref = cycles[0]
    segs = P.path_characteristics(cycles, bounds, o.stations, o.speed_window)
    in_cycle = np.zeros(len(tm), bool)
    in_other = np.zeros(len(tm), bool)
    in_hole = np.zeros(len(tm), bool)
    for k, (i0, i1) in enumerate(runs):
        j0, j1 = np.searchsorted(ta, [tj[i0], tj[i1]])
        (in_cycle if k in picked else in_hole if k in holes else in_other)[j0:j1] = True
    in_hole &= ~in_cycle
    in_other &= ~(in_cycle | in_hole)
    left_out = n_points - len(tm) - line.outside
    outside = {"points": int(n_points - in_cycle.sum()),
               "at_rest": int((inside & ~in_cycle & ~in_other & ~in_hole).sum()),
               "other_motions": int(in_other.sum()), "not_judged": int(in_hole.sum()),
               "outside_joint_states": int((~inside).sum()) + line.outside, "left_out": int(left_out)}
    v_max = max(s["v_c_m_s"] for s in segs)
    doc = {"robot": model.name, "source": source, "points": n_points, "joint_states": len(joint_stamps),
           "latency_s": tau, "latency_std_s": lat_doc["std_s"], "latency": lat_doc,
           "registration": {"method": registration, "T_tracker_base": T.tolist(),
                            "residual_rms_m": rms},
           "target_offset_m": None if offset is None else offset.tolist(),
           "cycles": len(picked), "cycles_from": how, "other_motions": len(others),
           "path_length_m": float(ref.s[-1]), "speed_m_s": v_max, "segments": segs, "overall": P.overall(segs),
           "outside": outside, "stations_per_segment": o.stations, "budget": None, "refused": None, "missed": [],
           "streams": {name: td.summary() for name, td in tidied.items()},
           "stream_gaps": {name: g.summary() for name, g in gaps.items()}, "not_judged": list(holes.values()),
           "stops": stops(ta, a, tj, p_c, runs, o.band, o.smooth), "weaving": weaving(cycles)}
    if budget is not None:
        _judge(doc, model, budget, ref, tj, qj, v_max, offset, None if latency is not None else at_p)
    return doc


def error_columns(model, tj, qj, offset=None):
    """times (n,) s -> (n, 3, p): the position error of the tool point (or the target ``offset``) per parameter of
    ``model`` at the joints commanded then (interpolated in the joint states ``tj``, ``qj``)."""
    target = at_point(model, offset)

    def columns(t):
        return target.fk_and_jacobian(P.interp_columns(np.asarray(t, float), tj, qj))[1].position
    return columns


def _within_epochs(runs, slices) -> list:
    """The motions ``runs`` [(i0, i1)] cut where an epoch of the joint states ends: no motion spans a cut."""
    ends = np.array([s.stop for s in slices[:-1]], int)
    out = []
    for a, b in runs:
        for e in ends[(ends > a) & (ends <= b)]:
            if e - 1 > a:
                out.append((a, int(e - 1)))
            a = int(e)
        if b > a:
            out.append((a, b))
    return out


def trajectory_corners(model, jp, t_ref, s_ref, offset=None, angle: float = P.CORNER_ANGLE) -> np.ndarray:
    """(k,) arc lengths (m, along the cycle sampled at ``t_ref`` with arc lengths ``s_ref``) of the corners of a
    trajectory's tool path: its knots (FK of the program's joints) where the chords before and after turn
    by more than ``angle`` rad, the knots being exact points of the path."""
    t0, t1 = float(t_ref[0]), float(t_ref[-1])
    k0 = int(np.floor(t0 / jp.period))
    near = range(max(k0 - 1, 0), min(k0 + 2, jp.cycles))     # the cycles about the one sampled
    knots_t, first = np.unique(np.concatenate([k * jp.period + jp.t for k in near]), return_index=True)
    knots_q = np.concatenate([jp.q for _ in near])[first]
    sel = (knots_t >= t0) & (knots_t <= t1)
    if np.count_nonzero(sel) < 3:
        return np.zeros(0)
    kt = knots_t[sel]
    kp = command_points(model, knots_q[sel], offset=offset)
    chord = np.diff(kp, axis=0)
    length = np.linalg.norm(chord, axis=1)
    moving = length > 1e-9
    kt, kp = np.concatenate([kt[:-1][moving], kt[-1:]]), np.concatenate([kp[:-1][moving], kp[-1:]])
    chord = np.diff(kp, axis=0)
    u = chord / np.linalg.norm(chord, axis=1)[:, None]
    turn = np.einsum("ij,ij->i", u[:-1], u[1:]) < np.cos(angle)
    return np.interp(kt[1:-1][turn], t_ref, s_ref)


def _check(model, tm, pm, tj, qj, covered, sample: int = 2000):
    """ValueError when the streams cannot be in the units they claim (``checks.units_problem`` on tracker
    points paired by stamp) or when most joint states lie beyond the joint limits (another robot)."""
    lo, hi = model.joint_limits[:, 0] - 0.01, model.joint_limits[:, 1] + 0.01
    wrapped = model.within_turn(qj)
    out = (wrapped < lo) | (wrapped > hi)
    if out.any(axis=1).mean() > 0.5:
        j = int(np.argmax(out.sum(axis=0)))
        revolute = np.array([t != "prismatic" for t in model.joint_types])
        q_deg = np.where(revolute, qj * np.pi / 180.0, qj)
        hint = ("the values fit the limits read as degrees: degrees labelled radians?"
                if not ((q_deg < lo) | (q_deg > hi)).any(axis=1).mean() > 0.5 else "another robot, or another unit?")
        raise ValueError(f"joint states: {int(out[:, j].sum())} of {len(qj)} values of {model.joint_names[j]} lie beyond "
                         f"its limits [{model.joint_limits[j, 0]:.4g}, {model.joint_limits[j, 1]:.4g}]: {hint}")
    sel = np.flatnonzero(covered)
    sel = sel[np.linspace(0, len(sel) - 1, min(sample, len(sel))).astype(int)] if len(sel) else sel
    if len(sel) >= 3:
        q = P.interp_columns(tm[sel], tj, qj)
        problem = units_problem(model, q, pm[sel])
        if problem:
            raise ValueError(problem)


def _judge(doc, model, budget, ref, tj, qj, v_max, offset=None, at_p=None):
    """The bound tube along the first cycle's stations (at the target) and the verdicts against the budget
    (into ``doc``). A latency too uncertain for the limit (2 x its uncertainty x the speed over ``LATENCY_SHARE``
    of it) refuses the verdict, unless ``at_p`` (the overall AT_p at another latency) gives the same verdict at
    both ends of its interval (+-2 uncertainties)."""
    from ..errors import criterion_bound
    delta = budget.vector_for(model)
    target = at_point(model, offset)
    for seg in doc["segments"]:
        sig = np.asarray(seg["along"]["s_m"])
        ts = np.interp(sig, ref.s, ref.t)
        q = P.interp_columns(ts, tj, qj)
        b = criterion_bound(target.error_jacobian(q).position, delta, budget.criterion)
        seg["along"]["bound_m"] = b.tolist()
        seg["bound_max_m"] = float(b.max())
        seg["stations_outside_bound"] = int(np.sum(np.asarray(seg["along"]["AT_m"]) > b))
    limit = budget.limit_position
    doc["budget"] = {"criterion": budget.criterion, "limit_position_m": limit,
                     "bound_max_m": max(s["bound_max_m"] for s in doc["segments"]),
                     "stations_outside_bound": sum(s["stations_outside_bound"] for s in doc["segments"])}
    if limit is None:
        return
    shift = 2.0 * doc["latency_std_s"] * v_max
    doc["budget"]["latency_shift_m"] = shift
    at = doc["overall"]["AT_p_m"]
    if shift > LATENCY_SHARE * limit and at_p is not None:
        u = doc["latency_std_s"]
        ends = [at_p(doc["latency_s"] - 2 * u), at_p(doc["latency_s"] + 2 * u)]
        doc["budget"]["AT_p_at_latency_interval_m"] = ends
        if len({x > limit for x in ends + [at]}) == 1:       # the same verdict wherever the latency lies in it
            shift = 0.0
    if shift > LATENCY_SHARE * limit:
        doc["refused"] = (f"the latency {doc['latency_s'] * 1e3:.2f} ms is too uncertain for the budget: 2 x its "
                          f"uncertainty {doc['latency_std_s'] * 1e3:.3f} ms x the speed {v_max:.3f} m/s moves the path "
                          f"by {shift * 1e3:.3f} mm, more than {LATENCY_SHARE:.0%} of the {limit * 1e3:.3f} mm limit")
        doc["missed"].append(doc["refused"])
        return
    if at > limit:
        doc["missed"].append(f"path accuracy AT_p {at * 1e3:.4f} mm exceeds the design limit {limit * 1e3:.4f} mm")
