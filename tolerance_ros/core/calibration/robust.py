"""One robust fit of a calibration candidate: the registration, the identification, the outliers.

``fit`` registers the tracker to the nominal base frame (globally, with each target's offset on the tool
when asked), then identifies the candidate's parameter errors, a base correction and the targets together
(``identification.identify``: converged Levenberg-Marquardt, a minimal set of dependent
parameters held at nominal, judged at nominal and at the solution). A regularised candidate weighs its
Gaussian prior against the fit's own residual noise (a fixed point: fit, estimate the noise from its
residuals, fit again); the registration carries no prior unless ``FitOptions.registration_prior`` asks.

Robust: the outliers are judged with the residuals of this fit itself, never inherited from a stiffer
model: fit, reject the measurements whose position residual exceeds ``checks.REJECT`` robust sigmas (the median
residual over that of a 3-D normal error, never below the tracker's noise), fit again, until the set is
stable. Each residual is first divided by its own spread: a fitted row's by ``sqrt(1 - h)`` (the fit absorbs
its leverage ``h``), a row left out by ``sqrt(1 + h)`` (its residual is a prediction), so that a row is
judged alike in or out of the fit and a good row once rejected comes back. At most ``checks.MAX_REJECTED`` of the
measurements are rejected; a rejection that would change which parameters are identifiable is not made:
those measurements are kept and listed as ``suspect``. SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..identification import FitOptions, Unknowns, base_matrix, identify
from ..accuracy.checks import outliers
from ..accuracy.registration import register
from ..models.base import PRISMATIC, Mechanism

MODELS = ("registration", "joint-offsets", "full", "full+elastic")
DEFLECTION = (0.01, 0.03)   # m, rad: prior std of a joint's elastic deflection at its largest load (regularised fits)
TOL_RANK = 1e-6             # a parameter whose scaled pivot is below this share of the largest is held
ROUNDS = 12                 # fit-judge-refit rounds (the rejected set and the noise settle in two to four)
NOISE_SETTLED = 1e-3        # the prior's noise is settled when a round changes it by less than this share


@dataclass
class FitData:
    """The measurements of a fit: joints q (n, dof) rad or m, tracker readings T (n, 4, 4) m, each row's target
    ``idx`` (n,) among ``names``, whether the readings are frames, and the joints' gravity loads (n, dof) N m
    or N (None without an elastostatic term)."""

    q: np.ndarray
    T: np.ndarray
    idx: np.ndarray
    names: tuple = ("",)
    frames: bool = True
    gravity: np.ndarray | None = None

    def __post_init__(self):
        self._registrations = {}

    def __len__(self):
        return len(self.q)

    def registration(self, model: Mechanism, tool: bool):
        """The global registration of these measurements to ``model``'s nominal poses (made once per kind)."""
        key = (id(model), bool(tool))
        if key not in self._registrations:
            self._registrations[key] = register(model.fk(self.q), self.T, tool=tool, index=self.idx, names=self.names,
                                                frames=self.frames)
        return self._registrations[key]

    def subset(self, rows) -> "FitData":
        return FitData(self.q[rows], self.T[rows], self.idx[rows], self.names, self.frames,
                       None if self.gravity is None else self.gravity[rows])


@dataclass
class Fit:
    """One robust fit: the registration, the identification, the rows it rejected (mask), its threshold (m),
    the rows kept although beyond it (``suspect``: their removal would change what is identifiable), and
    the noise the prior was weighed against (m, per axis)."""

    reg: object
    ident: object
    rejected: np.ndarray
    threshold: float
    suspect: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    noise: float = 0.0

    @property
    def converged(self) -> bool:
        return self.ident.convergence is None or self.ident.convergence.converged

    @property
    def row_thresholds(self) -> np.ndarray:
        """(n,) each measurement's rejection threshold on its position residual (m): ``threshold`` times its
        residual's share of the noise (``_spread``)."""
        return self.threshold * _spread(self.ident, self.rejected)


def estimate_sets(model: Mechanism, which: str, gravity):
    """(names of the parameters to estimate, (dof,) mask of the compliances to estimate or None)."""
    if which not in MODELS:
        raise ValueError(f"parameters: expected 'auto' or one of {list(MODELS)}, got {which!r}")
    if which == "registration":
        return [], None
    if which == "joint-offsets":
        return [model.param_names[j] for j in model.joint_columns()], None
    if which == "full":
        return list(model.param_names), None
    if gravity is None:
        raise ValueError(f"parameters: 'full+elastic' needs a URDF robot (robot {model.name!r} has no gravity load "
                         f"model)")
    return list(model.param_names), np.ptp(gravity, axis=0) > 1e-9


