"""Calibration: the identified errors of a measured robot, chosen by what predicts poses the fit did not see,
fitted robustly and checked for plausibility.

``calibrate`` registers the tracker to the nominal base frame (globally, with each target's offset on the
tool when asked, as ``report`` does), then identifies the parameter errors, a base correction and the
targets' offsets together with ``accuracy.identification.identify`` (no prior: every estimated parameter
comes from the data; a minimal set of dependent parameters is held at nominal, QR with column pivoting
at the nominal parameters; the covariance is scaled by the residual noise).

What to identify (``parameters``): ``registration`` (nothing but the tracker and the targets),
``joint-offsets`` (each joint's zero offset), ``full`` (every parameter of the error model) or
``full+elastic`` (and, for a URDF with inertials, a compliance per joint times its gravity load, see
``elastic``); the full sets also regularised: a Gaussian prior (``PRIOR``) on every origin error, one on
each compliance (its deflection at the largest load of the data, ``DEFLECTION``), none on the joint
offsets; only dependent unregularised columns are held. ``auto`` cross-validates each candidate and keeps
the simplest whose held-out position RMS is within ``PARSIMONY`` of the lowest: what predicts best, not
what fits best.

Validation is k-fold by test pose: the test poses are split into k folds (seeded); each fold is predicted
by a registration and a fit made without any of its poses, and compared with its measurements before
(nominal model, with its own registration) and after (calibrated model): position (and, for measured
frames, orientation) error RMS and max, and ISO 9283 AP per test pose and target.

Robust: each fit rejects the measurements whose position residual exceeds ``REJECT`` times the robust
noise (the median residual over that of a 3-D normal error), and fits again until the set is stable,
starting from the outliers of the registration-only fit (a flexible model can absorb an outlier that the
stiff one shows); every rejected measurement is listed with its residual and the threshold. A row that any
candidate's fit rejects is left out of every candidate's cross-validated score. Plausibility: a calibration
whose measurements do not spread like the robot (a unit mistake), whose identified errors exceed
``PLAUSIBLE_LENGTH`` of the robot's reach or ``PLAUSIBLE_ANGLE``, or whose held-out error does not fall,
is refused (``plausibility["ok"]`` False, with the reasons).

The calibrated model is ``T = B @ T_nominal(q + c g(q), dx) @ X_k`` in the nominal base frame that the
registration defines (``B``: the identified base correction, which also carries the held parameters of the
first joint; ``X_k``: the target's frame in the tool frame); ``calibrated_mechanism`` builds the chain part
as a model of the input's own kind. SI throughout.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from .. import interrupt
from ..accuracy.identification import BASE_NAMES, base_matrix, identify
from ..accuracy.iso9283 import pose_characteristics
from ..accuracy.registration import register, spread_ratio
from ..accuracy.targets import AtTarget, Targets
from ..accuracy.verdicts import pose_errors
from ..geometry import axis_angle_matrix, rpy_from_matrix, transform
from ..models.base import PRISMATIC, Mechanism, ModelError
from ..models.dh import DHChain
from ..models.urdf import URDFChain
from .elastic import DeflectedChain, gravity_loads, has_inertials

REGISTRATIONS = ("base", "base+tool")
MODELS = ("registration", "joint-offsets", "full", "full+elastic")
DEFLECTION = (0.01, 0.03)   # m, rad: prior std of a joint's elastic deflection at its largest load (regularised fits)
PRIOR = (0.01, 0.01)        # m, rad: default prior std of the origin errors of a regularised fit
PARSIMONY = 0.01            # the simplest candidate within this share of the lowest cross-validated RMS wins
CHI3_MEDIAN = 1.5382        # median of |e| for e ~ N(0, I3): sqrt(chi2_3 median)
REJECT = 4.594              # |e| / sigma beyond which a residual is an outlier: sqrt(chi2_3 quantile 0.9999)
TOL_RANK = 1e-6             # a parameter whose scaled pivot is below this share of the largest is held
MAX_REJECTED = 0.25         # at most this share of the measurements is rejected
PLAUSIBLE_LENGTH = 0.05     # identified length errors above this fraction of the robot's reach are refused
PLAUSIBLE_ANGLE = 0.2       # rad: identified angle errors (and elastic deflections) above this are refused
PLAUSIBLE_SPREAD = (0.5, 2.0)  # measured over nominal spread of the points: outside, the units are wrong
REPEATED = 0.02             # rad or m: a posture within this of a training one repeats it
INSIDE_MARGIN = 0.05        # rad or m: the training ranges widened by this are "inside"


@dataclass
class Calibration:
    """Identified parameter errors of one robot (SI) and what they rest on.

    dx, std : (p,) errors (identified - nominal) and standard uncertainties, m or rad; 0 where held.
    base : (6,) base correction [x y z (m), rotation vector (rad)], applied on the left of the model.
    T_tracker_base : 4x4 registration, nominal base frame -> tracker frame.  targets : the measured
    targets' frames in the tool frame (``targets_std`` their points' uncertainties, m).  compliance :
    (dof,) rad/(N m) or m/N per joint, or None (no elastostatic term).  held : parameters left at nominal
    (not identifiable from these poses).  aliases : what each estimated unknown absorbs of the held ones
    (see ``Identification``).  nominal_registration : tracker and targets of the registration-only fit
    (how the nominal robot is predicted, for ``before`` figures).  model : the identified set chosen and
    the cross-validation of the candidates.  rejected : measurements left out as outliers, with reasons.
    plausibility : {ok, problems}.  training : the training joints' ranges and postures (to group the
    postures of another campaign).  validation : see ``validate``.
    """

    robot: str
    names: tuple
    kinds: tuple
    dx: np.ndarray
    std: np.ndarray
    base: np.ndarray
    T_tracker_base: np.ndarray
    tool_offset: np.ndarray | None
    held: list
    unidentifiable: list
    aliases: dict
    condition: float
    fit_condition: float
    rank: int
    unknowns: int
    sigma: float
    residual_rms_before: float
    residual_rms_after: float
    measurements: int
    poses: int
    rows: int
    registration: str = "base"
    validation: dict | None = None
    sources: dict = field(default_factory=dict)
    targets: Targets | None = None
    targets_std: np.ndarray | None = None
    compliance: np.ndarray | None = None
    compliance_std: np.ndarray | None = None
    nominal_registration: dict | None = None
    model: dict = field(default_factory=dict)
    rejected: list = field(default_factory=list)
    plausibility: dict = field(default_factory=lambda: {"ok": True, "problems": []})
    repeatability: dict | None = None
    training: dict | None = None
    has_orientation: bool = True

    def __post_init__(self):
        if self.targets is None:
            self.targets = (Targets.from_offsets([""], [self.tool_offset]) if self.tool_offset is not None
                            else Targets.at_tool(frames=self.has_orientation))

    @property
    def B(self) -> np.ndarray:
        """4x4 base correction."""
        return base_matrix(self.base)

    def fk(self, model: Mechanism, q, target_index=None) -> np.ndarray:
        """(n, 4, 4) calibrated target frames (the tool frame without targets) in the nominal base frame, m."""
        T = self.B @ self.mechanism_chain(model).fk(q, self.dx)
        return self.targets.poses(T, target_index if target_index is not None else [])

    def mechanism_chain(self, model: Mechanism) -> Mechanism:
        """The nominal model with the elastostatic term, when there is one (parameters not applied)."""
        if self.compliance is not None and np.any(self.compliance):
            return DeflectedChain(model, self.compliance)
        return model

    def tool_point(self, target=None) -> tuple:
        """(name, 4x4 frame in the tool frame) of the target that is the tool point: ``target`` by name, or
        the first; ValueError for a name the calibration does not have."""
        names = self.targets.names
        if target is None:
            return names[0], self.targets.X[0]
        if str(target) not in names:
            raise ValueError(f"target: {target!r} is not one of the calibration's targets {list(names)}")
        return str(target), self.targets.X[names.index(str(target))]

    def mechanism(self, model: Mechanism, target=None) -> Mechanism:
        """The calibrated model: a Mechanism of the nominal model's kind (see ``calibrated_mechanism``), its
        joints deflected by the elastostatic term when there is one, its tool at the calibration's tool
        point (``tool_point``) when that is not the tool frame itself."""
        return self._at_tool_point(self.calibrated_chain(model), target)

    def calibrated_chain(self, model: Mechanism) -> Mechanism:
        """The calibrated chain, its tool frame the model's own (the targets are applied by who measures them)."""
        chain = calibrated_mechanism(model, self.dx, self.base)
        return DeflectedChain(chain, self.compliance) if self.compliance is not None and np.any(self.compliance) \
            else chain

    def nominal_at_tool_point(self, model: Mechanism, target=None) -> Mechanism:
        """The nominal model with its tool at the calibration's tool point (what the calibrated one is compared
        with)."""
        return self._at_tool_point(model, target)

    def _at_tool_point(self, chain, target):
        name, X = self.tool_point(target)
        return chain if np.array_equal(X, np.eye(4)) else AtTarget(chain, X, name)

    def to_dict(self) -> dict:
        """Plain dict, SI (m, rad)."""
        comp = None
        if self.compliance is not None:
            comp = {"unit": "rad/(N m) for revolute joints, m/N for prismatic ones",
                    "joints": {n: {"compliance": float(c), "std": float(s)} for n, c, s in
                               zip(self._joint_names(), self.compliance, self.compliance_std)}}
        return {"robot": self.robot, "registration": self.registration, "model": self.model,
                "parameters": [{"name": n, "unit": "m" if k == "length" else "rad", "error": float(v),
                                "std": float(s), "held": n in self.held, "absorbs": self.aliases.get(n, {})}
                               for n, k, v, s in zip(self.names, self.kinds, self.dx, self.std)],
                "base_correction": dict(zip(BASE_NAMES, map(float, self.base))),
                "base_absorbs": {k: v for k, v in self.aliases.items() if k.startswith("base.")},
                "held": list(self.held), "unidentifiable": list(self.unidentifiable),
                "T_tracker_base": self.T_tracker_base, "tool_offset_m": self.tool_offset,
                "targets": [{"name": n, "xyz_m": X[:3, 3].tolist(), "rotation": X[:3, :3].tolist(),
                             "std_m": None if self.targets_std is None else self.targets_std[k].tolist()}
                            for k, (n, X) in enumerate(zip(self.targets.names, self.targets.X))],
                "orientation_measured": self.has_orientation, "compliance": comp,
                "fit": {"measurements": self.measurements, "poses": self.poses, "rows": self.rows,
                        "unknowns": self.unknowns, "rank": self.rank, "condition": self.condition,
                        "fit_condition": self.fit_condition, "noise_m": self.sigma,
                        "residual_rms_before_m": self.residual_rms_before,
                        "residual_rms_after_m": self.residual_rms_after},
                "rejected": list(self.rejected), "plausibility": dict(self.plausibility),
                "repeatability": self.repeatability, "validation": self.validation, "sources": dict(self.sources)}

    def _joint_names(self):
        return self.sources.get("joint_names") or [f"joint{i + 1}" for i in range(len(self.compliance))]


