"""Simulated measurements: an as-built robot inside a tolerance budget, seen by a tracker.

The as-built robot has parameter errors drawn within the budget (seeded); the tracker measures the
tool pose in its own frame (``T_tracker_base`` maps base-frame poses into the tracker frame) with
Gaussian noise on position (m) and orientation (rad, a small rotation about a random axis).

``edited_urdf`` makes an as-built URDF by editing its joint origins (shifts, turns and zero offsets
composed exactly and written as rpy), and ``PinocchioArm`` measures it with pinocchio: a truth that does
not go through the error model under test.
"""
from __future__ import annotations

import numpy as np

from ..analysis import sample_errors
from ..geometry import exp_so3
from ..models.base import Mechanism
from ..targets import at_point


def as_built_errors(delta, seed=0, distribution="uniform") -> np.ndarray:
    """(p,) parameter errors of one as-built robot within ``+-delta`` (SI)."""
    return sample_errors(np.asarray(delta, dtype=float), 1, distribution, seed)[0]


def _small_rotations(rng, n, sigma):
    return exp_so3(rng.standard_normal((n, 3)) * sigma)


def measure(model: Mechanism, q, dx=None, noise_position=0.0, noise_orientation=0.0, T_tracker_base=None,
            seed=0) -> np.ndarray:
    """(n, 4, 4) tracker readings of the as-built tool at joints q (n, dof)."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    T = model.fk(q, dx)
    n = len(T)
    if noise_orientation > 0:
        T[:, :3, :3] = _small_rotations(rng, n, noise_orientation) @ T[:, :3, :3]
    if noise_position > 0:
        T[:, :3, 3] += rng.standard_normal((n, 3)) * noise_position
    if T_tracker_base is not None:
        T = np.asarray(T_tracker_base, dtype=float) @ T
    return T


def backlash(q_steps, play, revolute) -> np.ndarray:
    """(n, dof) joint deflections (rad) of a robot whose revolute joints have ``play`` (rad, the whole backlash)
    as it drives the configurations ``q_steps`` (n, dof) in turn: each joint lags ``play / 2`` behind the way it
    last moved (none before it first moves). ``revolute`` (dof,) bool: the joints with play."""
    q = np.asarray(q_steps, dtype=float)
    s = np.sign(np.diff(q, axis=0, prepend=q[:1]))
    rows = np.where(s != 0, np.arange(len(q))[:, None], 0)
    last = np.maximum.accumulate(rows, axis=0)            # the step each joint last moved at
    s = np.take_along_axis(s, last, axis=0)
    return -0.5 * float(play) * s * np.asarray(revolute, bool)[None]


def joint_compliance(model: Mechanism, q, dx, load, stiffness) -> np.ndarray:
    """(n, dof) joint deflections (rad) of the as-built robot (``dx``) at joints q (n, dof) under the loads at its
    tool point (base frame): (n, 3) forces N or (n, 6) forces and torques N m, ``K^-1 J^T W`` with J the tool's
    Jacobian in the joints (position rows, then rotation rows) and K the diagonal of ``stiffness`` (dof,) N m/rad
    (inf: a rigid joint, as every prismatic one)."""
    q = np.asarray(q, float)
    W = np.asarray(load, float)
    _, EJ = model.fk_and_jacobian(q, dx)
    Jq = EJ.J[:, :W.shape[1], model.joint_columns()] * model.joint_direction
    tau = np.einsum("nij,ni->nj", Jq, W)
    return tau / np.asarray(stiffness, float)[None]


def thermal_expansion(stamps, expansion, tau) -> np.ndarray:
    """(n,) relative growth of every length of a robot warming up: ``expansion (1 - exp(-t / tau))`` at t s
    after the first stamp (``expansion`` e.g. 1e-4, ``tau`` s). Uniform growth scales every position of the
    tool about the base origin by ``1 + growth`` and leaves orientations as they are."""
    t = np.asarray(stamps, dtype=float)
    return float(expansion) * -np.expm1(-(t - t[0]) / float(tau)) if len(t) else t


def measure_targets(model: Mechanism, q, dx=None, targets=None, noise_position=0.0, noise_orientation=0.0,
                    T_tracker_base=None, seed=0, stamps=None, labels=None, points=True, deflection=None,
                    growth=None):
    """Measurements of every target of ``targets`` (``targets.Targets``; default: the tool frame) at joints
    q (n, dof) by a tracker: one row per visit and target (a visit's rows share its stamp), as
    ``io.Measurements`` in the tracker frame. ``points``: the tracker reads points (no orientation);
    otherwise frames. ``deflection`` (n, dof) is added to the joints the as-built robot reaches (its
    elastic deflection, its backlash), not to the joints it reports; ``growth`` (n,) scales the positions about
    the base origin by ``1 + growth`` (``thermal_expansion``)."""
    from .io import Measurements
    from ..targets import Targets
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    q = np.asarray(q, float)
    targets = targets if targets is not None else Targets.at_tool(frames=not points)
    K, n = len(targets), len(q)
    T_tool = model.fk(q if deflection is None else q + deflection, dx)
    idx = np.tile(np.arange(K), n)
    rows = np.repeat(np.arange(n), K)
    T = targets.poses(T_tool[rows], idx)
    if growth is not None:
        T[:, :3, 3] *= 1.0 + np.asarray(growth, float)[rows, None]
    if noise_orientation > 0 and not points:
        T[:, :3, :3] = _small_rotations(rng, len(T), noise_orientation) @ T[:, :3, :3]
    if noise_position > 0:
        T[:, :3, 3] += rng.standard_normal((len(T), 3)) * noise_position
    if points:
        T[:, :3, :3] = np.eye(3)
    if T_tracker_base is not None:
        A = np.asarray(T_tracker_base, dtype=float)
        T[:, :3, 3] = T[:, :3, 3] @ A[:3, :3].T + A[:3, 3]
        if not points:
            T[:, :3, :3] = A[:3, :3] @ T[:, :3, :3]
    stamps = np.arange(n, dtype=float) if stamps is None else np.asarray(stamps, float)
    names = np.array(targets.names, dtype=object)
    return Measurements(stamps[rows], T, q[rows], model.joint_names,
                        None if labels is None else np.asarray(labels, dtype=object)[rows], np.full(len(T), -1),
                        not points, "simulated", [], names[idx] if K > 1 or targets.names[0] else None)


def _rotation(w) -> np.ndarray:
    return exp_so3(np.asarray(w, float))[0]


def edited_urdf(text: str, edits: dict) -> str:
    """URDF text with joint origins edited: ``edits[joint] = (dxyz (3,) m added in the parent frame, rotation
    vector (3,) rad applied in the parent frame on the left of the origin's rotation, zero offset (rad, a turn
    about the joint axis at the origin))``; each edited origin written as the rpy of its exact rotation."""
    import xml.etree.ElementTree as ET
    from ..geometry import rpy_from_matrix, rpy_to_matrix
    root = ET.fromstring(text)
    for j in root.findall("joint"):
        if j.get("name") not in edits:
            continue
        dxyz, w, off = edits[j.get("name")]
        org = j.find("origin")
        if org is None:
            org = ET.SubElement(j, "origin")
        xyz = np.array([float(v) for v in org.get("xyz", "0 0 0").split()])
        rpy = np.array([float(v) for v in org.get("rpy", "0 0 0").split()])
        ax = j.find("axis")
        axis = np.array([float(v) for v in (ax.get("xyz") if ax is not None else "1 0 0").split()])
        R = _rotation(w) @ rpy_to_matrix(rpy) @ _rotation(axis / np.linalg.norm(axis) * off)
        org.set("xyz", " ".join(repr(float(v)) for v in xyz + np.asarray(dxyz, float)))
        org.set("rpy", " ".join(repr(float(v)) for v in rpy_from_matrix(R[None])[0]))
    return ET.tostring(root, encoding="unicode")


class PinocchioArm:
    """Points on the tip link of a URDF, by pinocchio's forward kinematics (joint vectors in the URDF's own
    joint order, which for a serial chain of 1-DOF joints is the chain's order)."""

    def __init__(self, text: str, tip: str):
        import pinocchio as pin
        self.pin = pin
        self.model = pin.buildModelFromXML(text)
        self.data = self.model.createData()
        self.fid = self.model.getFrameId(tip)

    def points(self, q, offsets) -> np.ndarray:
        """(n, K, 3) points at ``offsets`` (K, 3) m in the tip frame, base frame, m."""
        out = np.empty((len(q), len(offsets), 3))
        for i, qi in enumerate(np.asarray(q, float)):
            self.pin.framesForwardKinematics(self.model, self.data, qi)
            M = self.data.oMf[self.fid]
            out[i] = np.asarray(offsets, float) @ M.rotation.T + M.translation
        return out

    def point_mass_torques(self, q, mass, h=1e-6) -> np.ndarray:
        """(n, dof) the generalized force of gravity on a point mass (kg) at the tip frame's origin, N m: -m g dz/dq
        by central differences (gravity 9.81 m/s^2 along -z; a joint of compliance c > 0 yields by c times it)."""
        q = np.asarray(q, float)
        out = np.empty_like(q)
        z0 = np.zeros((1, 3))
        for j in range(q.shape[1]):
            dq = np.zeros(q.shape[1])
            dq[j] = h
            out[:, j] = (self.points(q + dq, z0)[:, 0, 2] - self.points(q - dq, z0)[:, 0, 2]) / (2 * h)
        return -out * mass * 9.81


