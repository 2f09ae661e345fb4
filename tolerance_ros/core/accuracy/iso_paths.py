"""The test paths of ISO 9283 (path section) in the test cube's diagonal plane, as tool paths and as the
joint trajectories that drive them.

The cube (edge ``side``, centre ``c``, ``h = side / 2``) is the one of ``iso9283.iso_cube_points``; its test
plane is the diagonal plane through the corners (-,-,-), (+,+,-), (+,+,+), (-,-,+), spanned by
``u = (1, 1, 0) / sqrt(2)`` and ``w = (0, 0, 1)`` of the base frame. In it:

- ``line``: from P3 ``c - 0.8 h (1, 1, 1)`` to P2 ``c + 0.8 h (1, 1, 1)`` (the plane's diagonal, 80 % of it),
  then back (the return is another motion, not the test path);
- ``circle``: centre ``c``, diameter ``0.8 side``, starting at ``c + 0.4 side u``, once round;
- ``rectangle``: P3 -> P4 -> P2 -> P5 -> P3 (``P4 = c + 0.8 h (1, 1, -1)``, ``P5 = c + 0.8 h (-1, -1, 1)``),
  its four corners passed at the programmed speed;
- ``weave``: the line from P3 to P2 woven across in the test plane (a sine of peak-to-peak ``stroke`` across
  the line, a whole number of periods of about ``pitch`` along it; ISO 9283 weaving deviations), then straight
  back (another motion);
- ``positioning``: from the cube's centre along the test line and back, once for each of ``distances`` (ISO
  9283 minimum positioning time; a rest between moves);
- ``reorient``: the tool point held at the cube's centre while the tool turns about the base frame's x axis
  from ``-angle`` to ``+angle`` (ISO 9283 path accuracy on reorientation), then back (another motion); its
  moves are timed by the angle turned (``speed`` rad/s, ``accel`` rad/s^2).

The tool keeps the orientation of the centre pose. Each move starts and ends at rest with a speed profile
(``PROFILES``: trapezoidal by default, a raised cosine or minimum jerk; ``speed`` m/s, ``accel`` m/s^2); a cycle is a dwell at the start, then the move(s). Joints
come from the nominal model's inverse kinematics (``models.ik.nominal_solution``) at knots
every ``spacing`` along the path, continued from knot to knot, and are linear in time between knots.
SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .path import interp_columns

PATHS = ("line", "circle", "rectangle", "weave", "reorient", "positioning")
POSITIONING_DISTANCES = (0.01, 0.02, 0.05, 0.1, 0.2)  # m: the moves of a positioning program, those that fit
MAX_KNOT_STEP = 0.05  # rad or m: the largest joint change between knots before a path is called discontinuous
MAX_KNOTS = 100_000   # knots of a path's moves together: each is an inverse kinematics solve and a line of its file
MIN_KNOTS_PER_PERIOD = 8  # a weave's period drawn by fewer knots is no sine
# What a test path's options may be, and why (plan-campaign checks them before any work):
MIN_SIDE = 0.01       # m: the cube's edge; below 10 mm the test line holds fewer than 30 knots and a tracker's
#                       noise (10 um) is 0.1 % of it
MIN_STROKE = 1e-4     # m: a weave's stroke below 0.1 mm is ten times a tracker's noise: no weaving to measure
MAX_SPEED = 10.0      # m/s: no arm's tool is programmed faster (the fastest SCARAs reach about 10 m/s)
MAX_ACCEL = 100.0     # m/s^2: about 10 g, beyond the fastest arms
MAX_ANGULAR_SPEED = 20.0   # rad/s: beyond the fastest wrists (about 1,000 deg/s)
MAX_ANGULAR_ACCEL = 500.0  # rad/s^2
MAX_DWELL = 600.0     # s: a rest longer than ten minutes is a drift test (iso9283 --drift), not a cycle's start
MAX_PERIOD = 3600.0   # s: a cycle longer than an hour is no path test (the speed or the dwell cannot be meant)


def _check_knots(n: int, length: float, spacing: float):
    """ValueError when a path of ``n`` knots exceeds ``MAX_KNOTS``."""
    if n > MAX_KNOTS:
        raise ValueError(f"path: {n:.3g} knots ({spacing * 1e3:g} mm apart along {length:.4g} m) exceed the "
                         f"cap of {MAX_KNOTS:,} (each is an inverse kinematics solve and a line of the file)")


@dataclass
class ToolPath:
    """One test path: ``moves`` is a list of (k_i, 3) polylines (m) in the base frame, each driven from
    rest to rest; ``test`` the index of the move that is the test path; ``R`` the tool orientation, or
    ``turns`` the orientation at each point where it changes (a reorientation, timed by the angle turned)."""

    kind: str
    moves: list
    test: int
    R: np.ndarray
    center: np.ndarray
    side: float
    turns: list | None = None   # a reorientation's (k_i, 3, 3) tool orientation at each point of each move


def _polyline(corners, spacing) -> np.ndarray:
    """(k, 3) points every ``spacing`` (at most) along the straight legs between ``corners``, corners kept."""
    legs = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    _check_knots(int(np.sum(np.ceil(legs / spacing))), float(legs.sum()), spacing)
    out = [corners[:1]]
    for a, b in zip(corners[:-1], corners[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(out)


def tool_path(kind: str, center, side: float, R=None, spacing: float = 0.5e-3, stroke: float | None = None,
              pitch: float | None = None, angle: float | None = None, distances=None) -> ToolPath:
    """The test path ``kind`` (``PATHS``) of the cube of edge ``side`` (m) at ``center`` (m); a weave's ``stroke``
    and ``pitch`` (m; default 10 % and 20 % of the edge); a reorientation's ``angle`` (rad, default 30 degrees),
    turned in steps of ``spacing`` rad per metre (0.5 mrad for the default spacing: 0.5 mm); a positioning
    program's ``distances`` (m; default those of ``POSITIONING_DISTANCES`` within the line)."""
    if kind not in PATHS:
        raise ValueError(f"path: expected one of {', '.join(PATHS)}, got {kind!r}")
    c = np.asarray(center, float)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError("center: expected three finite numbers (m)")
    if not (np.isfinite(side) and side > 0):
        raise ValueError("side: expected a positive length (m)")
    h = side / 2.0
    u, w = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0), np.array([0.0, 0.0, 1.0])
    P2, P3 = c + 0.8 * h * np.array([1, 1, 1.0]), c - 0.8 * h * np.array([1, 1, 1.0])
    P4, P5 = c + 0.8 * h * np.array([1, 1, -1.0]), c + 0.8 * h * np.array([-1, -1, 1.0])
    R = np.eye(3) if R is None else np.asarray(R, float)
    L = float(np.linalg.norm(P2 - P3))                 # the test line, from P3 to P2
    d = (P2 - P3) / L
    if kind == "line":
        fwd = _polyline(np.array([P3, P2]), spacing)
        return ToolPath(kind, [fwd, fwd[::-1].copy()], 0, R, c, side)
    if kind == "positioning":
        room = 0.5 * L                                 # from the centre to P2 along the line
        ds = [x for x in POSITIONING_DISTANCES if x <= room] if distances is None else [float(x) for x in distances]
        if not ds or any(not (0 < x <= room) for x in ds):
            raise ValueError(f"positioning: expected distances up to {room * 1e3:g} mm (half the test line), got "
                             f"{[round(x * 1e3, 3) for x in ds]} mm")
        moves = []
        for x in ds:
            out = _polyline(np.array([c, c + x * d]), spacing)
            moves += [out, out[::-1].copy()]
        return ToolPath(kind, moves, 0, R, c, side)
    if kind == "reorient":
        from ..geometry import exp_so3
        angle = np.radians(30.0) if angle is None else float(angle)
        if not 0 < angle <= np.pi / 2:
            raise ValueError(f"reorient: expected an angle of 0 to 90 degrees, got {np.degrees(angle):g} degrees")
        n = int(np.ceil(2 * angle / spacing)) + 1
        th = np.linspace(-angle, angle, n)
        turns = exp_so3(th[:, None] * np.array([1.0, 0.0, 0.0])) @ R
        pts = np.tile(c, (n, 1))
        return ToolPath(kind, [pts, pts.copy()], 0, R, c, side, [turns, turns[::-1].copy()])
    if kind == "weave":
        stroke = 0.1 * side if stroke is None else float(stroke)
        pitch = 0.2 * side if pitch is None else float(pitch)
        if not (0 < stroke <= side and 0 < pitch <= side):
            raise ValueError(f"weave: expected a stroke and a pitch up to the cube's edge {side * 1e3:g} mm, got "
                             f"{stroke * 1e3:g} mm and {pitch * 1e3:g} mm")
        across = w - (w @ d) * d
        across /= np.linalg.norm(across)
        periods = max(3, int(round(L / pitch)))
        woven = L * np.hypot(1.0, np.pi * stroke * periods / L)      # m along the sine (about)
        n = int(np.ceil(woven / spacing)) + 1
        if n / periods < MIN_KNOTS_PER_PERIOD:
            least = np.sqrt(max((MIN_KNOTS_PER_PERIOD * spacing) ** 2 - (np.pi * stroke) ** 2, 0.0))
            raise ValueError(f"weave: a pitch of {pitch * 1e3:g} mm with a stroke of {stroke * 1e3:g} mm draws each "
                             f"period with {n / periods:.2g} knots ({spacing * 1e3:g} mm apart); a sine needs "
                             f"{MIN_KNOTS_PER_PERIOD}: a pitch of at least {least * 1e3:.3g} mm")
        if n > MAX_KNOTS:
            raise ValueError(f"weave: a pitch of {pitch * 1e3:g} mm with a stroke of {stroke * 1e3:g} mm weaves "
                             f"{woven:.4g} m, {n:.3g} knots {spacing * 1e3:g} mm apart, beyond the cap of "
                             f"{MAX_KNOTS:,} (each is an inverse kinematics solve and a line of the file); a longer "
                             f"pitch or a smaller stroke")
        sb = np.linspace(0.0, L, n)
        fwd = P3 + sb[:, None] * d + (0.5 * stroke * np.sin(2 * np.pi * periods * sb / L))[:, None] * across
        return ToolPath(kind, [fwd, _polyline(np.array([P2, P3]), spacing)], 0, R, c, side)
    if kind == "rectangle":
        return ToolPath(kind, [_polyline(np.array([P3, P4, P2, P5, P3]), spacing)], 0, R, c, side)
    r = 0.4 * side
    n = max(8, int(np.ceil(2 * np.pi * r / spacing)))
    _check_knots(n, 2 * np.pi * r, spacing)
    a = np.linspace(0.0, 2 * np.pi, n + 1)
    return ToolPath(kind, [c + r * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * w)], 0, R, c, side)


