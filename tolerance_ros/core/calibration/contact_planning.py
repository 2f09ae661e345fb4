"""Which contacts to make: postures that touch the cell's planes and points and make the contact calibration well
determined, by the criteria of ``planning`` (O1..O4 over the scaled identification Jacobian).

Candidates touch each plane or point with each target (``accuracy.simulate.touch`` on the nominal robot, seeded
postures within the limits). The Jacobian is the contact fit's (``contact._stack`` at nominal): a plane row or
three point rows per contact, in the parameters the fit estimates (those ``contact.fit_contacts`` holds over the
candidates are left out: the scale, what a motion of the rig hides, the dependent ones) and the rig (targets'
offsets, planes, points), columns scaled by 1 mm and 1 mrad. The rig's columns stay in: the determinant of the
whole information matrix is the rig's times that of the parameters with the rig eliminated, so that O1 (D-optimal)
chooses contacts that determine the parameters and the rig they are seen through. DETMAX selects ``n`` of them
(``planning.select``); the planned set is compared with random sets of the same size. SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..accuracy.simulate import touch
from ..models.base import Mechanism
from .contact import PLANE, ContactData, ContactLayout, Rig, SCALE_WITHOUT_BUDGET, TOL_RANK, _hold_scale, _Reference, \
    _stack
from ..identification import _Layout, _preference, dependent_columns
from .planning import CRITERIA, design_indices, select

RANDOM_SETS = 20


@dataclass
class ContactPlan:
    """The chosen contacts: joints (n, dof), and per row its target and contact ('plane:ID' / 'point:ID'); the
    observability of the planned and random sets (``planning.indices``), the held parameters, the columns."""

    q: np.ndarray
    target: list
    contact: list
    index: str
    held: list
    columns: list
    planned: dict
    random: dict
    candidates: int

    def to_dict(self) -> dict:
        strip = lambda d: {k: v for k, v in d.items() if k != "s"}  # noqa: E731
        return {"index": self.index, "poses": len(self.q), "joints": self.q.tolist(), "targets": self.target,
                "contacts": self.contact, "held": self.held, "unknowns": self.columns, "candidates": self.candidates,
                "observability": {"planned": strip(self.planned), "random": strip(self.random)}}


def plan_contacts(model: Mechanism, contacts, targets: dict, n: int, candidates=600, criterion="observability",
                  seed=0) -> ContactPlan:
    """``n`` contacts chosen among ``candidates`` (spread over the contacts and targets) for ``contacts`` =
    [(kind, id, where)] (a plane's (unit normal, offset m), a point's (3,) m) and ``targets`` {name: (3,) m}."""
    index = CRITERIA[criterion]
    names = list(targets)
    pairs = [(c, k) for c in range(len(contacts)) for k in range(len(names))]
    each = max(int(np.ceil(candidates / len(pairs))), 1)
    qs, tg, cs = [], [], []
    for c, k in pairs:
        kind, _, where = contacts[c]
        q = touch(model, None, targets[names[k]], kind, where, each, seed=[seed, c, k])
        qs.append(q)
        tg += [k] * len(q)
        cs += [c] * len(q)
    q = np.concatenate(qs)
    keys = [("", kind, cid) for kind, cid, _ in contacts]
    data = ContactData(q, tg, cs, keys, tuple(names))
    C = len(contacts)
    normals, d, points = np.full((C, 3), np.nan), np.full(C, np.nan), np.full((C, 3), np.nan)
    for c, (kind, _, where) in enumerate(contacts):
        if kind == PLANE:
            normals[c], d[c] = np.asarray(where[0], float), float(where[1])
        else:
            points[c] = np.asarray(where, float)
    offsets = np.array([targets[t] for t in names], float)
    ref = _Reference(Rig(tuple(keys), tuple(names), offsets, normals, d, points))
    layout = ContactLayout(model.n_params, len(names), C)
    J, _, _ = _stack(model, data, np.zeros(layout.n), ref, layout)
    J = J * SCALE_WITHOUT_BUDGET
    p = model.n_params
    held = np.zeros(layout.n, bool)
    _hold_scale(model, held)
    cand = np.flatnonzero(~held[:p])
    prefer = _preference(model, _Layout(p, 0, False, False, None), cand)
    held[cand[dependent_columns(J, cand, layout.nuisance, TOL_RANK, prefer)]] = True
    keep = ~held
    rows = np.where(data.kind == PLANE, 1, 3)
    start = np.concatenate([[0], np.cumsum(rows)[:-1]])
    G = np.zeros((len(q), 3, int(keep.sum())))
    for i in range(len(q)):
        G[i, :rows[i]] = J[start[i]:start[i] + rows[i]][:, keep]
    if n > len(q):
        raise ValueError(f"n: {n} contacts requested from {len(q)} candidates")
    design, _ = select(G, n, index, seed)
    planned = design_indices(G, design)
    rng = np.random.default_rng(seed + 1)
    randoms = [design_indices(G, rng.choice(len(q), n, replace=False)) for _ in range(RANDOM_SETS)]
    random = {k: float(np.median([r[k] for r in randoms])) for k in ("O1", "O2", "O3", "O4", "condition")}
    random["rank"] = int(np.median([r["rank"] for r in randoms]))
    random["unknowns"] = planned["unknowns"]
    column_names = [nm for nm, k in zip(layout.names(model, data), keep) if k]
    order = np.sort(design)
    return ContactPlan(q[order], [names[data.target[i]] for i in order],
                       [f"{contacts[data.constraint[i]][0]}:{contacts[data.constraint[i]][1]}" for i in order], index,
                       [model.param_names[j] for j in np.flatnonzero(held[:p])], column_names, planned, random,
                       len(q))