@dataclass
class _Fit:
    """One robust fit: the registration, the identification and the rows it rejected (mask, threshold m)."""

    reg: object
    ident: object
    rejected: np.ndarray
    threshold: float


def _estimate(model: Mechanism, which: str, gravity):
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
        raise ValueError(f"parameters: 'full+elastic' needs a URDF robot with inertials (robot {model.name!r} has "
                         f"no gravity load model)")
    return list(model.param_names), np.ptp(gravity, axis=0) > 1e-9


def prior_vector(model: Mechanism, prior) -> np.ndarray | None:
    """(p,) prior standard deviations of a regularised fit: ``prior`` = (length m, angle rad) for every
    origin error, joint zero offsets unregularised (they are often large); None without a prior."""
    if prior is None:
        return None
    delta = np.array([prior[0] if k == "length" else prior[1] for k in model.param_kinds], float)
    delta[model.joint_columns()] = np.inf
    return delta


def robust_identify(model, q, T_base, targets, idx, estimate_targets, sigma_position, sigma_orientation,
                    estimate, gravity=None, compliance=None, robust=True, iterations=12, prior=None,
                    noise=None, analysis=True, start=None, deflection=None):
    """(Identification, rejected (n,) mask, threshold m): ``identify`` of ``estimate`` (names) with the
    dependent parameters held, or, with a ``prior`` (p,) of standard deviations (m, rad; inf: none), the
    regularised (MAP) fit, only dependent parameters without a prior held, the data weighted by ``noise``
    (m), and the compliances regularised so that their deflection at the largest load has the prior std
    ``deflection`` (dof,) rad or m; refitted without the
    measurements whose position residual exceeds ``REJECT`` robust sigmas until the rejected set is stable
    (at most ``MAX_REJECTED`` of them; never one within ``REJECT`` tracker noises ``sigma_position``),
    starting from the rows ``start`` (n,) rejected (a stiffer model's outliers, which a flexible one can
    absorb)."""
    kw = dict(delta=None, sigma_position=sigma_position, sigma_orientation=sigma_orientation, iterations=iterations,
              hold="dependent", noise_from_residuals=True, tol_rank=TOL_RANK, targets=targets, target_index=idx,
              estimate_targets=estimate_targets, gravity=gravity, compliance=compliance, estimate=estimate,
              analysis=analysis)
    if prior is not None and estimate:
        kw.update(delta=prior, sigma_position=noise,
                  sigma_orientation=None if sigma_orientation is None else sigma_orientation * noise / sigma_position)
        if compliance is not None and deflection is not None:
            top = np.abs(gravity).max(axis=0)
            kw["compliance_prior"] = np.asarray(deflection, float) / np.where(top > 0, top, 1.0)
    n = len(q)
    rejected = np.zeros(n, bool) if start is None else np.asarray(start, bool).copy()
    ident = identify(model, q, T_base, weights=None if not rejected.any() else (~rejected).astype(float), **kw)
    threshold = np.inf
    if not robust:
        return ident, rejected, threshold
    for _ in range(8):
        r = ident.row_residuals
        sigma = np.median(r[~rejected]) / CHI3_MEDIAN
        threshold = REJECT * max(sigma, sigma_position)  # never below what the tracker's own noise explains
        new = r > threshold
        cap = int(MAX_REJECTED * n)
        if new.sum() > cap:
            new = np.zeros(n, bool)
            if cap:
                new[np.argsort(r)[-cap:]] = True
        if np.array_equal(new, rejected):
            break
        rejected = new
        ident = identify(model, q, T_base, weights=(~rejected).astype(float), **kw)
    return ident, rejected, float(threshold)


