"""Precision analysis over the workspace: sensitivity, salience, ceilings, correlation, Monte Carlo.

Sensitivity and salience follow Gao et al. (2023) eqs. 12-15: at each pose ``mu_j = |J_j|`` (the norm
of the Jacobian column), its mean over m sampled poses, and ``D_j = mean mu_j / sum_k mean mu_k``.
``D_j`` mixes length and angle parameters, so it depends on the length unit of the Jacobian; the paper
works in mm and rad, and ``length_unit`` says which unit is used.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import interrupt
from .errors import error_norms
from .geometry import rotation_error
from .models.base import Mechanism
from .units import length_scale

DISTRIBUTIONS = ("fixed", "extreme", "uniform", "normal")
PERCENTILES = (50.0, 90.0, 95.0, 99.0, 99.9)


def workspace_jacobian(model: Mechanism, m: int = 1000, seed=0, q=None, rows: str = "position"):
    """(q (m, dof), J rows (m, 3 or 6, p)) over ``m`` seeded uniform samples of the joint space."""
    q = model.sample_joints(m, seed) if q is None else model.check_joints(q)
    return q, model.error_jacobian(q).select(rows)


def _salience_weights(model, length_unit):
    """Per-column factor expressing position-row sensitivities in ``length_unit`` per parameter unit."""
    s = 1.0 / length_scale(length_unit)
    return np.array([1.0 if k == "length" else s for k in model.param_kinds])


@dataclass
class Sensitivity:
    """Sensitivity indices of every parameter over the workspace.

    mu_mean, mu_max : (p,) mean and max of ``|J_j|`` over the poses, SI (m per m, m per rad for
    position rows; rad per unit for orientation rows).  salience : (p,) ``D_j`` computed with lengths
    in ``length_unit`` (it depends on that choice; the paper uses mm).
    """

    names: tuple
    units: tuple
    mu_mean: np.ndarray
    mu_max: np.ndarray
    salience: np.ndarray
    samples: int
    seed: object
    rows: str
    length_unit: str

    def ranking(self) -> list:
        """Parameter names from the most to the least salient (stable for ties)."""
        order = np.argsort(-self.salience, kind="stable")
        return [self.names[i] for i in order]

    def to_dict(self) -> dict:
        return {"rows": self.rows, "salience_length_unit": self.length_unit, "samples": self.samples,
                "seed": self.seed,
                "parameters": [{"name": n, "unit": u, "mu_mean": float(a), "mu_max": float(b), "salience": float(d)}
                               for n, u, a, b, d in zip(self.names, self.units, self.mu_mean, self.mu_max,
                                                        self.salience)]}


def sensitivity(model: Mechanism, m: int = 1000, seed=0, q=None, rows: str = "position",
                length_unit: str = "m") -> Sensitivity:
    """Sensitivity ``mu_j`` (mean and max over poses, SI) and salience ``D_j`` (eqs. 12-15).

    For position rows the salience weighs length and angle parameters with lengths in ``length_unit``
    ('mm' reproduces the paper); orientation rows are unit-free in that respect.
    """
    q, J = workspace_jacobian(model, m, seed, q, rows)
    mu = np.sqrt(np.einsum("nkp,nkp->np", J, J))
    mean = mu.mean(axis=0)
    weighted = mean * (_salience_weights(model, length_unit) if rows == "position" else 1.0)
    total = weighted.sum()
    sal = weighted / total if total > 0 else np.zeros_like(mean)
    return Sensitivity(model.param_names, model.param_units, mean, mu.max(axis=0), sal, len(q),
                       seed if isinstance(seed, (int, type(None))) else "generator", rows, length_unit)


def ceilings(J, limit: float) -> np.ndarray:
    """(p,) eq. 18 ceilings ``Delta_j = limit / max over poses |J_j|``.

    A column whose largest entry is below 1e-12 of the largest entry of J (rounding noise, e.g. a tool
    point on the last joint axis) has no effect: its ceiling is inf.
    """
    mu_max = np.sqrt(np.einsum("nkp,nkp->np", J, J)).max(axis=0)
    effect = mu_max > 1e-12 * max(float(np.abs(J).max(initial=0.0)), 1e-300)
    out = np.full(mu_max.shape, np.inf)
    out[effect] = limit / mu_max[effect]
    return out


def correlation(J) -> np.ndarray:
    """(p, p) correlation of the Jacobian columns, pooled over poses and rows (section 5.2).

    Each column contributes its ``n * k`` entries; constant columns get NaN rows (undefined).
    """
    n, k, p = J.shape
    X = np.asarray(J).reshape(n * k, p)
    X = X - X.mean(axis=0)
    sd = np.sqrt((X * X).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        R = (X.T @ X) / np.outer(sd, sd)
    flat = sd <= 1e-12 * max(sd.max(), 1e-300)
    R[flat, :] = np.nan
    R[:, flat] = np.nan
    return np.clip(R, -1.0, 1.0)


def correlated_pairs(R, names, threshold: float = 0.8) -> list:
    """[(name_i, name_j, rho)] with ``|rho| >= threshold``, i < j, strongest first."""
    iu = np.triu_indices(R.shape[0], 1)
    vals = R[iu]
    keep = np.isfinite(vals) & (np.abs(vals) >= threshold)
    pairs = [(names[i], names[j], float(r)) for i, j, r in zip(iu[0][keep], iu[1][keep], vals[keep])]
    return sorted(pairs, key=lambda t: -abs(t[2]))


def sign_control(names, pairs, base_signs=None) -> np.ndarray:
    """Signs after Gao et al.'s assembly rule for correlated pairs (i, j, rho), i before j in ``names``:
    parameter i is assembled opposite to j when rho > 0 and in the same direction when rho < 0, so
    that their effects cancel. Adjusting the first member of each pair (the length parameter in the
    paper's ordering) is the reading that reproduces Table 5; adjusting the angle instead raises the
    maximum error on the paper's arm.
    """
    index = {n: i for i, n in enumerate(names)}
    s = np.ones(len(names)) if base_signs is None else np.array(base_signs, dtype=float)
    for a, b, rho in pairs:
        i, j = sorted((index[a], index[b]))
        s[i] = -s[j] if rho > 0 else s[j]
    return s


def sample_errors(delta, n: int, distribution: str = "extreme", seed=0, signs=None) -> np.ndarray:
    """(n, p) parameter errors within ``+-delta`` (SI).

    'fixed': every pose gets ``signs * delta`` (all +1 by default: the paper's extreme-value case);
    'extreme': ``+-delta`` with independent random signs; 'uniform': U(-delta, delta);
    'normal': N(0, (delta/3)^2), so that ``delta`` is the 3-sigma limit.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    delta = np.asarray(delta, dtype=float)
    p = delta.size
    if distribution == "fixed":
        s = np.ones(p) if signs is None else np.asarray(signs, dtype=float)
        return np.broadcast_to(s * delta, (n, p)).copy()
    if distribution == "extreme":
        return np.where(rng.random((n, p)) < 0.5, -1.0, 1.0) * delta
    if distribution == "uniform":
        return rng.uniform(-1.0, 1.0, (n, p)) * delta
    if distribution == "normal":
        return rng.standard_normal((n, p)) * (delta / 3.0)
    raise ValueError(f"distribution: expected one of {DISTRIBUTIONS}, got {distribution!r}")


def summarize(values, limit=None) -> dict:
    """max, mean, std (population), percentiles and the pass rate (``<= limit``) of an (n,) sample."""
    v = np.asarray(values, dtype=float)
    out = {"n": int(v.size), "max": float(v.max()), "mean": float(v.mean()), "std": float(v.std()),
           "percentiles": {f"p{q:g}": float(x) for q, x in zip(PERCENTILES, np.percentile(v, PERCENTILES))}}
    if limit is not None:
        out["limit"] = float(limit)
        out["pass_rate"] = float(np.mean(v <= limit))
        out["failures"] = int(np.sum(v > limit))
    return out


@dataclass
class Verification:
    """Monte Carlo verification of a tolerance set (errors in m and rad)."""

    position: np.ndarray
    orientation: np.ndarray
    q: np.ndarray
    distribution: str
    method: str
    seed: object
    limit_position: float | None = None
    limit_orientation: float | None = None
    summary: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"distribution": self.distribution, "method": self.method, "seed": self.seed,
                "poses": int(self.q.shape[0]), "position_m": self.summary["position"],
                "orientation_rad": self.summary["orientation"]}


def monte_carlo(model: Mechanism, delta, n: int = 10000, distribution: str = "extreme", seed=0,
                limit_position=None, limit_orientation=None, signs=None, q=None, method: str = "linear",
                chunk: int = 20000, progress=None) -> Verification:
    """Verify tolerances ``delta`` (p,) over ``n`` seeded uniform poses.

    ``method='linear'`` uses ``|J dx|`` (the first-order model of the paper); ``'nonlinear'`` evaluates the
    perturbed forward kinematics exactly. Poses and errors come from independent seeded streams, so
    the same seed gives the same poses whatever the distribution: ``model.sample_joints(n,
    default_rng(seed))``, the poses of the paper's tables and of the synthesis's verification.
    ``progress(done, total)`` is called after each chunk.
    """
    delta = np.asarray(delta, dtype=float)
    if delta.shape != (model.n_params,):
        raise ValueError(f"delta: expected {model.n_params} tolerances, got shape {delta.shape}")
    if np.any(~np.isfinite(delta)) or np.any(delta < 0):
        raise ValueError("delta: tolerances must be finite and >= 0")
    if method not in ("linear", "nonlinear"):
        raise ValueError(f"method: expected 'linear' or 'nonlinear', got {method!r}")
    ss = np.random.SeedSequence(seed if isinstance(seed, int) else None)
    pose_rng = np.random.default_rng(seed if isinstance(seed, int) else ss)  # the poses every study draws with seed
    err_rng = np.random.default_rng(ss.spawn(2)[1])
    q = model.sample_joints(n, pose_rng) if q is None else model.check_joints(q)
    n = q.shape[0]
    dx_all = sample_errors(delta, n, distribution, err_rng, signs)
    pos = np.empty(n)
    ori = np.empty(n)
    for a in range(0, n, chunk):
        interrupt.check()
        b = min(n, a + chunk)
        qc, dx = q[a:b], dx_all[a:b]
        if method == "linear":
            J = model.error_jacobian(qc).J
            pos[a:b] = error_norms(J[:, :3], dx)
            ori[a:b] = error_norms(J[:, 3:], dx)
        else:
            T0 = model.fk(qc)
            T1 = model.fk(qc, dx)
            pos[a:b] = np.linalg.norm(T1[:, :3, 3] - T0[:, :3, 3], axis=1)
            ori[a:b] = np.linalg.norm(rotation_error(T1[:, :3, :3], T0[:, :3, :3]), axis=1)
        if progress is not None:
            progress(b, n)
    summary = {"position": summarize(pos, limit_position), "orientation": summarize(ori, limit_orientation)}
    return Verification(pos, ori, q, distribution, method, seed, limit_position, limit_orientation, summary)
