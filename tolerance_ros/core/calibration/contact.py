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
point's ``(x, y, z)`` (m). Every plane and point touched is fitted; a target stays at its nominal place unless the
fit determines it well (``_target_holds``); an unregularised parameter that is nearly a motion of the rig is held
(``ALIAS``). The noise of the rows is estimated from them (robust, after the rig-only fit, then after the
parameters) unless given. The fit is ``identification._minimise`` (Levenberg-Marquardt to its convergence tests)
on ``sum(r^2) + prior``, the prior a Gaussian one weighed against the noise or a Tikhonov weight, its steps kept
within the plausible errors (``PLAUSIBLE_LENGTH``, ``PLAUSIBLE_ANGLE``: a robot folded until its contacts meet in
one point fits every plane exactly), robust by the rows' distances (``REJECT`` robust standard deviations at the
tail probability of the tracker's rule, per row kind). What to identify is chosen by the one-standard-error rule
over the folds of a cross-validation by pose (``one_standard_error``). SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..conformity import PLAUSIBLE_ANGLE, PLAUSIBLE_LENGTH
from ..targets import shift_jacobian
from ..models.base import Mechanism
from ..accuracy.folds import folds_of, pose_groups
from ..identification import (PRIOR, SCALE_WITHOUT_BUDGET, Convergence, _minimise, _preference, _Layout,
                             column_scale, dependent_columns)
from .elastic import COMPLIANCE, HELD, STANDING, ElasticJoints, Load
from .robust import prior_vector

PLANE, POINT = "plane", "point"
KINDS = (PLANE, POINT)
ROWS = {PLANE: 1, POINT: 3}
TOL_RANK = 1e-5            # singular values below this share of the largest leave a null space (see fit_contacts)
TAIL = 1e-4                # a row whose distance is this improbable under the robust noise is an outlier
MAX_REJECTED = 0.25        # at most this share of the rows left out
ROUNDS = 5                 # rejection rounds of a robust fit
ELASTIC = "joint-offsets+elastic"
MODELS = ("rig", "joint-offsets", "full", ELASTIC)
AUTO, FIT = "auto", "fit"
TARGET_MODES = (AUTO, FIT)  # the targets fitted where the contacts determine them well, or wherever they can be
TARGET_SHARE = 0.001       # ... well: a target coordinate's std at the rows' noise under this share of its lever arm
LEVER_FLOOR = 0.01         # share of the robot's reach: the lever arm of a target at the tool frame's origin
NOISE_FLOOR = 1e-9         # m: the floor of a noise estimated from the rows (contacts fitted exactly)
RIG_COPY = 1e-3            # a target coordinate whose column beyond the rig's is under this share of the largest is
                           # a copy of the rig (a condition number over 1000: a common height beside a plane's offset)
INFLATION = 2.0            # a target fitted only where it leaves the parameters' std within this factor of theirs
ALIAS = 0.03               # an unregularised parameter whose column keeps less than this share beyond the rig's span
                           # is nearly a motion of the rig, and held
TIKHONOV = (1e-3, 1e-2, 1e-1)   # weights of the regularised candidates, cost |r|^2 + lambda |dx|^2 (m, rad);
                                # 1e-3 is FIGAROH's on TALOS
DEFLECTIONS = (0.02, 0.05)      # rad: prior std of a joint's elastic deflection at its largest load in the rows, of
                                # the elastic candidates
ELASTIC_TIKHONOV = 1e-2         # their Tikhonov weight on the joint offsets (a yaw of the hip beside the torso's)
NO_LOAD = (f"parameters: {ELASTIC!r} needs the joints' gravity load (a URDF with inertials, its chain from a fixed "
           f"base or from the link the robot stands on)")


def _reject_levels():
    """|e| / sigma beyond which a plane row (1-D) and a point row (3-D) is an outlier, at ``TAIL``."""
    from scipy.stats import chi2
    return float(np.sqrt(chi2.isf(TAIL, 1))), float(np.sqrt(chi2.isf(TAIL, 3)))


