"""Decisions of conformity: is an estimated part error within its tolerance, out of it, or not decided by
the data, given the estimate's standard uncertainty (in the manner of ISO 14253-1 and ILAC-G8).

Rules (``DecisionRule.parse``):

- ``guarded:K`` (default K = 2): *out* when ``|e| - K u > t`` (non-conformance proven: guarded rejection),
  *within* when ``|e| + K u <= t`` (conformance proven: guarded acceptance), *undecided* otherwise. With a
  normal estimate, a part exactly at its tolerance is wrongly called out (or within) with a probability of at
  most ``P(z > K)`` (2.3 % for K = 2, one-sided), less the further it is from the limit.
- ``simple``: *out* when ``|e| > t``, else *within* (shared risk: up to 50 % of wrong calls at the limit).

A part the budget leaves free (infinite tolerance) is *free*: no decision. SI throughout.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DECISIONS = ("within", "out", "undecided", "free")
PLAUSIBLE_LENGTH = 0.05     # a length error beyond this fraction of the robot's reach is no build error
PLAUSIBLE_ANGLE = 0.2       # rad: an angle error beyond this is no build error


@dataclass(frozen=True)
class DecisionRule:
    """A decision rule: ``kind`` 'guarded' (with its guard ``k`` standard uncertainties) or 'simple'."""

    kind: str = "guarded"
    k: float = 2.0

    @classmethod
    def parse(cls, text: str) -> "DecisionRule":
        """'guarded', 'guarded:K' (K > 0 a number of standard uncertainties) or 'simple'; ValueError else."""
        t = str(text).strip().lower()
        if t == "simple":
            return cls("simple", 0.0)
        kind, sep, k = t.partition(":")
        if kind == "guarded":
            try:
                kv = float(k) if sep else 2.0
            except ValueError:
                kv = float("nan")
            if not (math.isfinite(kv) and 0 < kv <= 10):
                raise ValueError(f"decision rule: the guard of 'guarded:K' is a number of standard uncertainties "
                                 f"from 0 to 10 (e.g. guarded:2), got {text!r}")
            return cls("guarded", kv)
        raise ValueError(f"decision rule: expected 'guarded:K' (e.g. guarded:2) or 'simple', got {text!r}")

    def __str__(self) -> str:
        return "simple" if self.kind == "simple" else f"guarded:{self.k:g}"

    def risk(self) -> float:
        """Largest probability of a wrong 'out' (or 'within') for one part, at its tolerance limit, with a normal
        estimate: ``P(z > K)`` guarded, 0.5 simple."""
        return 0.5 if self.kind == "simple" else 0.5 * math.erfc(self.k / math.sqrt(2.0))

    def words(self) -> str:
        """The rule and its risk in one sentence, for report headers."""
        if self.kind == "simple":
            return ("decision rule simple (shared risk): out when |error| > tolerance, else within; a part at its "
                    "limit is called wrongly with a probability of up to 50 %")
        return (f"decision rule guarded:{self.k:g} (ISO 14253-1 guarded acceptance and rejection, "
                f"u the estimate's standard uncertainty): out when |error| - {self.k:g} u > tolerance, within when "
                f"|error| + {self.k:g} u <= tolerance, undecided otherwise; a part at its limit is called out (or "
                f"within) wrongly with a probability of at most {100 * self.risk():.2g} %")

    def decide(self, error, std, tolerance):
        """Decisions ('within', 'out', 'undecided', 'free') of estimates ``error`` with standard uncertainties
        ``std`` against ``tolerance`` (>= 0, inf: free), element-wise; a str for scalars, else an object array.
        A NaN estimate or uncertainty is 'undecided'."""
        e, u, t = np.broadcast_arrays(np.abs(np.asarray(error, float)), np.asarray(std, float),
                                      np.asarray(tolerance, float))
        g = 0.0 if self.kind == "simple" else self.k
        with np.errstate(invalid="ignore"):
            out = e - g * u > t
            within = (e + g * u <= t) if self.kind != "simple" else (e <= t)
        res = np.where(np.isinf(t), "free", np.where(out, "out", np.where(within, "within", "undecided")))
        res = np.where(~np.isinf(t) & ~(np.isfinite(e) & np.isfinite(u)), "undecided", res).astype(object)
        return res.item() if res.ndim == 0 else res


DEFAULT_RULE = DecisionRule()


def counts(decisions) -> dict:
    """{decision: count} over ``decisions``, every decision named (0 where none)."""
    d = list(decisions)
    return {k: sum(1 for x in d if x == k) for k in DECISIONS}


def parameter_groups(names, kinds, dx, std, held, aliases, delta, rule: DecisionRule = DEFAULT_RULE,
                     undetermined=None) -> list:
    """What estimates ``dx`` (p,) with standard uncertainties ``std`` (p,) say of each part against the budget
    ``delta`` (p,), SI: each estimated parameter j (not in ``held``) measures the combination
    ``e_j + sum_h c_h e_h`` of itself and the held parameters it absorbs (``aliases`` {j: {h: c}}), whose
    tolerance is ``delta_j + sum_h |c_h| delta_h`` (the worst case of the group). ``parameters`` names the members
    that matter (a held parameter whose tolerance moves the group by less than 1 % of its own is not named, though
    it counts); ``kinds`` (p,) 'length' or 'angle' gives each group the unit of its first member ('m' or 'rad').

    ``undetermined`` {name: why}: estimated parameters the data cannot tell (a near-copy of another, or set by a
    prior; ``Identification.undetermined``): their estimate is arbitrary, so their group is ``undecided`` whatever
    it reads, ``note`` saying why.

    Returns [{parameters, coefficients {name: c} (every member), error, std, tolerance, ratio, unit, decision,
    note}], the decisions by ``rule``; out first, then undecided, within and free, each by ratio, largest first.
    """
    undetermined = undetermined or {}
    names = list(names)
    d = np.asarray(delta, float)
    groups = []
    for j, name in enumerate(names):
        if name in held:
            continue
        coef = {name: 1.0, **aliases.get(name, {})}
        shown = [h for h, c in coef.items() if h == name or abs(c) * d[names.index(h)] >= 0.01 * d[j]]
        tol = float(sum(abs(c) * d[names.index(h)] for h, c in coef.items()))
        err, u = float(dx[j]), float(std[j])
        groups.append({"parameters": shown, "coefficients": coef, "error": err, "std": u, "tolerance": tol,
                       "ratio": abs(err) / tol if tol > 0 else float("inf"),
                       "unit": "m" if kinds[j] == "length" else "rad", "decision": rule.decide(err, u, tol),
                       "note": undetermined.get(name)})
        if name in undetermined and groups[-1]["decision"] != "free":
            groups[-1]["decision"] = "undecided"
    order = {"out": 0, "undecided": 1, "within": 2, "free": 3}
    groups.sort(key=lambda g: (order[g["decision"]], -g["ratio"]))
    return groups


def implausible(names, kinds, dx, reach: float) -> dict:
    """{name: why} of the identified errors beyond any build error (``PLAUSIBLE_LENGTH`` of the robot's ``reach``
    m, ``PLAUSIBLE_ANGLE``): what makes a calibration refused, and an estimate the data do not determine."""
    out = {}
    for n, k, v in zip(names, kinds, dx):
        if k == "length" and abs(v) > PLAUSIBLE_LENGTH * reach:
            out[n] = (f"identified error {v * 1e3:+.4g} mm is more than {PLAUSIBLE_LENGTH * 100:g} % of the robot's "
                      f"reach ({reach:.3g} m)")
        elif k == "angle" and abs(v) > PLAUSIBLE_ANGLE:
            out[n] = f"identified error {v:+.4g} rad is more than {PLAUSIBLE_ANGLE:g} rad"
    return out


def out_words(grp) -> str | None:
    """'2 part(s) decided out of tolerance by the decision rule guarded:2: a3, d6+alpha6' of ``judged``'s result,
    or None when no part is decided out."""
    out = ["+".join(g["parameters"]) for g in grp["groups"] if g["decision"] == "out"]
    return (f"{len(out)} part(s) decided out of tolerance by the decision rule {grp['rule']}: {', '.join(out)}"
            if out else None)


def judged(names, kinds, dx, std, held, aliases, delta, rule: DecisionRule = DEFAULT_RULE,
           undetermined=None, reach: float | None = None) -> dict:
    """``parameter_groups`` with the rule said: {groups, rule, rule_words, counts {decision: n},
    out_of_tolerance (the groups decided out)}; with the robot's ``reach`` (m), an implausible estimate
    (``implausible``) is undetermined too."""
    if reach is not None:
        undetermined = {**{n: f"{why}, beyond any build error: the fit, not the data, put it there"
                           for n, why in implausible(names, kinds, dx, reach).items()}, **(undetermined or {})}
    groups = parameter_groups(names, kinds, dx, std, held, aliases, delta, rule, undetermined)
    return {"groups": groups, "rule": str(rule), "rule_words": rule.words(),
            "counts": counts(g["decision"] for g in groups),
            "out_of_tolerance": [g for g in groups if g["decision"] == "out"]}
