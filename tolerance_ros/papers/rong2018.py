"""Reproduction of Rong, Han, Liu, Qu (2018): error analysis of the metamorphic 3-PUPS manipulator.

Uses the shipped robot ``rong2018_3pups`` (``tolerance_ros.core.models.pups`` documents the frames,
the 27 error sources and the completion of the paper's three projected equations to a 6 x 27 G) and
the campaign ``rong2018_pe`` (Table 2). Published numbers are transcribed in the paper's units (mm,
deg) and converted to SI; every function returns plain dicts and arrays, lengths in m, angles in rad.

- ``fig3_study``: the paper's Fig. 3 sweep of |da_1|, |db_1|, |dl_1| and the salience of the source
  groups, with the check of its conclusion (da and db dominate, dl is weak).
- ``grades``: tolerance allocation for this robot mapped to ISO 286 grades of the six fits of Table 1.
- ``table3``: mean pose error per test pose (Table 3) with ISO 9283 AP and RP, next to the paper's.
- ``generate_example_measurements`` / ``write_measurements_csv``: the simulated 30-cycle campaign
  shipped as ``config/data/rong2018_pe_measurements.csv``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core import analysis
from ..core.accuracy.io import Measurements, read_csv, write_csv
from ..core.accuracy.iso9283 import pose_characteristics
from ..core.accuracy.simulate import as_built_errors, measure
from ..core.campaign import load_campaign
from ..core.errors import rss_bound, worst_case_bound
from ..core.geometry import rotation_error
from ..core.iso286 import coarsest_grade, it_tolerance
from ..core.models import load_robot
from ..core.models.pups import GROUPS
from ..core.resources import config_dir
from ..core.synthesis import allocate, build_problem
from ..render import plots
from ..render.text import Progress, table

ROBOT = "rong2018_3pups"
CAMPAIGN = "rong2018_pe"
EXAMPLE_CSV = "rong2018_pe_measurements.csv"
EXAMPLE_SEED = 2018
DEG = np.pi / 180.0

# Table 2: X, Y, Z (mm), alpha, beta, gamma (deg).
PUBLISHED_TABLE2 = {"PE1": (0, 0, 1300, 0, 0, 0), "PE2": (500, 500, 1200, 15, 15, 35),
                    "PE3": (-500, -500, 1200, -15, -15, -35), "PE4": (500, -500, 1200, 15, 15, 35),
                    "PE5": (-500, 500, 1200, -15, -15, -35), "PE6": (0, 0, 1500, 10, 10, -30)}
# Table 3 as printed: dX, dY, dZ (mm), dalpha, dbeta, dgamma (deg); all printed values are positive.
PUBLISHED_TABLE3_MM_DEG = {"PE1": (0.006, 0.010, 0.005, 0.018, 0.016, 0.011),
                           "PE2": (0.018, 0.020, 0.016, 0.021, 0.026, 0.031),
                           "PE3": (0.036, 0.032, 0.038, 0.040, 0.041, 0.033),
                           "PE4": (0.021, 0.023, 0.019, 0.026, 0.020, 0.030),
                           "PE5": (0.037, 0.032, 0.037, 0.032, 0.040, 0.044),
                           "PE6": (0.010, 0.009, 0.007, 0.010, 0.013, 0.011)}
TABLE3_KEYS = ("dX", "dY", "dZ", "dalpha", "dbeta", "dgamma")
PUBLISHED_TABLE3 = {k: dict(zip(TABLE3_KEYS, np.array(v) * np.array([1e-3] * 3 + [DEG] * 3)))
                    for k, v in PUBLISHED_TABLE3_MM_DEG.items()}
# Abstract and section 4: every position error within 0.005-0.038 mm, every orientation error within 0.010-0.044 deg.
PUBLISHED_RANGES = {"position_m": (0.005e-3, 0.038e-3), "orientation_rad": (0.010 * DEG, 0.044 * DEG)}

# Table 1 fits and the error sources each one sets (component names without the limb number).
FITS = (
    {"fit": "base slider screw shaft - bearing", "size_mm": 10, "paper_grade": 6, "paper_fit": "H6/g5",
     "sources": ("a.x", "a.y", "a.z"), "why": "bearing play of the slider's screw shaft moves the slider, A_i"},
    {"fit": "U-joint cross shaft - bearing", "size_mm": 8, "paper_grade": 6, "paper_fit": "H6/g5",
     "sources": ("b.x", "b.y", "b.z"), "why": "play of the cross shaft offsets the two revolute centres, A_iB_i"},
    {"fit": "sleeve screw shaft - bearing", "size_mm": 12, "paper_grade": 7, "paper_fit": "H7/g6",
     "sources": ("l.z",), "why": "axial play of the leg screw changes the leg length"},
    {"fit": "guide rod - screw-nut guide bearing", "size_mm": 15, "paper_grade": 8, "paper_fit": "H8/f7",
     "sources": ("l.z",), "why": "play of the anti-rotation guide turns the nut on the screw: leg length"},
    {"fit": "telescopic rod - end-cap guide bearing", "size_mm": 30, "paper_grade": 9, "paper_fit": "H9/d9",
     "sources": ("l.x", "l.y"), "why": "radial play of the rod in the sleeve moves its end sideways"},
    {"fit": "spherical joint ball bearing - shaft", "size_mm": 8, "paper_grade": 8, "paper_fit": "H8/f7",
     "sources": ("l.x", "l.y", "l.z"), "why": "play of the sphere centre at the end of the leg"},
)
# Design limits of the allocation: the paper's own accuracy claims (section 4: position errors below
# 0.04 mm, orientation errors below 0.045 deg, "the level of a general industrial robot").
LIMIT_POSITION = 0.04e-3
LIMIT_ORIENTATION = 0.045 * DEG
# Simulated measurement source of the shipped example (1 sigma).
TRACKER_NOISE = {"position_m": 5e-6, "orientation_rad": 2e-5}
JOINT_REPEATABILITY = {"a": 1e-6, "psi": 5e-6, "l": 1e-6}


def _setup(model=None, campaign=None):
    model = load_robot(model or ROBOT)
    campaign = campaign if campaign is not None and not isinstance(campaign, (str, Path)) \
        else load_campaign(campaign or CAMPAIGN, model)
    return model, campaign


def pe_poses(model=None, campaign=None):
    """(names, T (k, 4, 4) commanded poses, q (k, 9) joints by the model's inverse kinematics)."""
    model, campaign = _setup(model, campaign)
    q = campaign.joints_for(model)
    T = np.array([tp.pose if tp.pose is not None else model.fk(tp.joints)[0] for tp in campaign.poses])
    return campaign.names, T, q


def _columns(model, group, limb):
    return model.param_index([f"{group}{limb}.{ax}" for ax in "xyz"])


def _effects(J, model, limb):
    """{convention: {group: (n, 2) [position m/m, orientation rad/m]}} for the sources of one limb."""
    out = {}
    for g in GROUPS:
        B = J[:, :, _columns(model, g, limb)]
        P, O = B[:, :3], B[:, 3:]
        conv = {
            "worst": (np.linalg.norm(P, 2, axis=(1, 2)), np.linalg.norm(O, 2, axis=(1, 2))),
            "rms": (np.linalg.norm(P, axis=(1, 2)) / np.sqrt(3), np.linalg.norm(O, axis=(1, 2)) / np.sqrt(3)),
            "diagonal": (np.linalg.norm(P.sum(axis=2), axis=1) / np.sqrt(3),
                         np.linalg.norm(O.sum(axis=2), axis=1) / np.sqrt(3)),
        }
        for k, ax in enumerate("xyz"):
            conv[ax] = (np.linalg.norm(P[:, :, k], axis=1), np.linalg.norm(O[:, :, k], axis=1))
        for c, (p, o) in conv.items():
            out.setdefault(c, {})[g] = np.stack([p, o], axis=1)
    return out


def fig3_study(model=None, campaign=None, magnitudes=None, limb: int = 1, m: int = 2000, seed: int = 0,
               margin: float = 0.01) -> dict:
    """Fig. 3: platform errors against |da_limb|, |db_limb|, |dl_limb|, and the check of its conclusion.

    magnitudes : (k,) error magnitudes, m (default 0.001 ... 0.01 mm in 10 steps).
    Sweep: at each test pose, each source vector alone, along its worst direction for the position error
    (the top right singular vector of its 3 x 3 position block of G); the loops are re-solved with the
    perturbed geometry (nonlinear) and the linear ``G`` prediction is given beside it. The orientation
    error is that of the same vector.
    Conclusion check under several direction conventions (``conventions``): the paper's claim holds at
    a pose when ``min(effect of da, effect of db) > (1 + margin) * effect of dl`` for the row type.
    Workspace figures use ``m`` poses of ``model.sample_joints(m, seed)``.
    """
    model, campaign = _setup(model, campaign)
    mags = np.linspace(1e-6, 1e-5, 10) if magnitudes is None else np.asarray(magnitudes, dtype=float)
    names, _, q_pe = pe_poses(model, campaign)
    q_ws = model.sample_joints(m, seed)
    J_pe, J_ws = model.error_jacobian(q_pe).J, model.error_jacobian(q_ws).J
    k, s = len(names), len(mags)

    sweep = {}
    T0 = model.fk(q_pe)
    for g in GROUPS:
        cols = _columns(model, g, limb)
        _, _, Vt = np.linalg.svd(J_pe[:, :3, cols])
        v = Vt[:, 0, :]
        dx = np.zeros((k, s, model.n_params))
        dx[:, :, cols] = mags[None, :, None] * v[:, None, :]
        T1 = model.fk(np.repeat(q_pe, s, axis=0), dx.reshape(k * s, -1))
        T0r = np.repeat(T0, s, axis=0)
        dp = np.linalg.norm(T1[:, :3, 3] - T0r[:, :3, 3], axis=1).reshape(k, s)
        dphi = np.linalg.norm(rotation_error(T1[:, :3, :3], T0r[:, :3, :3]),
                              axis=1).reshape(k, s)
        lin = np.einsum("nrc,nc->nr", J_pe[:, :, cols], v)
        sweep[g] = {"direction": v, "position_m": dp, "orientation_rad": dphi,
                    "position_linear_m": np.linalg.norm(lin[:, :3], axis=1)[:, None] * mags,
                    "orientation_linear_rad": np.linalg.norm(lin[:, 3:], axis=1)[:, None] * mags}

    eff_pe, eff_ws = _effects(J_pe, model, limb), _effects(J_ws, model, limb)
    checks = {}
    for conv in eff_pe:
        entry = {}
        for label, eff in (("test_poses", eff_pe[conv]), ("workspace", eff_ws[conv])):
            holds = np.minimum(eff["a"], eff["b"]) > (1.0 + margin) * eff["l"]
            ratio = eff["l"] / np.minimum(eff["a"], eff["b"])
            if label == "test_poses":
                entry[label] = {n: {"position": bool(h[0]), "orientation": bool(h[1]),
                                    "dl_over_min_da_db": [float(r[0]), float(r[1])]}
                                for n, h, r in zip(names, holds, ratio)}
            else:
                entry[label] = {"fraction_holds_position": float(holds[:, 0].mean()),
                                "fraction_holds_orientation": float(holds[:, 1].mean()),
                                "mean_dl_over_min_da_db": [float(ratio[:, 0].mean()), float(ratio[:, 1].mean())]}
        entry["per_unit_at_test_poses"] = {g: {"position_m_per_m": eff_pe[conv][g][:, 0].tolist(),
                                               "orientation_rad_per_m": eff_pe[conv][g][:, 1].tolist()}
                                           for g in GROUPS}
        checks[conv] = entry

    sal = {}
    for rows in ("position", "orientation"):
        sens = analysis.sensitivity(model, q=q_ws, rows=rows)
        d = dict(zip(model.param_names, sens.salience))
        sal[rows] = {"all_limbs": {g: float(sum(v for n, v in d.items() if n[0] == g)) for g in GROUPS},
                     f"limb{limb}": {g: float(sum(d[f"{g}{limb}.{ax}"] for ax in "xyz")) for g in GROUPS},
                     "mu_mean": {n: float(x) for n, x in zip(model.param_names, sens.mu_mean)},
                     "salience": {n: float(x) for n, x in d.items()}}

    worst = eff_ws["worst"]
    spread = max(float(np.max(np.abs(worst[g] - worst["a"]) / worst["a"])) for g in GROUPS)
    ab = float(np.max(np.abs(J_ws[:, :, _columns(model, "a", limb)] - J_ws[:, :, _columns(model, "b", limb)])))
    verdict = {}
    for conv, e in checks.items():
        f = min(e["workspace"]["fraction_holds_position"], e["workspace"]["fraction_holds_orientation"])
        verdict[conv] = "holds" if f >= 0.95 else "fails" if f <= 0.05 else "mixed"
    return {
        "limb": limb, "magnitudes_m": mags, "test_poses": list(names), "workspace_poses": int(len(q_ws)),
        "seed": seed, "margin": margin,
        "sweep": sweep,
        "conventions": {
            "worst": "each source along its own worst direction (largest singular value of its block)",
            "rms": "root mean square over uniformly random directions (Frobenius norm / sqrt 3)",
            "diagonal": "along (1, 1, 1) / sqrt 3 of the source's own frame",
            "x": "along the x axis of the source's own frame (base for a, A_i for b, leg frame B_i for l)",
            "y": "along the y axis of the source's own frame", "z": "along the z axis of the source's own frame"},
        "checks": checks,
        "verdict": verdict,
        "salience": sal,
        "facts": {
            "worst_direction_relative_spread": spread,
            "max_abs_difference_da_db_columns": ab,
            "note": "every source vector of a limb displaces its sphere centre C_i (da_i directly, db_i through "
                    "R_Ai, dl_i through R_Ai R_Bi), so along their own worst directions (and in the rms over "
                    "random directions) da, db and dl have exactly the same effect; R_A1 = I makes the "
                    "columns of da_1 and db_1 identical. Differences come only from the axes the vectors "
                    "are stated along: dl's x axis (u_i) is the direction the passive theta_i absorbs.",
        },
    }


def _source_index(model):
    """{component name like 'a.x': column indices over the three limbs}."""
    return {f"{g}.{ax}": model.param_index([f"{g}{i}.{ax}" for i in (1, 2, 3)]) for g in GROUPS for ax in "xyz"}


def paper_tolerances(model=None) -> np.ndarray:
    """(27,) tolerances (m) implied by the paper's Table 1: each source component gets the sum of the
    half zones ``IT / 2`` of the fits mapped to it (``FITS``), a worst-case stack of those fits."""
    model = load_robot(model or ROBOT)
    delta = np.zeros(model.n_params)
    idx = _source_index(model)
    for f in FITS:
        half = it_tolerance(f["paper_grade"], f["size_mm"]) / 2.0
        for s in f["sources"]:
            delta[idx[s]] += half
    return delta


def grades(model=None, limit_position: float = LIMIT_POSITION, limit_orientation: float = LIMIT_ORIENTATION,
           criterion: str = "rss", model_type: str = "min-cost", floor: float = 1e-6, samples: int = 5000,
           seed: int = 0, verify: bool = False, n_mc: int = 2000, solver_options=None) -> dict:
    """Allocate tolerances to the 27 sources and map them to ISO 286 grades of the Table 1 fits.

    Limits: 0.04 mm and 0.045 deg, the accuracy the paper claims for its prototype; criterion 'rss'
    (3 sigma, independent errors: 99.73 % of as-built robots), min-cost objective, floors ``floor`` (m).
    The workspace searches of the allocation move the platform pose (``PUPS3.search_space``).

    Mapping (``FITS``): each fit sets the source components listed with it, in every limb; a component
    set by several fits (l.z by three, l.x and l.y by two) shares its tolerance equally among them.
    A fit's tolerance is the smallest share over its components and limbs, and its grade the coarsest
    IT grade whose zone fits ``2 * tolerance`` at the fit's nominal diameter. ``li.x`` has no
    first-order effect (the passive U-joint takes it up), so it is free and sets nothing.
    The reverse mapping (``paper_tolerances``) turns the paper's grades into source tolerances, whose
    errors over the workspace are reported under ``paper_set``. ``solver_options`` go to the active-set
    solver (its workspace search: ``n_check``, ``n_starts``).
    """
    model = load_robot(model or ROBOT)
    problem = build_problem(model, limit_position, limit_orientation, criterion, floors={"length": floor},
                            samples=samples, seed=seed)
    res = allocate(model, limit_position, model_type=model_type, criterion=criterion,
                   orientation_limit=limit_orientation, problem=problem, seed=seed, verify=verify, n_mc=n_mc,
                   solver_options=solver_options)
    delta = np.where(problem.active, res.delta, np.inf)
    idx = _source_index(model)
    nfits = {s: sum(s in f["sources"] for f in FITS) for s in idx}
    fits = []
    for f in FITS:
        shares = np.concatenate([delta[idx[s]] / nfits[s] for s in f["sources"]])
        t = float(shares.min())
        grade = coarsest_grade(t, f["size_mm"]) if np.isfinite(t) else None
        fits.append({"fit": f["fit"], "size_mm": f["size_mm"], "sources": list(f["sources"]), "why": f["why"],
                     "tolerance_m": t, "grade": grade, "paper_grade": f["paper_grade"], "paper_fit": f["paper_fit"],
                     "paper_half_zone_m": it_tolerance(f["paper_grade"], f["size_mm"]) / 2.0})
    paper = paper_tolerances(model)
    q = model.sample_joints(n_mc, seed + 1)
    J = model.error_jacobian(q)
    paper_set = {"tolerances": dict(zip(model.param_names, paper.tolist())), "poses": int(len(q))}
    for rows, lim in (("position", limit_position), ("orientation", limit_orientation)):
        Jr = J.select(rows)
        paper_set[rows] = {"limit": lim, "max": {"rss": float(rss_bound(Jr, paper).max()),
                                                 "worst-case": float(worst_case_bound(Jr, paper).max())}}
    return {"limits": {"position_m": limit_position, "orientation_rad": limit_orientation},
            "criterion": criterion, "model_type": model_type, "floor_m": floor, "status": res.status,
            "success": bool(res.success), "message": res.message,
            "tolerances": {n: (float(d) if a else None)
                           for n, d, a in zip(model.param_names, res.delta, problem.active)},
            "free": [n for n, a in zip(model.param_names, problem.active) if not a],
            "fits": fits, "paper_set": paper_set, "verification": res.verification if verify else None}


def table3(campaign, model, measured: dict) -> dict:
    """Table 3 (mean of the measured poses minus the nominal pose) with ISO 9283 AP and RP per test pose.

    measured : {test pose name: (n, 4, 4) measured platform poses, m}. Angles are REP 103 roll, pitch,
    yaw (alpha, beta, gamma); errors are signed, m and rad. ``published`` holds the paper's values in
    SI (printed in mm and deg, all positive: magnitudes, signs not given).
    """
    model, campaign = _setup(model, campaign)
    names, T_cmd, _ = pe_poses(model, campaign)
    rows = []
    for name, C in zip(names, T_cmd):
        if name not in measured:
            raise ValueError(f"measured: no poses for test pose {name!r}")
        pc = pose_characteristics(C, measured[name])
        mean = dict(zip(TABLE3_KEYS, (pc.AP_x, pc.AP_y, pc.AP_z, pc.AP_a, pc.AP_b, pc.AP_c)))
        rows.append({"pose": name, "n": pc.n, "mean_error": mean, "iso9283": pc.to_dict(),
                     "published": PUBLISHED_TABLE3.get(name)})
    pos = np.abs([[r["mean_error"][k] for k in TABLE3_KEYS[:3]] for r in rows])
    ori = np.abs([[r["mean_error"][k] for k in TABLE3_KEYS[3:]] for r in rows])
    return {"units": "m and rad", "rows": rows,
            "range": {"position_m": [float(pos.min()), float(pos.max())],
                      "orientation_rad": [float(ori.min()), float(ori.max())]},
            "published_range": PUBLISHED_RANGES}


def generate_example_measurements(seed: int = EXAMPLE_SEED, model=None, campaign=None, delta=None,
                                  tracker_noise=None, joint_repeatability=None) -> dict:
    """The simulated campaign: an as-built robot measured 30 times at each test pose.

    The as-built source errors are uniform within ``delta`` (default ``paper_tolerances``: the
    tolerances the paper's Table 1 grades imply); each visit commands the inverse-kinematics joints of
    the nominal model, reached with Gaussian actuator repeatability ``joint_repeatability``
    (1 sigma: {'a': m, 'psi': rad, 'l': m}; locked joints exact); the tracker adds Gaussian noise
    ``tracker_noise`` ({'position_m', 'orientation_rad'}, 1 sigma) to the pose of the as-built robot.
    Source errors, repeatability and tracker noise come from three streams of ``SeedSequence(seed)``.
    Visits follow the campaign order, one every ``dwell`` seconds.
    Returns {'pose', 'cycle', 'stamp' (N,), 'T' (N, 4, 4), 'q' (N, 9), 'dx' (27,), 'delta' (27,), 'settings'}.
    """
    model, campaign = _setup(model, campaign)
    delta = paper_tolerances(model) if delta is None else np.asarray(delta, dtype=float)
    tn = {**TRACKER_NOISE, **(tracker_noise or {})}
    jr = {**JOINT_REPEATABILITY, **(joint_repeatability or {})}
    err_rng, joint_rng, tracker_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3))
    dx = as_built_errors(delta, err_rng, "uniform")
    q_nom = campaign.joints_for(model)
    seq = np.array(campaign.sequence())
    idx, cyc = seq[:, 0], seq[:, 1]
    sigma = np.repeat([jr["a"], jr["psi"], jr["l"]], 3)
    sigma = np.where(model.joint_limits[:, 0] == model.joint_limits[:, 1], 0.0, sigma)
    q = q_nom[idx] + joint_rng.standard_normal((len(idx), model.dof)) * sigma
    T = measure(model, q, dx, tn["position_m"], tn["orientation_rad"], seed=tracker_rng)
    names = np.array(campaign.names)
    return {"pose": names[idx], "cycle": cyc, "stamp": campaign.dwell_s * (np.arange(len(idx)) + 1.0), "T": T,
            "q": q, "dx": dx, "delta": delta,
            "settings": {"seed": seed, "robot": model.name, "campaign": campaign.name, "cycles": campaign.cycles,
                         "order": campaign.order, "dwell_s": campaign.dwell_s, "tracker_noise": tn,
                         "joint_repeatability": jr, "ik_sliders_m": model.redundancy.tolist()
                         if hasattr(model, "redundancy") else None}}