class PathStreams:
    """A simulated run along a joint trajectory: the joint states (``joint_stamps`` (k,) s, ``joints`` (k, dof),
    the commanded joints as the controller logs them) and the tracker's stream (``stamps`` (n,) s, ``points``
    (n, 3) m in the tracker frame), stamped ``latency`` s late, with the truth beside: ``true_times`` (n,) s
    when each point was measured and ``true_points`` (n, 3) m, the as-built tool there (base frame, no noise)."""

    def __init__(self, **kw):
        self.__dict__.update(kw)


def path_streams(model: Mechanism, jp, dx=None, T_tracker_base=None, joint_rate: float = 500.0,
                 tracker_rate: float = 1000.0, latency: float = 0.008, noise: float = 10e-6, seed=0,
                 t0: float = 1000.0, lead: float = 0.5, repeatability: float = 0.0, offset=None,
                 settling=None, noise_orientation=None) -> PathStreams:
    """The joint states and the tracker's stream of the as-built robot (errors ``dx``) driving ``jp``
    (``iso_paths.JointPath``, run time 0 at clock time ``t0`` s), from ``lead`` s before to ``lead`` s after;
    the tracker's clock starts at a random phase of its period, its noise is Gaussian per axis (m).
    ``repeatability``: the standard deviation (rad or m) of a joint offset drawn per joint and cycle, added
    to the joints the as-built robot reaches (the cycles then differ; the joint states do not show it).
    ``offset`` (3,) m: the tracked target's position on the tool frame (None: its origin). ``settling``
    (natural frequency rad/s, damping ratio): the joints the as-built robot reaches follow the command through
    a second-order response (``settle``), so that it lags in motion and oscillates about each stop.
    ``noise_orientation`` (rad): the tracker measures frames (a 6-DOF tracker), with this noise (a small turn about
    a random axis): ``rotations`` (n, 3, 3) in the tracker frame and ``true_rotations`` (base frame) beside."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    span = jp.duration + 2 * lead
    tj = t0 - lead + np.arange(int(span * joint_rate) + 1) / joint_rate
    tt = t0 - lead + (rng.uniform() + np.arange(int(span * tracker_rate))) / tracker_rate
    jitter = rng.standard_normal((jp.cycles, model.dof)) * repeatability
    true = np.empty((len(tt), 3))
    frames = noise_orientation is not None
    true_R = np.empty((len(tt), 3, 3)) if frames else None
    target = at_point(model, offset)
    reached = None
    if settling is not None:
        cyc = np.clip(np.floor((tt - t0) / jp.period), 0, jp.cycles - 1).astype(int)
        reached = settle(jp.at(tt - t0) + jitter[cyc], 1.0 / tracker_rate, *settling)
    for i in range(0, len(tt), 100_000):
        tr = tt[i:i + 100_000] - t0
        cyc = np.clip(np.floor(tr / jp.period), 0, jp.cycles - 1).astype(int)
        q = jp.at(tr) + jitter[cyc] if reached is None else reached[i:i + 100_000]
        T = target.fk(q, dx)
        true[i:i + 100_000] = T[:, :3, 3]
        if frames:
            true_R[i:i + 100_000] = T[:, :3, :3]
    meas = true + rng.standard_normal(true.shape) * noise
    A = np.eye(4) if T_tracker_base is None else np.asarray(T_tracker_base, float)
    rotations = None
    if frames:
        turned = _small_rotations(rng, len(tt), noise_orientation) @ true_R if noise_orientation > 0 else true_R
        rotations = A[:3, :3] @ turned
    return PathStreams(joint_stamps=tj, joints=jp.at(tj - t0), stamps=tt + latency, points=meas @ A[:3, :3].T + A[:3, 3],
                       true_times=tt, true_points=true, T_tracker_base=A, latency=latency, dx=dx, noise=noise,
                       rotations=rotations, true_rotations=true_R)


def settle(q, dt: float, omega: float, zeta: float) -> np.ndarray:
    """(n, dof) joints of a robot whose every joint follows the command q (n, dof), sampled every ``dt`` s, as a
    second-order system ``x'' = omega^2 (q - x) - 2 zeta omega x'`` (natural frequency ``omega`` rad/s, damping
    ratio ``zeta``), at rest at q[0] to start: discretised exactly for a command held over each step."""
    from scipy.signal import cont2discrete, lfilter, lfilter_zi
    if not (omega > 0 and zeta > 0 and dt > 0):
        raise ValueError(f"settling: expected a positive natural frequency, damping ratio and step, got {omega!r}, "
                         f"{zeta!r}, {dt!r}")
    b, a, _ = cont2discrete(([omega ** 2], [1.0, 2.0 * zeta * omega, omega ** 2]), dt, method="zoh")
    b = np.ravel(b)
    q = np.asarray(q, float)
    zi = lfilter_zi(b, a)[:, None] * q[:1]
    return lfilter(b, a, q, axis=0, zi=zi)[0]


def touch(model: Mechanism, dx, offset, kind, where, n, seed=0, noise=0.0):
    """(n, dof) joints at which the as-built robot (``dx``) puts its target at ``offset`` (3,) m of its tool frame
    on a plane or a point, or its several targets ``offset`` (K, 3) on one plane at once (flush, as fingertips on
    a table), found by damped Newton steps of least joint change from seeded postures within the limits
    (ValueError when fewer than ``n`` of them reach it within the limits). ``kind`` 'plane' with ``where`` =
    (unit normal (3,), offset d m): ``n . P = d + e``; 'point' with ``where`` (3,) m: ``P = c + e``; ``e`` a
    seeded normal error of std ``noise`` m (per target and row, per axis for a point)."""
    rng = np.random.default_rng(seed)
    offsets = np.asarray(offset, float).reshape(-1, 3)
    K = len(offsets)
    if kind == "point" and K != 1:
        raise ValueError("point contact: one target at a time (several cannot be at one point)")
    cols = model.joint_columns()
    sign = model.joint_direction
    out = []
    tries = 0
    while sum(len(o) for o in out) < n and tries < 40:
        tries += 1
        q = model.sample_joints(max(20 * n, 200), rng)
        m = len(q)
        if kind == "plane":
            normal, d = np.asarray(where[0], float), float(where[1])
            e = rng.standard_normal((m, K)) * noise
        else:
            c = np.asarray(where, float)
            e = rng.standard_normal((m, 3)) * noise

        def misfit(q):
            T, EJ = model.fk_and_jacobian(q, dx)
            rows, jac = [], []
            for k in range(K):
                arms = T[:, :3, :3] @ offsets[k]
                P = T[:, :3, 3] + arms
                Jq = (EJ.J[:, :3, cols] - np.cross(arms[:, :, None], EJ.J[:, 3:, cols], axis=1)) * sign
                if kind == "plane":
                    rows.append((P @ normal - d - e[:, k])[:, None])
                    jac.append(np.einsum("i,nij->nj", normal, Jq)[:, None])
                else:
                    rows.append(P - c - e)
                    jac.append(Jq)
            return np.concatenate(rows, axis=1), np.concatenate(jac, axis=1)
        for _ in range(30):
            f, Jc = misfit(q)
            A = Jc @ Jc.transpose(0, 2, 1) + 1e-6 * np.eye(f.shape[1])   # damped: no jump at a singularity
            q = q - np.einsum("nji,nj->ni", Jc, np.linalg.solve(A, f[:, :, None])[:, :, 0])
        f, _ = misfit(q)
        ok = (np.abs(f).max(axis=1) < 1e-9) & ~model.out_of_limits(q).any(axis=1)
        out.append(q[ok])
    q = np.concatenate(out) if out else np.zeros((0, model.dof))
    if len(q) < n:
        raise ValueError(f"{kind} contact: only {len(q)} of {n} postures reach it within the joint limits (place it "
                         f"where the robot reaches)")
    return q[:n]
