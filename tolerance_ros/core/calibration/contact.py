"""Calibration from contact, without a tracker: targets on the tool touching planes and fixed points.

A row says that target ``k`` (a point fixed in the tool frame, nominally ``t_k``) touched a plane or a point of
the cell at joints ``q``. The model of the row is the target's point ``P = T(q, dx) t_k`` in the robot's base
frame; its residual is a distance (m): ``n . P - d`` to the plane ``{n . x = d}`` (one row) or ``P - c`` to the
point ``c`` (three rows). The rig (every plane and point, one set per session, and the targets' offsets on the
tool) is unknown: nuisance unknowns fitted with the parameter errors, their span projected out of the
parameters' columns before the dependent parameters are chosen (``identification.dependent_columns``), so that
what contact cannot see is held and said: a plane sees nothing along itself, a turn of the first joint about
a plane's normal is a rigid motion of the plane, a common target height is the plane's offset.

Unknowns, in this order: the parameter errors (p), the targets' offsets (3 per target, tool frame, m), then 3
per constraint: a plane's normal turned by ``(u, v)`` (rad) in its tangent plane and its offset ``w`` (m), or a
point's ``(x, y, z)`` (m). The fit is ``identification._minimise`` (Levenberg-Marquardt to its convergence
tests) on ``sum(r^2) / sigma^2 + prior``, its steps kept within the plausible errors (``PLAUSIBLE_LENGTH``,
``PLAUSIBLE_ANGLE``: a robot folded until its contacts meet in one point fits every plane exactly), robust by the rows' distances (``REJECT`` robust standard deviations
at the tail probability of the tracker's rule, per row kind). SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..targets import shift_jacobian
from ..models.base import Mechanism
from ..accuracy.folds import folds_of, pose_groups
from ..identification import (PRIOR, SCALE_WITHOUT_BUDGET, Convergence, _minimise, _preference, _Layout,
                             column_scale, dependent_columns)
from .robust import prior_vector

PLANE, POINT = "plane", "point"
KINDS = (PLANE, POINT)
ROWS = {PLANE: 1, POINT: 3}
TOL_RANK = 1e-5            # singular values below this share of the largest leave a null space (see fit_contacts)
TAIL = 1e-4                # a row whose distance is this improbable under the robust noise is an outlier
MAX_REJECTED = 0.25        # at most this share of the rows left out
ROUNDS = 5                 # rejection rounds of a robust fit
PARSIMONY = 0.01           # the simplest candidate within this share of the lowest held-out RMS wins
MODELS = ("rig", "joint-offsets", "full")
PLAUSIBLE_LENGTH = 0.05    # the search stays where length errors and target moves are below this share of the reach
PLAUSIBLE_ANGLE = 0.2      # rad, and angle errors below this: beyond, a calibration is refused anyway, and a
                           # plane-contact fit free to go there can fold the robot until its contacts meet in a point


def _reject_levels():
    """|e| / sigma beyond which a plane row (1-D) and a point row (3-D) is an outlier, at ``TAIL``."""
    from scipy.stats import chi2
    return float(np.sqrt(chi2.isf(TAIL, 1))), float(np.sqrt(chi2.isf(TAIL, 3)))


@dataclass
class ContactData:
    """Contact rows. q (n, dof) joints (SI); target (n,) index into ``target_names``; constraint (n,) index into
    ``constraints``, each ``(session, kind, id)``; labels (n,) test-pose names or None; where (n,) where each row
    comes from ('line 23'); stamps (n,) s or None."""

    q: np.ndarray
    target: np.ndarray
    constraint: np.ndarray
    constraints: tuple
    target_names: tuple
    labels: np.ndarray | None = None
    where: list | None = None
    stamps: np.ndarray | None = None

    def __post_init__(self):
        self.q = np.asarray(self.q, float)
        self.target = np.asarray(self.target, int).reshape(-1)
        self.constraint = np.asarray(self.constraint, int).reshape(-1)
        self.constraints = tuple(tuple(c) for c in self.constraints)
        n = len(self.q)
        if len(self.target) != n or len(self.constraint) != n:
            raise ValueError(f"contacts: {n} joint rows, {len(self.target)} targets, {len(self.constraint)} contacts")
        for s, kind, i in self.constraints:
            if kind not in KINDS:
                raise ValueError(f"contact {kind}:{i}: expected one of {KINDS}")

    def __len__(self):
        return len(self.q)

    @property
    def kind(self) -> np.ndarray:
        """(n,) 'plane' or 'point' of each row."""
        return np.array([self.constraints[c][1] for c in self.constraint], dtype=object)

    def subset(self, rows) -> "ContactData":
        """The rows selected by a mask or indices (the constraints and targets keep their numbering)."""
        rows = np.asarray(rows)
        labels = None if self.labels is None else np.asarray(self.labels, dtype=object)[rows]
        where = None if self.where is None else list(np.asarray(self.where, dtype=object)[rows])
        stamps = None if self.stamps is None else np.asarray(self.stamps, float)[rows]
        return ContactData(self.q[rows], self.target[rows], self.constraint[rows], self.constraints,
                           self.target_names, labels, where, stamps)

    def constraint_name(self, c) -> str:
        s, kind, i = self.constraints[c]
        return f"{kind}:{i}" + (f" (session {s})" if s else "")


@dataclass
class Rig:
    """The cell as contact sees it: the targets' offsets in the tool frame (K, 3) m, and per constraint a plane
    (unit normal, offset d: ``n . x = d``, m) or a point (m), base frame, with standard uncertainties (normal:
    the rad of its turn, offset and point: m; None before a fit)."""

    constraints: tuple
    target_names: tuple
    offsets: np.ndarray
    normals: np.ndarray
    d: np.ndarray
    points: np.ndarray
    offsets_std: np.ndarray | None = None
    normals_std: np.ndarray | None = None
    d_std: np.ndarray | None = None
    points_std: np.ndarray | None = None

    def to_dict(self) -> dict:
        def std(a, i):
            return None if a is None else np.asarray(a[i], float).tolist()
        out = {"targets": [{"name": n, "xyz_m": self.offsets[k].tolist(), "std_m": std(self.offsets_std, k)}
                           for k, n in enumerate(self.target_names)], "planes": [], "points": []}
        for c, (s, kind, i) in enumerate(self.constraints):
            if kind == PLANE:
                out["planes"].append({"session": s, "id": i, "normal": self.normals[c].tolist(),
                                      "offset_m": float(self.d[c]), "normal_std_rad": std(self.normals_std, c),
                                      "offset_std_m": None if self.d_std is None else float(self.d_std[c])})
            else:
                out["points"].append({"session": s, "id": i, "xyz_m": self.points[c].tolist(),
                                      "std_m": std(self.points_std, c)})
        return out


class _Reference:
    """The fixed frame of the rig's unknowns: each plane's reference normal ``n0`` with a tangent basis
    ``(e1, e2)`` and offset ``d0``; each point's reference ``c0``; the targets' nominal offsets."""

    def __init__(self, rig: Rig):
        self.rig = rig
        self.n0 = np.array(rig.normals, float)
        C = len(rig.constraints)
        self.e1, self.e2 = np.zeros((C, 3)), np.zeros((C, 3))
        for c in range(C):
            if rig.constraints[c][1] == PLANE:
                self.e1[c], self.e2[c] = _tangents(self.n0[c])
        self.d0 = np.array(rig.d, float)
        self.c0 = np.array(rig.points, float)
        self.t0 = np.array(rig.offsets, float)

    def normal(self, z):
        """(C, 3) unit normals and (C,) norms of ``n0 + u e1 + v e2`` at ``z`` (C, 3) = (u, v, w)."""
        m = self.n0 + z[:, :1] * self.e1 + z[:, 1:2] * self.e2
        norm = np.linalg.norm(m, axis=1)
        return m / np.where(norm > 0, norm, 1.0)[:, None], norm

    def rig_at(self, x, layout, cov=None) -> Rig:
        """The rig at unknowns ``x`` (with the standard uncertainties of ``cov`` when given)."""
        z = x[layout.g].reshape(-1, 3)
        n, _ = self.normal(z)
        planes = np.array([k == PLANE for _, k, _ in self.rig.constraints])
        normals = np.where(planes[:, None], n, np.nan)
        d = np.where(planes, self.d0 + z[:, 2], np.nan)
        points = np.where(planes[:, None], np.nan, self.c0 + z)
        offsets = self.t0 + x[layout.t].reshape(-1, 3)
        out = Rig(self.rig.constraints, self.rig.target_names, offsets, normals, d, points)
        if cov is not None:
            sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
            zs = sd[layout.g].reshape(-1, 3)
            out.offsets_std = sd[layout.t].reshape(-1, 3)
            out.normals_std = np.where(planes[:, None], zs[:, :2], np.nan)
            out.d_std = np.where(planes, zs[:, 2], np.nan)
            out.points_std = np.where(planes[:, None], np.nan, zs)
        return out


def _tangents(n):
    """Two unit vectors orthogonal to ``n`` and to each other."""
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


class ContactLayout:
    """Columns: parameter errors (p), target offsets (3K), constraints (3C)."""

    def __init__(self, p, K, C):
        self.p, self.K, self.C = p, K, C
        self.t = slice(p, p + 3 * K)
        self.g = slice(self.t.stop, self.t.stop + 3 * C)
        self.n = self.g.stop

    @property
    def nuisance(self) -> np.ndarray:
        return np.arange(self.p, self.n)

    def names(self, model, data) -> list:
        out = list(model.param_names)
        out += [f"target {t}.{a}" for t in data.target_names for a in "xyz"]
        for c, (s, kind, i) in enumerate(data.constraints):
            out += [f"{data.constraint_name(c)}.{a}" for a in (("u", "v", "offset") if kind == PLANE else "xyz")]
        return out


def initial_rig(model: Mechanism, data: ContactData, offsets, dx=None) -> Rig:
    """The rig that the model (``dx``, the targets at ``offsets`` (K, 3) m) puts through the rows: each plane
    fitted to its points (least squares), each point their mean. ValueError for a plane whose points do not span
    one (fewer than 3, or on a line)."""
    offsets = np.asarray(offsets, float).reshape(len(data.target_names), 3)
    P = target_points(model, data.q, data.target, offsets, dx)
    C = len(data.constraints)
    normals, d, points = np.full((C, 3), np.nan), np.full(C, np.nan), np.full((C, 3), np.nan)
    for c, (s, kind, i) in enumerate(data.constraints):
        sel = P[data.constraint == c]
        if not len(sel):
            continue
        mean = sel.mean(axis=0)
        if kind == POINT:
            points[c] = mean
            continue
        if len(sel) < 3:
            raise ValueError(f"contact {data.constraint_name(c)}: {len(sel)} row(s); a plane needs 3 or more contacts "
                             f"not on one line")
        _, s_, Vt = np.linalg.svd(sel - mean, full_matrices=False)
        if s_[1] <= 1e-6 * max(s_[0], 1e-300) or s_[1] < 1e-6:
            raise ValueError(f"contact {data.constraint_name(c)}: its {len(sel)} contacts lie on one line; a plane "
                             f"needs contacts spread over it")
        n = Vt[2]
        normals[c] = n
        d[c] = float(n @ mean)
    return Rig(data.constraints, data.target_names, offsets, normals, d, points)


def target_points(model, q, target, offsets, dx=None) -> np.ndarray:
    """(n, 3) base-frame points of each row's target (offsets (K, 3) in the tool frame), m."""
    T = model.fk(q, dx)
    t = np.asarray(offsets, float)[np.asarray(target, int)]
    return T[:, :3, 3] + np.einsum("nij,nj->ni", T[:, :3, :3], t)