def measured_by_pose(data: dict) -> dict:
    """{test pose name: (n, 4, 4) measured poses} of a ``generate_example_measurements`` result."""
    return {str(n): data["T"][data["pose"] == n] for n in dict.fromkeys(data["pose"])}


def example_comments(data: dict, model=None) -> list:
    """Comment lines (without '#') saying how ``data`` was generated."""
    model = load_robot(model or ROBOT)
    s = data["settings"]
    um = dict(zip(model.param_names, data["delta"] * 1e6))
    groups = {}
    for n, v in um.items():
        groups.setdefault(f"{n[0]}.{n.split('.')[1]}", set()).add(round(v, 6))
    tol = ", ".join(f"{k} +-{'/'.join(f'{x:g}' for x in sorted(v))}" for k, v in groups.items())
    dx = ", ".join(f"{n}={v * 1e6:+.4f}" for n, v in zip(model.param_names, data["dx"]))
    return [
        f"Simulated measurements of the {s['campaign']} campaign (Rong et al. 2018, Table 2) on robot {s['robot']}.",
        f"Generated by tolerance_ros.papers.rong2018.generate_example_measurements(seed={s['seed']}) and "
        f"write_measurements_csv; not measured data.",
        f"As-built robot: source errors uniform within the tolerances implied by the paper's Table 1 grades "
        f"(rong2018.paper_tolerances, um, every limb): {tol}.",
        f"As-built source errors drawn (um): {dx}.",
        f"Commanded joints: inverse kinematics of the nominal model, free sliders at "
        f"{[round(a * 1e3, 3) for a in s['ik_sliders_m']]} mm; actuator repeatability per visit (1 sigma): "
        f"a {s['joint_repeatability']['a'] * 1e6:g} um, psi {s['joint_repeatability']['psi'] * 1e6:g} urad, "
        f"l {s['joint_repeatability']['l'] * 1e6:g} um.",
        f"Tracker noise (1 sigma): position {s['tracker_noise']['position_m'] * 1e6:g} um per axis, orientation "
        f"{s['tracker_noise']['orientation_rad'] * 1e6:g} urad about a random axis.",
        f"{s['cycles']} cycles, order {s['order']} (PE1..PE6 per cycle), one visit every {s['dwell_s']:g} s; "
        f"roll/pitch/yaw = alpha/beta/gamma of R = Rz(yaw) Ry(pitch) Rx(roll).",
    ]


