"""A laser-tracker campaign of the shape of a real industrial one, simulated on the FANUC R-2000iC/165F URDF.

The shape of the held-back campaign of issue 27: 24 joint configurations, 21 of them at one joint-1 angle
and 3 at others, each visited ``repeats`` times, three reflectors on the flange, tracker noise 40 um per
axis. The as-built robot is the nominal URDF with its joint origins edited in the XML (a 3 mrad
non-perpendicularity of axes 1 and 2, small errors elsewhere, joint zero offsets) and a lumped joint
compliance of 0.2 mrad/kN m loaded by a point mass at the flange; its tool positions come from
pinocchio on the edited URDF, and the gravity torques from finite differences of that forward
kinematics: nothing here uses the error model under test.

``campaign()`` returns the measurements and the truth; ``independent_fit()`` fits the same measurement
model with scipy's Levenberg-Marquardt on pinocchio's forward kinematics of an edited model (the check
of ``calibrate``'s optimum).
"""
from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing
from tolerance_ros.core.accuracy.simulate import PinocchioArm, edited_urdf  # noqa: E402
from tolerance_ros.core.geometry import exp_so3, rpy_to_matrix  # noqa: E402

URDF = ROOT / "test" / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"
JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6")
REFLECTORS = {"R1": (0.03, 0.09, 0.0), "R2": (0.03, -0.045, 0.078), "R3": (0.03, -0.045, -0.078)}  # flange frame, m
TRACKER = ((3.2, -1.1, 0.4), (0.01, -0.02, 2.4))  # base in the tracker frame: xyz m, rpy rad
GRAVITY = 9.81


def _rotvec(w):
    return exp_so3(np.asarray(w, float))[0]


def configurations(seed=0, n_fixed=21, moved_j1=(0.45, -0.5, 0.9)):
    """(24, 6) joints: ``n_fixed`` configurations at joint 1 = 0 and one per ``moved_j1`` angle, rad."""
    rng = np.random.default_rng(seed)
    n = n_fixed + len(moved_j1)
    lo = np.array([0.0, -0.6, -0.7, -2.0, -1.6, -2.5])
    hi = np.array([0.0, 0.9, 0.8, 2.0, 1.6, 2.5])
    q = lo + rng.random((n, 6)) * (hi - lo)
    q[n_fixed:, 0] = moved_j1
    return q


def default_truth(seed=1):
    """The as-built robot: {joint: (dxyz m, rotation vector rad, offset rad)} and the compliance (rad/(N m))."""
    rng = np.random.default_rng(seed)
    edits = {}
    for j in JOINTS:
        edits[j] = (rng.normal(0, 0.15e-3, 3), rng.normal(0, 0.15e-3, 3), rng.normal(0, 0.5e-3))
    # axes 1 and 2 not perpendicular: joint_2's origin turned 3 mrad about its parent's x
    edits["joint_2"] = (edits["joint_2"][0], np.array([-3.0e-3, 0.1e-3, -0.1e-3]), edits["joint_2"][2])
    compliance = np.array([0.0, 0.2e-6, 0.2e-6, 0.2e-6, 0.2e-6, 0.0])  # 0.2 mrad per kN m
    return edits, compliance


@dataclass
class Campaign:
    """A simulated campaign: per row its pose label, cycle, target, joints (rad) and tracker point (m)."""

    labels: np.ndarray
    cycles: np.ndarray
    targets: np.ndarray
    q: np.ndarray
    points: np.ndarray
    truth_text: str
    compliance: np.ndarray
    mass: float
    noise: float
    T_tracker_base: np.ndarray

    def write_csv(self, path):
        """The measurement CSV of ``tolerance-ros`` (positions in mm, joints in rad)."""
        head = "stamp[s],pose,cycle,target,x[mm],y[mm],z[mm]," + ",".join(f"joint:{j}[rad]" for j in JOINTS)
        lines = [head]
        for i in range(len(self.q)):
            p = self.points[i] * 1e3
            lines.append(f"{i * 0.5:.1f},{self.labels[i]},{self.cycles[i]},{self.targets[i]},"
                         + ",".join(f"{v:.6f}" for v in p) + "," + ",".join(repr(float(v)) for v in self.q[i]))
        Path(path).write_text("\n".join(lines) + "\n")
        return Path(path)