def fit(model: Mechanism, q, T_tracker, registration="base", sigma_position=1e-5, sigma_orientation=None,
        target_index=None, target_names=("",), frames=True, parameters="full", gravity=None, robust=True, prior=None):
    """(Registration, Identification) of tracker readings (n, 4, 4) at joints q (n, dof): the global
    registration, then the robust identification of ``parameters`` with the base and the targets
    (regularised with ``prior`` = (length m, angle rad), see ``prior_vector``)."""
    f = _fit(model, model.check_joints(q), np.asarray(T_tracker, float), registration, sigma_position,
             sigma_orientation, target_index, target_names, frames, parameters, gravity, robust, prior)
    return f.reg, f.ident


def _fit(model, q, T_tracker, registration, sigma_position, sigma_orientation, idx, names, frames, which, gravity,
         robust, prior=None, analysis=True, start=None) -> _Fit:
    if registration not in REGISTRATIONS:
        raise ValueError(f"registration: expected one of {REGISTRATIONS}, got {registration!r}")
    tool = registration == "base+tool"
    if len(names) > 1 and not tool:
        raise ValueError(f"registration: {len(names)} targets ({', '.join(names)}) sit at different points of the "
                         f"tool; fit their offsets with registration 'base+tool'")
    idx = np.zeros(len(q), int) if idx is None else np.asarray(idx, int)
    T_tool = model.fk(q)
    estimate, cmask = _estimate(model, which, gravity)
    deflection = None if prior is None else np.where(np.array(model.joint_types) == PRISMATIC, DEFLECTION[0],
                                                     DEFLECTION[1])
    out = np.zeros(len(q), bool) if start is None else np.asarray(start, bool)
    for _ in range(4):  # the registration and the prior's noise from the rows the last fit kept
        keep = ~out if np.count_nonzero(~out) >= 3 else np.ones(len(q), bool)
        reg = register(T_tool[keep], T_tracker[keep], tool=tool, index=idx[keep], names=names, frames=frames)
        noise = max(reg.rms / np.sqrt(3.0), sigma_position)  # per-axis noise the prior weighs against (an upper bound)
        ident, rejected, thr = robust_identify(model, q, reg.to_base(T_tracker), reg.targets, idx, tool,
                                               sigma_position, sigma_orientation, estimate, gravity, cmask, robust,
                                               prior=prior_vector(model, prior), noise=noise, analysis=analysis,
                                               start=out, deflection=deflection)
        if np.array_equal(rejected, out):
            break
        out = rejected
    return _Fit(reg, ident, rejected, thr)