def write_measurements_csv(path, data: dict, comments=()) -> Path:
    """Write measurements (``generate_example_measurements`` layout) in the project's CSV format
    (``accuracy.io.write_csv``: mm and deg)."""
    m = Measurements(np.asarray(data["stamp"], float), data["T"], None, (), np.asarray(data["pose"], dtype=object),
                     np.asarray(data["cycle"], dtype=int))
    return write_csv(path, m, comments)


def write_example_measurements(path, seed: int = EXAMPLE_SEED) -> Path:
    """Regenerate the shipped example file (``config/data/rong2018_pe_measurements.csv``)."""
    data = generate_example_measurements(seed)
    return write_measurements_csv(path, data, example_comments(data))


def run(seed: int = 2023, plot_dir=None, synthesis: bool = True, quiet: bool = False) -> dict:
    """Fig. 3 study, Table 1 grades (unless ``synthesis=False``) and Table 3 from the shipped example data."""
    prog = Progress("rong2018", not quiet)
    model = load_robot(ROBOT)
    campaign = load_campaign(CAMPAIGN, model)
    prog(0, 3)
    res = {"fig3": fig3_study(model, campaign, seed=seed % 1000)}
    prog(1, 3)
    if synthesis:
        res["grades"] = grades(model, seed=seed % 1000)
    prog(2, 3)
    path = config_dir() / "data" / EXAMPLE_CSV
    meas = read_csv(path)
    res["table3"] = table3(campaign, model, {n: meas.T[meas.pose == n] for n in campaign.names})
    res["table3"]["source"] = str(path)
    res["table3"]["registration"] = ("none: the measurements are base-frame poses, as the paper's Table 3 "
                                     "(tolerance-ros report --registration none gives the same AP)")
    prog(3, 3)
    if plot_dir:
        res["plots"] = [str(fig3_plot(res["fig3"], Path(plot_dir) / "rong2018_fig3.png"))]
    return res


