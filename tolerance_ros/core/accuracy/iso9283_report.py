"""The figures of an ISO 9283 test report from a campaign's measurements (``iso9283_report``), as a plain dict
(SI: m, rad, s): every pose characteristic the data allow, the path characteristics where a stream is given
(``path_report``), the test conditions, and for every other characteristic the data it needs.

- AP, RP per test pose (``evaluation.evaluate_file``, the figures of ``report --campaign``);
- vAP (multi-directional pose accuracy variation) for each test pose the campaign approaches in more than one
  way (``of`` and ``via`` in the campaign: ``plan-campaign --iso9283 --approach``);
- AD, RD (distance accuracy and repeatability) between two test poses (the standard's P2 and P4 by default),
  their visits paired by cycle;
- dAP, dRP (drift) for each test pose whose visits span two windows (1 h by default);
- E (exchangeability) for each test pose measured on every robot given (``others``: other robots of the type);
- static compliance C (m/N) for each test pose visited under loads (the measurements' load columns; the other
  characteristics take the unloaded visits only);
- the path characteristics and the pose stabilisation time and overshoot at each stop of a stream (``path``);
- the path accuracy on reorientation from a 6-DOF tracker's stream (``reorientation.reorientation_report``).

Every report says where its base frame comes from (``frame``): a calibration of the same tracker set-up or a
separate registration measurement (``Frame``), the measuring frame itself ('none', refused where the data are
evidently not in the base frame), or else a fit on the test poses themselves, which makes AP a lower bound and
says so with the count of coordinates the fit absorbed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..identification import base_matrix
from .evaluation import NOT_BASE_FRAME, evaluate_file, measurement_joints, register_measurements
from .iso9283 import distance_characteristics, drift, exchangeability, multidirectional, static_compliance
from .registration import Registration

COMMANDED_TOLERANCE = 1e-6  # m: the approaches of one test pose must command the same position within this
MAX_FORCE = 5e4             # N: beyond any robot's payload (the largest carry about 23 kN): a unit slip
MAX_TORQUE = 5e4            # N m: likewise
CONDITIONS = ("load", "speed", "temperature", "measuring_system", "notes")


class ISOReportError(ValueError):
    """Data that cannot give an ISO 9283 report; the message names what and why."""


@dataclass
class Frame:
    """A base frame found apart from the test poses: ``source`` 'calibration' (``from_calibration``) or 'poses'
    (``from_poses``), its ``registration`` (tracker placement and targets), and ``words`` saying where it comes
    from, for the report."""

    source: str
    registration: Registration
    words: str

    @classmethod
    def from_calibration(cls, T_tracker_base, base, targets, name) -> "Frame":
        """The frame of a calibration made with the same tracker set-up: its placement ``T_tracker_base`` (4x4) and
        base correction ``base`` (6,) (the robot's base frame as the calibration found it), its ``targets``."""
        T = np.asarray(T_tracker_base, float) @ base_matrix(np.asarray(base, float))
        return cls("calibration", Registration(T, targets, np.zeros(1), 0),
                   f"the tracker placement and base correction of the calibration {name} (the same tracker set-up): the "
                   f"robot's base frame as that calibration found it, joint 1's axis and zero position; an offset of "
                   f"the mounting along or about joint 1's axis, which no kinematic calibration can tell from the "
                   f"robot's own errors, is not in AP")

    @classmethod
    def from_poses(cls, model, meas, campaign=None) -> "Frame":
        """The frame fitted on a separate registration measurement ``meas`` (the standard's base-frame measurement, or
        another campaign: joint columns, or rows named by ``campaign``'s poses); ISOReportError where it is the test
        poses themselves (every pose it measures is one of ``campaign``'s)."""
        if len(meas) < 3:
            raise ISOReportError(f"{meas.source}: {len(meas)} measurement(s); a registration needs 3 or more poses")
        try:
            q = measurement_joints(model, meas, campaign)
        except ValueError as exc:
            raise ISOReportError(f"registration poses: {exc}") from None
        if campaign is not None:
            tests = campaign.joints_for(model)
            apart = np.min(np.abs(q[:, None, :] - tests[None]).max(axis=2), axis=1) > 1e-6
            if not apart.any():
                raise ISOReportError(f"{meas.source}: every pose of the registration measurement is a test pose of "
                                     f"campaign {campaign.name!r}; a frame fitted on the test poses absorbs AP (measure "
                                     f"other poses, or give --registration-from a calibration)")
        names = meas.target_names
        reg = register_measurements(model.fk(q), meas, meas.target_index(names), names,
                                    "base" if len(names) == 1 else "base+tool")
        poses = len(np.unique(np.round(q, 6), axis=0))
        return cls("poses", reg, f"fitted on {len(meas)} measurement(s) of {poses} pose(s) apart from the test poses "
                                 f"({meas.source}; residual RMS {reg.rms * 1e3:.4g} mm)")


@dataclass
class ISOOptions:
    """What the report computes: ``distance`` the two test poses of AD/RD (None: P2 and P4 where the campaign
    has them), ``drift_window`` (s), ``registration`` ('base': fitted on the test poses, or 'none': the data in the
    base frame already), unless ``frame`` (a ``Frame`` found apart from them) is given, ``conditions`` the test
    conditions the standard asks to state (free text by key of ``CONDITIONS``)."""

    distance: tuple | None = None
    drift_window: float = 3600.0
    registration: str = "base"
    conditions: dict = field(default_factory=dict)
    frame: Frame | None = None

    @property
    def registering(self):
        """What ``evaluate_file`` registers with: the frame's Registration, or 'base' / 'none'."""
        return self.frame.registration if self.frame is not None else self.registration


def _pose_data(model, meas, campaign, registration) -> tuple:
    """(evaluate_file's result, attained (n, 4, 4) base frame, pose names (n,), stamps (n,), cycles (n,),
    commanded {name: 4x4}) of one robot's measurements."""
    if len(meas.target_names) > 1:
        raise ISOReportError(f"{meas.source}: {len(meas.target_names)} targets ({', '.join(meas.target_names)}); an "
                             f"ISO 9283 report takes one target (the tool frame or one reflector)")
    if meas.pose is None or not any(str(p) for p in meas.pose):
        raise ISOReportError(f"{meas.source}: no pose column; the ISO 9283 characteristics need each row named by its "
                             f"test pose")
    res = evaluate_file(model, meas, None, campaign, registration=registration, identification=False)
    if isinstance(registration, str) and registration == "none":
        wrong = [w for w in res.get("warnings", []) if w.startswith(NOT_BASE_FRAME)]
        if wrong:
            raise ISOReportError(f"{meas.source}: --registration none: {wrong[0]}")
    rows = res["rows"]
    names = np.array([str(p) for p in rows["pose"]], dtype=object)
    cyc = rows["visit_cycle"] if rows["visit_cycle"] is not None else np.full(len(names), -1)
    # the one target's keys (``name@target`` where it is named: a reflector's) by test pose name
    suffix = f"@{meas.target_names[0]}" if meas.target_names and meas.target_names[0] else ""
    res["per_pose"] = {_pose_of(k, suffix): v for k, v in res.get("per_pose", {}).items()}
    commanded = {_pose_of(k, suffix): v for k, v in rows["commanded"].items()}
    return res, rows["attained"], names, np.asarray(rows["stamp"], float), np.asarray(cyc), commanded


def _pose_of(key: str, suffix: str) -> str:
    return key[:-len(suffix)] if suffix and key.endswith(suffix) else key


def _pairs(names, cycles, a, b) -> tuple:
    """(rows of a, rows of b) of the visits of test poses a and b paired by cycle (when every visit has one),
    else in their order."""
    ia, ib = np.flatnonzero(names == a), np.flatnonzero(names == b)
    if (cycles[ia] >= 0).all() and (cycles[ib] >= 0).all():
        ca, first_a = np.unique(cycles[ia], return_index=True)     # each cycle's first visit
        cb, first_b = np.unique(cycles[ib], return_index=True)
        _, ka, kb = np.intersect1d(ca, cb, return_indices=True)
        return ia[first_a[ka]], ib[first_b[kb]]
    n = min(len(ia), len(ib))
    return ia[:n], ib[:n]


def iso9283_report(model, meas, campaign, options: ISOOptions | None = None, others=(), path=None,
                   reorientation=None) -> dict:
    """The ISO 9283 figures of ``meas`` (see the module docstring); ``others``: measurements of the same campaign
    on other robots of the type (exchangeability); ``path``: a ``path_report`` result to include;
    ``reorientation``: (stamps, frames (n, 4, 4) tracker frame, joint stamps, joints, latency s, source) of a 6-DOF
    tracker's stream along a reorientation, judged in the campaign's registration. ``meas`` None: a stream alone,
    the path figures and every pose characteristic named missing. Keys: robot,
    source, campaign, orientation_measured, conditions, pose (AP/RP per test pose), multidirectional, distance,
    drift, exchangeability, compliance, path, missing [{characteristic, needs}], warnings."""
    options = options or ISOOptions()
    if meas is None:
        return _stream_only(model, options, path, reorientation)
    if campaign is None:
        raise ISOReportError("an ISO 9283 report needs the campaign (its test poses and approaches)")
    loaded = meas.loaded
    if loaded.all():
        raise ISOReportError(f"{meas.source}: every row is under load; the pose characteristics and the compliance "
                             f"need the unloaded visits too")
    res, T, names, stamps, cycles, commanded = _pose_data(model, meas.select(~loaded), campaign, options.registering)
    ori = bool(res["orientation_measured"])
    missing, warnings = [], list(res.get("warnings", []))
    frame = _frame(options, res, names, ori)
    out = {"robot": model.name, "source": meas.source, "campaign": campaign.name, "measurements": len(meas),
           "under_load": int(loaded.sum()), "frame": frame,
           "orientation_measured": ori, "registration": {k: res["registration"][k] for k in ("method", "residual_rms_m")
                                                         if k in res["registration"]},
           "conditions": _conditions(options, campaign, names, stamps),
           "pose": {k: v for k, v in res.get("per_pose", {}).items() if v.get("n", 0) >= 2},
           "left_out": res.get("left_out", [])}
    out["multidirectional"] = _multidirectional(campaign, commanded, T, names, ori, missing)
    out["distance"] = _distance(options, campaign, commanded, T, names, cycles, ori, missing)
    out["drift"] = _drift(options, campaign, commanded, T, names, stamps, ori, missing)
    out["exchangeability"] = _exchangeability(model, campaign, options, T, names, others, missing, warnings, meas)
    out["compliance"] = _compliance(meas, res, campaign, missing)
    out["path"] = path
    out["reorientation"] = None
    if reorientation is None:
        missing.append({"characteristic": "path accuracy on reorientation",
                        "needs": "a 6-DOF tracker's stream along a reorientation (plan-campaign --path reorient; "
                                 "--reorientation with --reorientation-joints and --latency)"})
    else:
        from .reorientation import reorientation_report
        t, Tr, tj, qj, latency, source = reorientation
        T_tb = np.asarray(res["registration"]["T_tracker_base"], float)
        try:
            out["reorientation"] = reorientation_report(model, t, Tr, tj, qj, T_tb, latency, source=source)
        except ValueError as exc:
            raise ISOReportError(f"{source}: {exc}") from None
    _path_missing(path, missing)
    out["missing"] = missing
    out["warnings"] = warnings
    return out


POSE_NEEDS = "the campaign and its measurements (--campaign, --measurements: the test poses visited in cycles)"


def _stream_only(model, options, path, reorientation) -> dict:
    """The report of a stream alone (no campaign measured): the path figures; every pose characteristic missing."""
    if path is None:
        raise ISOReportError("nothing to report: give the campaign and its measurements (--campaign, --measurements), "
                             "or a stream (--stream)")
    if reorientation is not None:
        raise ISOReportError("--reorientation: judged in the campaign's registration, so it needs the campaign and its "
                             "measurements (--campaign, --measurements)")
    reg = path["registration"]
    source, words = ("stream", "fitted on the path stream itself (path-report's registration); no campaign measured"
                     if reg["method"] == "base" else "the measuring frame itself (--registration none)")
    if options.frame is not None:
        source, words = options.frame.source, options.frame.words
    frame = {"source": source, "words": words, "lower_bound": False, "absorbed": None, "coordinates": None,
             "T_tracker_base": reg["T_tracker_base"], "residual_rms_m": reg["residual_rms_m"]}
    missing = [{"characteristic": c, "needs": POSE_NEEDS} for c in (
        "AP, RP (pose accuracy and repeatability)", "vAP (multi-directional pose accuracy variation)",
        "AD, RD (distance accuracy and repeatability)", "dAP, dRP (drift of pose characteristics)",
        "E (exchangeability)", "static compliance", "path accuracy on reorientation")]
    _path_missing(path, missing)
    return {"robot": model.name, "source": path["source"], "campaign": None, "measurements": 0, "under_load": 0,
            "frame": frame, "orientation_measured": False, "registration": {k: reg[k] for k in ("method",
                                                                                               "residual_rms_m")},
            "conditions": _conditions(options, None, np.zeros(0, dtype=object), np.zeros(0)), "pose": {},
            "left_out": [], "multidirectional": {}, "distance": {}, "drift": {}, "exchangeability": {},
            "compliance": {}, "path": path, "reorientation": None, "missing": missing, "warnings": []}


def _path_missing(path, missing):
    """What the path characteristics need that ``path`` (a ``path_report`` result, or None) does not give."""
    if path is None:
        missing.append({"characteristic": "AT, RT, CR, CO, AV, RV, FV (path)",
                        "needs": "the tracker's stream along a test path and the command (--stream with --joint-states "
                                 "or --trajectory)"})
    if path is None or not path.get("weaving"):
        missing.append({"characteristic": "WS, WF (weaving deviations)",
                        "needs": "the tracker's stream along a weaving program (plan-campaign --path weave; --stream)"})
    if path is None or not (path.get("stops") or {}).get("judged"):
        missing.append({"characteristic": "pose stabilisation time, pose overshoot, minimum positioning time",
                        "needs": "the tracker's stream with the robot coming to rest after its motions (--stream; "
                                 "rests of 0.1 s or more; the moves over the distances to time, at full speed)"})


def _frame(options, res, names, ori) -> dict:
    """Where the base frame comes from: {source, words, lower_bound, absorbed, coordinates, T_tracker_base,
    residual_rms_m}. Fitted on the test poses, the registration absorbs 6 of the coordinates of their mean poses
    (3 per test pose, 6 with orientations), so AP and E (each robot registered on its own) are lower bounds; RP,
    vAP, AD_p, RD and the drift do not depend on a fixed frame."""
    reg = res["registration"]
    out = {"T_tracker_base": reg["T_tracker_base"], "residual_rms_m": reg["residual_rms_m"], "lower_bound": False,
           "absorbed": None, "coordinates": None}
    if options.frame is not None:
        return {**out, "source": options.frame.source, "words": options.frame.words}
    if options.registration == "none":
        return {**out, "source": "none", "words": "the measuring frame itself (--registration none): the measurements "
                                                  "are taken as base-frame poses"}
    poses = len({str(n) for n in names})
    coords = poses * (6 if ori else 3)
    words = (f"fitted on the test poses themselves, a lower bound of AP: the fit absorbed 6 of the {coords} "
             f"coordinates of the {poses} test poses' mean {'poses' if ori else 'positions'}, so every AP (and E) here is "
             f"a lower bound of the robot's; RP, vAP, AD_p, RD and the drift do not depend on it. Give "
             f"--registration-from a calibration of the same set-up, or --registration-poses a separate registration "
             f"measurement")
    return {**out, "source": "test poses", "words": words, "lower_bound": True, "absorbed": 6, "coordinates": coords}


def _conditions(options, campaign, names, stamps) -> dict:
    bad = sorted(set(options.conditions) - set(CONDITIONS))
    if bad:
        raise ISOReportError(f"conditions: unknown {bad}; expected {list(CONDITIONS)}")
    out = {k: str(v) for k, v in options.conditions.items() if v}
    if campaign is None:
        return out
    visits = max((int((names == p).sum()) for p in campaign.names), default=0)
    out.update(cycles=visits, dwell_s=campaign.dwell_s, test_poses=len(campaign.names),
               duration_s=float(stamps.max() - stamps.min()) if len(stamps) else 0.0)
    return out


def _multidirectional(campaign, commanded, T, names, ori, missing) -> dict:
    groups = campaign.approaches()
    if not groups:
        missing.append({"characteristic": "vAP (multi-directional pose accuracy variation)",
                        "needs": "a campaign approaching each test pose from several directions (plan-campaign "
                                 "--iso9283 --approach 100mm)"})
        return {}
    out = {}
    for pose, members in groups.items():
        C = [commanded[m] for m in members]
        far = max(np.linalg.norm(c[:3, 3] - C[0][:3, 3]) for c in C)
        if far > COMMANDED_TOLERANCE:
            raise ISOReportError(f"campaign {campaign.name!r}: the approaches of {pose} ({', '.join(members)}) command "
                                 f"positions {far * 1e3:.4g} mm apart; they must command one pose")
        have = {m: T[names == m] for m in members if (names == m).sum() >= 1}
        if len(have) < 2:
            out[pose] = {"note": f"measured from {len(have)} of its {len(members)} approaches"}
            continue
        out[pose] = multidirectional(C[0], have, ori)
    return out


def _distance(options, campaign, commanded, T, names, cycles, ori, missing) -> dict:
    pair = options.distance
    if pair is None:
        pair = ("P2", "P4") if {"P2", "P4"} <= set(campaign.names) else None
    if pair is None:
        missing.append({"characteristic": "AD, RD (distance accuracy and repeatability)",
                        "needs": "two test poses to measure the distance between (--distance P2,P4; the campaign has "
                                 "no P2 and P4)"})
        return {}
    a, b = pair
    unknown = [p for p in pair if p not in campaign.names]
    if unknown:
        raise ISOReportError(f"distance: test pose(s) {unknown} are not in campaign {campaign.name!r} "
                             f"({', '.join(campaign.names[:20])})")
    ia, ib = _pairs(names, cycles, a, b)
    if len(ia) < 2:
        missing.append({"characteristic": "AD, RD (distance accuracy and repeatability)",
                        "needs": f"two or more cycles visiting both {a} and {b} (found {len(ia)})"})
        return {}
    return {"between": [a, b], **distance_characteristics(commanded[a], commanded[b], T[ia], T[ib], ori)}


def _drift(options, campaign, commanded, T, names, stamps, ori, missing) -> dict:
    out = {}
    for pose in campaign.names:
        sel = names == pose
        if sel.sum() < 4:
            continue
        try:
            out[pose] = drift(commanded[pose], stamps[sel], T[sel], options.drift_window, ori)
        except ValueError:
            continue
    if not out:
        span = float(stamps.max() - stamps.min()) if len(stamps) else 0.0
        missing.append({"characteristic": "dAP, dRP (drift of pose characteristics)",
                        "needs": f"visits of a test pose spanning two windows of {options.drift_window:g} s (these "
                                 f"span {span:.6g} s; the standard runs 8 h of cycles; --drift-window sets the "
                                 f"window)"})
    return out


def _compliance(meas, res, campaign, missing) -> dict:
    """Static compliance per test pose: every visit (loaded or not) in the base frame of the unloaded ones'
    registration."""
    loaded = meas.loaded
    if loaded.any():
        _check_loads(meas)
    if not loaded.any():
        missing.append({"characteristic": "static compliance",
                        "needs": "visits measured under known loads at the tool (load:fx, load:fy, load:fz columns, "
                                 "and load:mx, load:my, load:mz for torques; simulate --load 200N --torque 20Nm)"})
        return {}
    T_tb = np.asarray(res["registration"]["T_tracker_base"], float)
    T = np.linalg.inv(T_tb) @ meas.T
    names = np.array([str(p) for p in meas.pose], dtype=object)
    out = {}
    for pose in campaign.names:
        sel = names == pose
        if loaded[sel].any():
            try:
                out[pose] = static_compliance(T[sel], meas.load[sel], bool(meas.has_orientation))
            except ValueError as exc:
                out[pose] = {"note": str(exc)}
    return out


def _check_loads(meas):
    """ISOReportError naming a load no robot test can apply (a unit slip: N labelled kN, N m labelled kN m)."""
    L = np.asarray(meas.load, float)
    for cols, cap, what, unit in ((slice(0, 3), MAX_FORCE, "force", "N"), (slice(3, 6), MAX_TORQUE, "torque", "N m")):
        if L.shape[1] <= cols.start:
            continue
        big = np.linalg.norm(L[:, cols], axis=1)
        if big.max() > cap:
            i = int(np.argmax(big))
            raise ISOReportError(f"{meas.source}: a {what} of {big[i]:.4g} {unit} at the tool ({meas.where(i)}), beyond "
                                 f"any robot's payload ({cap:.0f} {unit}): the load columns' unit cannot be right "
                                 f"({unit} labelled k{unit}?)")


def _same_data(a, b) -> bool:
    """Whether two measurement sets hold the same readings (another copy of one file)."""
    return len(a) == len(b) and np.array_equal(a.T, b.T)


def _exchangeability(model, campaign, options, T, names, others, missing, warnings, first) -> dict:
    if not others:
        missing.append({"characteristic": "E (exchangeability)",
                        "needs": "the same campaign measured on other robots of the type (--other)"})
        return {}
    robots = [(T, names)]
    for k, m in enumerate(others):
        same = [o.source for o in others[:k] if _same_data(o, m)]
        if same or _same_data(m, first):
            raise ISOReportError(f"--other {m.source}: the same measurements as {same[0] if same else first.source}; "
                                 f"exchangeability compares other robots of the type")
        m = m.select(~m.loaded)                                 # the unloaded visits, as for the first robot
        res, To, no, *_ = _pose_data(model, m, campaign, options.registering)
        warnings += [f"{m.source}: {w}" for w in res.get("warnings", [])]
        robots.append((To, no))
    out = {}
    for pose in campaign.names:
        if all((n == pose).any() for _, n in robots):
            bary = [Tr[n == pose][:, :3, 3].mean(axis=0) for Tr, n in robots]
            out[pose] = exchangeability(bary)
    out["sources"] = [m.source for m in others]
    return out