def _predict(model, fitted: _Fit, q, T_tracker, idx, gravity=None):
    """(measured (n, 4, 4) base frame, calibrated prediction (n, 4, 4)) of rows by a fit."""
    ident = fitted.ident
    q_eff = q if ident.compliance is None else q + gravity * ident.compliance
    T = base_matrix(ident.base) @ model.fk(q_eff, ident.dx)
    return fitted.reg.to_base(T_tracker), ident.targets.poses(T, idx)


def candidates(model: Mechanism, parameters="auto", prior=PRIOR, gravity=None) -> list:
    """[(label, parameters, prior)] to cross-validate: for 'auto' the registration alone, the joint offsets,
    the full set, the full set regularised with ``prior`` (m, rad) and, where gravity loads the joints,
    the full set with the elastostatic term (regularised too); otherwise the one given."""
    def label(which, pr):
        return which if pr is None else f"{which}, prior {pr[0] * 1e3:g} mm / {pr[1] * 1e3:g} mrad"
    if parameters != "auto":
        _estimate(model, parameters, gravity)
        pr = prior if parameters in ("full", "full+elastic") else None
        return [(label(parameters, pr), parameters, pr)]
    out = [("registration", "registration", None), ("joint-offsets", "joint-offsets", None), ("full", "full", None)]
    if prior is not None:
        out.append((label("full", prior), "full", prior))
    if gravity is not None:
        out.append((label("full+elastic", prior), "full+elastic", prior))
    return out