PROFILES = ("trapezoid", "raised-cosine", "minimum-jerk")
MINJERK_SPEED, MINJERK_ACCEL = 1.875, 10.0 / np.sqrt(3.0)   # peak speed and acceleration of 10t^3-15t^4+6t^5


def profile_duration(L: float, speed: float, accel: float, profile: str = "trapezoid") -> float:
    """(s) the duration of a move of ``L`` m (or rad) from rest to rest whose speed stays within ``speed`` and whose
    acceleration stays within ``accel``: a trapezoid (constant acceleration, cruise, constant deceleration), a
    raised cosine (the speed rising and falling as half a cosine: the acceleration smooth, its jerk bounded) or a
    minimum-jerk move (``L (10 tau^3 - 15 tau^4 + 6 tau^5)``)."""
    if not (speed > 0 and accel > 0):
        raise ValueError("speed and accel must be > 0")
    if profile not in PROFILES:
        raise ValueError(f"profile: expected one of {', '.join(PROFILES)}, got {profile!r}")
    if profile == "minimum-jerk":
        return max(MINJERK_SPEED * L / speed, float(np.sqrt(MINJERK_ACCEL * L / accel)))
    k = 1.0 if profile == "trapezoid" else np.pi / 2     # the acceleration phase lasts k v / accel
    v = min(speed, float(np.sqrt(accel * L / k)))
    return 2 * k * v / accel + (L - k * v * v / accel) / v