def _stack(model, data, x, ref, layout, sqrt_w=None):
    """(J (rows, unknowns), r (rows,), (n,) distances): the derivative of the model of each row (its signed
    plane distance, or its point's offset from the contact point) and the residual ``0 - model``, rows in row
    order, a plane row one, a point row three; the distances unweighted (m)."""
    p = layout.p
    T, EJ = model.fk_and_jacobian(data.q, x[:p])
    t = ref.t0[data.target] + x[layout.t].reshape(-1, 3)[data.target]
    R = T[:, :3, :3]
    arms = np.einsum("nij,nj->ni", R, t)
    P = T[:, :3, 3] + arms
    Jp = shift_jacobian(EJ.J, arms)[:, :3]
    z = x[layout.g].reshape(-1, 3)
    normal, norm = ref.normal(z)
    c = data.constraint
    plane = np.array([ref.rig.constraints[k][1] == PLANE for k in c])
    k = np.where(plane, 1, 3)
    start = np.concatenate([[0], np.cumsum(k)[:-1]])
    rows = int(k.sum())
    J = np.zeros((rows, layout.n))
    r = np.zeros(rows)
    dist = np.zeros(len(c))
    tcol = layout.t.start + 3 * data.target
    gcol = layout.g.start + 3 * c
    i = np.flatnonzero(plane)
    if len(i):
        ci, at = c[i], start[i]
        n = normal[ci]
        f = np.einsum("ni,ni->n", n, P[i]) - (ref.d0[ci] + z[ci, 2])
        r[at] = -f
        dist[i] = np.abs(f)
        J[at, :p] = np.einsum("ni,nij->nj", n, Jp[i])
        tv = np.einsum("ni,nij->nj", n, R[i])
        proj = np.eye(3) - n[:, :, None] * n[:, None, :]
        for a, e in enumerate((ref.e1[ci], ref.e2[ci])):
            J[at, gcol[i] + a] = np.einsum("ni,ni->n", P[i], np.einsum("nij,nj->ni", proj, e)) / norm[ci]
        J[at, gcol[i] + 2] = -1.0
        for a in range(3):
            J[at, tcol[i] + a] = tv[:, a]
    j = np.flatnonzero(~plane)
    if len(j):
        cj = c[j]
        e = P[j] - (ref.c0[cj] + z[cj])
        dist[j] = np.linalg.norm(e, axis=1)
        for a in range(3):
            row = start[j] + a
            r[row] = -e[:, a]
            J[row, :p] = Jp[j, a]
            for b in range(3):
                J[row, tcol[j] + b] = R[j, a, b]
            J[row, gcol[j] + a] = -1.0
    if sqrt_w is not None:
        w = np.repeat(sqrt_w, k)
        J *= w[:, None]
        r = r * w
    return J, r, dist