@dataclass
class ContactData:
    """Contact rows. q (n, dof) joints (SI); target (n,) index into ``target_names``; constraint (n,) index into
    ``constraints``, each ``(session, kind, id)``; labels (n,) test-pose names or None; where (n,) where each row
    comes from ('line 23'); stamps (n,) s or None; others (n, m) the readings (SI) of the robot's joints outside the
    chain ``other_names`` (the rest of a standing robot's posture, which loads its joints), or None."""

    q: np.ndarray
    target: np.ndarray
    constraint: np.ndarray
    constraints: tuple
    target_names: tuple
    labels: np.ndarray | None = None
    where: list | None = None
    stamps: np.ndarray | None = None
    others: np.ndarray | None = None
    other_names: tuple = ()

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
        others = None if self.others is None else np.asarray(self.others, float)[rows]
        return ContactData(self.q[rows], self.target[rows], self.constraint[rows], self.constraints,
                           self.target_names, labels, where, stamps, others, self.other_names)

    @property
    def posture(self) -> tuple | None:
        """(q (n, dof), other joint names, their readings (n, m)) of the rows, or None without other joints: what
        ``elastic.ElasticJoints`` loads the joints with."""
        if self.others is None or not len(self.other_names):
            return None
        return self.q, tuple(self.other_names), np.asarray(self.others, float)

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
    rows left out, the noise (m: from the residuals, the covariance's scale), the covariance of the unknowns, the
    convergence, the rows' distances (m). ``noise_rig``: the noise (m) that judged the targets (the robust estimate
    after the fit of the planes and points alone, or the one given: ``noise_given``); ``noise_robust``: the robust
    estimate after this fit, which judged its outliers and weighed its prior (``prior_weight``, m); ``targets_why``
    {target coordinate: held or fitted, and why}, judged at the noise ``targets_judged_at`` (m: the rig's, then
    again at the one the parameters leave); ``effective_unknowns``: the trace of the fit's hat matrix."""

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
    noise_rig: float | None = None
    noise_robust: float | None = None
    noise_given: bool = False
    targets_why: dict = field(default_factory=dict)
    effective_unknowns: float = 0.0
    prior_weight: float = 0.0
    targets_judged_at: float | None = None

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
    """(p,) parameters a candidate estimates (the compliances among them only for ``ELASTIC``, on a model with
    compliance columns: ``elastic.ElasticJoints``)."""
    if which not in MODELS:
        raise ValueError(f"parameters: expected one of {MODELS}, got {which!r}")
    compliance = np.array(model.param_kinds) == COMPLIANCE
    m = np.zeros(model.n_params, bool)
    if which in ("joint-offsets", ELASTIC):
        m[model.joint_columns()] = True
    elif which == "full":
        m[~compliance] = True
    if which == ELASTIC:
        if not compliance.any():
            raise ValueError(NO_LOAD)
        m[compliance] = True
    return m


def _largest_loads(model, q) -> np.ndarray:
    """(p,) the largest gravity load (N m, N) over the rows' joints q of each compliance column's joint (1 for the
    other columns)."""
    out = np.ones(model.n_params)
    if isinstance(model, ElasticJoints):
        out[model.compliance_columns()] = np.maximum(model.largest_loads(q), 1e-9)
    return out


def _row_count(data, weights):
    k = np.where(data.kind == PLANE, 1, 3)
    return int(np.sum(k[weights > 0]))