def campaign(repeats=10, noise=40e-6, mass=120.0, seed=0, edits=None, compliance=None, q=None) -> Campaign:
    """The simulated campaign (see the module docstring); ``mass`` kg loads the compliance at the flange."""
    nominal = URDF.read_text()
    if edits is None or compliance is None:
        e, c = default_truth()
        edits = e if edits is None else edits
        compliance = c if compliance is None else compliance
    text = edited_urdf(nominal, edits)
    arm = PinocchioArm(text, "flange")
    q = configurations() if q is None else np.asarray(q, float)
    names = list(REFLECTORS)
    offs = np.array([REFLECTORS[k] for k in names])
    rng = np.random.default_rng(seed + 100)
    rows = []
    A = np.eye(4)
    A[:3, :3] = rpy_to_matrix(TRACKER[1])
    A[:3, 3] = TRACKER[0]
    for c in range(repeats):
        q_read = q + rng.normal(0, 2e-6, q.shape)  # encoder readings of each visit
        q_true = q_read + arm.point_mass_torques(q_read, mass) * compliance
        pts = arm.points(q_true, offs)
        for i in range(len(q)):
            for k, name in enumerate(names):
                p = pts[i, k] + rng.normal(0, noise, 3)
                rows.append((f"P{i + 1}", c + 1, name, q_read[i], A[:3, :3] @ p + A[:3, 3]))
    labels, cycles, targets, qs, ps = zip(*rows)
    return Campaign(np.array(labels, object), np.array(cycles), np.array(targets, object), np.array(qs),
                    np.array(ps), text, np.asarray(compliance, float), mass, noise, A)