@dataclass
class ContactFit:
    """One fit: the unknowns ``x`` on ``layout`` from ``reference``; which parameters were held (and why), the
    rows left out, the noise (m), the covariance of the unknowns, the convergence, the rows' distances (m)."""

    layout: ContactLayout
    reference: _Reference
    x: np.ndarray
    held: list
    held_why: dict
    rejected: np.ndarray
    noise: float
    cov: np.ndarray
    convergence: Convergence
    distances: np.ndarray
    rank: int = 0
    condition: float = float("nan")
    undetermined_rig: list = field(default_factory=list)
    threshold: np.ndarray | None = None
    rig_held: list = field(default_factory=list)
    held_judged_at: str = "nominal"

    @property
    def dx(self) -> np.ndarray:
        return self.x[:self.layout.p]

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.maximum(np.diag(self.cov)[:self.layout.p], 0.0))

    @property
    def rig(self) -> Rig:
        return self.reference.rig_at(self.x, self.layout, self.cov)

    def rms(self, rows=None) -> float:
        d = self.distances[~self.rejected] if rows is None else self.distances[rows]
        return float(np.sqrt(np.mean(d ** 2))) if len(d) else float("nan")


def not_converged_words(c: Convergence) -> str:
    """How a fit that did not converge stopped, in words."""
    return (f"it stopped ({c.stop}) after {c.iterations} iterations, a full step still lowering the cost by "
            f"{c.decrement:.2g} of it (largest gradient cosine {c.gradient_cosine:.1e})")