def fit_contacts(model: Mechanism, data: ContactData, offsets, which="full", prior=None, sigma=None, robust=True,
                 iterations=200, fixed=None, analysis=True, start=None, targets=AUTO, target_prior=None,
                 tikhonov=None, deflection=None) -> ContactFit:
    """The robust least-squares fit of candidate ``which`` (``MODELS``) with its rig, from the targets' nominal
    offsets (K, 3) m; ``prior`` (m, rad) on the origin errors (``robust.prior_vector``: none on joint offsets) or
    None. ``fixed``: (dx (p,), target offsets (K, 3)) of a calibrated model whose parameters and targets are held
    (only the planes and points are fitted: validation on another session, and the 'before' figures). ``start``:
    a ContactFit on the same layout to start from.

    ``sigma``: the contact noise (m), or None to estimate it from the rows (``_robust_sigma``: after the fit of the
    planes and points alone, the nominal robot and targets held; then after the parameters); given, it overrides
    the first estimate and floors the later ones. ``targets`` (``TARGET_MODES``): 'auto' fits a target's coordinate
    only where the contacts determine it well (``_target_holds``), 'fit' fits every one the rig does not make a
    copy of; ``target_prior`` (m): a Gaussian prior of that std on each target's offset from its nominal place
    (the targets then fitted as with 'fit'). ``tikhonov``: a weight lambda on the parameter errors estimated, the
    cost ``|r|^2 + lambda |dx|^2`` (m^2; dx in m and rad), whatever the noise. ``deflection`` (rad or m): on a model
    with compliance columns (``elastic.ElasticJoints``), the Gaussian prior std of each joint's elastic deflection at
    its largest load in the rows, weighed against the noise. Every plane and point touched is always fitted."""
    if targets not in TARGET_MODES:
        raise ValueError(f"targets: expected one of {TARGET_MODES}, got {targets!r}")
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
    prior_std = np.full(layout.n, np.inf)    # m or rad; inf: no prior
    if delta is not None:
        prior_std[:p] = delta
    if target_prior is not None and fixed is None:
        prior_std[layout.t] = float(target_prior)
        scale[layout.t] = float(target_prior)
    ridge = np.zeros(layout.n)
    if tikhonov is not None and fixed is None:
        ridge[:p] = float(tikhonov)
    kinds = np.array(model.param_kinds)
    compliance = kinds == COMPLIANCE
    loads = _largest_loads(model, data.q)
    if deflection is not None and fixed is None and compliance.any():
        prior_std[:p][compliance] = float(deflection) / loads[compliance]
        scale[:p][compliance] = prior_std[:p][compliance]
        ridge[:p][compliance] = 0.0
    natural = np.full(layout.n, SCALE_WITHOUT_BUDGET)
    natural[:p][compliance] = SCALE_WITHOUT_BUDGET / loads[compliance]
    reach = model.reach()   # the search stays within the build errors: free, a plane-contact fit can fold the robot
    bound = np.r_[np.where(kinds == "length", PLAUSIBLE_LENGTH * reach, PLAUSIBLE_ANGLE / loads),
                  np.full(3 * layout.K, PLAUSIBLE_LENGTH * reach)]
    n = len(data)
    rot = np.zeros((0, 3), int)
    reject_plane, reject_point = _reject_levels()
    floor = NOISE_FLOOR if sigma is None else float(sigma)
    plane = data.kind == PLANE

    def precision(noise):
        """(n,) the prior's weight on each unknown in the cost (m^2 per unit^2), weighed against ``noise``."""
        return np.where(np.isinf(prior_std), 0.0, (noise / prior_std) ** 2) + ridge

    def solve(weights, noise, x0, held):
        sw = np.sqrt(weights)
        pr = precision(noise)

        def evaluate(x):
            if np.any(np.abs(x[:layout.g.start]) > bound):
                raise ValueError("a step beyond the plausible errors")
            J, r, _ = _stack(base_model, data, x, ref, layout, sw)
            return J, r
        free = np.flatnonzero(~held)
        return _minimise(evaluate, np.where(held, 0.0, x0), free, scale, pr, rot, iterations), free

    J0, _, _ = _stack(base_model, data, np.zeros(layout.n), ref, layout)
    why, targets_why = {}, {}
    rejected = np.zeros(n, bool)
    noise_rig = None
    if fixed is None:
        # the noise and the gross rows first from the planes and points alone (the nominal robot and targets held):
        # the rows it judges gross start out of the fit, and the fit's own residuals judge every row again from there
        base = fit_contacts(model, data, off0, sigma=sigma, robust=robust, iterations=iterations,
                            fixed=(np.zeros(p), off0), analysis=False)
        noise_rig = float(sigma) if sigma is not None else base.noise_robust
        if robust and (~held[:p]).any():
            rejected = base.rejected.copy()
        names = layout.names(model, data)
        why.update(_hold_scale(model, held))
        r0 = _stack(base_model, data, base.x, ref, layout, np.sqrt((~rejected).astype(float)))[1]
        for j, w in _target_holds(J0, layout, held, sigma, off0, reach, targets, target_prior, precision, r0).items():
            targets_why[names[j][len("target "):]] = w
            held[j] = not w["fitted"]
        if sigma is None and not held[layout.t].all():
            # the noise after the rig-only fit: its planes and points and the targets it sees well
            rig_only = held.copy()
            rig_only[:p] = True
            (xr, _, _, _), _ = solve((~rejected).astype(float), noise_rig, np.zeros(layout.n), rig_only)
            dist_r = _stack(base_model, data, xr, ref, layout)[2]
            noise_rig = max(_robust_sigma(dist_r[~rejected], plane[~rejected]), floor)
    rig_held = [f"target {k}" for k, w in targets_why.items() if not w["fitted"]]
    cand = np.flatnonzero(~held[:p])
    nuisance = np.flatnonzero(~held[p:]) + p
    if len(cand) and fixed is None:
        unregularised = cand[np.isinf(prior_std[cand]) & (ridge[cand] == 0)]
        for j, share in _near_rig(J0 * natural, unregularised, nuisance).items():
            held[j] = True
            why[model.param_names[j]] = (
                f"nearly a motion of the rig: {share * 100:.2g} % of its effect on the contacts is not one of the "
                f"planes and points (under {ALIAS * 100:g} %); free, it would drift with the rig (held at nominal; a "
                f"regularised candidate keeps it, its prior deciding)")
        cand = np.flatnonzero(~held[:p])
        prefer = _preference(model, _Layout(p, 0, False, False, None), cand)
        dep = dependent_columns(J0 * natural, cand, nuisance, TOL_RANK, prefer)
        held[cand[dep]] = True
        why.update(_held_reasons(model, J0 * natural, cand[dep], nuisance))
    noise = noise_rig if noise_rig is not None else floor
    x = np.zeros(layout.n) if start is None else np.where(held, 0.0, start.x)
    weights = (~rejected).astype(float)
    still = np.zeros(len(data.constraints), bool)
    still[np.unique(data.constraint[~rejected])] = True
    held[layout.g] |= ~np.repeat(still, 3)
    threshold = None
    noise_robust = None
    for round_ in range(ROUNDS + 1):
        (x, J, r, conv), free = solve(weights, noise, x, held)
        _, _, dist = _stack(base_model, data, x, ref, layout)
        s = max(_robust_sigma(dist[~rejected], plane[~rejected]), floor)
        noise_robust = s
        if not robust or round_ == ROUNDS:
            break
        threshold = np.where(plane, reject_plane * s, reject_point * s)
        new = dist > threshold
        cap = int(MAX_REJECTED * n)
        if new.sum() > cap:
            new = np.zeros(n, bool)
            if cap:
                new[np.argsort(dist / threshold)[-cap:]] = True
        if np.array_equal(new, rejected) and (not np.isfinite(prior_std).any() or abs(s / noise - 1.0) < 0.05):
            break
        rejected, noise = new, s
        weights = (~rejected).astype(float)
        still = np.zeros(len(data.constraints), bool)
        still[np.unique(data.constraint[~rejected])] = True
        held[layout.g] |= ~np.repeat(still, 3)
    judged_noise = noise_rig
    if (fixed is None and sigma is None and targets == AUTO and target_prior is None and layout.K
            and noise_robust < noise_rig):
        # the targets judged again at the noise the parameters leave (the real noise, not the rig's misfit)
        again = held.copy()
        again[layout.t] = False
        judged_noise = noise_robust
        verdict = _target_holds(J, layout, again, noise_robust, off0, reach, targets, None, precision)
        again[list(verdict)] = [not w["fitted"] for w in verdict.values()]
        targets_why = {names[j][len("target "):]: w for j, w in verdict.items()}
        rig_held = [f"target {k}" for k, w in targets_why.items() if not w["fitted"]]
        if not np.array_equal(again, held):
            held = again
            x = np.where(held, 0.0, x)
            (x, J, r, conv), free = solve(weights, noise, x, held)
            _, _, dist = _stack(base_model, data, x, ref, layout)
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
    pr = precision(noise)
    H = Jf.T @ Jf + np.diag(pr[free] * sf ** 2)
    Hinv = np.linalg.pinv(H)
    edf = float(np.trace(Hinv @ (Jf.T @ Jf))) if len(free) else 0.0
    dof = rows_used - edf
    final = float(np.sqrt(r @ r / dof)) if dof >= 1 else noise
    final = max(final, 1e-300)
    cov = np.zeros((layout.n, layout.n))
    cov[np.ix_(free, free)] = Hinv * np.outer(sf, sf) * final ** 2
    out = ContactFit(layout, ref, x, [model.param_names[j] for j in np.flatnonzero(held[:p])], why, rejected, final,
                     cov, conv, dist, threshold=threshold, rig_held=rig_held, held_judged_at=judged,
                     noise_rig=noise_rig, noise_robust=noise_robust, noise_given=sigma is not None,
                     targets_why=targets_why, effective_unknowns=edf, prior_weight=float(noise),
                     targets_judged_at=judged_noise)
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