def folds_of(labels, k=10, seed=0):
    """(n,) fold of each row: the test poses (by first visit) split as ``calibrate`` splits them."""
    uniq, first, g = np.unique(labels, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    g = rank[np.asarray(g).reshape(-1)]
    fold_of = np.empty(len(uniq), int)
    fold_of[np.random.default_rng(seed).permutation(len(uniq))] = np.arange(len(uniq)) % min(k, len(uniq))
    return fold_of[g]


class IndependentModel:
    """The measurement model fitted independently: per joint an origin shift (3, parent frame, m), an origin
    turn (rotation vector, parent frame, rad) and a zero offset (rad); the tracker transform (6: xyz m,
    rotation vector rad, on the left of the nominal ``A0``); each reflector's point on the flange (3 each,
    m); optionally a compliance per joint loaded by a point mass at the flange (``compliant`` joints,
    rad/(N m) of a 1 kg mass). Forward kinematics by pinocchio on a model whose joint placements are edited."""

    def __init__(self, A0, compliant=()):
        import pinocchio as pin
        self.pin = pin
        self.model = pin.buildModelFromXML(URDF.read_text())
        self.data = self.model.createData()
        self.fid = self.model.getFrameId("flange")
        self.jids = [self.model.getJointId(j) for j in JOINTS]
        self.M0 = [self.model.jointPlacements[j].copy() for j in self.jids]
        self.axes = []
        for j in JOINTS:
            el = next(e for e in ET.fromstring(URDF.read_text()).findall("joint") if e.get("name") == j)
            a = np.array([float(v) for v in el.find("axis").get("xyz").split()])
            self.axes.append(a / np.linalg.norm(a))
        self.A0 = np.asarray(A0, float)
        self.compliant = [JOINTS.index(j) for j in compliant]
        self.n = 7 * 6 + 6 + 9 + len(self.compliant)
        self._torques = {}

    def _apply(self, x):
        pin = self.pin
        for k, jid in enumerate(self.jids):
            d = x[7 * k:7 * k + 7]
            M = self.M0[k]
            R = _rotvec(d[3:6]) @ M.rotation @ _rotvec(self.axes[k] * d[6])
            self.model.jointPlacements[jid] = pin.SE3(R, M.translation + d[:3])

    def predict(self, x, q, target_index):
        """(n, 3) tracker points of rows at joints q (n, 6) and reflector index (n,)."""
        q = np.asarray(q, float)
        if self.compliant:
            c = np.zeros(6)
            c[self.compliant] = x[57:]
            key = q.tobytes()
            if key not in self._torques:  # on the nominal model, as calibrate's load (its change with dx neglected)
                self._torques[key] = self._torque(q)
            q = q + self._torques[key] * c
        self._apply(x)
        A = np.eye(4)
        A[:3, :3] = _rotvec(x[45:48]) @ self.A0[:3, :3]
        A[:3, 3] = self.A0[:3, 3] + x[42:45]
        offs = x[48:57].reshape(3, 3)
        pin = self.pin
        out = np.empty((len(q), 3))
        for i, qi in enumerate(q):
            pin.framesForwardKinematics(self.model, self.data, qi)
            M = self.data.oMf[self.fid]
            out[i] = M.rotation @ offs[target_index[i]] + M.translation
        return out @ A[:3, :3].T + A[:3, 3]

    def _torque(self, q, h=1e-6):
        pin = self.pin
        self._apply(np.zeros(self.n))
        out = np.empty_like(q)
        for i, qi in enumerate(q):
            for j in range(6):
                z = []
                for s in (h, -h):
                    qq = qi.copy()
                    qq[j] += s
                    pin.framesForwardKinematics(self.model, self.data, qq)
                    z.append(self.data.oMf[self.fid].translation[2])
                out[i, j] = (z[0] - z[1]) / (2 * h) * GRAVITY
        return out


def independent_fit(c: Campaign, rows, compliant=(), x0=None):
    """(x, IndependentModel) of scipy ``least_squares`` (Levenberg-Marquardt, tolerances 1e-15) on ``rows``."""
    from scipy.optimize import least_squares
    m = IndependentModel(c.T_tracker_base @ np.eye(4), compliant)
    names = list(REFLECTORS)
    tidx = np.array([names.index(t) for t in c.targets])
    x = np.zeros(m.n) if x0 is None else np.asarray(x0, float).copy()
    if x0 is None:
        x[48:57] = np.array([REFLECTORS[k] for k in names]).reshape(-1)
    q, P, ti = c.q[rows], c.points[rows], tidx[rows]
    res = least_squares(lambda v: (m.predict(v, q, ti) - P).reshape(-1), x, method="lm", xtol=1e-15, ftol=1e-15,
                        gtol=1e-15, x_scale=np.r_[np.full(42, 1e-3), np.full(6, 1e-3), np.full(9, 1e-3),
                                                  np.full(len(m.compliant), 1e-7)], max_nfev=20000)
    return res.x, m, res


def independent_figures(c: Campaign, compliant=(), folds=10, seed=0):
    """{in_rms, in_max, cv_rms, cv_max} (m, 3-D) of ``independent_fit``: in-sample on every row, and k-fold by
    test pose (seed as ``calibrate``'s split), every row scored."""
    names = list(REFLECTORS)
    ti = np.array([names.index(t) for t in c.targets])
    x, m, _ = independent_fit(c, np.arange(len(c.q)), compliant)
    e_in = np.linalg.norm(m.predict(x, c.q, ti) - c.points, axis=1)
    fold = folds_of(c.labels, folds, seed)
    e_cv = np.empty(len(c.q))
    for f in np.unique(fold):
        test = fold == f
        xf, mf, _ = independent_fit(c, np.flatnonzero(~test), compliant, x0=x)
        e_cv[test] = np.linalg.norm(mf.predict(xf, c.q[test], ti[test]) - c.points[test], axis=1)
    rms = lambda e: float(np.sqrt(np.mean(e ** 2)))  # noqa: E731
    return {"in_rms": rms(e_in), "in_max": float(e_in.max()), "cv_rms": rms(e_cv), "cv_max": float(e_cv.max()),
            "x": x}