def prior_vector(model: Mechanism, prior) -> np.ndarray | None:
    """(p,) prior standard deviations of a regularised fit: ``prior`` = (length m, angle rad) for every
    origin error, joint zero offsets unregularised (they are often large); None without a prior."""
    if prior is None:
        return None
    delta = np.array([prior[0] if k == "length" else prior[1] for k in model.param_kinds], float)
    delta[model.joint_columns()] = np.inf
    return delta


def _spread(ident, rejected) -> np.ndarray:
    """(n,) standard deviation of each measurement's residual in units of the noise: ``sqrt(1 - h)`` for a fitted
    row (the fit absorbs its share ``h``, its leverage), ``sqrt(1 + h)`` for a row left out (its residual is a
    prediction); ones without leverages."""
    h = getattr(ident, "row_leverage", None)
    if h is None:
        return np.ones(len(rejected))
    return np.sqrt(np.where(rejected, 1.0 + h, np.maximum(1.0 - h, 1e-6)))


def _judge(r, rejected, sigma_position):
    """(rows beyond the threshold (n,), threshold m) of standardised position residuals ``r`` (n,) m (each
    divided by its ``_spread``, so that a row is judged alike whether it is in the fit or left out of it): the
    kept rows' spread, never below what the tracker's own noise explains (``checks.outliers``)."""
    kept = ~rejected if np.any(~rejected) else np.ones(len(r), bool)
    return outliers(r, kept, sigma_position)


def fit(model: Mechanism, data: FitData, which: str, prior, opts: FitOptions, analysis=True) -> Fit:
    """The robust fit of candidate ``which`` (``MODELS``) with ``prior`` (m, rad) or None (see the module
    docstring)."""
    tool = opts.registration == "base+tool"
    if len(data.names) > 1 and not tool:
        raise ValueError(f"registration: {len(data.names)} targets ({', '.join(data.names)}) sit at different points "
                         f"of the tool; fit their offsets with registration 'base+tool'")
    n = len(data)
    estimate, cmask = estimate_sets(model, which, data.gravity)
    sigma = opts.sigma_position
    use_ori = opts.sigma_orientation if data.frames else None
    reg = data.registration(model, tool)
    T_base = reg.to_base(data.T)
    delta = prior_vector(model, prior) if estimate else None
    cprior = None
    if delta is not None and cmask is not None:
        deflection = np.where(np.array(model.joint_types) == PRISMATIC, DEFLECTION[0], DEFLECTION[1])
        top = np.abs(data.gravity).max(axis=0)
        cprior = deflection / np.where(top > 0, top, 1.0)
    noise = max(reg.rms / np.sqrt(3.0), sigma) if delta is not None else sigma

    unknowns = Unknowns(estimate=estimate, targets=reg.targets, target_index=data.idx, estimate_targets=tool,
                        gravity=data.gravity, compliance=cmask, compliance_prior=cprior)

    def identify_with(rows_out, noise, start):
        noisy = opts.updated(sigma_position=noise,
                             sigma_orientation=None if use_ori is None else use_ori * noise / sigma)
        return identify(model, data.q, T_base, delta, noisy, unknowns, hold="dependent", noise_from_residuals=True,
                        tol_rank=TOL_RANK, analysis=analysis, start=start,
                        weights=None if not rows_out.any() else (~rows_out).astype(float))

    rejected = np.zeros(n, bool)
    suspect = np.zeros(n, bool)
    threshold = np.inf
    ident = identify_with(rejected, noise, None)
    whole = ident  # the fit of every row: what the data identify when nothing is left out
    for _ in range(ROUNDS):
        new_noise = max(ident.sigma, sigma) if delta is not None else noise
        new = rejected
        if opts.robust:
            new, threshold = _judge(ident.row_residuals / _spread(ident, rejected), rejected, sigma)
            new &= ~suspect
        if np.array_equal(new, rejected) and abs(new_noise / noise - 1.0) < NOISE_SETTLED:
            break
        trial = identify_with(new, new_noise, ident)
        if new.any() and _loses_identifiability(whole, trial):
            suspect |= new
            new = rejected
            trial = identify_with(new, new_noise, ident)
        rejected, noise, ident = new, new_noise, trial
    return Fit(reg, ident, rejected, threshold, suspect & ~rejected, noise)


def _loses_identifiability(whole, trial) -> bool:
    """True when ``trial`` (some rows left out) holds a parameter or compliance that ``whole`` estimates."""
    return bool(set(trial.held) - set(whole.held)) or \
        bool(set(getattr(trial, "compliance_held", [])) - set(getattr(whole, "compliance_held", [])))


def predict(model: Mechanism, fitted: Fit, data: FitData):
    """(measured (n, 4, 4) in the base frame, calibrated prediction (n, 4, 4)) of rows by a fit."""
    ident = fitted.ident
    q = data.q if ident.compliance is None else data.q + data.gravity * ident.compliance
    T = base_matrix(ident.base) @ model.fk(q, ident.dx)
    return fitted.reg.to_base(data.T), ident.targets.poses(T, data.idx)
