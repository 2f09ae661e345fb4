"""Calibration: the identified parameter errors of a measured robot, checked on poses the fit did not see.

``calibrate`` registers the tracker to the nominal base frame (as ``report`` does), then identifies the
parameter errors and a base correction with ``accuracy.identification.identify`` (no prior: every
estimated parameter comes from the data; a minimal set of dependent parameters is held at nominal,
QR with column pivoting at the nominal parameters; the covariance is scaled by the residual noise).
Validation is k-fold by test pose: the test poses are split into k folds (seeded); each fold is
predicted by a registration and a fit made without any of its poses, and compared with its
measurements before (nominal model) and after (calibrated model): position and orientation error RMS
and max, and ISO 9283 AP per test pose.

The calibrated model is ``T = B @ T_nominal(q, dx)`` in the nominal base frame that the registration
defines (``B``: the identified base correction, which also carries the held parameters of the first
joint); ``calibrated_mechanism`` builds it as a model of the input's own kind. SI throughout.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from ..accuracy.identification import BASE_NAMES, base_matrix, identify
from ..accuracy.iso9283 import pose_characteristics
from ..accuracy.registration import register
from ..accuracy.verdicts import pose_errors
from ..geometry import axis_angle_matrix, rpy_from_matrix, transform
from ..models.base import PRISMATIC, Mechanism, ModelError
from ..models.dh import DHChain
from ..models.urdf import URDFChain

REGISTRATIONS = ("base", "base+tool")


@dataclass
class Calibration:
    """Identified parameter errors of one robot (SI) and what they rest on.

    dx, std : (p,) errors (identified - nominal) and standard uncertainties, m or rad; 0 where held.
    base : (6,) base correction [x y z (m), rotation vector (rad)], applied on the left of the model.
    T_tracker_base : 4x4 registration, nominal base frame -> tracker frame.  tool_offset : (3,) m or None.
    held : parameters left at nominal (not identifiable from these poses).  aliases : what each
    estimated unknown absorbs of the held ones (see ``Identification``).  validation : see ``validate``.
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

    @property
    def B(self) -> np.ndarray:
        """4x4 base correction."""
        return base_matrix(self.base)

    def fk(self, model: Mechanism, q) -> np.ndarray:
        """(n, 4, 4) calibrated tool poses in the nominal base frame, m."""
        return self.B @ model.fk(q, self.dx)

    def mechanism(self, model: Mechanism) -> Mechanism:
        """The calibrated model as a Mechanism of the nominal model's kind (see ``calibrated_mechanism``)."""
        return calibrated_mechanism(model, self.dx, self.base)

    def to_dict(self) -> dict:
        """Plain dict, SI (m, rad)."""
        return {"robot": self.robot, "registration": self.registration,
                "parameters": [{"name": n, "unit": "m" if k == "length" else "rad", "error": float(v),
                                "std": float(s), "held": n in self.held, "absorbs": self.aliases.get(n, {})}
                               for n, k, v, s in zip(self.names, self.kinds, self.dx, self.std)],
                "base_correction": dict(zip(BASE_NAMES, map(float, self.base))),
                "base_absorbs": {k: v for k, v in self.aliases.items() if k.startswith("base.")},
                "held": list(self.held), "unidentifiable": list(self.unidentifiable),
                "T_tracker_base": self.T_tracker_base, "tool_offset_m": self.tool_offset,
                "fit": {"measurements": self.measurements, "poses": self.poses, "rows": self.rows,
                        "unknowns": self.unknowns, "rank": self.rank, "condition": self.condition,
                        "fit_condition": self.fit_condition, "noise_m": self.sigma,
                        "residual_rms_before_m": self.residual_rms_before,
                        "residual_rms_after_m": self.residual_rms_after},
                "validation": self.validation, "sources": dict(self.sources)}


def fit(model: Mechanism, q, T_tracker, registration="base", sigma_position=1e-5, sigma_orientation=None):
    """(Registration, Identification) of tracker readings (n, 4, 4) at joints q (n, dof).

    ``sigma_orientation`` (rad) adds the orientation rows, weighted ``sigma_position / sigma_orientation``.
    """
    if registration not in REGISTRATIONS:
        raise ValueError(f"registration: expected one of {REGISTRATIONS}, got {registration!r}")
    q = model.check_joints(q)
    reg = register(model.fk(q), T_tracker, tool=registration == "base+tool")
    ident = identify(model, q, reg.to_base(T_tracker), None, sigma_position, sigma_orientation, iterations=12,
                     hold="dependent", noise_from_residuals=True)
    return reg, ident


