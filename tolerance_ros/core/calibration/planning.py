"""Which poses to measure: observability indices of the identification Jacobian and a pose selection.

The identification Jacobian is the one ``identify`` solves: per pose, the position rows (and, when the
tracker measures orientation, the orientation rows weighted ``sigma_position / sigma_orientation``) in
the unknowns [parameter errors; base correction], at the nominal parameters, each column scaled by the
expected size of its unknown (its tolerance with a budget, else 1 mm or 1 mrad), without the parameters
that no pose can separate (``dependent_parameters`` over the candidate set, held at nominal by the
calibration). With ``s_1 >= ... >= s_L`` its singular values over ``m`` measured poses:

- ``O1 = (s_1 s_2 ... s_L)^(1/L) / sqrt(m)``: Borm & Menq (1991), "Determination of optimal measurement
  configurations for robot calibration based on observability measure", Int. J. Robotics Research
  10(1); maximising it is D-optimal design (the determinant of ``J^T J``);
- ``O2 = s_L / s_1``, the inverse condition number: Driels & Pathre (1990), IEEE Trans. Robotics and
  Automation 6(2);
- ``O3 = s_L``, the smallest singular value: Nahvi, Hollerbach & Hayward (1994), ICRA;
- ``O4 = s_L^2 / s_1``, the noise amplification index: Nahvi & Hollerbach (1996), ICRA.
Sun & Hollerbach (2008, ICRA) compare them; O1 and O4 are the usual choices.

``plan`` draws seeded candidate poses within the joint limits (with a ``core.workspace.Workspace``:
within its joint ranges, keeping those that pass its check: tool workspace and collisions) and chooses
``n`` of them by a DETMAX exchange (Mitchell 1974): from a seeded random design, add the candidate that
raises the criterion most, then drop the design pose whose loss lowers it least, until the pose dropped
is the one added. O1 uses the determinant lemma (one small determinant per candidate); the others the
eigenvalues of ``J^T J`` per candidate, in batches.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..identification import BASE_NAMES, base_jacobian, column_scale, dependent_parameters
from ..accuracy.iso9283 import iso_cube_joints
from ..geometry import rotation_error
from ..models.base import Mechanism

CRITERIA = {"observability": "O1", "condition": "O2", "min-singular": "O3", "noise-amplification": "O4"}
REFERENCES = {"O1": "Borm & Menq 1991", "O2": "Driels & Pathre 1990", "O3": "Nahvi, Hollerbach & Hayward 1994",
              "O4": "Nahvi & Hollerbach 1996"}


def pose_blocks(model: Mechanism, q, delta=None, sigma_ratio=None, held=None, tick=None, chunk=2000):
    """((n, r, L) scaled identification Jacobian per pose, names of its L columns, (p,) held mask).

    ``sigma_ratio`` = sigma_position / sigma_orientation (m/rad) adds the orientation rows; ``held``
    ((p,) mask) drops those parameters, by default ``dependent_parameters`` over these poses. The poses'
    Jacobians are evaluated ``chunk`` at a time, ``tick(fraction done)`` after each.
    """
    q = model.check_joints(q)
    p = model.n_params
    T, EJ = model.fk_and_jacobian(q[:chunk])
    if len(q) > chunk:
        Ts, Js = [T], [EJ.J]
        for a in range(chunk, len(q), chunk):
            if tick is not None:
                tick(a / len(q))
            Ta, EJa = model.fk_and_jacobian(q[a:a + chunk])
            Ts.append(Ta)
            Js.append(EJa.J)
        T, EJ = np.concatenate(Ts), type(EJ)(np.concatenate(Js), EJ.names, EJ.units)
    Jb = base_jacobian(T[:, :3, 3])
    rows = [np.concatenate([EJ.position, Jb[:, :3]], axis=2)]
    if sigma_ratio is not None:
        rows.append(sigma_ratio * np.concatenate([EJ.orientation, Jb[:, 3:]], axis=2))
    G = np.concatenate(rows, axis=1) * column_scale(delta, p)
    if tick is not None:
        tick(0.9)
    if held is None:
        held = dependent_parameters(G.reshape(-1, p + 6), p)
    keep = np.r_[~np.asarray(held, bool), np.ones(6, bool)]
    names = tuple(model.param_names) + BASE_NAMES
    return G[:, :, keep], tuple(n for n, k in zip(names, keep) if k), np.asarray(held, bool)


def indices(s, m: int, L: int) -> dict:
    """O1..O4 (see the module docstring; m), rank and condition from the singular values ``s`` of the
    scaled Jacobian of ``m`` measured poses in ``L`` unknowns; O1..O4 are 0 when it is rank-deficient."""
    s = np.sort(np.asarray(s, float))[::-1]
    rank = int(np.sum(s > 1e-9 * s[0])) if len(s) else 0
    full = rank == L
    if not full:
        return {"O1": 0.0, "O2": 0.0, "O3": 0.0, "O4": 0.0, "rank": rank, "unknowns": L, "condition": float("inf")}
    return {"O1": float(np.exp(np.mean(np.log(s))) / np.sqrt(m)), "O2": float(s[-1] / s[0]), "O3": float(s[-1]),
            "O4": float(s[-1] ** 2 / s[0]), "rank": rank, "unknowns": L, "condition": float(s[0] / s[-1])}


def design_indices(G, design) -> dict:
    """``indices`` of the poses ``design`` (indices into G (n, r, L)), with their singular values ``s``
    (padded with zeros to L)."""
    A = G[np.asarray(design)].reshape(-1, G.shape[2])
    s = np.linalg.svd(A, compute_uv=False)
    out = indices(s, len(design), G.shape[2])
    out["s"] = np.r_[s, np.zeros(G.shape[2] - len(s))]
    return out


def _score(M, index):
    """O2, O3 or O4 of a batch of information matrices ``J^T J`` (k, L, L), from their eigenvalues."""
    lam = np.linalg.eigvalsh(M)
    lmin, lmax = np.maximum(lam[:, 0], 0.0), lam[:, -1]
    if index == "O2":
        return np.sqrt(lmin / lmax)
    if index == "O3":
        return np.sqrt(lmin)
    return lmin / np.sqrt(lmax)


def _gains(M, G, index, sign, chunk=500, tick=None):
    """Criterion of M + sign * G_c^T G_c for every block G_c of G (k, r, L); for O1 the change of
    log det (the same maximiser as O1 for a fixed number of poses), by the determinant lemma. In chunks
    of ``chunk`` blocks, ``tick(fraction done)`` after each."""
    out = np.empty(len(G))
    if index == "O1":
        Minv = np.linalg.inv(M)
        eye = np.eye(G.shape[1])
    for a in range(0, len(G), chunk):
        g = G[a:a + chunk]
        if index == "O1":
            sgn, logdet = np.linalg.slogdet(eye + sign * np.einsum("kri,ij,ksj->krs", g, Minv, g))
            out[a:a + chunk] = np.where(sgn > 0, logdet, -np.inf)
        else:
            out[a:a + chunk] = _score(M[None] + sign * np.einsum("kri,krj->kij", g, g), index)
        if tick is not None:
            tick(min(1.0, (a + chunk) / len(G)))
    return out


@dataclass
class Plan:
    """Chosen poses (joints (n, dof), SI) and the observability of the chosen, ISO-cube and random sets."""

    q: np.ndarray
    criterion: str
    index: str
    candidates: int
    seed: int
    exchanges: int
    columns: tuple
    held: list
    chosen: dict
    random: dict
    iso_cube: dict | None
    iso_cube_note: str
    spectra: dict
    restrictions: dict | None = None  # the workspace's restrictions and its candidates' report (``plan``)

    def to_dict(self) -> dict:
        return {"criterion": self.criterion, "index": self.index, "reference": REFERENCES[self.index],
                "poses": len(self.q), "joints": self.q, "candidates": self.candidates, "seed": self.seed,
                "exchanges": self.exchanges, "unknowns": list(self.columns), "held": list(self.held),
                "restrictions": self.restrictions,
                "observability": {"planned": self.chosen, "random": self.random, "iso_cube": self.iso_cube},
                "iso_cube_note": self.iso_cube_note, "singular_values": self.spectra}


def select(G, n: int, index="O1", seed=0, max_exchanges=None, tick=None):
    """(design (n,) indices into G, exchanges made): DETMAX exchange (see the module docstring).
    ``tick(fraction of the most exchanges)`` as the candidates of each exchange are scored."""
    k, _, L = G.shape
    if n > k:
        raise ValueError(f"n: {n} poses requested from {k} candidates")
    rng = np.random.default_rng(seed)
    design = list(rng.choice(k, n, replace=False))
    if tick is not None:
        tick(0.0)
    info = np.einsum("kri,krj->kij", G, G)
    M = info[design].sum(axis=0) + 1e-12 * np.eye(L)
    exchanges = 0
    most = max_exchanges or 20 * n
    for exchanges in range(most):
        outside = np.setdiff1d(np.arange(k), design)
        scored = None if tick is None else (lambda f, e=exchanges: tick((e + f) / most))
        add = outside[np.argmax(_gains(M, G[outside], index, +1.0, tick=scored))]
        M1 = M + info[add]
        pool = np.array(design + [add])
        drop = pool[np.argmax(_gains(M1, G[pool], index, -1.0))]
        if drop == add:
            break
        design.remove(drop)
        design.append(add)
        M = M1 - info[drop]
    return np.array(design), exchanges


PROGRESS_STEPS = 1000  # the total of ``plan``'s progress


def plan(model: Mechanism, n: int, criterion="observability", candidates=2000, seed=0, delta=None,
         sigma_ratio=None, iso_joints=None, random_draws=20, progress=None, workspace=None,
         max_draws=None) -> Plan:
    """Choose ``n`` poses within the joint limits that maximise the criterion (see the module docstring).

    iso_joints : (k, dof) joints of an ISO 9283 cube campaign to compare with (default: built by
    ``accuracy.iso9283.iso_cube_joints``). The random set's indices are the medians over ``random_draws`` seeded draws
    of ``n`` candidates. workspace : a ``core.workspace.Workspace``: the candidates are drawn within its
    joint ranges until ``candidates`` pass its check or ``max_draws`` (default 10 x candidates) are drawn;
    ValueError with the counts when fewer than ``n`` pass. ``progress(done, PROGRESS_STEPS)`` is called as
    the work goes: the candidates drawn and checked (the first 10 %), their Jacobians (to 20 %), each chunk
    of candidates scored by each exchange (up to 90 %; the exchange stops early when no swap helps), then
    the comparisons.
    """
    if criterion not in CRITERIA:
        raise ValueError(f"criterion: expected one of {sorted(CRITERIA)}, got {criterion!r}")
    if n > candidates:
        raise ValueError(f"n: {n} poses requested from {candidates} candidates")
    index = CRITERIA[criterion]

    def stage(lo, hi):
        if progress is None:
            return None
        return lambda f: progress(int(PROGRESS_STEPS * (lo + (hi - lo) * min(max(f, 0.0), 1.0))), PROGRESS_STEPS)

    rng = np.random.default_rng(seed)
    report = None
    if workspace is None:
        qc = model.sample_joints(int(candidates), rng)
    else:
        from ..workspace import rejection_summary
        qc, report = workspace.sample(int(candidates), rng, int(max_draws or 10 * candidates), stage(0.0, 0.1))
        if len(qc) < n:
            raise ValueError(f"too few candidates for {n} poses: {rejection_summary(report)} (at most "
                             f"{report['drawn']:,} draws); widen the --joint-range, lower or drop the planes, enlarge "
                             f"--inside-box, lower --clearance, or lower --n")
        report = {**workspace.to_dict(), **report, "asked": int(candidates)}
    G, columns, held = pose_blocks(model, qc, delta, sigma_ratio, tick=stage(0.1, 0.2))
    if n * G.shape[1] < G.shape[2]:
        raise ValueError(f"n: {n} poses give {n * G.shape[1]} equations for {G.shape[2]} unknowns; "
                         f"plan at least {-(-G.shape[2] // G.shape[1])} poses")
    design, exchanges = select(G, n, index, seed, tick=stage(0.2, 0.9))
    if progress is not None:
        progress(int(0.9 * PROGRESS_STEPS), PROGRESS_STEPS)
    chosen = design_indices(G, design)
    spectra = {"planned": chosen.pop("s")}
    draws = [design_indices(G, rng.choice(len(qc), n, replace=False)) for _ in range(random_draws)]
    rand = {k: float(np.median([d[k] for d in draws])) for k in ("O1", "O2", "O3", "O4", "condition")}
    rand["rank"] = int(np.median([d["rank"] for d in draws]))
    rand["draws"] = random_draws
    spectra["random (median O1 draw)"] = draws[int(np.argsort([d["O1"] for d in draws])[len(draws) // 2])]["s"]
    if iso_joints is None:
        iso_joints, note = iso_cube_joints(model, qc, seed,
                                           allowed=None if workspace is None else lambda q: workspace.check(q).ok)
    else:
        note = "ISO 9283 cube: the given campaign's test poses"
    iso = None
    if iso_joints is not None:
        Gi = pose_blocks(model, iso_joints, delta, sigma_ratio, held)[0]
        iso = design_indices(Gi, np.arange(len(Gi)))
        iso["poses"] = int(len(Gi))
        spectra["ISO 9283 cube"] = iso.pop("s")
    return Plan(qc[design], criterion, index, int(len(qc)), int(seed), int(exchanges), columns,
                [model.param_names[j] for j in np.flatnonzero(held)], chosen, rand, iso, note, spectra, report)


def file_joints(q, prismatic) -> list:
    """Joints (dof,) SI as a campaign file of ``campaign_dict`` writes them: degrees, prismatic joints in m."""
    return [float(v) if pr else float(np.degrees(v)) for v, pr in zip(q, prismatic)]


def campaign_dict(model: Mechanism, q, name, cycles=3, dwell=2.0, description="", restrictions=None) -> dict:
    """A campaign file (``core/campaign.py`` format) with the poses q (n, dof): angles in degrees,
    prismatic joints in m; test poses C1..Cn; ``restrictions`` (``Restrictions.texts``), the ones its
    poses were planned under, checked again when it is loaded."""
    prismatic = [t == "prismatic" for t in model.joint_types]
    poses = []
    for i, row in enumerate(np.asarray(q, float)):
        entry = {"name": f"C{i + 1}", "joints": file_joints(row, prismatic)}
        if any(prismatic):
            entry["joint_units"] = ["length" if pr else "angle" for pr in prismatic]
        poses.append(entry)
    out = {"name": name, "robot": model.name, "units": {"length": "m", "angle": "deg"}, "cycles": int(cycles),
           "dwell": float(dwell), "order": "cycle", "description": description}
    if restrictions is not None:
        out["restrictions"] = {k: v for k, v in restrictions.items() if v not in (None, [])}
    out["poses"] = poses
    return out


AXES = {"+x": (0, 1.0), "+y": (1, 1.0), "+z": (2, 1.0), "-x": (0, -1.0), "-y": (1, -1.0), "-z": (2, -1.0)}


def _pre_pose_problem(model, q, target, allowed) -> str | None:
    """What stops the pre-pose joints q (1, dof) solved for ``target`` (4, 4): the reach, a joint limit or a
    restriction (``allowed``); None when nothing does."""
    T = model.fk(q)[0]
    if not np.allclose(T, target, atol=1e-6):
        gap = float(np.linalg.norm(T[:3, 3] - target[:3, 3]))
        return (f"is beyond the robot's reach (the nominal inverse kinematics stops {gap * 1e3:.3g} mm from it, "
                f"turned {float(np.linalg.norm(rotation_error(T[:3, :3], target[:3, :3]))):.3g} rad)")
    out = model.out_of_limits(q)[0]
    if out.any():
        j = int(np.flatnonzero(out)[0])
        prismatic = model.joint_types[j] == "prismatic"
        value, (lo, hi) = q[0, j], model.joint_limits[j]
        shown = ((lambda v: f"{v * 1e3:.4g} mm") if prismatic else (lambda v: f"{np.degrees(v):.4g} deg"))
        return f"needs joint {model.joint_names[j]} at {shown(value)}, beyond its limits [{shown(lo)}, {shown(hi)}]"
    if allowed is not None:
        v = allowed(q)
        ok = np.asarray(getattr(v, "ok", v), bool)
        if not ok.all():
            reason = getattr(v, "reason", None)
            detail = getattr(v, "detail", None)
            said = f": {reason[0]}" + (f" ({detail[0]})" if detail is not None and detail[0] else "") \
                if reason is not None else ""
            return f"breaks a restriction{said}"
    return None


def iso9283_campaign(model: Mechanism, q_poses, approach=None, directions=("+x", "+y", "+z"), cycles=30, dwell=2.0,
                     names=None, description="", allowed=None) -> dict:
    """An ISO 9283 campaign file (``core/campaign.py`` format) of the test poses q_poses (k, dof), named P1..Pk,
    and with ``approach`` (m) each pose also approached along each of ``directions`` of the base frame (``+x``:
    moving in +x, from a pre-pose ``approach`` metres before it), as poses ``Pk+x`` ... with ``of: Pk`` and the
    pre-pose's joints in ``via`` (the nominal model's inverse kinematics from the pose's own joints; ISO 9283
    multi-directional pose accuracy variation). ValueError naming the pose and the limit that stops its pre-pose:
    the robot's reach, a joint limit (the joint, its value and limits), or, with ``allowed`` (a function of
    joints (k, dof) -> (k,) bool, or a ``workspace.Verdict`` with its reasons), a restriction."""
    from ..models.ik import nominal_solution
    q_poses = np.asarray(q_poses, float)
    names = names or [f"P{i + 1}" for i in range(len(q_poses))]
    doc = campaign_dict(model, q_poses, f"{model.name}_iso9283", cycles, dwell, description)
    for entry, name in zip(doc["poses"], names):
        entry["name"] = name
    if approach is None:
        return doc
    bad = [d for d in directions if d not in AXES]
    if bad or len(set(directions)) != len(directions):
        raise ValueError(f"directions: expected distinct ones of {sorted(AXES)}, got {list(directions)}")
    if not (np.isfinite(approach) and approach > 0):
        raise ValueError(f"approach: expected a positive distance (m), got {approach!r}")
    T = model.fk(q_poses)
    prismatic = [t == "prismatic" for t in model.joint_types]
    extra = []
    for k, (name, Tk) in enumerate(zip(names, T)):
        for d in directions:
            axis, sign = AXES[d]
            q = q_poses[k][None]
            for f in np.linspace(0.1, 1.0, 10):   # walked back in steps: the pre-pose joints nearest the pose's
                target = Tk.copy()
                target[axis, 3] -= sign * approach * f
                q = nominal_solution(model, target[None], seed=q[0], tol_position=1e-7, tol_orientation=1e-7)
            why = _pre_pose_problem(model, q, target, allowed)
            if why:
                raise ValueError(f"{name}: its pre-pose {approach * 1e3:g} mm before it along {d} {why}; shorten "
                                 f"--approach")
            entry = dict(doc["poses"][k], joints=list(doc["poses"][k]["joints"]), name=f"{name}{d}", of=name,
                         approach=d, via=file_joints(q[0], prismatic))
            extra.append(entry)
    doc["poses"] += extra
    return doc
