"""The tolerance-allocation problem of Gao et al. (2023), generalised.

Variables: tolerances ``delta_j`` (m, rad), each error within ``+-delta_j``.
Constraints: floors ``tau_j <= delta_j <= Delta_j`` ceilings (eq. 18), and at every pose of the joint
space ``e(q, delta) <= [Delta]`` (position; optionally orientation), where the error criterion ``e`` is
- 'paper':      ``|J delta|``, every error at +delta (eq. 11);
- 'worst-case': ``max over signs s of |J (s * delta)|``, the true worst case;
- 'rss':        ``(k/3) sqrt(sum_j |J_j|^2 delta_j^2)``, guaranteed at confidence ``2 Phi(k) - 1`` for
                normal errors with sigma = delta/3 (see ``tolerance_ros.core.errors``).
Each is a norm of a linear map of delta, so every constraint is convex; at a fixed pose (and fixed
signs for 'worst-case') it is the quadratic form ``delta' M delta <= [Delta]^2``.
Objectives: minimum cost (eq. 17) ``sum K_j delta_j^-alpha_j`` with lengths in mm and angles in rad,
or optimal precision (eqs. 20-22): the largest tolerances in the sense of the smallest index
``I = sum_j w_j |delta_j - Delta_j|`` (``w_j = max mu_j`` in mm per unit), i.e. ``max sum w_j delta_j``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import DEFAULT_LIMIT_CRITERION, LIMIT_CRITERIA, criterion_bound, per_axis_bound, worst_case_bound
from ..models.base import Mechanism
from .search import column_maxima

MODELS = ("min-cost", "optimal-precision")
DEFAULT_FLOORS = {"length": 0.05e-3, "angle": 0.0003}
DEFAULT_K = {"length": 1.0, "angle": 1.5}
COST_UNIT = {"length": 1e3, "angle": 1.0}  # the paper's cost index takes lengths in mm, angles in rad


class SynthesisError(ValueError):
    """An allocation problem that cannot be set up or solved; the message names the cause."""


class InfeasibleError(SynthesisError):
    """A well-posed allocation problem without a solution (the message says which constraint)."""


@dataclass
class SynthesisProblem:
    """A fully specified allocation problem (SI)."""

    model: Mechanism
    limit: float
    orientation_limit: float | None
    criterion: str
    k_sigma: float
    floors: np.ndarray
    ceilings: np.ndarray
    active: np.ndarray
    K: np.ndarray
    alpha: np.ndarray
    weights: np.ndarray
    mu_max_position: np.ndarray
    mu_max_orientation: np.ndarray
    seed: int = 0
    samples: int = 20000
    notes: list = field(default_factory=list)

    @property
    def rows(self) -> list:
        """[(rows, limit)] the criterion is applied to."""
        out = [("position", self.limit)]
        if self.orientation_limit is not None:
            out.append(("orientation", self.orientation_limit))
        return out

    def cost(self, delta) -> float:
        """Eq. 17 cost index over the active parameters (lengths in mm, angles in rad)."""
        d = np.asarray(delta, dtype=float)[self.active]
        unit = np.array([COST_UNIT[k] for k in self.model.param_kinds])[self.active]
        return float(np.sum(self.K[self.active] * (d * unit) ** (-self.alpha[self.active])))

    def index_I(self, delta) -> float:
        """Eq. 21 relative-cost index ``sum w_j |delta_j - Delta_j|``, m (the paper's mm divided by 1000)."""
        d = np.asarray(delta, dtype=float)
        unit = np.array([COST_UNIT[k] for k in self.model.param_kinds])
        a = self.active
        return float(np.sum(self.weights[a] * np.abs(d[a] - self.ceilings[a]) * unit[a])) * 1e-3

    def values(self, J, delta, criterion=None) -> np.ndarray:
        """(n,) criterion values for Jacobian rows J (n, 3, p) and tolerances delta (p,)."""
        criterion = criterion or self.criterion
        if criterion not in LIMIT_CRITERIA:
            raise SynthesisError(f"criterion: expected one of {LIMIT_CRITERIA}, got {criterion!r}")
        return criterion_bound(J, np.where(self.active, delta, 0.0), criterion, self.k_sigma)

    def upper(self, J, delta, criterion=None) -> np.ndarray | None:
        """A cheap upper bound of ``values`` where the criterion is expensive (worst case), else None."""
        if (criterion or self.criterion) == "worst-case":
            return per_axis_bound(J, np.where(self.active, delta, 0.0))
        return None

    def quadratic_forms(self, J, delta, criterion=None) -> np.ndarray:
        """(n, p, p) matrices M with ``criterion(delta') = sqrt(delta' M delta')`` near ``delta`` at each pose
        (for 'worst-case' the signs are those of the worst vertex at ``delta``). J and delta share their
        columns (all parameters, or only the active ones)."""
        criterion = criterion or self.criterion
        if criterion == "paper":
            return np.einsum("nkp,nkq->npq", J, J)
        if criterion == "worst-case":
            _, s = worst_case_bound(J, delta, return_signs=True)
            A = J * s[:, None, :]
            return np.einsum("nkp,nkq->npq", A, A)
        if criterion == "rss":
            c2 = np.einsum("nkp,nkp->np", J, J) * (self.k_sigma / 3.0) ** 2
            return np.einsum("np,pq->npq", c2, np.eye(J.shape[2]))
        raise SynthesisError(f"criterion: expected one of {LIMIT_CRITERIA}, got {criterion!r}")

    def to_dict(self) -> dict:
        names = self.model.param_names
        return {"robot": self.model.name, "limit_position_m": self.limit,
                "limit_orientation_rad": self.orientation_limit, "criterion": self.criterion,
                "k_sigma": self.k_sigma if self.criterion == "rss" else None,
                "floors": dict(zip(names, self.floors)), "ceilings": dict(zip(names, self.ceilings)),
                "free": [n for n, a in zip(names, self.active) if not a]}


def build_problem(model: Mechanism, limit: float, orientation_limit: float | None = None,
                  criterion=DEFAULT_LIMIT_CRITERION, floors=None, k_sigma: float = 3.0, cost_K=None, cost_alpha=1.0,
                  samples=20000, seed=0) -> SynthesisProblem:
    """Set up an allocation problem: validate inputs, compute the ceilings over the workspace.

    floors : None (paper defaults 0.05 mm, 0.0003 rad), a dict by kind {'length': m, 'angle': rad}, by
        parameter name, or both (names override kinds).  cost_K : dict by kind or name (defaults 1 for
        lengths, 1.5 for angles).  cost_alpha : scalar or dict.
    """
    if criterion not in LIMIT_CRITERIA:
        raise SynthesisError(f"criterion: expected one of {LIMIT_CRITERIA}, got {criterion!r}")
    if not (isinstance(limit, (int, float)) and np.isfinite(limit) and limit > 0):
        raise SynthesisError(f"limit: the position limit must be a positive length in m, got {limit!r}")
    if orientation_limit is not None and not (np.isfinite(orientation_limit) and orientation_limit > 0):
        raise SynthesisError(f"orientation_limit: must be a positive angle in rad, got {orientation_limit!r}")
    if not (np.isfinite(k_sigma) and k_sigma > 0):
        raise SynthesisError(f"k_sigma: must be positive, got {k_sigma!r}")
    names, kinds = model.param_names, model.param_kinds
    fl = _per_param(model, floors, DEFAULT_FLOORS, "floors")
    if np.any(fl <= 0):
        bad = [n for n, v in zip(names, fl) if v <= 0]
        raise SynthesisError(f"floors: must be > 0, got {bad}")
    K = _per_param(model, cost_K, DEFAULT_K, "cost_K")
    alpha = _per_param(model, cost_alpha if isinstance(cost_alpha, dict) else
                       {"length": cost_alpha, "angle": cost_alpha}, {"length": 1.0, "angle": 1.0}, "cost_alpha")
    mu_p = column_maxima(model, "position", samples, seed=seed)
    mu_o = column_maxima(model, "orientation", samples, seed=seed) if orientation_limit is not None \
        else np.zeros(len(names))
    with np.errstate(divide="ignore"):
        ceil = np.where(mu_p > 0, limit / np.where(mu_p > 0, mu_p, 1), np.inf)
        if orientation_limit is not None:
            ceil = np.minimum(ceil, np.where(mu_o > 0, orientation_limit / np.where(mu_o > 0, mu_o, 1), np.inf))
    active = np.isfinite(ceil)
    if not active.any():
        raise SynthesisError("no parameter moves the constrained errors; nothing to allocate")
    high = [f"{n} (floor {fl[j]:.4g} > ceiling {ceil[j]:.4g} {model.param_units[j]})"
            for j, n in enumerate(names) if active[j] and fl[j] > ceil[j]]
    if high:
        raise InfeasibleError("floors above ceilings: " + ", ".join(high) + "; even alone these errors exceed "
                             "the limit somewhere in the workspace: lower their floors or raise the limit")
    unit = np.array([COST_UNIT[k] for k in kinds])
    weights = mu_p / unit  # eq. 22: max mu_j in mm per mm or mm per rad
    return SynthesisProblem(model, float(limit), orientation_limit, criterion, float(k_sigma), fl, ceil, active, K,
                            alpha, weights * 1e3, mu_p, mu_o, seed, samples)


def _per_param(model, spec, defaults, field):
    names, kinds = model.param_names, model.param_kinds
    spec = dict(spec or {})
    by_kind = {**defaults, **{k: v for k, v in spec.items() if k in ("length", "angle")}}
    by_name = {k: v for k, v in spec.items() if k not in ("length", "angle")}
    unknown = sorted(set(by_name) - set(names))
    if unknown:
        raise SynthesisError(f"{field}: unknown parameter name(s) {unknown} for robot {model.name!r}")
    out = np.array([float(by_name.get(n, by_kind[k])) for n, k in zip(names, kinds)])
    if not np.all(np.isfinite(out)):
        raise SynthesisError(f"{field}: values must be finite")
    return out
