"""What a node checks before it puts a calibration in force, and what it says about it (ROS-free).

``CalibrationGate.admit(cal, model, source)`` passes a calibration (already read and checked against the
robot, its content hash verified by the reader) only when

- it is signed by one of the node's trusted keys, when the node has any (parameter ``trusted_calibration_keys``;
  ``core.calibration.provenance``), and
- its correction is within the node's envelope (parameters ``max_joint_correction`` rad and
  ``max_tool_correction`` m; ``core.calibration.envelope``);

otherwise it raises ``CalibrationRefused`` naming the reason, counts the refusal and keeps it for the node's
diagnostics; the calibration in force stays. Each calibration put in force is described by ``summary`` (its id,
content hash, maker, time, log hash and where it came from), and ``swap`` says old -> new for the log.
"""
from __future__ import annotations

import time

from ..core.calibration.envelope import Envelope
from ..core.calibration.provenance import ProvenanceError, load_public_keys, verify_signature
from ..core.models.base import ModelError


class CalibrationRefused(ValueError):
    """A calibration the gate does not put in force; the message says why."""


def short(sha) -> str:
    """The first 12 hex digits of a hash, for logs ('none' for None)."""
    return sha[:12] if isinstance(sha, str) else "none"


def summary(cal, source: str = "") -> dict:
    """What identifies a calibration in logs, diagnostics and reports: {id, sha256, made_by, time, log_sha256,
    request_id, signed_by, source}."""
    prov = cal.provenance or {}
    return {"id": prov.get("id"), "sha256": prov.get("content_sha256"), "made_by": prov.get("made_by"),
            "time": prov.get("time"), "log_sha256": prov.get("log_sha256"), "request_id": prov.get("request_id"),
            "signed_by": (cal.signature or {}).get("key_id"), "source": source}


def describe(s: dict | None) -> str:
    """One line of a calibration summary: 'sha256 51b7c2e0a9f1 (id 3f0c..., by /arm/monitor, made 2026-...)'."""
    if s is None:
        return "none"
    extra = ", ".join(f"{label} {s[k]}" for k, label in (("id", "id"), ("made_by", "by"), ("time", "made")) if s.get(k))
    return f"sha256 {short(s.get('sha256'))}" + (f" ({extra})" if extra else "")


class CalibrationGate:
    """See the module docstring. ``envelope``: an Envelope (None: no bound); ``trusted_keys``: PEM paths of the
    Ed25519 public keys whose signatures are accepted (empty: signatures are not required)."""

    def __init__(self, envelope: Envelope | None = None, trusted_keys=(), clock=time.time):
        self.envelope = envelope
        self.trusted = load_public_keys(trusted_keys) if trusted_keys else {}
        self.clock = clock
        self.current = None          # summary of the calibration in force
        self.correction = None       # its envelope check
        self.refused = 0
        self.last_refusal = None     # {"reason", "sha256", "source", "time"}
        self.swapped_at = None

    def admit(self, cal, model, source: str = "") -> dict:
        """The envelope check of ``cal`` when the gate lets it in force; CalibrationRefused otherwise."""
        try:
            if self.trusted:
                verify_signature(cal.content_sha256 or "", cal.signature, self.trusted, "calibration")
            check = self.envelope.check(cal, model) if self.envelope is not None else None
        except (ProvenanceError, ModelError) as exc:
            self._refuse(str(exc), cal, source)
        if check is not None and not check["ok"]:
            self._refuse(f"correction outside the envelope: {check['reason']}", cal, source)
        return check

    def _refuse(self, reason, cal, source):
        self.record(reason, cal.content_sha256, source)
        raise CalibrationRefused(reason)

    def record(self, reason: str, sha256=None, source: str = ""):
        """Count a refusal and keep it for the diagnostics (also one made before the gate: a calibration that
        cannot be read, is for another robot, or whose content no longer matches its hash)."""
        self.refused += 1
        self.last_refusal = {"reason": str(reason), "sha256": sha256, "source": source, "time": self.clock()}

    def swap(self, cal, source: str = "", check=None) -> str:
        """Record ``cal`` as the calibration in force; returns the log line 'old -> new'."""
        new = summary(cal, source)
        line = f"calibration in force: {describe(self.current)} -> {describe(new)}" + (f" from {source}" if source else "")
        if check is not None:
            line += (f"; correction up to {check['joint_rad'] * 1e3:.3g} mrad ({check['joint']}) and "
                     f"{check['tool_m'] * 1e3:.3g} mm at the tool")
        self.current, self.correction, self.swapped_at = new, check, self.clock()
        return line

    def clear(self, reason: str) -> str:
        """No calibration in force any more (its robot went away); returns the log line."""
        line = f"calibration in force: {describe(self.current)} -> none ({reason})"
        self.current = self.correction = None
        return line

    def diagnostic_values(self) -> dict:
        """Key values (strings) for /diagnostics: the calibration in force and the last refusal."""
        cur = self.current or {}
        out = {"calibration_sha256": cur.get("sha256") or "none", "calibration_id": cur.get("id") or "none",
               "calibration_made_by": cur.get("made_by") or "-", "calibration_signed_by": cur.get("signed_by") or "-",
               "calibrations_refused": str(self.refused)}
        if self.correction is not None:
            out["correction_joint_rad"] = f"{self.correction['joint_rad']:.6g}"
            out["correction_tool_m"] = f"{self.correction['tool_m']:.6g}"
        if self.last_refusal is not None:
            out["last_refused_sha256"] = self.last_refusal["sha256"] or "none"
            out["last_refusal"] = self.last_refusal["reason"][:400]
        return out

    def refusal_message(self) -> str | None:
        """'calibration ... refused, the one in force stays: <reason>' when the last calibration offered was
        refused (none was put in force since), else None: what a node's diagnostic message says."""
        r = self.last_refusal
        if r is None or (self.swapped_at is not None and self.swapped_at >= r["time"]):
            return None
        return f"calibration {short(r['sha256'])} refused, the one in force stays: {r['reason']}"[:500]