def profile_distance(t, L: float, speed: float, accel: float, profile: str = "trapezoid") -> np.ndarray:
    """(n,) m (or rad) covered at times ``t`` (n,) s of the move of ``profile_duration``, 0 before it, L after."""
    T = profile_duration(L, speed, accel, profile)
    t = np.clip(np.asarray(t, float), 0.0, T)
    if profile == "minimum-jerk":
        x = t / T
        return L * x ** 3 * (10 - 15 * x + 6 * x * x)
    k = 1.0 if profile == "trapezoid" else np.pi / 2
    v = min(speed, float(np.sqrt(accel * L / k)))
    ta = k * v / accel

    def ramp(u):                       # the distance u s into an acceleration from rest
        if profile == "trapezoid":
            return 0.5 * accel * u * u
        return 0.5 * v * (u - ta / np.pi * np.sin(np.pi * u / ta))
    return np.where(t < ta, ramp(t), np.where(t <= T - ta, ramp(ta) + v * (t - ta),
                                               L - ramp(np.maximum(T - t, 0.0))))


def profile_times(s, speed: float, accel: float, profile: str = "trapezoid") -> np.ndarray:
    """(k,) time (s) at arc lengths ``s`` (k,) m of a move from rest to rest of length ``s[-1]`` by ``profile``
    (``profile_distance`` inverted)."""
    if profile == "trapezoid":
        return trapezoid_times(s, speed, accel)
    s = np.asarray(s, float)
    L = float(s[-1])
    T = profile_duration(L, speed, accel, profile)
    grid = np.linspace(0.0, T, 20001)
    t = np.interp(s, profile_distance(grid, L, speed, accel, profile), grid)
    t[-1] = T
    return np.maximum.accumulate(t)