def _estimate_mask(model, which) -> np.ndarray:
    """(p,) parameters a candidate estimates."""
    if which not in MODELS:
        raise ValueError(f"parameters: expected one of {MODELS}, got {which!r}")
    m = np.zeros(model.n_params, bool)
    if which == "joint-offsets":
        m[model.joint_columns()] = True
    elif which == "full":
        m[:] = True
    return m


def _row_count(data, weights):
    k = np.where(data.kind == PLANE, 1, 3)
    return int(np.sum(k[weights > 0]))


def fit_contacts(model: Mechanism, data: ContactData, offsets, which="full", prior=None, sigma=1e-5, robust=True,
                 iterations=200, fixed=None, analysis=True, start=None) -> ContactFit:
    """The robust least-squares fit of candidate ``which`` (``MODELS``) with its rig, from the targets' nominal
    offsets (K, 3) m; ``prior`` (m, rad) on the origin errors (``robust.prior_vector``: none on joint offsets) or
    None. ``fixed``: (dx (p,), target offsets (K, 3)) of a calibrated model whose parameters and targets are held
    (only the planes and points are fitted: validation on another session, and the 'before' figures). ``start``:
    a ContactFit on the same layout to start from."""
    p = model.n_params
    if fixed is not None:
        dx0, off0 = np.asarray(fixed[0], float), np.asarray(fixed[1], float)
        base_model = _Fixed(model, dx0)
    else:
        dx0, off0, base_model = np.zeros(p), np.asarray(offsets, float), model
    ref = _Reference(initial_rig(model, data, off0, dx0 if fixed is not None else None))
    layout = ContactLayout(p, len(data.target_names), len(data.constraints))
    held = np.zeros(layout.n, bool)
    held[:p] = ~_estimate_mask(model, which) if fixed is None else True
    if fixed is not None:
        held[layout.t] = True
    used = np.zeros(len(data.constraints), bool)
    used[np.unique(data.constraint)] = True
    held[layout.g] = ~np.repeat(used, 3)
    delta = prior_vector(model, prior) if prior is not None else None
    scale = np.concatenate([column_scale(delta, p)[:p], np.full(layout.n - p, SCALE_WITHOUT_BUDGET)])
    prior_diag = np.zeros(layout.n)
    if delta is not None:
        prior_diag[:p] = np.where(np.isinf(delta), 0.0, (sigma / scale[:p]) ** 2)
    natural = np.full(layout.n, SCALE_WITHOUT_BUDGET)
    reach = model.reach()
    bound = np.r_[np.where(np.array(model.param_kinds) == "length", PLAUSIBLE_LENGTH * reach, PLAUSIBLE_ANGLE),
                  np.full(3 * layout.K, PLAUSIBLE_LENGTH * reach)]
    n = len(data)
    rot = np.zeros((0, 3), int)
    reject_plane, reject_point = _reject_levels()

    def solve(weights, noise, x0, held):
        sw = np.sqrt(weights)
        pr = prior_diag * (noise / sigma) ** 2

        def evaluate(x):
            if np.any(np.abs(x[:layout.g.start]) > bound):
                raise ValueError("a step beyond the plausible errors")
            J, r, _ = _stack(base_model, data, x, ref, layout, sw)
            return J, r
        free = np.flatnonzero(~held)
        return _minimise(evaluate, np.where(held, 0.0, x0), free, scale, pr, rot, iterations), free

    J0, _, _ = _stack(base_model, data, np.zeros(layout.n), ref, layout)
    why = {}
    rig_cols = np.flatnonzero(~held[p:]) + p
    rig_held = []
    if len(rig_cols):
        # the rig's own directions the contacts cannot see (a target's shift along the plane it touches flush, a
        # common height that is the plane's offset) are held where they were put: free, a fit would drift along
        # them into degenerate solutions (``_unseen_rig``)
        names = layout.names(model, data)
        for j in _unseen_rig(J0, rig_cols, rig_cols >= layout.g.start, sigma):
            held[j] = True
            rig_held.append(names[j])
    if fixed is None:
        why.update(_hold_scale(model, held))
    cand = np.flatnonzero(~held[:p])
    nuisance = np.flatnonzero(~held[p:]) + p
    if len(cand) and fixed is None:
        prefer = _preference(model, _Layout(p, 0, False, False, None), cand)
        dep = dependent_columns(J0 * natural, cand, nuisance, TOL_RANK, prefer)
        held[cand[dep]] = True
        why.update(_held_reasons(model, J0 * natural, cand[dep], nuisance))
    noise = sigma
    x = np.zeros(layout.n) if start is None else np.where(held, 0.0, start.x)
    rejected = np.zeros(n, bool)
    if robust and fixed is None and (~held[:p]).any():
        # a gross outlier can pull a free fit into a degenerate valley (the robot folded so that a plane's contacts
        # fall on a line, its distances to zero): the rows the rig-only fit judges gross start out of the fit, and the
        # fit's own residuals judge every row again from there
        stiff = fit_contacts(model, data, offsets, "rig", None, sigma, True, iterations, analysis=False)
        rejected = stiff.rejected.copy()
    weights = (~rejected).astype(float)
    still = np.zeros(len(data.constraints), bool)
    still[np.unique(data.constraint[~rejected])] = True
    held[layout.g] |= ~np.repeat(still, 3)
    threshold = None
    plane = data.kind == PLANE
    for round_ in range(ROUNDS + 1):
        (x, J, r, conv), free = solve(weights, noise, x, held)
        _, _, dist = _stack(base_model, data, x, ref, layout)
        if not robust or round_ == ROUNDS:
            break
        s = max(_robust_sigma(dist[~rejected], plane[~rejected]), sigma)
        threshold = np.where(plane, reject_plane * s, reject_point * s)
        new = dist > threshold
        cap = int(MAX_REJECTED * n)
        if new.sum() > cap:
            new = np.zeros(n, bool)
            if cap:
                new[np.argsort(dist / threshold)[-cap:]] = True
        if np.array_equal(new, rejected) and (delta is None or abs(s / noise - 1.0) < 0.05):
            break
        rejected, noise = new, s
        weights = (~rejected).astype(float)
        still = np.zeros(len(data.constraints), bool)
        still[np.unique(data.constraint[~rejected])] = True
        held[layout.g] |= ~np.repeat(still, 3)
    judged = "nominal"
    if fixed is None and len(cand):
        # a dependence that only the solution shows, among the parameters still free (as ``identify`` judges)
        still = cand[~held[cand]]
        rig_free = np.flatnonzero(~held[p:]) + p
        prefer = _preference(model, _Layout(p, 0, False, False, None), still)
        dep = dependent_columns(J * natural, still, rig_free, TOL_RANK, prefer) if len(still) else np.zeros(0, bool)
        judged = "nominal and solution"
        if dep.any():
            held[still[dep]] = True
            why.update({model.param_names[j]: "dependent at the solution: held at nominal" for j in still[dep]})
            x = np.where(held, 0.0, x)
            (x, J, r, conv), free = solve(weights, noise, x, held)
            _, _, dist = _stack(base_model, data, x, ref, layout)
    rows_used = _row_count(data, weights)
    sf = scale[free]
    Jf = J[:, free] * sf
    H = Jf.T @ Jf + np.diag(prior_diag[free] * sf ** 2)
    Hinv = np.linalg.pinv(H)
    edf = float(np.trace(Hinv @ (Jf.T @ Jf))) if len(free) else 0.0
    dof = rows_used - edf
    noise = float(np.sqrt(r @ r / dof)) if dof >= 1 else sigma
    noise = max(noise, 1e-300)
    cov = np.zeros((layout.n, layout.n))
    cov[np.ix_(free, free)] = Hinv * np.outer(sf, sf) * noise ** 2
    out = ContactFit(layout, ref, x, [model.param_names[j] for j in np.flatnonzero(held[:p])], why, rejected, noise,
                     cov, conv, dist, threshold=threshold, rig_held=rig_held, held_judged_at=judged)
    if analysis:
        lam, V = np.linalg.eigh(Jf.T @ Jf) if len(free) else (np.zeros(0), np.zeros((0, 0)))
        top = lam.max() if lam.size else 0.0
        live = lam > TOL_RANK ** 2 * top
        out.rank = int(live.sum())
        out.condition = float(np.sqrt(top / lam[live].min())) if live.any() else float("inf")
        names = layout.names(model, data)
        null = V[:, ~live]
        weight = np.sqrt(np.sum(null ** 2, axis=1)) if null.size else np.zeros(len(free))
        out.undetermined_rig = [names[free[i]] for i in np.flatnonzero(weight >= 0.1)]
    return out