def calibrate(model: Mechanism, q, T_tracker, labels=None, registration="base", sigma_position=1e-5,
              sigma_orientation=None, folds=5, seed=0, has_orientation=True, sources=None) -> Calibration:
    """Calibrate from tracker readings T_tracker (n, 4, 4) at joints q (n, dof), with k-fold validation.

    labels : (n,) test-pose name of each measurement, or None (measurements at equal joints form a pose).
    has_orientation : whether the readings carry orientations (orientation errors are validated then).
    """
    q = model.check_joints(q)
    T_tracker = np.asarray(T_tracker, float)
    if T_tracker.shape != (len(q), 4, 4):
        raise ValueError(f"measurements: expected ({len(q)}, 4, 4) poses, got {T_tracker.shape}")
    groups, names = pose_groups(q, labels)
    if len(names) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (measure more poses)")
    reg, ident = fit(model, q, T_tracker, registration, sigma_position, sigma_orientation)
    rows = len(q) * (6 if sigma_orientation is not None else 3)
    cal = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), ident.dx.copy(),
                      ident.std.copy(), ident.base.copy(), reg.T_tracker_base, reg.tool_offset, ident.held,
                      ident.unidentifiable, ident.aliases, ident.condition, ident.fit_condition, ident.rank,
                      model.n_params + 6 - len(ident.held), ident.sigma, ident.residual_rms_before,
                      ident.residual_rms_after, len(q), len(names), rows, registration,
                      sources=dict(sources or {}))
    cal.validation = validate(model, q, T_tracker, groups, registration, sigma_position, sigma_orientation, folds,
                              seed, has_orientation, names)
    return cal


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
             folds=5, seed=0, has_orientation=True, names=None) -> dict:
    """k-fold validation by test pose (see the module docstring); a plain dict, SI.

    Keys: method, folds, poses, measurements; ``before`` and ``after`` with position_rms_m,
    position_max_m, orientation_rms_rad, orientation_max_rad (None without orientations), AP_p_mean_m,
    AP_p_max_m; ``improvement`` (1 - after/before position RMS); ``per_pose`` {index: AP before/after};
    ``position_error_m`` {before, after} per measurement (for plots). ``names`` label the test poses.
    """
    groups = np.asarray(groups, int)
    uniq = np.unique(groups)
    if len(uniq) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (measure more poses)")
    k = int(min(folds, len(uniq)))
    if k < 2:
        raise ValueError("validation: folds must be >= 2")
    fold_of = np.empty(uniq.max() + 1, int)
    fold_of[np.random.default_rng(seed).permutation(uniq)] = np.arange(len(uniq)) % k
    fold = fold_of[groups]
    n = len(q)
    Tb = np.empty((n, 4, 4))
    Tn = np.empty((n, 4, 4))
    Tc = np.empty((n, 4, 4))
    for f in range(k):
        test = fold == f
        reg, ident = fit(model, q[~test], T_tracker[~test], registration, sigma_position, sigma_orientation)
        Tb[test] = reg.to_base(T_tracker[test])
        Tn[test] = model.fk(q[test])
        Tc[test] = base_matrix(ident.base) @ model.fk(q[test], ident.dx)
    out = {"method": f"{k}-fold cross-validation by test pose (seed {seed}): each fold's poses predicted by a "
                     f"registration and a fit made without them",
           "folds": k, "poses": int(len(uniq)), "measurements": int(n)}
    per_pose = {}
    errs = {}
    for label, T_model in (("before", Tn), ("after", Tc)):
        dp, dphi = pose_errors(T_model, Tb)
        ep, eo = np.linalg.norm(dp, axis=1), np.linalg.norm(dphi, axis=1)
        ap = []
        for g in uniq:
            sel = np.flatnonzero(groups == g)
            att = Tb[sel] if len(sel) > 1 else np.repeat(Tb[sel], 2, axis=0)  # AP of one visit: its error
            c = pose_characteristics(T_model[sel[0]], att)
            key = names[g] if names is not None else str(g)
            per_pose.setdefault(key, {"n": int(len(sel)), "fold": int(fold[sel[0]])})
            per_pose[key].update({f"AP_p_{label}_m": c.AP_p,
                                     f"AP_abc_{label}_rad": [c.AP_a, c.AP_b, c.AP_c] if has_orientation else None})
            ap.append(c.AP_p)
        errs[label] = ep
        out[label] = {"position_rms_m": float(np.sqrt(np.mean(ep ** 2))), "position_max_m": float(ep.max()),
                      "orientation_rms_rad": float(np.sqrt(np.mean(eo ** 2))) if has_orientation else None,
                      "orientation_max_rad": float(eo.max()) if has_orientation else None,
                      "AP_p_mean_m": float(np.mean(ap)), "AP_p_max_m": float(np.max(ap))}
    out["improvement"] = 1.0 - out["after"]["position_rms_m"] / out["before"]["position_rms_m"]
    out["per_pose"] = per_pose
    out["position_error_m"] = errs
    return out