def trapezoid_times(s, speed: float, accel: float) -> np.ndarray:
    """(k,) time (s) at arc lengths ``s`` (k,) m of a move from rest to rest of length ``s[-1]``: accelerate
    at ``accel``, cruise at ``speed`` (or less when the move is too short), decelerate."""
    if not (speed > 0 and accel > 0):
        raise ValueError("speed and accel must be > 0")
    L = float(s[-1])
    v = min(speed, np.sqrt(accel * L))
    da = v * v / (2 * accel)
    ta, tc = v / accel, (L - 2 * da) / v
    s = np.asarray(s, float)
    t = np.where(s < da, np.sqrt(2 * np.maximum(s, 0) / accel),
                 np.where(s <= L - da, ta + (s - da) / v,
                          2 * ta + tc - np.sqrt(2 * np.maximum(L - s, 0) / accel)))
    return np.maximum.accumulate(t)


@dataclass
class JointPath:
    """One cycle of a joint trajectory: knots ``t`` (k,) s from the cycle's start, ``q`` (k, dof); a run is
    ``cycles`` of them in a row, then the last pose held."""

    joint_names: tuple
    t: np.ndarray
    q: np.ndarray
    cycles: int = 1
    kind: str = ""
    speed: float = float("nan")

    @property
    def period(self) -> float:
        return float(self.t[-1])

    @property
    def duration(self) -> float:
        return self.period * self.cycles

    def at(self, t) -> np.ndarray:
        """(n, dof) joints at run times ``t`` (n,) s (0 = the first cycle's start)."""
        t = np.asarray(t, float)
        k = np.clip(np.floor(t / self.period), 0, self.cycles - 1)
        tc = np.clip(t - k * self.period, 0.0, self.period)
        return interp_columns(tc, self.t, self.q)

    def to_dict(self) -> dict:
        """The trajectory file (``read_trajectory``): SI, one cycle of knots; the programmed speed under
        ``speed_m_s``, a reorientation's angular speed under ``speed_rad_s``."""
        key = "speed_rad_s" if self.kind == "reorient" else "speed_m_s"
        return {"kind": "joint_trajectory", "path": self.kind, key: self.speed, "cycles": self.cycles,
                "joint_names": list(self.joint_names),
                "points": [{"time_from_start": float(ti), "positions": [float(v) for v in qi]}
                           for ti, qi in zip(self.t, self.q)]}


