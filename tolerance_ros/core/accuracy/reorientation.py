"""ISO 9283 path accuracy on reorientation: the tool turning about its point (``plan-campaign --path reorient``),
measured by a 6-DOF tracker (frames), against the commanded joints.

The command's motions are found in its joints (``path.motions`` on the joint values, rad or m): the cycles are
the motions of the most frequent start, end and length (``path.cycles_of``), the turns back are other
motions. Each cycle carries ``stations`` calculation points at equal fractions of its duration (its motions
have the same timing). At each station ``i`` and cycle ``j`` the deviation of the attained frame from the
commanded one is interpolated from the tracker's samples (aligned by the given latency, put in the base frame
by the given placement): the position ``d_ij`` (m) and the roll, pitch, yaw differences ``a_ij``, ``b_ij``,
``c_ij`` (rad, wrapped). Then, as for the path figures:

- ``AT_p = max_i |mean_j d_ij|``, ``RT_p = max_i (l_bar_i + 3 S_li)`` with ``l_ij = |d_ij - mean_j d_ij|``;
- ``AT_a = max_i |mean_j a_ij|`` and ``RT_a = max_i 3 S_ai`` (b, c);
- ``excursion_m``: the largest ``|d_ij|``, how far the tool point left its place at all.
"""
from __future__ import annotations

import numpy as np

from . import path as P
from .iso9283 import wrap
from ..geometry import rotation_error, rpy_from_matrix

REST_SPEED = 1e-3      # rad/s (or m/s) of the fastest joint: the command at rest below this


HELD_POINT = 2e-3        # m: a reorientation's commanded tool point stays within this of its mean (1 mm of IK slack)
MIN_TURN = np.radians(1.0)   # rad: a reorientation turns its tool by more than this


def _check_command(model, qj):
    """ValueError when the joint states cannot be a reorientation's: the tool point they command moves (joint
    states of another path), or the tool does not turn."""
    T = model.fk(qj[np.linspace(0, len(qj) - 1, min(len(qj), 2000)).astype(int)])
    moved = float(np.linalg.norm(T[:, :3, 3] - T[:, :3, 3].mean(axis=0), axis=1).max())
    if moved > HELD_POINT:
        raise ValueError(f"reorientation: along these joint states the commanded tool point moves by up to "
                         f"{moved * 1e3:.4g} mm from its mean, where a reorientation holds it (within "
                         f"{HELD_POINT * 1e3:g} mm): the joint states of another path?")
    turn = float(np.linalg.norm(rotation_error(T[:, :3, :3], np.broadcast_to(T[0, :3, :3], T[:, :3, :3].shape)),
                                axis=1).max())
    if turn < MIN_TURN:
        raise ValueError(f"reorientation: along these joint states the tool turns by {np.degrees(turn):.3g} deg at "
                         f"most; a reorientation turns it (more than {np.degrees(MIN_TURN):g} deg)")


def reorientation_report(model, stamps, T_tracker, joint_stamps, joints, T_tracker_base=None, latency: float = 0.0,
                         stations: int = 100, source: str = "") -> dict:
    """The figures of the module docstring (SI). ``T_tracker`` (n, 4, 4) frames in the tracker frame stamped
    ``stamps`` (n,) s; the commanded ``joints`` (k, dof) stamped ``joint_stamps`` (k,) s; ``T_tracker_base`` the
    tracker's placement (None: the frames are in the base frame). ValueError when they cannot be judged."""
    t = np.asarray(stamps, float)
    T = np.asarray(T_tracker, float)
    tj, qj = np.asarray(joint_stamps, float), np.asarray(joints, float)
    if T.shape != (len(t), 4, 4) or len(t) < 10:
        raise ValueError(f"reorientation: expected (n >= 10, 4, 4) frames with n stamps, got {T.shape}")
    if qj.shape != (len(tj), model.dof) or len(tj) < 3:
        raise ValueError(f"reorientation: expected (k >= 3, {model.dof}) joints with k stamps, got {qj.shape}")
    ok = np.isfinite(t) & np.isfinite(T).all(axis=(1, 2))
    order = np.argsort(t[ok], kind="stable")
    t, T = t[ok][order] - float(latency), T[ok][order]
    jorder = np.argsort(tj, kind="stable")
    tj, qj = tj[jorder], qj[jorder]
    if T_tracker_base is not None:
        T = np.linalg.inv(np.asarray(T_tracker_base, float)) @ T
    runs = P.motions(tj, qj, REST_SPEED)
    picked, others = P.cycles_of(qj, runs)
    if not picked:
        raise ValueError("reorientation: the command never moves (joint states at rest)")
    _check_command(model, qj)
    inside = (t >= tj[0]) & (t <= tj[-1])
    if inside.sum() >= 3:
        from .checks import orientation_problem
        sub = np.flatnonzero(inside)[:: max(1, int(inside.sum()) // 500)]
        problem = orientation_problem(model, P.interp_columns(t[sub], tj, qj), T[sub, :3, :3])
        if problem:
            raise ValueError(f"reorientation: {problem}")
    turned = []
    dev_p, dev_a = [], []
    f = (np.arange(stations) + 0.5) / stations
    for k in picked:
        i0, i1 = runs[k]
        sel = (t >= tj[i0]) & (t <= tj[i1])
        if sel.sum() < 10:
            continue
        ts = t[sel]
        Tc = model.fk(P.interp_columns(ts, tj, qj))
        dp = T[sel, :3, 3] - Tc[:, :3, 3]
        da = wrap(rpy_from_matrix(T[sel, :3, :3]) - rpy_from_matrix(Tc[:, :3, :3]))
        at = tj[i0] + f * (tj[i1] - tj[i0])
        dev_p.append(P.interp_columns(at, ts, dp))
        dev_a.append(P.interp_columns(at, ts, da))
        ends = model.fk(qj[[i0, i1]])
        turned.append(float(np.linalg.norm(rotation_error(ends[1, :3, :3], ends[0, :3, :3]))))
    if not dev_p:
        raise ValueError("reorientation: no tracker frame lies along the command's motions (the streams do not "
                         "overlap, or the latency is wrong)")
    D, A = np.array(dev_p), np.array(dev_a)          # (cycles, stations, 3)
    mean_p = D.mean(axis=0)
    out = {"source": source, "robot": model.name, "cycles": len(D), "other_motions": len(others),
           "stations": int(stations), "latency_s": float(latency), "turn_rad": float(np.mean(turned)),
           "AT_p_m": float(np.linalg.norm(mean_p, axis=1).max()), "excursion_m": float(np.linalg.norm(D, axis=2).max())}
    if len(D) >= 2:
        l = np.linalg.norm(D - mean_p, axis=2)
        out["RT_p_m"] = float((l.mean(axis=0) + 3 * l.std(axis=0, ddof=1)).max())
    else:
        out["RT_p_m"] = None
    for i, ax in enumerate("abc"):
        out[f"AT_{ax}_rad"] = float(np.abs(A[:, :, i].mean(axis=0)).max())
        out[f"RT_{ax}_rad"] = float((3 * A[:, :, i].std(axis=0, ddof=1)).max()) if len(A) >= 2 else None
    return out