def calibrate(model: Mechanism, q, T_tracker, labels=None, registration="base", sigma_position=1e-5,
              sigma_orientation=None, folds=10, seed=0, has_orientation=True, sources=None, target_index=None,
              target_names=("",), parameters="auto", robust=True, stamps=None, prior=PRIOR,
              progress=None) -> Calibration:
    """Calibrate from tracker readings T_tracker (n, 4, 4) at joints q (n, dof), with k-fold validation.

    labels : (n,) test-pose name of each measurement, or None (measurements at equal joints form a pose).
    has_orientation : whether the readings carry orientations (orientation errors are fitted and validated
    only then).  target_index, target_names : each row's target and the targets' names (several need
    registration 'base+tool').  parameters : 'auto' (of ``candidates``, the one that predicts held-out poses
    best) or one of ``MODELS``.  prior : (length m, angle rad) prior std of origin errors of the regularised
    fits, or None.  robust : reject outliers (listed in ``rejected``).  stamps : (n,) for the rejected list.
    progress : called with (done, total) after each candidate's cross-validation and the final fit.
    """
    q = model.check_joints(q)
    T_tracker = np.asarray(T_tracker, float)
    n = len(q)
    if T_tracker.shape != (n, 4, 4):
        raise ValueError(f"measurements: expected ({n}, 4, 4) poses, got {T_tracker.shape}")
    names = tuple(target_names)
    idx = np.zeros(n, int) if target_index is None else np.asarray(target_index, int)
    groups, pose_names = pose_groups(q, labels)
    if len(pose_names) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (measure more poses)")
    use_ori = sigma_orientation if has_orientation else None
    gravity = gravity_loads(model, q) if has_inertials(model) else None
    problems = _units_problems(model, q, T_tracker, idx, names)
    scores, validations, fits = [], {}, {}
    todo = candidates(model, parameters, prior, gravity)
    if problems:  # the units cannot be right: no fit beyond the registration's is worth its time
        todo = [("registration", "registration", None)]
    stiff = _fit(model, q, T_tracker, registration, sigma_position, use_ori, idx, names, has_orientation,
                 "registration", None, robust, analysis=False)
    for label, which, pr in todo:  # every candidate's robust fit of all the data: which rows are outliers
        try:
            fits[label] = _fit(model, q, T_tracker, registration, sigma_position, use_ori, idx, names,
                               has_orientation, which, gravity, robust, pr, analysis=False, start=stiff.rejected)
        except (ValueError, np.linalg.LinAlgError):
            continue
    # a row that a candidate's robust fit rejects is left out of every candidate's score, so that outliers
    # neither dominate the comparison nor favour the model that happens to flag them
    exclude = np.zeros(n, bool)
    for f in fits.values():
        exclude |= f.rejected
    for step, (label, which, pr) in enumerate(todo):
        if progress is not None:
            progress(step, len(todo) + 1)
        try:
            validations[label] = validate(model, q, T_tracker, groups, registration, sigma_position, use_ori, folds,
                                          seed, has_orientation, pose_names, parameters=which, target_index=idx,
                                          target_names=names, gravity=gravity, robust=robust, prior=pr,
                                          exclude=exclude)
        except (ValueError, np.linalg.LinAlgError) as exc:
            scores.append({"label": label, "parameters": which, "prior": pr, "error": str(exc)})
            continue
        v = validations[label]
        scores.append({"label": label, "parameters": which, "prior": None if pr is None else list(pr),
                       "cv_position_rms_m": v["after"]["position_rms_m"],
                       "cv_position_max_m": v["after"]["position_max_m"], "unknowns": v["unknowns"]})
    valid = [s for s in scores if "cv_position_rms_m" in s]
    if not valid:
        raise ValueError("calibration: no candidate could be fitted: " + "; ".join(s["error"] for s in scores))
    lowest = min(s["cv_position_rms_m"] for s in valid)
    best = next(s for s in valid if s["cv_position_rms_m"] <= lowest * (1 + PARSIMONY))
    chosen, chosen_prior = best["parameters"], best["prior"]
    final = _fit(model, q, T_tracker, registration, sigma_position, use_ori, idx, names, has_orientation, chosen,
                 gravity, robust, chosen_prior, start=stiff.rejected)
    nominal = stiff
    if progress is not None:
        progress(len(todo) + 1, len(todo) + 1)
    ident, reg = final.ident, final.reg
    rows = int(np.count_nonzero(~final.rejected)) * (6 if use_ori is not None else 3)
    cal = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), ident.dx.copy(),
                      ident.std.copy(), ident.base.copy(), reg.T_tracker_base, None, ident.held,
                      ident.unidentifiable, ident.aliases, ident.condition, ident.fit_condition, ident.rank,
                      ident.n_free, ident.sigma, ident.residual_rms_before, ident.residual_rms_after, n,
                      len(pose_names), rows, registration, sources=dict(sources or {}), targets=ident.targets,
                      targets_std=ident.targets_std, compliance=ident.compliance,
                      compliance_std=ident.compliance_std, has_orientation=has_orientation)
    cal.tool_offset = cal.targets.offsets[0].copy() if registration == "base+tool" and len(names) == 1 else None
    cal.sources.setdefault("joint_names", list(model.joint_names))
    cal.nominal_registration = {"T_tracker_base": nominal.reg.T_tracker_base, "targets": nominal.ident.targets,
                                "base": nominal.ident.base.copy()}
    cal.model = {"parameters": chosen, "prior": chosen_prior, "label": best["label"],
                 "how": "chosen by the lowest cross-validated position RMS" if parameters == "auto" else "given",
                 "candidates": scores, "held_compliance": list(getattr(ident, "compliance_held", []))}
    cal.rejected = _rejected_list(final, stamps, labels, names, idx)
    cal.validation = validations[best["label"]]
    problems += _plausibility_problems(model, cal)
    cal.plausibility = {"ok": not problems, "problems": problems}
    cal.repeatability = repeatability(final.reg.to_base(T_tracker)[:, :3, 3], final, groups, idx, len(names))
    cal.training = {"joint_ranges": np.c_[q.min(axis=0), q.max(axis=0)].tolist(),
                    "postures": np.unique(np.round(q, 6), axis=0).tolist()}
    return cal