def _target_holds(J, layout, held, noise, offsets, reach, mode, target_prior, precision, r=None) -> dict:
    """{column: {fitted, kind, why, std_m}} of every target coordinate not ``held``, on the Jacobian ``J`` (per m and
    rad). First, scale-free, the coordinates that the planes and points and the other targets make a copy of
    (``dependent_columns`` of the columns scaled by 1 mm, ``RIG_COPY``; kind 'copy': a common height is a plane's
    offset) are held. Then ('auto', no ``target_prior``) a coordinate is fitted only where the fit determines it well
    (kind 'seen'): its standard deviation at the rows' ``noise`` (m; None: the robust noise of the residuals ``r``
    (rows, 0 for a row left out) that the planes and points and the targets still free leave, to first order, the
    rig-only fit), the planes and points and the parameters not ``held`` fitted with it (but those that copy a target
    or the rig, which ``dependent_columns`` holds instead; ``precision(noise)`` (n,): the prior's weight on each
    unknown, m^2 per unit^2 of the cost), under
    ``TARGET_SHARE`` of the target's lever arm (its nominal distance from the tool frame's origin, at least
    ``LEVER_FLOOR`` of the ``reach``); while one is not, the worst is held (kind 'unseen': fingertips flush on a table
    do not see their places along it, nor their heights beside a wrist's turn; free, a fit would move them onto one
    point, where one contact per posture is fitted exactly by the robot's many parameters); and where the rest pass,
    a target whose freedom makes a parameter's std more than ``INFLATION`` times larger (scale-free: a ratio at one
    noise) is held, the worst first (kind 'shared': a fingertip's height beside the wrist's turn). Kinds 'asked'
    (``mode`` 'fit') and 'prior' (``target_prior`` m) fit the others."""
    tcols = np.flatnonzero(~held[layout.t]) + layout.t.start
    gcols = np.flatnonzero(~held[layout.g]) + layout.g.start
    out = {}
    if not len(tcols):
        return out

    def entry(fitted, kind, why, std=None):
        return {"fitted": fitted, "kind": kind, "why": why, "std_m": None if std is None else float(std)}
    rig = np.r_[tcols, gcols]
    Js = J * SCALE_WITHOUT_BUDGET
    dep = dependent_columns(Js[:, rig], np.arange(len(tcols)), np.arange(len(tcols), len(rig)), RIG_COPY)
    for j in tcols[dep]:
        out[j] = entry(False, "copy", "held at its nominal place: the contacts cannot tell it from the rig (a place "
                                      "along the plane a target touches flush; a common height of targets flush on a "
                                      "plane, which is the plane's offset)")
    free = list(tcols[~dep])
    lever = np.maximum(np.linalg.norm(np.asarray(offsets, float), axis=1), LEVER_FLOOR * reach)
    if target_prior is not None:
        for j in free:
            out[j] = entry(True, "prior", f"fitted with a prior of {target_prior * 1e3:.4g} mm on its nominal place")
    elif mode == FIT:
        for j in free:
            out[j] = entry(True, "asked", "fitted as asked, however well the contacts see it")
    candidates = np.flatnonzero(~held[:layout.p])
    given = noise
    while free and target_prior is None and mode != FIT:
        params = candidates     # but those that copy a target still free, which ``dependent_columns`` holds instead
        if len(params):
            params = params[~dependent_columns(Js, params, np.r_[free, gcols], TOL_RANK)]
        noise = given if given is not None else _rig_noise(J[:, np.r_[free, gcols]], r)
        A = J / noise                                # rows in units of the noise
        cols = np.r_[free, gcols, params]
        lam, V = np.linalg.eigh(A[:, cols].T @ A[:, cols] + np.diag(precision(noise)[cols] / noise ** 2))
        live = lam > 1e-12 * max(lam[-1], 1e-300)
        std = np.sqrt(np.maximum((V[:len(free), live] ** 2) @ (1.0 / lam[live]), 0.0))
        std = np.where(np.any(np.abs(V[:len(free), ~live]) > 1e-9, axis=1), np.inf, std)
        k = (np.asarray(free) - layout.t.start) // 3
        share = std / lever[k]
        worst = int(np.argmax(share))
        if share[worst] <= TARGET_SHARE and len(params):
            alone = _param_std(A, np.r_[gcols, params], precision(noise) / noise ** 2, len(params))
            inflation = np.array([np.max(_param_std(A, np.r_[j, gcols, params], precision(noise) / noise ** 2,
                                                    len(params)) / alone) for j in free])
            if inflation.max() > INFLATION:
                i = int(np.argmax(inflation))
                j = free.pop(i)
                out[j] = entry(False, "shared", f"held at its nominal place: fitted, it would share the contacts with "
                                                f"the parameters (their std up to {inflation[i]:.3g} times larger, over "
                                                f"{INFLATION:g})", std[i])
                continue
        if share[worst] <= TARGET_SHARE:
            for i, j in enumerate(free):
                out[j] = entry(True, "seen", f"fitted: std {std[i] * 1e3:.3g} mm at the noise {noise * 1e3:.3g} mm, "
                                             f"{share[i] * 100:.2g} % of its lever arm {lever[k[i]] * 1e3:.4g} mm (under "
                                             f"{TARGET_SHARE * 100:g} %)", std[i])
            break
        j = free.pop(worst)
        out[j] = entry(False, "unseen", f"held at its nominal place: std {std[worst] * 1e3:.3g} mm at the noise "
                                        f"{noise * 1e3:.3g} mm, {share[worst] * 100:.3g} % of its lever arm "
                                        f"{lever[k[worst]] * 1e3:.4g} mm (over {TARGET_SHARE * 100:g} %): the contacts "
                                        f"hardly see it", std[worst])
    return {j: out[j] for j in sorted(out)}