def joint_path(model, tp: ToolPath, q_seed, speed: float, accel: float, dwell: float = 0.5,
               cycles: int = 1, profile: str = "trapezoid") -> JointPath:
    """The joint trajectory of ``tp`` for ``model``: IK at every knot (position and orientation ``tp.R``),
    continued from ``q_seed`` (dof,), each move timed by ``profile`` (``PROFILES``); ValueError when a knot is
    out of reach or the joints jump."""
    from ..models.ik import solve
    times, qs, t0 = [], [], 0.0
    q_prev = np.asarray(q_seed, float)
    for k, pts in enumerate(tp.moves):
        T = np.tile(np.eye(4), (len(pts), 1, 1))
        T[:, :3, :3], T[:, :3, 3] = (tp.R if tp.turns is None else tp.turns[k]), pts
        q = np.empty((len(pts), model.dof))
        step = 200
        for i in range(0, len(pts), step):  # each block starts from the previous block's last answer
            q0 = np.broadcast_to(q_prev, (min(step, len(pts) - i), model.dof))
            qi, rp, ro, _ = solve(model, T[i:i + step], q0, tol_position=1e-9, tol_orientation=1e-9)
            if rp.max() > 1e-6 or ro.max() > 1e-6:
                bad = i + int(np.argmax(rp))
                raise ValueError(f"path {tp.kind}: the tool point {np.round(pts[bad] * 1e3, 1).tolist()} mm is out "
                                 f"of reach of {model.name} at this orientation")
            q[i:i + len(qi)], q_prev = qi, qi[-1]
        jumps = np.abs(np.diff(np.vstack([q[:1], q]), axis=0)).max(axis=1)
        if jumps.max() > MAX_KNOT_STEP:
            raise ValueError(f"path {tp.kind}: the joints jump by {jumps.max():.3f} between knots (a singularity or "
                             f"a change of branch); choose another centre or a smaller cube")
        if model.out_of_limits(q).any():
            raise ValueError(f"path {tp.kind}: the joints leave their limits along the path")
        if tp.turns is None:
            s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        else:                               # a reorientation: timed by the angle turned
            from ..geometry import rotation_error
            R = tp.turns[k]
            s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(rotation_error(R[1:], R[:-1]), axis=1))])
        tm = profile_times(s, speed, accel, profile)
        if k == 0:                          # the cycle starts at rest at the first knot
            times.append(t0)
            qs.append(q[0])
        if dwell > 0:                       # a knot per move's start, unless no time passes there
            times.append(t0 + dwell)
            qs.append(q[0])
        times += list(t0 + dwell + tm[1:])
        qs += list(q[1:])
        t0 = times[-1]
    return JointPath(tuple(model.joint_names), np.array(times), np.array(qs), cycles, tp.kind, speed)