class _Fixed:
    """A model whose parameter errors are fixed at ``dx``: the rig-only fits see no parameter columns' effect
    (their columns are held) and the poses of the calibrated model."""

    def __init__(self, model, dx):
        self.model, self.dx = model, dx

    def fk_and_jacobian(self, q, dx=None, jacobian=True):
        return self.model.fk_and_jacobian(q, self.dx, jacobian)


UNSEEN = 0.1   # a rig unknown the contacts determine worse than this share of its scale (1 mm, 1 mrad) is held


def _unseen_rig(J, cols, keep_first, sigma) -> list:
    """The rig columns to hold, in the order held: while one of ``cols`` has a standard deviation beyond ``UNSEEN``
    of its scale (the rig alone fitted to rows of noise ``sigma``, m, at nominal: infinite in an exact null
    direction, large where only the robot's own errors tilt a flush tool), the worst is held, a target's before a
    plane's or point's (``keep_first`` marks those). Free, such a direction lets a fit drift far: fingertips
    flush on a table, their places along it free, are moved onto one point, where a single contact per posture
    is fitted exactly by the robot's many parameters (a zero residual, a degenerate calibration)."""
    A = J[:, cols] * SCALE_WITHOUT_BUDGET / sigma
    free = list(range(len(cols)))
    out = []
    while free:
        H = A[:, free].T @ A[:, free]
        lam, V = np.linalg.eigh(H)
        top = max(lam[-1], 1e-300)
        inv = np.where(lam > 1e-12 * top, 1.0 / np.where(lam > 0, lam, 1.0), np.inf)
        with np.errstate(invalid="ignore"):
            var = np.where(np.abs(V) > 1e-9, V ** 2, 0.0) @ np.where(np.isinf(inv), 1e300, inv)
        worst = np.sqrt(var)
        if worst.max() <= UNSEEN:
            break
        order = np.lexsort((-worst, np.asarray(keep_first)[free]))   # targets first, then the largest spread
        bad = [i for i in order if worst[i] > UNSEEN]
        k = free[bad[0]]
        out.append(cols[k])
        free.remove(k)
    return out


