"""Offline accuracy report of a measurement file: registration, errors, budget check, ISO 9283 per
test pose and identification, returned as a plain dict (SI) by ``evaluate_file``."""
from __future__ import annotations

import numpy as np

from .evaluate import identify, measurement_joints, per_pose_statistics
from .io import MeasurementError, read_csv, read_log, read_rosbag
from .registration import KabschAccumulator, Registration, register
from .stream import AccuracyAccumulator

IDENTIFY_MAX = 20000  # up to this many measurements the nonlinear identification runs on all of them


def read_measurements(path, joint_names=None, skip_bad=False, slop=0.005):
    """Measurements from a CSV file, a campaign log (.jsonl) or a rosbag2 directory / .db3 / .mcap."""
    from pathlib import Path
    p = Path(path)
    if p.is_dir() or p.suffix in (".db3", ".mcap"):
        return read_rosbag(p, joint_names=joint_names, skip_bad=skip_bad, slop=slop)
    if p.suffix in (".jsonl", ".log"):
        return read_log(p, skip_bad=skip_bad)
    return read_csv(p, skip_bad=skip_bad)


def evaluate_file(model, meas, budget=None, campaign=None, registration="base", keep_rows=True,
                  sigma_position=1e-5, sigma_orientation=None) -> dict:
    """Evaluate measurements (see the module docstring).

    registration : 'base' (estimate base -> tracker), 'base+tool' (and the tool offset), 'none'
    (measurements already in the base frame) or a Registration.
    """
    if len(meas) == 0:
        raise MeasurementError(f"{meas.source}: no measurements")
    q = measurement_joints(model, meas, campaign)
    T_nom = model.fk(q)
    if isinstance(registration, Registration):
        reg = registration
    elif registration == "none":
        reg = Registration(np.eye(4), None, np.linalg.norm(meas.T[:, :3, 3] - T_nom[:, :3, 3], axis=1), len(q))
    elif registration in ("base", "base+tool"):
        reg = register(T_nom, meas.T, tool=registration == "base+tool")
    else:
        raise ValueError(f"registration: expected 'base', 'base+tool' or 'none', got {registration!r}")
    delta = budget.vector_for(model) if budget is not None else None
    names = campaign.names if campaign is not None else []
    acc = AccuracyAccumulator(model, delta, budget.criterion if budget else "paper",
                              budget.limit_position if budget else None,
                              budget.limit_orientation if budget else None, reg.T_tracker_base, reg.tool_offset,
                              campaign.joints_for(model) if campaign is not None else None, names,
                              campaign.cycles if campaign is not None else 30)
    labels = None
    if meas.pose is not None and any(str(p) for p in meas.pose):
        labels = np.array([str(p) for p in meas.pose], dtype=object)
    rows = []
    for a in range(0, len(q), 5000):
        b = min(len(q), a + 5000)
        r = acc.add(meas.T[a:b], q[a:b], None if labels is None else labels[a:b])
        if keep_rows:
            rows.append(r)
    out = {"source": meas.source, "robot": model.name, "measurements": len(q), "skipped_rows": meas.skipped,
           "registration": reg.to_dict(), "summary": acc.summary(sigma_position)}
    T_base = reg.to_base(meas.T)
    if campaign is not None:
        lab = labels if labels is not None else acc.label(q)
        out["per_pose"] = per_pose_statistics(names, acc.commanded(), T_base, lab)
    if len(q) <= IDENTIFY_MAX:
        ident = identify(model, q, T_base, delta, sigma_position,
                         sigma_orientation if meas.has_orientation else None)
        out["identification"] = ident.to_dict()
    else:
        out["identification"] = out["summary"].pop("identification", None)
    if keep_rows:
        cat = {k: np.concatenate([r[k] for r in rows]) for k in rows[0] if k not in ("dp", "dphi")}
        out["rows"] = {"stamp": meas.stamps, "joints": q, "dp": np.concatenate([r["dp"] for r in rows]),
                       "dphi": np.concatenate([r["dphi"] for r in rows]), **cat}
    return out


def stream_file(model, path, budget=None, campaign=None, chunk_rows=5000, registration="base") -> dict:
    """Constant-memory evaluation of a large CSV file: pass 1 registers the base (position sums),
    pass 2 feeds the accumulator chunk by chunk. Identification is the linearised one."""
    delta = budget.vector_for(model) if budget is not None else None
    T_tb = np.eye(4)
    if registration == "base":
        kab = KabschAccumulator()
        for m in read_csv(path, chunk_rows=chunk_rows):
            kab.add(model.fk(measurement_joints(model, m, campaign))[:, :3, 3], m.T[:, :3, 3])
        T_tb = kab.result()
    elif registration != "none":
        raise ValueError("stream_file: registration must be 'base' or 'none'")
    acc = AccuracyAccumulator(model, delta, budget.criterion if budget else "paper",
                              budget.limit_position if budget else None, budget.limit_orientation if budget else None,
                              T_tb, None, campaign.joints_for(model) if campaign is not None else None,
                              campaign.names if campaign is not None else [],
                              campaign.cycles if campaign is not None else 30)
    skipped = []
    for m in read_csv(path, chunk_rows=chunk_rows):
        labels = np.array([str(p) for p in m.pose], dtype=object) if m.pose is not None and any(m.pose) else None
        acc.add(m.T, measurement_joints(model, m, campaign), labels)
        skipped += m.skipped
    return {"source": str(path), "robot": model.name, "measurements": acc.n, "skipped_rows": skipped,
            "T_tracker_base": T_tb, "summary": acc.summary()}