def _param_std(A, cols, precision, k) -> np.ndarray:
    """(k,) standard deviations, in units of the noise, of the last ``k`` of the unknowns ``cols`` fitted together
    on the columns ``A`` (rows in units of the noise) with the prior's weights ``precision`` (per unit^2 of the
    unknowns, in units of the noise)."""
    H = A[:, cols].T @ A[:, cols] + np.diag(precision[cols])
    return np.sqrt(np.maximum(np.diag(np.linalg.pinv(H))[-k:], 1e-300))


def _rig_noise(Jr, r) -> float:
    """Robust noise per axis (m) of the residuals ``r`` (rows; 0 for a row left out) beyond the span of the rig's
    columns ``Jr``: the median |e| over 0.6745, corrected for the unknowns; at least ``NOISE_FLOOR``."""
    used = r != 0
    Q, R = np.linalg.qr(Jr[used])
    keep = np.abs(np.diag(R)) > 1e-9 * max(np.abs(R).max(), 1e-300) if R.size else np.zeros(0, bool)
    Q = Q[:, keep]
    e = r[used] - Q @ (Q.T @ r[used])
    m = int(used.sum())
    return max(float(np.median(np.abs(e)) / 0.6745 * np.sqrt(m / max(m - Q.shape[1], 1))), NOISE_FLOOR)


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