def _units_problems(model, q, T_tracker, idx, names) -> list:
    """Reasons the measurements cannot be in the length unit claimed (their spread against the robot's)."""
    ratio = spread_ratio(model.fk(q)[:, :3, 3], T_tracker[:, :3, 3])
    lo, hi = PLAUSIBLE_SPREAD
    if lo <= ratio <= hi:
        return []
    hint = " (metres labelled millimetres?)" if ratio < 0.01 else " (millimetres labelled metres?)" if ratio > 100 \
        else ""
    return [f"units: the measured points spread {ratio:.4g} times as far as the robot's tool moves; the length unit "
            f"of the measurements cannot be right{hint}"]


def _plausibility_problems(model, cal) -> list:
    """Reasons the identified model cannot be right: errors beyond a fraction of the robot's reach or a
    plausible angle, elastic deflections beyond it, a held-out error that does not fall."""
    out = []
    reach = robot_reach(model)
    limit = PLAUSIBLE_LENGTH * reach
    for n, k, v in zip(cal.names, cal.kinds, cal.dx):
        if k == "length" and abs(v) > limit:
            out.append(f"{n}: identified error {v * 1e3:+.4g} mm is more than {PLAUSIBLE_LENGTH * 100:g} % of the "
                       f"robot's reach ({reach:.3g} m)")
        elif k == "angle" and abs(v) > PLAUSIBLE_ANGLE:
            out.append(f"{n}: identified error {v:+.4g} rad is more than {PLAUSIBLE_ANGLE:g} rad")
    far = np.linalg.norm(cal.targets.offsets, axis=1)
    for name, d in zip(cal.targets.names, far):
        if d > max(reach, 1.0):
            out.append(f"target {name or '(unnamed)'}: {d:.4g} m from the tool frame, farther than the robot reaches")
    v = cal.validation
    if v["after"]["position_rms_m"] >= v["before"]["position_rms_m"]:
        out.append(f"hold-out validation: the calibrated model does not reduce the position error RMS "
                   f"({v['before']['position_rms_m'] * 1e3:.4f} mm before, {v['after']['position_rms_m'] * 1e3:.4f} "
                   f"mm after)")
    return out


def robot_reach(model: Mechanism, samples=512) -> float:
    """Largest distance (m) of the tool point from the base origin over seeded joint samples."""
    q = model.sample_joints(samples, 7)
    return float(np.linalg.norm(model.fk(q)[:, :3, 3], axis=1).max())


def _rejected_list(fitted: _Fit, stamps, labels, names, idx) -> list:
    out = []
    r = fitted.ident.row_residuals
    for i in np.flatnonzero(fitted.rejected):
        entry = {"row": int(i), "target": names[idx[i]], "residual_m": float(r[i]), "threshold_m": fitted.threshold,
                 "reason": f"position residual {r[i] * 1e3:.4g} mm exceeds {fitted.threshold * 1e3:.4g} mm "
                           f"({REJECT:g} robust standard deviations of the fit)"}
        if stamps is not None:
            entry["stamp"] = float(stamps[i])
        if labels is not None:
            entry["pose"] = str(labels[i])
        out.append(entry)
    return out


def repeatability(points, fitted: _Fit, groups, idx, n_targets) -> dict:
    """The residual of a fit beside the scatter of repeated visits of one pose (same pose and target):
    ``scatter_m`` is the RMS distance of a repeated measured point (``points`` (n, 3), m) from its pose's
    mean, ``residual_rms_m`` the fit's, ``unexplained_m`` sqrt(residual^2 - scatter^2), what noise does not
    explain (0 when it explains all); None without repeats. Rejected measurements are left out."""
    keep = ~fitted.rejected
    res = float(np.sqrt(np.mean(fitted.ident.row_residuals[keep] ** 2)))
    key = np.asarray(groups, int) * max(n_targets, 1) + np.asarray(idx, int)
    sq, count = 0.0, 0
    for k in np.unique(key[keep]):
        sel = keep & (key == k)
        if sel.sum() >= 2:
            d = points[sel] - points[sel].mean(axis=0)
            sq += float(np.sum(d ** 2))
            count += int(sel.sum()) - 1
    if not count:
        return {"repeated_measurements": 0, "scatter_m": None, "residual_rms_m": res, "unexplained_m": None}
    scatter = float(np.sqrt(sq / count))
    return {"repeated_measurements": count, "scatter_m": scatter, "residual_rms_m": res,
            "unexplained_m": float(np.sqrt(max(res ** 2 - scatter ** 2, 0.0)))}


def pose_groups(q, labels=None):
    """((n,) test-pose index of each measurement, names of the test poses in order of first visit): by
    label when the measurements carry two or more, else by equal joint values (named 'q1', 'q2', ...)."""
    keys = None
    if labels is not None:
        keys = np.asarray([str(v) for v in labels], dtype=object)
        if len(set(keys)) < 2:
            keys = None
    if keys is None:
        _, first, g = np.unique(np.round(np.asarray(q, float), 9), axis=0, return_index=True, return_inverse=True)
        names = None
    else:
        _, first, g = np.unique(keys, return_index=True, return_inverse=True)
        names = keys
    g = np.asarray(g, int).reshape(-1)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    g = rank[g]
    labels_out = [str(names[first[i]]) if names is not None else f"q{j + 1}" for j, i in enumerate(order)]
    return g, labels_out