def _robust_sigma(dist, plane) -> float:
    """Robust noise per axis (m) of the rows' distances: the median |e| of plane rows over 0.6745 (a normal's), of
    point rows over 1.5382 (a 3-D normal's), weighed by their counts."""
    parts, counts = [], []
    if plane.any():
        parts.append(np.median(dist[plane]) / 0.6745)
        counts.append(plane.sum())
    if (~plane).any():
        parts.append(np.median(dist[~plane]) / 1.5382)
        counts.append((~plane).sum())
    return float(np.average(parts, weights=counts)) if parts else 0.0


def _hold_scale(model, held) -> dict:
    """Hold the estimated length of the largest nominal value (its name: why), in place in ``held``. Contact has no
    length standard: every length of the robot, its targets, planes' offsets and points scaled by one factor meet
    the same contacts, with every distance scaled by it, so that a fit free to scale would shrink the robot to
    shrink its residuals; holding the longest length fixes the scale where it is best known (the nominal)."""
    p = model.n_params
    lengths = np.array([k == "length" for k in model.param_kinds]) & ~held[:p]
    nominal = np.abs(np.asarray(getattr(model, "nominal", np.zeros(p)), float).reshape(-1))[:p]
    if not lengths.any() or not np.any(nominal[lengths] > 0):
        return {}
    j = int(np.flatnonzero(lengths)[np.argmax(nominal[lengths])])
    held[j] = True
    return {model.param_names[j]: (f"the overall scale: contact has no length standard (the robot, its targets and the "
                                   f"rig scaled alike meet the same contacts), so the longest length "
                                   f"({nominal[j]:.4g} m nominal) is held at nominal")}