def _near_rig(Js, cols, nuisance) -> dict:
    """{column: share} of the ``cols`` of the scaled Jacobian ``Js`` whose effect on the contacts is nearly a motion
    of the rig: the share of the column's norm beyond the span of the ``nuisance`` columns (the planes, points and
    targets fitted) under ``ALIAS`` (scale-free: the sine of the angle between the column and the rig's span; an
    ankle's pitch beside a table's tilt), exact motions (share 0) left to ``dependent_columns``."""
    if not len(cols) or not len(nuisance):
        return {}
    Q, R = np.linalg.qr(Js[:, nuisance])
    Q = Q[:, np.abs(np.diag(R)) > 1e-12 * max(np.abs(R).max(), 1e-300)]
    A = Js[:, cols]
    size = np.linalg.norm(A, axis=0)
    beyond = np.linalg.norm(A - Q @ (Q.T @ A), axis=0)
    share = np.where(size > 0, beyond / np.where(size > 0, size, 1.0), 0.0)
    return {int(j): float(f) for j, f, z in zip(cols, share, size) if z > 0 and 1e-6 < f < ALIAS}


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


@dataclass(frozen=True)
class Candidate:
    """What a contact fit identifies: the parameters ``which`` (``MODELS``), regularised by a Gaussian ``prior``
    (length m, angle rad) on the origin errors weighed against the rows' noise (none on the joint offsets), or by a
    ``tikhonov`` weight lambda on every parameter estimated (cost ``|r|^2 + lambda |dx|^2``, m and rad), or
    neither; ``ELASTIC`` with the prior std ``deflection`` (rad) of each joint's elastic deflection at its largest
    load, the joints loaded as ``load`` says (an ``elastic.Load`` kind; None: the model's own)."""

    which: str
    prior: tuple | None = None
    tikhonov: float | None = None
    deflection: float | None = None
    load: str | None = None

    @property
    def label(self) -> str:
        if self.deflection is not None:
            weight = "" if self.tikhonov is None else f", Tikhonov {self.tikhonov:g}"
            held = " (root link held)" if self.load == HELD else ""
            return f"{self.which}{held}, deflection prior {self.deflection * 1e3:g} mrad{weight}"
        if self.prior is not None:
            return f"{self.which}, prior {self.prior[0] * 1e3:g} mm / {self.prior[1] * 1e3:g} mrad"
        if self.tikhonov is not None:
            return f"{self.which}, Tikhonov {self.tikhonov:g}"
        return self.which

    def to_dict(self) -> dict:
        return {"label": self.label, "parameters": self.which,
                "prior": None if self.prior is None else list(self.prior), "tikhonov": self.tikhonov,
                "deflection": self.deflection, "load": self.load}


def candidates(prior=PRIOR, tikhonov=TIKHONOV, elastic=False) -> list:
    """The ``Candidate`` list ``calibrate_contacts`` cross-validates: the rig alone, the joint offsets (alone and
    with each ``tikhonov`` weight), every parameter (alone, with the ``prior`` (m, rad) if any, with each weight),
    and where the joints' gravity load is known (``elastic``: the ``elastic.Load`` kind of the model) the joint
    offsets with every joint's compliance (each ``DEFLECTIONS`` prior, ``ELASTIC_TIKHONOV`` on the offsets); a robot
    standing on the chain's base carries its whole weight, or its root link is held (a harness, a gantry)."""
    out = [Candidate("rig"), Candidate("joint-offsets")]
    out += [Candidate("joint-offsets", tikhonov=w) for w in tikhonov]
    out.append(Candidate("full"))
    if prior is not None:
        out.append(Candidate("full", prior=tuple(prior)))
    out += [Candidate("full", tikhonov=w) for w in tikhonov]
    if elastic:
        loads = (STANDING, HELD) if elastic == STANDING else (None,)
        out += [Candidate(ELASTIC, tikhonov=ELASTIC_TIKHONOV, deflection=d, load=k) for k in loads for d in DEFLECTIONS]
    return out


def model_for(model: Mechanism, which: str, data: ContactData | None = None, load: str | None = None) -> Mechanism:
    """The model a candidate ``which`` is fitted on: ``model``, or for ``ELASTIC`` the model with its joints'
    compliances among its parameters (``elastic.ElasticJoints``, loaded as ``load`` (an ``elastic.Load`` kind of a
    standing robot) or ``elastic.Load.for_model`` says, the robot's other joints as ``data`` recorded them);
    ValueError where no load is known."""
    if which != ELASTIC:
        return model
    own = Load.for_model(model)
    if own is None:
        raise ValueError(NO_LOAD)
    return ElasticJoints(model, own if load is None else Load(load), None if data is None else data.posture)


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