def validate(model, q, T_tracker, groups, registration="base", sigma_position=1e-5, sigma_orientation=None,
             folds=10, seed=0, has_orientation=True, names=None, parameters="full", target_index=None,
             target_names=("",), gravity=None, robust=True, prior=None, exclude=None) -> dict:
    """k-fold validation by test pose (see the module docstring); a plain dict, SI. ``exclude`` (n,) marks
    measurements left out of every figure (outliers; they still cannot enter a fold's fit as inliers).

    Keys: method, folds, poses, measurements, parameters, unknowns; ``before`` and ``after`` with
    position_rms_m, position_max_m, orientation_rms_rad, orientation_max_rad (None without orientations),
    AP_p_mean_m, AP_p_max_m; ``improvement`` (1 - after/before position RMS); ``per_pose`` {pose (or
    pose@target): AP before/after}; ``position_error_m`` {before, after} per measurement (for plots);
    ``outliers``: held-out measurements beyond their fold's rejection threshold (counted in the figures: a
    score that left out a model's own worst predictions would favour the model that overfits); ``excluded``:
    the measurements ``exclude`` left out.
    ``names`` label the test poses.
    """
    groups = np.asarray(groups, int)
    n = len(q)
    idx = np.zeros(n, int) if target_index is None else np.asarray(target_index, int)
    tnames = tuple(target_names)
    uniq = np.unique(groups)
    if len(uniq) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (measure more poses)")
    k = int(min(folds, len(uniq)))
    if k < 2:
        raise ValueError("validation: folds must be >= 2")
    fold_of = np.empty(uniq.max() + 1, int)
    fold_of[np.random.default_rng(seed).permutation(uniq)] = np.arange(len(uniq)) % k
    fold = fold_of[groups]
    Tb = np.empty((n, 4, 4))
    Tbn = np.empty((n, 4, 4))
    Tn = np.empty((n, 4, 4))
    Tc = np.empty((n, 4, 4))
    outlier = np.zeros(n, bool)
    unknowns = None
    for f in range(k):
        interrupt.check()  # a cancel or time limit stops the cross-validation here (nothing outside a watch)
        test = fold == f
        g = None if gravity is None else gravity[~test]
        nom = _fit(model, q[~test], T_tracker[~test], registration, sigma_position, sigma_orientation, idx[~test],
                   tnames, has_orientation, "registration", None, robust, analysis=False)
        cal = nom if parameters == "registration" else _fit(
            model, q[~test], T_tracker[~test], registration, sigma_position, sigma_orientation, idx[~test], tnames,
            has_orientation, parameters, g, robust, prior, analysis=False, start=nom.rejected)
        unknowns = unknowns or cal.ident.n_free
        Tb[test], Tc[test] = _predict(model, cal, q[test], T_tracker[test], idx[test],
                                      None if gravity is None else gravity[test])
        Tbn[test], Tn[test] = _predict(model, nom, q[test], T_tracker[test], idx[test])
        err = np.linalg.norm(Tb[test, :3, 3] - Tc[test, :3, 3], axis=1)
        outlier[np.flatnonzero(test)[err > cal.threshold]] = True
    keep = np.ones(n, bool) if exclude is None else ~np.asarray(exclude, bool)
    out = {"method": f"{k}-fold cross-validation by test pose (seed {seed}): each fold's poses predicted by a "
                     f"registration and a fit made without them",
           "folds": k, "poses": int(len(uniq)), "measurements": int(n), "parameters": parameters,
           "prior": None if prior is None else list(prior), "unknowns": unknowns}
    per_pose = {}
    errs = {}
    for label, T_model, T_seen in (("before", Tn, Tbn), ("after", Tc, Tb)):
        dp, dphi = pose_errors(T_model, T_seen)
        ep, eo = np.linalg.norm(dp, axis=1), np.linalg.norm(dphi, axis=1)
        ap = []
        for gi in uniq:
            for t in np.unique(idx[groups == gi]):
                sel = np.flatnonzero((groups == gi) & (idx == t) & keep)
                if not len(sel):
                    continue
                att = T_seen[sel] if len(sel) > 1 else np.repeat(T_seen[sel], 2, axis=0)  # AP of one visit: its error
                c = pose_characteristics(T_model[sel[0]], att, has_orientation)
                key = names[gi] if names is not None else str(gi)
                if len(tnames) > 1 or tnames[0]:
                    key = f"{key}@{tnames[t]}"
                per_pose.setdefault(key, {"n": int(len(sel)), "fold": int(fold[sel[0]])})
                per_pose[key].update({f"AP_p_{label}_m": c.AP_p,
                                      f"AP_abc_{label}_rad": [c.AP_a, c.AP_b, c.AP_c] if has_orientation else None})
                ap.append(c.AP_p)
        errs[label] = ep[keep]
        out[label] = {"position_rms_m": float(np.sqrt(np.mean(ep[keep] ** 2))), "position_max_m": float(ep[keep].max()),
                      "orientation_rms_rad": float(np.sqrt(np.mean(eo[keep] ** 2))) if has_orientation else None,
                      "orientation_max_rad": float(eo[keep].max()) if has_orientation else None,
                      "AP_p_mean_m": float(np.mean(ap)), "AP_p_max_m": float(np.max(ap))}
    out["improvement"] = 1.0 - out["after"]["position_rms_m"] / out["before"]["position_rms_m"]
    out["per_pose"] = per_pose
    out["position_error_m"] = errs
    out["outliers"] = [int(i) for i in np.flatnonzero(outlier)]
    out["excluded"] = [int(i) for i in np.flatnonzero(~keep)]
    return out