def _held_reasons(model, Js, held, nuisance) -> dict:
    """{parameter: why it is held}: a rigid motion of the rig (its column within the rig's span) or a
    combination of other parameters (and the rig)."""
    out = {}
    N = Js[:, nuisance]
    Q, Rn = np.linalg.qr(N) if N.size else (np.zeros((len(Js), 0)), np.zeros((0, 0)))
    if Rn.size:
        Q = Q[:, np.abs(np.diag(Rn)) > 1e-12 * max(np.abs(Rn).max(), 1e-300)]
    top = np.linalg.norm(Js, 2) if Js.size else 0.0
    for j in held:
        col = Js[:, j]
        size = np.linalg.norm(col)
        if size <= 1e-12 * top:
            out[model.param_names[j]] = "no effect on these contacts: held at nominal"
        elif np.linalg.norm(col - Q @ (Q.T @ col)) <= 1e-6 * size:
            out[model.param_names[j]] = ("a motion of the rig (a plane's offset or a turn about its normal, a point's "
                                         "place, a target's offset): contact cannot see it")
        else:
            out[model.param_names[j]] = "a combination of other parameters and the rig: held at nominal"
    return out


def candidates(prior=PRIOR) -> list:
    """[(label, parameters, prior)] that ``calibrate_contacts`` cross-validates."""
    out = [("rig", "rig", None), ("joint-offsets", "joint-offsets", None), ("full", "full", None)]
    if prior is not None:
        out.append((f"full, prior {prior[0] * 1e3:g} mm / {prior[1] * 1e3:g} mrad", "full", tuple(prior)))
    return out


def _score_rows(model, data, fitted: ContactFit, rows, sigma) -> np.ndarray:
    """(len(rows),) distances of held-out ``rows`` under a fit of other rows: its parameters and targets, its
    planes and points where it fitted them, else theirs refitted from the held-out rows alone (model held)."""
    test = data.subset(rows)
    rig = fitted.rig
    trained = np.zeros(len(data.constraints), bool)
    trained[np.unique(data.constraint[~np.isin(np.arange(len(data)), rows)])] = True
    P = target_points(model, test.q, test.target, rig.offsets, fitted.dx)
    out = np.full(len(test), np.nan)
    for c in np.unique(test.constraint):
        sel = test.constraint == c
        if trained[c]:
            if data.constraints[c][1] == PLANE:
                out[sel] = np.abs(P[sel] @ rig.normals[c] - rig.d[c])
            else:
                out[sel] = np.linalg.norm(P[sel] - rig.points[c], axis=1)
    missing = np.isnan(out)
    if missing.any():
        sub = test.subset(missing)
        try:
            refit = fit_contacts(model, sub, rig.offsets, sigma=sigma, robust=False, fixed=(fitted.dx, rig.offsets),
                                 analysis=False)
            out[missing] = refit.distances
        except ValueError:
            pass
    return out


def cross_validate(model, data, which, prior, sigma, folds=10, seed=0, robust=True, offsets=None) -> dict:
    """K-fold by test pose: each fold's rows predicted by the fit of the others (``_score_rows``); every row
    scored. {'after': {contact_rms_m, contact_max_m}, 'distances_m', 'rows_scored', 'not_converged'}."""
    groups, _ = pose_groups(data.q, data.labels)
    fold, k = folds_of(groups, folds, seed)
    dist = np.full(len(data), np.nan)
    bad = []
    for f in range(k):
        test = np.flatnonzero(fold == f)
        train = data.subset(fold != f)
        try:
            fitted = fit_contacts(model, train, offsets, which, prior, sigma, robust, analysis=False)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if not fitted.convergence.converged:
            bad.append(f)
        dist[test] = _score_rows(model, data, fitted, test, sigma)
    scored = np.isfinite(dist)
    d = dist[scored]
    return {"after": {"contact_rms_m": float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan"),
                      "contact_max_m": float(d.max()) if d.size else float("nan")},
            "distances_m": dist, "rows_scored": int(scored.sum()), "folds": k, "not_converged": bad}


@dataclass
class ContactCalibration:
    """What ``calibrate_contacts`` found: the chosen fit, the nominal model's fit of the rig alone, the candidates'
    cross-validation, the validation of the chosen one, and the rows left out."""

    fit: ContactFit
    nominal: ContactFit
    label: str
    which: str
    prior: tuple | None
    scores: list
    validation: dict
    rejected: list
    warnings: list