def cross_validate(model, data, candidate: Candidate, sigma=None, folds=10, seed=0, robust=True, offsets=None,
                   targets=AUTO, target_prior=None) -> dict:
    """K-fold by test pose: each fold's rows predicted by the fit of the others (``_score_rows``); every row
    scored. {'after': {contact_rms_m, contact_max_m}, 'distances_m', 'rows_scored', 'folds', 'fold_rms_m' (each
    fold's RMS, nan where none of its rows was scored), 'standard_error_m' (the folds' standard deviation over
    sqrt(k)), 'effective_unknowns' (the folds' mean), 'not_converged', 'estimated' (how many parameters the
    candidate estimates)}, distances in m."""
    groups, _ = pose_groups(data.q, data.labels)
    fold, k = folds_of(groups, folds, seed)
    dist = np.full(len(data), np.nan)
    bad, edf = [], []
    model = model_for(model, candidate.which, data, candidate.load)
    for f in range(k):
        test = np.flatnonzero(fold == f)
        train = data.subset(fold != f)
        try:
            fitted = fit_contacts(model, train, offsets, candidate.which, candidate.prior, sigma, robust,
                                  analysis=False, targets=targets, target_prior=target_prior,
                                  tikhonov=candidate.tikhonov, deflection=candidate.deflection)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if not fitted.convergence.converged:
            bad.append(f)
        edf.append(fitted.effective_unknowns)
        dist[test] = _score_rows(model, data, fitted, test, sigma)
    scored = np.isfinite(dist)
    d = dist[scored]
    per_fold = np.array([np.sqrt(np.mean(dist[(fold == f) & scored] ** 2)) if np.any((fold == f) & scored)
                         else np.nan for f in range(k)])
    ok = np.isfinite(per_fold)
    se = float(np.std(per_fold[ok], ddof=1) / np.sqrt(ok.sum())) if ok.sum() > 1 else float("nan")
    return {"after": {"contact_rms_m": float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan"),
                      "contact_max_m": float(d.max()) if d.size else float("nan")},
            "distances_m": dist, "rows_scored": int(scored.sum()), "folds": k, "fold_rms_m": per_fold.tolist(),
            "standard_error_m": se, "effective_unknowns": float(np.mean(edf)) if edf else float("nan"),
            "not_converged": bad, "estimated": int(_estimate_mask(model, candidate.which).sum())}


def one_standard_error(scores) -> tuple:
    """(chosen score, reason) by the one-standard-error rule over the folds, among ``scores`` (dicts with
    ``cv_contact_rms_m``, ``standard_error_m``, ``estimated`` (how many parameters the candidate estimates) and
    ``not_converged_folds``): the best is the lowest held-out RMS among the candidates whose every fold converged
    (among all when none did); within one standard error of it (its folds' scatter over sqrt(k)) the candidate
    estimating the fewest parameters wins, and of equally many the lower held-out RMS (a regulariser is tuned by
    the folds, the parameter set by parsimony)."""
    valid = [s for s in scores if np.isfinite(s.get("cv_contact_rms_m", np.nan))]
    pool = [s for s in valid if not s["not_converged_folds"]] or valid
    best = min(pool, key=lambda s: s["cv_contact_rms_m"])
    se = best["standard_error_m"] if np.isfinite(best["standard_error_m"]) else 0.0
    limit = best["cv_contact_rms_m"] + se
    chosen = min((s for s in pool if s["cv_contact_rms_m"] <= limit),
                 key=lambda s: (s["estimated"], s["cv_contact_rms_m"]))
    why = (f"the one-standard-error rule over the folds: the lowest held-out RMS {best['cv_contact_rms_m'] * 1e3:.4g} mm "
           f"({best['label']}) plus its standard error {se * 1e3:.3g} mm gives {limit * 1e3:.4g} mm; within it, the "
           f"fewest parameters estimated, then the lower held-out RMS")
    if len(pool) < len(valid):
        why += "; candidates with a fold that did not converge are not chosen"
    return chosen, why


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
    how: str = ""
    tikhonov: float | None = None
    deflection: float | None = None
    load: Load | None = None
    largest_loads: np.ndarray | None = None


