"""Cross-validation by test pose: what a calibration candidate predicts of poses its fit did not see.

The test poses are split into k folds (seeded); each fold is predicted by a robust fit made without any of
its poses (``robust.fit``, the same procedure in every fold, its outliers judged by its own residuals) and
compared with its measurements before (the nominal robot with its own registration) and after (the
calibrated model): position (and, for measured frames, orientation) error RMS and max, and ISO 9283 AP per
test pose and target. Every measurement is scored; where some are left out (``exclude``: the outliers),
the figures over the kept ones are given beside, each named. Every RMS is of the 3-D error. SI throughout.
"""
from __future__ import annotations

import numpy as np

from .. import interrupt
from ..accuracy.folds import folds_of
from ..accuracy.iso9283 import pose_characteristics
from ..accuracy.verdicts import pose_errors
from ..identification import FitOptions
from .robust import FitData, fit, predict


class Folds:
    """The k-fold split of a campaign by test pose, shared by every candidate's validation: each fold's training
    and held-out measurements, and the registration-only fit of each training set (the 'before' model), made
    once."""

    def __init__(self, model, data: FitData, groups, opts: FitOptions):
        self.model, self.data, self.opts = model, data, opts
        self.groups = np.asarray(groups, int)
        self.fold, self.k = folds_of(self.groups, opts.folds, opts.seed)
        self.parts = [(self.fold == f, data.subset(self.fold != f), data.subset(self.fold == f)) for f in range(self.k)]
        self._nominal = {}

    def nominal(self, f):
        """The registration-only fit of fold ``f``'s training measurements."""
        if f not in self._nominal:
            self._nominal[f] = fit(self.model, self.parts[f][1], "registration", None, self.opts, analysis=False)
        return self._nominal[f]


def _figures(ep, eo, ap, has_orientation) -> dict:
    return {"position_rms_m": float(np.sqrt(np.mean(ep ** 2))), "position_max_m": float(ep.max()),
            "orientation_rms_rad": float(np.sqrt(np.mean(eo ** 2))) if has_orientation else None,
            "orientation_max_rad": float(eo.max()) if has_orientation else None,
            "AP_p_mean_m": float(np.mean(ap)) if ap else None, "AP_p_max_m": float(np.max(ap)) if ap else None}