def calibrate_contacts(model: Mechanism, data: ContactData, offsets, parameters="auto", prior=PRIOR, sigma=1e-5,
                       folds=10, seed=0, robust=True, progress=None) -> ContactCalibration:
    """Choose what to identify by the held-out contact RMS (``cross_validate``; the simplest within ``PARSIMONY``
    of the lowest), fit it on every row, and validate: ``before`` is the nominal model with its rig fitted on
    every row (its best case), ``after`` the calibrated one predicting each fold's poses from the others."""
    groups, names = pose_groups(data.q, data.labels)
    if len(names) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (touch from more poses)")
    todo = candidates(prior) if parameters == "auto" else [
        (parameters if not (parameters == "full" and prior) else candidates(prior)[-1][0], parameters,
         prior if parameters == "full" else None)]
    scores, cvs = [], {}
    for step, (label, which, pr) in enumerate(todo):
        if progress is not None:
            progress(step, len(todo) + 1)
        try:
            cv = cross_validate(model, data, which, pr, sigma, folds, seed, robust, offsets)
        except (ValueError, np.linalg.LinAlgError) as exc:
            scores.append({"label": label, "parameters": which, "error": str(exc)})
            continue
        cvs[label] = cv
        scores.append({"label": label, "parameters": which, "prior": None if pr is None else list(pr),
                       "cv_contact_rms_m": cv["after"]["contact_rms_m"], "cv_contact_max_m": cv["after"]["contact_max_m"],
                       "rows_scored": cv["rows_scored"], "not_converged_folds": cv["not_converged"]})
    valid = [s for s in scores if np.isfinite(s.get("cv_contact_rms_m", np.nan))]
    if not valid:
        raise ValueError("calibration: no candidate could be fitted: " + "; ".join(s.get("error", "no row scored")
                                                                               for s in scores))
    lowest = min(s["cv_contact_rms_m"] for s in valid)
    best = next(s for s in valid if s["cv_contact_rms_m"] <= lowest * (1 + PARSIMONY))
    pr = None if best.get("prior") is None else tuple(best["prior"])
    final = fit_contacts(model, data, offsets, best["parameters"], pr, sigma, robust)
    nominal = fit_contacts(model, data, offsets, "rig", None, sigma, robust)
    if progress is not None:
        progress(len(todo) + 1, len(todo) + 1)
    cv = cvs[best["label"]]
    before, after = nominal.rms(np.arange(len(data))), cv["after"]["contact_rms_m"]
    validation = {"method": f"{cv['folds']}-fold cross-validation by test pose ({len(names)} poses); 'before' is the "
                            f"nominal model with its rig fitted on every row",
                  "before": {"contact_rms_m": before, "contact_max_m": float(nominal.distances.max())},
                  "after": dict(cv["after"]), "rows_scored": cv["rows_scored"], "rows": len(data),
                  "improvement": float(1.0 - after / before) if before > 0 else 0.0,
                  "distances_m": cv["distances_m"].tolist()}
    rejected = [{"row": int(i), "where": data.where[i] if data.where is not None else f"row {int(i)}",
                 "contact": data.constraint_name(data.constraint[i]), "target": data.target_names[data.target[i]],
                 "distance_m": float(final.distances[i]), "threshold_m": float(final.threshold[i]),
                 "reason": f"distance {final.distances[i] * 1e3:.4g} mm beyond {final.threshold[i] * 1e3:.4g} mm "
                           f"(robust noise at tail probability {TAIL:g})"}
                for i in np.flatnonzero(final.rejected)]
    warnings = []
    if not final.convergence.converged:
        warnings.append(f"the final fit did not converge: {not_converged_words(final.convergence)}")
    if cv["not_converged"]:
        warnings.append(f"the fits of fold(s) {cv['not_converged']} of the cross-validation did not converge")
    if cv["rows_scored"] < len(data):
        warnings.append(f"{len(data) - cv['rows_scored']} row(s) could not be scored held out (their plane or point "
                        f"touched from too few poses outside their fold)")
    if final.rig_held:
        warnings.append("held where given (contact cannot see them): " + ", ".join(final.rig_held)
                        + "; a target's place along the plane it touches flush, or its height beside the plane's offset")
    if final.undetermined_rig:
        warnings.append("the contacts do not determine " + ", ".join(final.undetermined_rig)
                        + " (left at their nominal or first estimate)")
    return ContactCalibration(final, nominal, best["label"], best["parameters"], pr, scores, validation, rejected,
                              warnings)


def validate_contacts(model: Mechanism, data: ContactData, dx, offsets, nominal_offsets, sigma=1e-5,
                      robust=True) -> dict:
    """Score a calibration (``dx`` (p,), targets at ``offsets`` (K, 3)) on other rows (another session): only
    their planes and points are fitted, for the calibrated model (``after``) and the nominal one with the nominal
    targets (``before``). {'before': {...}, 'after': {...}, 'rig': ...}, distances in m."""
    after = fit_contacts(model, data, offsets, sigma=sigma, robust=robust, fixed=(dx, offsets))
    before = fit_contacts(model, data, nominal_offsets, sigma=sigma, robust=robust,
                          fixed=(np.zeros(model.n_params), nominal_offsets))
    out = {}
    for key, f in (("before", before), ("after", after)):
        keep = ~f.rejected
        out[key] = {"contact_rms_m": f.rms(), "contact_max_m": float(f.distances[keep].max()),
                    "rows": int(keep.sum()), "rejected": int(f.rejected.sum())}
    out["rig"] = after.rig.to_dict()
    out["improvement"] = float(1.0 - out["after"]["contact_rms_m"] / out["before"]["contact_rms_m"]) \
        if out["before"]["contact_rms_m"] > 0 else 0.0
    return out