def calibrate_contacts(model: Mechanism, data: ContactData, offsets, parameters="auto", prior=PRIOR, sigma=None,
                       folds=10, seed=0, robust=True, progress=None, targets=AUTO,
                       target_prior=None) -> ContactCalibration:
    """Choose what to identify by the held-out contact RMS (``cross_validate``; ``one_standard_error``), fit it on
    every row, and validate: ``before`` is the nominal model with its rig fitted on every row (its best case),
    ``after`` the calibrated one predicting each fold's poses from the others. ``sigma`` (m): the contact noise,
    None to estimate it from the rows; ``targets``, ``target_prior``: see ``fit_contacts``."""
    groups, names = pose_groups(data.q, data.labels)
    if len(names) < 2:
        raise ValueError("validation: needs at least 2 distinct test poses (touch from more poses)")
    load = Load.for_model(model)
    todo = candidates(prior, elastic=load.kind if load is not None else False) if parameters == "auto" else [
        Candidate(parameters, tuple(prior) if parameters == "full" and prior else None,
                  ELASTIC_TIKHONOV if parameters == ELASTIC else None, DEFLECTIONS[0] if parameters == ELASTIC else None)]
    scores, cvs = [], {}
    kw = {"targets": targets, "target_prior": target_prior}
    for step, cand in enumerate(todo):
        if progress is not None:
            progress(step, len(todo) + 1)
        try:
            cv = cross_validate(model, data, cand, sigma, folds, seed, robust, offsets, **kw)
        except (ValueError, np.linalg.LinAlgError) as exc:
            scores.append({**cand.to_dict(), "error": str(exc)})
            continue
        cvs[cand.label] = cv
        fold_rms = np.asarray(cv["fold_rms_m"], float)
        scores.append({**cand.to_dict(), "estimated": cv["estimated"],
                       "cv_contact_rms_m": cv["after"]["contact_rms_m"], "cv_contact_max_m": cv["after"]["contact_max_m"],
                       "fold_rms_m": cv["fold_rms_m"], "standard_error_m": cv["standard_error_m"],
                       "fold_scatter_m": float(np.nanstd(fold_rms, ddof=1)) if np.isfinite(fold_rms).sum() > 1 else None,
                       "effective_unknowns": cv["effective_unknowns"], "rows_scored": cv["rows_scored"],
                       "not_converged_folds": cv["not_converged"]})
    valid = [s for s in scores if np.isfinite(s.get("cv_contact_rms_m", np.nan))]
    if not valid:
        raise ValueError("calibration: no candidate could be fitted: " + "; ".join(s.get("error", "no row scored")
                                                                               for s in scores))
    if parameters == "auto":
        best, how = one_standard_error(valid)
    else:
        best, how = valid[0], "given (--parameters)"
    for s in scores:
        s["chosen"] = s is best
    cand = Candidate(best["parameters"], None if best.get("prior") is None else tuple(best["prior"]),
                     best.get("tikhonov"), best.get("deflection"), best.get("load"))
    chosen = model_for(model, cand.which, data, cand.load)
    final = fit_contacts(chosen, data, offsets, cand.which, cand.prior, sigma, robust, tikhonov=cand.tikhonov,
                         deflection=cand.deflection, **kw)
    nominal = fit_contacts(model, data, offsets, "rig", None, sigma, robust, **kw)
    if progress is not None:
        progress(len(todo) + 1, len(todo) + 1)
    cv = cvs[best["label"]]
    before, after = nominal.rms(np.arange(len(data))), cv["after"]["contact_rms_m"]
    validation = {"method": f"{cv['folds']}-fold cross-validation by test pose ({len(names)} poses); 'before' is the "
                            f"nominal model with its rig fitted on every row",
                  "before": {"contact_rms_m": before, "contact_max_m": float(nominal.distances.max())},
                  "after": dict(cv["after"]), "rows_scored": cv["rows_scored"], "rows": len(data),
                  "improvement": float(1.0 - after / before) if before > 0 else 0.0,
                  "distances_m": cv["distances_m"].tolist(), "fold_rms_m": cv["fold_rms_m"],
                  "standard_error_m": cv["standard_error_m"]}
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
    if final.undetermined_rig:
        warnings.append("the contacts do not determine " + ", ".join(final.undetermined_rig)
                        + " (left at their nominal or first estimate)")
    return ContactCalibration(final, nominal, best["label"], cand.which, cand.prior, scores, validation, rejected,
                              warnings, how, cand.tikhonov, cand.deflection, getattr(chosen, "load", None),
                              chosen.largest_loads(data.q) if isinstance(chosen, ElasticJoints) else None)


def validate_contacts(model: Mechanism, data: ContactData, dx, offsets, nominal_offsets, sigma=None,
                      robust=True, chain: Mechanism | None = None) -> dict:
    """Score a calibration (``dx`` (p,), targets at ``offsets`` (K, 3)) on other rows (another session): only
    their planes and points are fitted, for the calibrated model (``after``: ``chain``, the model with the
    calibration's elastic term, or ``model``) and the nominal one with the nominal targets (``before``).
    {'before': {...}, 'after': {...}, 'rig': ...}, distances in m."""
    after = fit_contacts(chain or model, data, offsets, sigma=sigma, robust=robust, fixed=(dx, offsets))
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