def plan_path(model, kind: str, speed: float = 0.1, accel: float = 1.0, dwell: float = 0.5, cycles: int = 10,
              side: float | None = None, q_center=None, spacing: float = 0.5e-3, seed: int = 0,
              stroke: float | None = None, pitch: float | None = None, angle: float | None = None,
              distances=None, profile: str = "trapezoid"):
    """(JointPath, ToolPath) of the test path ``kind`` in an ISO cube the model reaches: centred at the tool
    pose of ``q_center`` (dof,) rad or m, or else at the cube of ``iso9283.iso_cube_joints``;
    of edge ``side`` m, or else the largest of 0.4 m halved until the whole path is reached within the joint
    limits without a jump; each move timed by ``profile``. ValueError when none is."""
    from ..models.ik import solve
    if q_center is None:
        from .iso9283 import iso_cube_joints
        q_iso, note = iso_cube_joints(model, model.sample_joints(2000, seed), seed)
        if q_iso is None:
            raise ValueError(f"{model.name}: {note}")
        q_center = q_iso[0]
    q_center = model.check_joints(q_center, "center joints")[0]
    T = model.fk(q_center[None])[0]
    sides = [side] if side else [0.4 / 2 ** k for k in range(6)]
    why = ""
    for sd in sides:
        tp = tool_path(kind, T[:3, 3], sd, T[:3, :3], spacing, stroke, pitch, angle, distances)
        T0 = T.copy()
        T0[:3, 3] = tp.moves[0][0]
        if tp.turns is not None:
            T0[:3, :3] = tp.turns[0][0]
        q0 = solve(model, T0[None], q_center[None])[0][0]
        try:
            return joint_path(model, tp, q0, speed, accel, dwell, cycles, profile), tp
        except ValueError as exc:
            why = str(exc)
    raise ValueError(f"{model.name}: no ISO cube{'' if side else ' of edge 12.5 mm to 400 mm'} centred at "
                     f"{np.round(T[:3, 3] * 1e3, 1).tolist()} mm carries the {kind} path: {why}")


def read_trajectory(path, model) -> JointPath:
    """A trajectory file (YAML or JSON: ``joint_names``, ``points`` of ``time_from_start`` s and
    ``positions`` rad or m, optional ``cycles``), its joints put in the model's order; a reorientation's angular
    speed from ``speed_rad_s`` (files written before it was so named: from ``speed_m_s``)."""
    from ..yamlio import read_yaml
    data = read_yaml(path)
    where = str(path)
    if not isinstance(data, dict) or "points" not in data or "joint_names" not in data:
        raise ValueError(f"{where}: a trajectory needs joint_names and points (time_from_start, positions)")
    names = [str(n) for n in data["joint_names"]]
    missing = [n for n in model.joint_names if n not in names]
    if missing:
        raise ValueError(f"{where}: joint_names lacks {missing} of robot {model.name}")
    pts = data["points"]
    if not isinstance(pts, list) or len(pts) < 2:
        raise ValueError(f"{where}: points: expected a list of at least 2 points")
    try:
        t = np.array([float(p["time_from_start"]) for p in pts])
        Q = np.array([[float(v) for v in p["positions"]] for p in pts])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{where}: points: each needs time_from_start and positions ({exc})") from None
    if Q.shape[1] != len(names) or not np.all(np.isfinite(Q)) or not np.all(np.isfinite(t)):
        raise ValueError(f"{where}: points: every point needs {len(names)} finite positions")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"{where}: points: time_from_start must increase")
    cycles = int(data.get("cycles", 1))
    if cycles < 1:
        raise ValueError(f"{where}: cycles: must be >= 1")
    Q = Q[:, [names.index(n) for n in model.joint_names]]
    kind = str(data.get("path", ""))
    speed = data.get("speed_rad_s", data.get("speed_m_s")) if kind == "reorient" else data.get("speed_m_s")
    return JointPath(tuple(model.joint_names), t - t[0], Q, cycles, kind,
                     float("nan") if speed is None else float(speed))
