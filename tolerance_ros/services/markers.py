"""RViz markers of the accuracy monitor, as plain dicts (the node turns them into visualization_msgs).

At the tool point of the latest joint state, the budget's predicted position error: a sphere whose
radius is the worst-case bound, and the RSS covariance ellipsoid ``Sigma = J diag((delta/3)^2) J^T``
(J: the position rows of the parameter-error Jacobian) with semi-axes ``k sqrt(eigenvalues)`` along its
eigenvectors (``k`` = 3: the ellipsoid lies within the sphere of the RSS bound). For each recent
measurement, an arrow from the nominal to the measured tool point, green within its predicted bound
and red above it, with a text of the margin (bound - error) in mm. Errors are about a millimetre on a
metre-sized robot, so every error length is drawn ``scale`` times enlarged (default 100, said in the
bound's text). Positions in the robot base frame, m; namespaces and ids are stable, so RViz replaces
markers instead of piling them up; ``DELETE_ALL`` first when the robot or the budget changed.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import worst_case_bound
from ..core.geometry import matrices_to_quat

GREEN, RED, BLUE, ORANGE, WHITE = (0.1, 0.8, 0.2, 0.9), (0.9, 0.1, 0.1, 0.9), (0.2, 0.4, 1.0, 0.25), \
    (1.0, 0.6, 0.0, 0.5), (1.0, 1.0, 1.0, 0.9)
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def _marker(ns, mid, kind, position, scale, color, orientation=IDENTITY, **extra) -> dict:
    return {"ns": ns, "id": int(mid), "type": kind, "position": [float(v) for v in position],
            "orientation": [float(v) for v in orientation], "scale": [float(v) for v in scale],
            "color": list(color), **extra}


def rss_ellipsoid(J_position, delta, k_sigma: float = 3.0):
    """(axes (3, 3) orthonormal, columns; semi-axes (3,) m) of the RSS covariance ellipsoid, errors
    within +-delta taken as normal with sigma = delta / 3; a right-handed frame."""
    J = np.asarray(J_position, float)
    sigma2 = (np.asarray(delta, float) / 3.0) ** 2
    cov = (J * sigma2) @ J.T
    lam, axes = np.linalg.eigh(cov)
    if np.linalg.det(axes) < 0:
        axes[:, 0] *= -1.0
    return axes, k_sigma * np.sqrt(np.maximum(lam, 0.0))


def bound_markers(model, q, delta, scale: float = 100.0, k_sigma: float = 3.0) -> list:
    """Sphere (worst case), ellipsoid (RSS) and a text at the tool point of joints ``q`` (dof,)."""
    T, EJ = model.fk_and_jacobian(np.asarray(q, float)[None])
    p, J = T[0, :3, 3], EJ.position[0]
    worst = float(worst_case_bound(J[None], delta)[0])
    axes, semi = rss_ellipsoid(J, delta, k_sigma)
    quat = matrices_to_quat(axes[None])[0]
    d = 2.0 * scale
    text = (f"predicted error x{scale:g}: worst case {worst * 1e3:.3f} mm (sphere), RSS {k_sigma:g} sigma "
            f"{np.sqrt(np.sum(semi ** 2)) * 1e3:.3f} mm (ellipsoid {', '.join(f'{s * 1e3:.3f}' for s in semi)} mm)")
    return [_marker("bound", 0, "sphere", p, [d * worst] * 3, ORANGE),
            _marker("bound", 1, "sphere", p, d * semi, BLUE, quat),
            _marker("bound", 2, "text", p + [0.0, 0.0, scale * worst + 0.05], [0.0, 0.0, 0.03], WHITE, text=text)]


def measurement_markers(model, recent, scale: float = 100.0, slots: int = 20) -> list:
    """Arrows nominal -> measured tool point (error drawn ``scale`` times) and margin texts for the recent
    paired measurements: dicts with ``seq``, ``joints``, ``nominal`` (the target's nominal point, m; the
    tool point when absent), ``dp`` (measured - nominal, m), ``bound`` and ``margin`` (m; NaN without a
    budget). Ids cycle over ``slots``."""
    if not recent:
        return []
    if all("nominal" in r for r in recent):
        nominal = np.array([r["nominal"] for r in recent], float)
    else:
        nominal = model.fk(np.array([r["joints"] for r in recent], float))[:, :3, 3]
    out = []
    for r, p in zip(recent, nominal):
        tip = p + scale * np.asarray(r["dp"], float)
        over = np.isfinite(r["margin"]) and r["margin"] < 0
        color = RED if over else GREEN
        length = float(np.linalg.norm(tip - p))
        mid = r["seq"] % slots
        out.append(_marker("measurements", mid, "arrow", [0.0, 0.0, 0.0], [0.004, 0.008, min(0.01, length / 3)],
                           color, points=[p.tolist(), tip.tolist()]))
        label = f"{r['margin'] * 1e3:+.3f} mm" if np.isfinite(r["margin"]) else "no budget"
        out.append(_marker("margins", mid, "text", tip + [0.0, 0.0, 0.02], [0.0, 0.0, 0.02], color, text=label))
    return out


def delete_all() -> dict:
    """The marker that clears every marker of the publisher (sent first after a robot or budget change)."""
    return {"ns": "", "id": 0, "type": "delete_all"}