def fig3_plot(f: dict, path) -> Path:
    """Fig. 3 as a PNG: platform position (um) and orientation (urad) errors against the source error
    magnitude (mm), mean over the test poses; along their worst directions the three sources coincide."""
    mags = np.array(f["magnitudes_m"]) * 1e3
    pos = {f"d{g}{f['limb']}": np.array(f["sweep"][g]["position_m"]).mean(axis=0) * 1e6 for g in GROUPS}
    ori = {f"d{g}{f['limb']}": np.array(f["sweep"][g]["orientation_rad"]).mean(axis=0) * 1e6 for g in GROUPS}
    return plots.panels_plot(mags, [("platform position error [um]", pos), ("platform orientation error [urad]", ori)],
                             path, "source error magnitude along its worst direction [mm]",
                             "Fig. 3: platform error vs source error (mean over PE1-PE6)")


def print_report(res):
    f = res["fig3"]
    print("Rong, Han, Liu, Qu (2018): 3-PUPS parallel manipulator, error analysis.")
    print(f"\nFig. 3: limb {f['limb']} sources swept 0.001-0.01 mm along their worst direction; errors at 0.01 mm "
          f"(position um / orientation urad):")
    rows = []
    for k, name in enumerate(f["test_poses"]):
        rows.append([name] + [f"{f['sweep'][g]['position_m'][k][-1] * 1e6:.3f} / "
                              f"{f['sweep'][g]['orientation_rad'][k][-1] * 1e6:.2f}" for g in ("a", "b", "l")])
    print(table(["pose", "da1", "db1", "dl1"], rows))
    print("\nPaper's conclusion 'da and db dominate, dl is weak', by the direction the error vectors are taken along:")
    print(table(["direction", "verdict", "meaning"], [[k, v, f["conventions"][k]] for k, v in f["verdict"].items()],
                ["<", "<", "<"]))
    sal = f["salience"]["position"]["all_limbs"]
    print(f"salience by group (position, all limbs): a {sal['a']:.3f}, b {sal['b']:.3f}, l {sal['l']:.3f}")
    print(f"note: {f['facts']['note']}")
    if "grades" in res:
        g = res["grades"]
        print(f"\nTable 1, ISO 286 grades from an allocation ({g['criterion']}, {g['model_type']}; limits "
              f"{g['limits']['position_m'] * 1e3:g} mm and {np.degrees(g['limits']['orientation_rad']):g} deg; "
              f"{g['status']}):")
        print(table(["fit", "size mm", "tolerance um", "grade", "paper"],
                    [[x["fit"], x["size_mm"], f"{x['tolerance_m'] * 1e6:.2f}", f"IT{x['grade']}" if x["grade"] else "-",
                      f"IT{x['paper_grade']} ({x['paper_fit']})"] for x in g["fits"]], ["<", ">", ">", ">", "<"]))
        ps = g["paper_set"]
        print(f"the paper's grades as tolerances: position up to {ps['position']['max']['rss'] * 1e3:.4f} mm (rss), "
              f"{ps['position']['max']['worst-case'] * 1e3:.4f} mm (worst-case) against {ps['position']['limit'] * 1e3:g} mm")
    t = res["table3"]
    print(f"\nTable 3 from {t['source']} (simulated measurements, 30 cycles; registration {t['registration']}; "
          f"mean error, mm and deg), beside the "
          f"published values:")
    rows = []
    for r in t["rows"]:
        me, pub, iso = r["mean_error"], r["published"], r["iso9283"]
        rows.append([r["pose"], r["n"]] + [f"{me[k] * 1e3:+.4f} ({pub[k] * 1e3:.3f})" for k in ("dX", "dY", "dZ")]
                    + [f"{np.degrees(me[k]):+.4f} ({np.degrees(pub[k]):.3f})" for k in ("dalpha", "dbeta", "dgamma")]
                    + [f"{iso['AP_p'] * 1e3:.4f}", f"{iso['RP_l'] * 1e3:.4f}"])
    print(table(["pose", "n", "dX", "dY", "dZ", "dalpha", "dbeta", "dgamma", "AP_p mm", "RP_l mm"], rows))
    for p in res.get("plots", []):
        print(f"plot: {p}")