def calibrate_measurements(model, meas, campaign=None, registration="base", sigma_position=1e-5,
                           sigma_orientation=None, folds=5, seed=0) -> Calibration:
    """``calibrate`` for a ``Measurements`` (joints from its columns or from the campaign's test poses)."""
    from ..accuracy.evaluation import measurement_joints
    q = measurement_joints(model, meas, campaign)
    labels = meas.pose if meas.pose is not None and any(str(p) for p in meas.pose) else None
    use_ori = sigma_orientation if meas.has_orientation else None
    return calibrate(model, q, meas.T, labels, registration, sigma_position, use_ori, folds, seed,
                     meas.has_orientation, {"measurements": meas.source})


def calibrated_mechanism(model: Mechanism, dx, base=None) -> Mechanism:
    """The model with parameter errors dx (p,) and base correction [x y z, rotation vector] applied.

    D-H: a DHChain with the identified values and ``base := B @ base``. URDF: a copy of the chain whose
    nominal vector holds the corrected origins (``corrected_origins``), zero offsets.
    """
    dx = np.asarray(dx, float)
    B = base_matrix(np.zeros(6) if base is None else np.asarray(base, float))
    if isinstance(model, DHChain):
        p = model.nominal + dx
        n = model.dof
        return DHChain(model.name, p[:n], p[2 * n:3 * n], p[n:2 * n], p[3 * n:], model.joint_types,
                       model.joint_limits, model.joint_names, model.convention, B @ model.base, model.tool)
    if isinstance(model, URDFChain):
        xyz_rpy, _ = corrected_origins(model, dx, B)
        out = copy.copy(model)
        out.nominal = np.concatenate([np.r_[xyz_rpy[k], 0.0] for k in range(model.dof)])
        return out
    raise ModelError(f"calibration: robot {model.name!r} is a {type(model).__name__}; calibrated models are "
                     f"built for D-H and URDF chains")


def corrected_origins(model: URDFChain, dx, B=None):
    """((dof, 6) xyz (m) and rpy (rad) of each joint origin of a URDF chain with the parameter errors dx
    folded in exactly, (dof,) mask of the joints that changed).

    Each origin takes its xyz/rpy errors, then its zero offset (a turn about, or a shift along, the joint
    axis); the base correction B (4x4, model base frame) is folded into the first origin. Where neither
    an offset nor B turns an origin, its rpy are the parameter values themselves (no round trip).
    """
    dx = np.asarray(dx, float)
    p = model.nominal + dx
    out = np.empty((model.dof, 6))
    changed = np.zeros(model.dof, bool)
    identity = B is None or np.array_equal(B, np.eye(4))
    for k in range(model.dof):
        x, y, z, roll, pitch, yaw, off = p[7 * k:7 * k + 7]
        changed[k] = bool(np.any(dx[7 * k:7 * k + 7] != 0)) or (k == 0 and not identity)
        if off == 0 and (k > 0 or identity):
            out[k] = (x, y, z, roll, pitch, yaw)
            continue
        O = transform([x, y, z], [roll, pitch, yaw])
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