def calibrate_measurements(model, meas, campaign=None, registration="base", sigma_position=1e-5,
                           sigma_orientation=None, folds=10, seed=0, parameters="auto", robust=True,
                           prior=PRIOR, progress=None) -> Calibration:
    """``calibrate`` for a ``Measurements`` (joints from its columns or from the campaign's test poses)."""
    from ..accuracy.evaluation import measurement_joints
    q = measurement_joints(model, meas, campaign)
    labels = meas.pose if meas.pose is not None and any(str(p) for p in meas.pose) else None
    use_ori = sigma_orientation if meas.has_orientation else None
    return calibrate(model, q, meas.T, labels, registration, sigma_position, use_ori, folds, seed,
                     meas.has_orientation, {"measurements": meas.source}, meas.target_index(), meas.target_names,
                     parameters, robust, meas.stamps, prior, progress)


def calibrated_mechanism(model: Mechanism, dx, base=None) -> Mechanism:
    """The model with parameter errors dx (p,) and base correction [x y z, rotation vector] applied.

    D-H: a DHChain with the identified values and ``base := B @ base``. URDF: a copy of the chain whose
    origins (nominal xyz and rpy) are the corrected ones (``corrected_origins``), no errors, zero offsets.
    """
    dx = np.asarray(dx, float)
    B = base_matrix(np.zeros(6) if base is None else np.asarray(base, float))
    if isinstance(model, DHChain):
        p = model.nominal + dx
        n = model.dof
        return DHChain(model.name, p[:n], p[2 * n:3 * n], p[n:2 * n], p[3 * n:], model.joint_types,
                       model.joint_limits, model.joint_names, model.convention, B @ model.base, model.tool,
                       model.direction, model.joint_offset)
    if isinstance(model, URDFChain):
        xyz_rpy, _ = corrected_origins(model, dx, B)
        out = copy.copy(model)
        out.nominal = np.concatenate([np.r_[xyz_rpy[k, :3], 0.0, 0.0, 0.0, 0.0] for k in range(model.dof)])
        out.origin_rpy = xyz_rpy[:, 3:].copy()
        return out
    raise ModelError(f"calibration: robot {model.name!r} is a {type(model).__name__}; calibrated models are "
                     f"built for D-H and URDF chains")


def corrected_origins(model: URDFChain, dx, B=None):
    """((dof, 6) xyz (m) and rpy (rad) of each joint origin of a URDF chain with the parameter errors dx
    folded in exactly, (dof,) mask of the joints that changed).

    Each origin takes its shift, its turns ``Rx(rx) Ry(ry) Rz(rz)`` after its nominal rotation, then its zero
    offset (a turn about, or a shift along, the joint axis); the base correction B (4x4, model base frame)
    is folded into the first origin. An origin whose rotation nothing changes keeps its rpy values as they
    are (no round trip through a matrix); a changed one is written as the rpy of its exact rotation matrix.
    """
    dx = np.asarray(dx, float)
    p = model.nominal + dx
    out = np.empty((model.dof, 6))
    changed = np.zeros(model.dof, bool)
    identity = B is None or np.array_equal(B, np.eye(4))
    for k in range(model.dof):
        x, y, z, rx, ry, rz, off = p[7 * k:7 * k + 7]
        changed[k] = bool(np.any(dx[7 * k:7 * k + 7] != 0)) or (k == 0 and not identity)
        rpy = model.origin_rpy[k]
        if off == 0 and rx == 0 and ry == 0 and rz == 0 and (k > 0 or identity):
            out[k] = (x, y, z, *rpy)
            continue
        O = transform([x, y, z], rpy)
        O[:3, :3] = O[:3, :3] @ axis_angle_matrix((1.0, 0.0, 0.0), rx) @ axis_angle_matrix((0.0, 1.0, 0.0), ry) \
            @ axis_angle_matrix((0.0, 0.0, 1.0), rz)
        axis = model._axes[k]
        if model.joint_types[k] == PRISMATIC:
            O[:3, 3] += O[:3, :3] @ (axis * off)
        else:
            O[:3, :3] = O[:3, :3] @ axis_angle_matrix(axis, off)
        if k == 0 and not identity:
            F0 = model._fixed[0]
            O = np.linalg.inv(F0) @ B @ F0 @ O
        out[k] = np.r_[O[:3, 3], rpy_from_matrix(O[:3, :3])[0]]
    return out, changed