def validate(model, data: FitData, groups, which, prior, opts: FitOptions, names=None, exclude=None,
             folds: Folds | None = None) -> dict:
    """k-fold validation of candidate ``which`` with ``prior`` by test pose (see the module docstring); a plain
    dict, SI.

    Keys: method, folds, poses, measurements, parameters, prior, unknowns; ``before`` and ``after`` over every
    measurement, with position_rms_m, position_max_m (3-D), orientation_rms_rad, orientation_max_rad (None
    without orientations), AP_p_mean_m, AP_p_max_m; ``improvement`` (1 - after/before position RMS, every
    measurement); ``per_pose`` {pose (or pose@target): AP before/after}; ``position_error_m`` and
    ``orientation_error_rad`` {before, after} per measurement (for plots); ``outliers``: held-out
    measurements beyond their fold's rejection threshold; ``not_converged``: folds whose fit stopped at its
    iteration cap; and the kept figures of ``kept_figures`` for ``exclude`` (n,).
    ``names`` label the test poses; ``folds`` the split (and its nominal fits) shared with other candidates.
    """
    folds = folds or Folds(model, data, groups, opts)
    groups, fold, k = folds.groups, folds.fold, folds.k
    n = len(data)
    Tb, Tbn = np.empty((n, 4, 4)), np.empty((n, 4, 4))
    Tn, Tc = np.empty((n, 4, 4)), np.empty((n, 4, 4))
    outlier = np.zeros(n, bool)
    unknowns, capped = None, []
    for f in range(k):
        interrupt.check()  # a cancel or time limit stops the cross-validation here (nothing outside a watch)
        test, train, held_out = folds.parts[f]
        nom = folds.nominal(f)
        cal = nom if which == "registration" else fit(model, train, which, prior, opts, analysis=False)
        unknowns = unknowns or cal.ident.n_free
        if not cal.converged or not nom.converged:
            capped.append(f)
        Tb[test], Tc[test] = predict(model, cal, held_out)
        Tbn[test], Tn[test] = predict(model, nom, held_out)
        err = np.linalg.norm(Tb[test, :3, 3] - Tc[test, :3, 3], axis=1)
        outlier[np.flatnonzero(test)[err > cal.threshold]] = True
    out = {"method": f"{k}-fold cross-validation by test pose (seed {opts.seed}): each fold's poses predicted by a "
                     f"registration and a fit made without them; every measurement scored",
           "folds": k, "poses": int(len(np.unique(groups))), "measurements": int(n), "parameters": which,
           "prior": None if prior is None else list(prior), "unknowns": unknowns}
    per_pose, errs, oerrs = {}, {}, {}
    tnames = tuple(data.names)
    for label, T_model, T_seen in (("before", Tn, Tbn), ("after", Tc, Tb)):
        dp, dphi = pose_errors(T_model, T_seen)
        ep, eo = np.linalg.norm(dp, axis=1), np.linalg.norm(dphi, axis=1)
        ap = []
        for gi in np.unique(groups):
            for t in np.unique(data.idx[groups == gi]):
                sel = np.flatnonzero((groups == gi) & (data.idx == t))
                att = T_seen[sel] if len(sel) > 1 else np.repeat(T_seen[sel], 2, axis=0)  # AP of one visit: its error
                c = pose_characteristics(T_model[sel[0]], att, data.frames)
                key = names[gi] if names is not None else str(gi)
                if len(tnames) > 1 or tnames[0]:
                    key = f"{key}@{tnames[t]}"
                per_pose.setdefault(key, {"n": int(len(sel)), "fold": int(fold[sel[0]])})
                per_pose[key].update({f"AP_p_{label}_m": c.AP_p,
                                      f"AP_abc_{label}_rad": [c.AP_a, c.AP_b, c.AP_c] if data.frames else None})
                ap.append(c.AP_p)
        errs[label], oerrs[label] = ep, eo
        out[label] = _figures(ep, eo, ap, data.frames)
    out["improvement"] = 1.0 - out["after"]["position_rms_m"] / out["before"]["position_rms_m"]
    out["per_pose"] = per_pose
    out["position_error_m"] = errs
    out["orientation_error_rad"] = oerrs if data.frames else None
    out["outliers"] = [int(i) for i in np.flatnonzero(outlier)]
    out["not_converged"] = capped
    return kept_figures(out, exclude)


def kept_figures(validation, exclude) -> dict:
    """``validation`` with the figures over the measurements ``exclude`` (n,) does not leave out: ``before_kept``,
    ``after_kept`` (position and orientation RMS and max) and ``kept_measurements``, and ``excluded``; those
    keys removed when nothing is left out."""
    v = validation
    for key in ("before_kept", "after_kept", "kept_measurements"):
        v.pop(key, None)
    ex = np.zeros(v["measurements"], bool) if exclude is None else np.asarray(exclude, bool)
    v["excluded"] = [int(i) for i in np.flatnonzero(ex)]
    if not ex.any():
        return v
    keep = ~ex
    ori = v.get("orientation_error_rad")
    for label in ("before", "after"):
        ep = np.asarray(v["position_error_m"][label])[keep]
        eo = np.asarray(ori[label])[keep] if ori else np.zeros(0)
        v[f"{label}_kept"] = _figures(ep, eo, [], ori is not None)
    v["kept_measurements"] = int(keep.sum())
    return v


def score(validation) -> float:
    """The figure candidates are compared by: the held-out position RMS over the kept measurements (every
    measurement when none was left out), m."""
    v = validation.get("after_kept") or validation["after"]
    return v["position_rms_m"]
