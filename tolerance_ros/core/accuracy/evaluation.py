"""The numbers of an accuracy report: registration, errors, the budget check, ISO 9283 per test pose and
identification of a set of measurements, as a plain dict (SI): ``evaluate_file`` (all in memory) and
``stream_file`` (constant memory, large CSV files)."""
from __future__ import annotations

import numpy as np

from ..ingest import IngestError, JointOrder
from .accumulator import AccuracyAccumulator
from .identification import identify
from .io import MeasurementError, read_csv
from .iso9283 import pose_characteristics
from .registration import KabschAccumulator, Registration, register

IDENTIFY_MAX = 20000  # up to this many measurements the nonlinear identification runs on all of them


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
    acc = AccuracyAccumulator.from_budget(model, budget, campaign, reg.T_tracker_base, reg.tool_offset)
    labels = None
    if meas.pose is not None and any(str(p) for p in meas.pose):
        labels = np.array([str(p) for p in meas.pose], dtype=object)
    rows = []
    for a in range(0, len(q), 5000):
        b = min(len(q), a + 5000)
        r = acc.add(meas.T[a:b], q[a:b], None if labels is None else labels[a:b])
        if keep_rows:
            rows.append(r)
    method = registration if isinstance(registration, str) else "given"
    out = {"source": meas.source, "robot": model.name, "measurements": len(q), "skipped_rows": meas.skipped,
           "registration": {"method": method, **reg.to_dict()}, "summary": acc.summary(sigma_position)}
    T_base = reg.to_base(meas.T)
    if campaign is not None:
        lab = labels if labels is not None else acc.label(q)
        out["per_pose"] = per_pose_statistics(campaign.names, acc.commanded(), T_base, lab)
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
    T_tb = np.eye(4)
    if registration == "base":
        kab = KabschAccumulator()
        for m in read_csv(path, chunk_rows=chunk_rows):
            kab.add(model.fk(measurement_joints(model, m, campaign))[:, :3, 3], m.T[:, :3, 3])
        T_tb = kab.result()
    elif registration != "none":
        raise ValueError("stream_file: registration must be 'base' or 'none'")
    acc = AccuracyAccumulator.from_budget(model, budget, campaign, T_tb)
    skipped = []
    for m in read_csv(path, chunk_rows=chunk_rows):
        labels = np.array([str(p) for p in m.pose], dtype=object) if m.pose is not None and any(m.pose) else None
        acc.add(m.T, measurement_joints(model, m, campaign), labels)
        skipped += m.skipped
    return {"source": str(path), "robot": model.name, "measurements": acc.n, "skipped_rows": skipped,
            "T_tracker_base": T_tb, "summary": acc.summary()}


def per_pose_statistics(names, T_commanded: dict, T_measured, labels) -> dict:
    """ISO 9283 characteristics for each test pose name (measured poses grouped by ``labels``)."""
    out = {}
    labels = np.asarray(labels, dtype=object)
    for name in names:
        sel = labels == name
        if sel.sum() >= 2:
            out[name] = pose_characteristics(T_commanded[name], np.asarray(T_measured)[sel]).to_dict()
        else:
            out[name] = {"n": int(sel.sum()), "note": "fewer than 2 measurements"}
    return out


def measurement_joints(model, meas, campaign=None) -> np.ndarray:
    """(n, dof) joints of each measurement in the model's order: from the joint columns, or from the
    campaign's test pose named in the ``pose`` column."""
    if meas.joints is not None and len(meas.joint_names):
        try:
            return JointOrder(model.joint_names).rows(meas.joint_names, meas.joints)
        except IngestError as exc:
            raise MeasurementError(f"{meas.source}: joint columns: {exc}") from None
    if campaign is None or meas.pose is None:
        raise ValueError(f"{meas.source}: measurements carry no joints; give a campaign and label each row with "
                         f"its test pose")
    table = dict(zip(campaign.names, campaign.joints_for(model)))
    unknown = sorted({str(p) for p in meas.pose if p not in table})
    if unknown:
        raise ValueError(f"{meas.source}: test pose(s) {unknown} are not in campaign {campaign.name!r} "
                         f"({campaign.names})")
    return np.array([table[p] for p in meas.pose])
