"""Logic of the ``calibrate`` service: calibration as a service, from what the accuracy monitor logged (SI).

Request (on ``tolerance/calibrate/request``, std_msgs/String JSON; the shape of ``allocate_tolerances``)::

    {"id": "k1", "log": "current",        # the monitor's own campaign log, or a log, CSV or rosbag2 under log_dir
     "window": [t0, t1],                  # optional: only measurements stamped in [t0, t1] (s)
     "registration": "base",              # or "base+tool"
     "parameters": "auto",                # registration | joint-offsets | full | full+elastic
     "prior": [0.005, 0.005],             # m, rad; null: no regularised candidate
     "noise": 1e-5, "orientation_noise": null, "folds": 10, "seed": 0, "robust": true,
     "time_limit": 300}
    {"id": ..., "command": "status"}, {"id": ..., "command": "cancel", "target": <id of a job>}

A log of contacts (``tolerance/contact`` requests latched by the monitor, or a contact CSV) is calibrated from
contact (``core.calibration.contact_campaign``): ``"targets": {"A": [x, y, z]}`` (m, tool frame) gives the targets'
nominal places where the logged requests did not; ``noise``, absent or null, is estimated from its rows; its
validation figures are ``contact_rms_m``.

Answers: ``{"status": "accepted", "queued": n}`` at once, progress on ``.../progress``, then ``{"status":
"done", "success": true|false, "robot", "measurements", "model", "validation": {before, after, improvement},
"plausibility", "rejected", "repeatability", "calibration_file"}``. A calibration that the plausibility checks
accept goes out as ``calibration`` (the calibration file's text, SI), which the node publishes latched on
``tolerance_calibration``; one they refuse is answered (``success: false`` with the reasons) and not put in
force. Errors carry the services' codes (``invalid_request`` naming the field, ``unknown_robot``, ``busy``,
``cancelled``, ``timeout``; ``infeasible`` for a log that cannot be calibrated, with the reason).

What the service trusts: it reads only logs under its ``log_dir`` (a relative path is taken from there; a path
elsewhere, also through a symbolic link, is refused), so a request cannot fit a calibration to any file the
node can read. Each calibration carries its provenance (``core.calibration.provenance``): an id, the time, the
request's id, the node that made it (``made_by``) and the SHA-256 of the log it was fitted to; a log file is
first copied into the calibration's folder (``log_dir/calibrations/<id>/``, beside ``calibration.yaml``), so
that the hash names exactly the bytes fitted, though the monitor's own log keeps growing. With a signing key
the calibration is signed. A calibration whose correction leaves the node's envelope
(``core.calibration.envelope``) is answered ``success: false`` with the reason in ``envelope`` and not put in
force, as one the plausibility checks refuse. The file saved is exactly the text published.
"""
from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.accuracy.io import MeasurementError, read_measurements
from ..core.accuracy.io.contact_csv import is_contact_campaign, read_contact_campaign
from ..core.calibration.calibrate import MODELS, PRIOR, FitOptions, calibrate_measurements
from ..core.calibration.envelope import Envelope
from ..core.calibration.provenance import file_sha256, new_provenance
from ..core.conformity import DEFAULT_RULE, DecisionRule, judged
from ..core.calibration.calibration_file import SI, calibration_text
from ..core.models.base import Mechanism
from ..core.yamlio import loads_yaml
from .allocation import DEFAULT_TIME_LIMIT_S, MAX_TIME_LIMIT_S, MIN_TIME_LIMIT_S
from .contracts import ContractError, Limits, number, parse_request
from .jobs import JobService, command_of

FIELDS = {"command": ((str,), False), "robot": ((str,), False), "log": ((str,), False), "window": ((list,), False),
          "registration": ((str,), False), "parameters": ((str,), False), "prior": ((list, type(None)), False),
          "noise": ((int, float), False), "orientation_noise": ((int, float, type(None)), False),
          "folds": ((int,), False), "seed": ((int,), False), "robust": ((bool,), False),
          "time_limit": ((int, float), False), "target": ((str, int), False), "targets": ((dict,), False),
          "decision_rule": ((str,), False)}
PARAMETERS = ("auto",) + MODELS


@dataclass(frozen=True)
class CalibrationJob:
    """A validated calibration request (SI)."""

    id: object
    robot: str
    mechanism: Mechanism
    log: str
    window: tuple | None = None
    registration: str = "base"
    parameters: str = "auto"
    prior: tuple | None = PRIOR
    noise: float | None = None      # m; None: 1e-5 for a tracker's log, estimated from the rows for contacts
    orientation_noise: float | None = None
    folds: int = 10
    seed: int = 0
    robust: bool = True
    time_limit_s: float = DEFAULT_TIME_LIMIT_S
    targets: dict | None = None     # contact logs: {target: (3,) m in the tool frame}, beside the logged ones
    rule: DecisionRule = DEFAULT_RULE  # how each identified part is judged against the node's budget


MAX_NAME_CHARS = 255     # characters of one part of a log's path (the file systems' own limit)
MAX_PATH_CHARS = 4096    # characters of a log's whole path


def log_path(log: str, log_dir) -> str:
    """The path of a requested log: under ``log_dir`` (a relative one from there), symbolic links resolved;
    ContractError 'invalid_request' for a name no file can have (a NUL byte, a part over ``MAX_NAME_CHARS``),
    a path elsewhere or one that does not exist; its message shows at most 60 characters of the name and
    nothing of the node's own folders. ``log_dir`` None: any path."""
    shown = repr(log[:60]) + ("..." if len(log) > 60 else "")
    if "\x00" in log:
        raise ContractError("invalid_request", f"log: {shown} holds a NUL byte; no file is named so")
    if len(log) > MAX_PATH_CHARS or any(len(part) > MAX_NAME_CHARS for part in log.split("/")):
        raise ContractError("invalid_request", f"log: {shown} is longer than a file name can be ({MAX_NAME_CHARS} "
                                               f"characters a part, {MAX_PATH_CHARS} in all)")
    try:
        if log_dir is None:
            path = Path(log)
        else:
            base = Path(log_dir).expanduser().resolve()
            path = (base / log).resolve()
            if not path.is_relative_to(base):
                raise ContractError("invalid_request", f"log: {shown} is outside this node's log_dir; the calibrate "
                                                       f"service reads only logs under it")
        found = path.exists()
    except (OSError, ValueError, RuntimeError) as exc:   # a loop of links, a name the system refuses
        raise ContractError("invalid_request", f"log: {shown} cannot be read as a file name "
                                               f"({type(exc).__name__})") from None
    if not found:
        raise ContractError("invalid_request", f"log: no such file {shown}")
    return str(path)


def parse_calibrate_request(text, robots, limits: Limits, current_log=None, max_time_limit_s=MAX_TIME_LIMIT_S,
                            log_dir=None):
    """A CalibrationJob or a Command; raises ContractError naming the field. ``current_log`` is the monitor's
    own log (what ``"log": "current"`` means); other logs must lie under ``log_dir`` (when given)."""
    req = parse_request(text, FIELDS, limits)
    command = command_of(req, "calibrate")
    if command is not None:
        return command
    name, model = robots.select(req.get("robot"))
    log = req.get("log", "current")
    if log == "current":
        if not current_log:
            raise ContractError("invalid_request", "log: this node keeps no campaign log; give a file")
        log = str(current_log)
    log = log_path(log, log_dir)
    window = req.get("window")
    if window is not None:
        if len(window) != 2:
            raise ContractError("invalid_request", "window: expected [t_start, t_end] (s)")
        window = (number(window[0], "window[0]"), number(window[1], "window[1]"))
        if not window[0] < window[1]:
            raise ContractError("invalid_request", "window: t_start must be before t_end")
    registration = req.get("registration", "base")
    if registration not in ("base", "base+tool"):
        raise ContractError("invalid_request", f"registration: expected 'base' or 'base+tool', got {registration[:40]!r}")
    parameters = req.get("parameters", "auto")
    if parameters not in PARAMETERS:
        raise ContractError("invalid_request", f"parameters: expected one of {list(PARAMETERS)}, got "
                                               f"{parameters[:40]!r}")
    prior = req.get("prior", list(PRIOR))
    if prior is not None:
        if len(prior) != 2:
            raise ContractError("invalid_request", "prior: expected [length m, angle rad] or null")
        prior = (number(prior[0], "prior[0]", 1e-9, 10.0), number(prior[1], "prior[1]", 1e-9, np.pi))
    onoise = req.get("orientation_noise")
    time_limit = number(req.get("time_limit", min(DEFAULT_TIME_LIMIT_S, max_time_limit_s)), "time_limit",
                        MIN_TIME_LIMIT_S, max_time_limit_s)
    targets = req.get("targets")
    if targets is not None:
        if len(targets) > 20:
            raise ContractError("invalid_request", "targets: at most 20")
        for k, v in targets.items():
            if not isinstance(v, list) or len(v) != 3:
                raise ContractError("invalid_request", f"targets.{str(k)[:40]}: expected [x, y, z] (m, tool frame)")
            targets[k] = tuple(number(c, f"targets.{str(k)[:40]}", -5.0, 5.0) for c in v)
    return CalibrationJob(req["id"], name, model, log, window, registration, parameters, prior,
                          None if req.get("noise") is None else number(req["noise"], "noise", 1e-9, 1.0),
                          None if onoise is None else number(onoise, "orientation_noise", 1e-12, 1.0),
                          int(number(req.get("folds", 10), "folds", 2, 100, integer=True)),
                          int(number(req.get("seed", 0), "seed", 0, 2 ** 31, integer=True)),
                          bool(req.get("robust", True)), time_limit, targets, _rule(req.get("decision_rule", "guarded:2")))


def _rule(text) -> DecisionRule:
    try:
        return DecisionRule.parse(text)
    except ValueError as exc:
        raise ContractError("invalid_request", f"decision_rule: {exc}") from None


def run_calibration(job: CalibrationJob, progress=None, made_by="tolerance_ros calibrate service", snapshot=None):
    """(response dict, Calibration) of a job; MeasurementError / ValueError for data that cannot be calibrated.
    The log is fitted from ``snapshot`` (a path: the log file is copied there first) when given; the
    calibration's provenance names ``made_by`` and the SHA-256 of the bytes fitted."""
    log = job.log
    if snapshot is not None and Path(log).is_file():
        Path(snapshot).parent.mkdir(parents=True, exist_ok=True)
        log = str(shutil.copyfile(log, snapshot))
    log_sha256 = file_sha256(log)
    if is_contact_campaign(log):
        return _run_contacts(job, log, log_sha256, progress, made_by)
    meas = read_measurements(log, joint_names=job.mechanism.joint_names, skip_bad=True)
    if job.window is not None:
        keep = (meas.stamps >= job.window[0]) & (meas.stamps <= job.window[1])
        if not keep.any():
            raise MeasurementError(f"window: no measurement of {job.log} is stamped in [{job.window[0]:.9g}, "
                                   f"{job.window[1]:.9g}] s")
        meas = meas.select(keep)
    opts = FitOptions(registration=job.registration, sigma_position=1e-5 if job.noise is None else job.noise,
                      sigma_orientation=job.orientation_noise,
                      robust=job.robust, prior=job.prior, folds=job.folds, seed=job.seed)
    cal = calibrate_measurements(job.mechanism, meas, None, opts, parameters=job.parameters, progress=progress)
    cal.sources.update(measurements=job.log)
    cal.provenance = new_provenance(made_by, log=log, log_sha256=log_sha256, request_id=job.id)
    v = cal.validation
    resp = {"id": job.id, "ok": True, "status": "done", "success": bool(cal.plausibility["ok"]), "robot": job.robot,
            "measurements": cal.measurements, "skipped": len(meas.skipped), "model": cal.model,
            "validation": {k: v[k] for k in ("method", "folds", "poses", "before", "after", "improvement",
                                             "before_kept", "after_kept", "kept_measurements") if k in v},
            "fit": cal.fit_dict(), "plausibility": cal.plausibility, "rejected": cal.rejected,
            "suspect": cal.suspect, "warnings": cal.warnings, "repeatability": cal.repeatability,
            "provenance": dict(cal.provenance)}
    return resp, cal


def _run_contacts(job: CalibrationJob, log, log_sha256, progress, made_by):
    """``run_calibration`` of a log of contacts (``core.calibration.contact_campaign``): the targets' offsets from
    the request, else from the contact requests logged."""
    from ..core.calibration.contact_campaign import calibrate_campaign, contact_fit
    if job.registration != "base" or job.orientation_noise is not None or job.parameters not in (
            "auto", "joint-offsets", "full"):
        raise ContractError("invalid_request", "a log of contacts: registration, orientation_noise do not apply and "
                                               "parameters is auto, joint-offsets or full")
    model = job.mechanism
    contacts, logged = read_contact_campaign(log, model.joint_names, model.joint_types, skip_bad=True)
    if job.window is not None:
        keep = (contacts.stamps >= job.window[0]) & (contacts.stamps <= job.window[1])
        if not keep.any():
            raise MeasurementError(f"window: no contact of {job.log} is stamped in [{job.window[0]:.9g}, "
                                   f"{job.window[1]:.9g}] s")
        contacts = contacts.select(keep)
    offsets = {k: v for k, v in logged.items() if v is not None} | dict(job.targets or {})
    cal = calibrate_campaign(model, contacts, offsets, job.parameters, job.prior, job.noise, job.folds, job.seed,
                             job.robust, progress)
    cal.sources.update(measurements=job.log)
    cal.provenance = new_provenance(made_by, log=log, log_sha256=log_sha256, request_id=job.id)
    resp = {"id": job.id, "ok": True, "status": "done", "success": bool(cal.plausibility["ok"]), "robot": job.robot,
            "measurements": cal.measurements, "skipped": len(contacts.skipped), "model": cal.model,
            "validation": {k: v for k, v in cal.validation.items() if k != "distances_m"},
            "fit": contact_fit(cal), "plausibility": cal.plausibility, "rejected": cal.rejected,
            "warnings": cal.warnings, "provenance": dict(cal.provenance)}
    return resp, cal


def folder_name(rid) -> str:
    """A request id as a folder name: letters, digits, '-' and '_' kept, anything else '_' (no '/' or '..')."""
    safe = "".join(c if c.isascii() and (c.isalnum() or c in "-_") else "_" for c in str(rid))[:80]
    return safe or "_"


class CalibrationService(JobService):
    """Queue, worker and answers of the calibration service (see the module docstring and
    ``jobs.JobService``); ROS-free. ``current_log()`` gives the node's campaign log path; ``save_dir`` (or
    None) keeps each finished calibration's file and the log it was fitted to; ``log_dir`` (or None) is where
    requested logs must lie; ``made_by`` names the node in the provenance; ``envelope`` bounds the correction
    of a calibration put in force; ``signing_key`` (an Ed25519 private key, or None) signs it."""

    KIND = "calibration"

    def __init__(self, robots, emit, current_log=None, limits: Limits | None = None, max_queue: int = 2,
                 save_dir=None, max_time_limit_s: float = MAX_TIME_LIMIT_S, log_dir=None,
                 made_by="tolerance_ros calibrate service", envelope: Envelope | None = None, signing_key=None,
                 budget=None):
        self.robots, self.current_log, self.save_dir, self.budget = robots, current_log, save_dir, budget
        self.limits = limits or Limits(max_bytes=100_000)
        self.max_time_limit_s = max_time_limit_s
        self.log_dir, self.made_by, self.envelope, self.signing_key = log_dir, made_by, envelope, signing_key
        super().__init__(emit, max_queue)

    def parse(self, text):
        return parse_calibrate_request(text, self.robots, self.limits,
                                       self.current_log() if self.current_log else None, self.max_time_limit_s,
                                       self.log_dir)

    def folder(self, job) -> Path | None:
        """The folder of a job's files (``save_dir/<id>``), or None without ``save_dir``."""
        return None if self.save_dir is None else Path(self.save_dir) / folder_name(job.id)

    def run(self, job, progress) -> dict:
        """The answer of one job; a log that cannot be calibrated (too few poses, unreadable, out of the
        window) answers ``infeasible`` with the reason."""
        folder = self.folder(job)
        snapshot = None if folder is None else folder / f"measurements{Path(job.log).suffix}"
        try:
            resp, cal = run_calibration(job, progress, self.made_by, snapshot)
        except (MeasurementError, ValueError) as exc:
            raise ContractError("infeasible", f"the log cannot be calibrated: {exc}") from None
        except OSError as exc:
            raise ContractError("infeasible", f"the log cannot be read or copied: {exc}") from None
        budget = self.budget() if self.budget else None
        if budget is not None:
            resp["budget"] = {"source": budget.source, **judged(cal.names, cal.kinds, cal.dx, cal.std, cal.held,
                                                                 cal.aliases, budget.vector_for(job.mechanism),
                                                                 job.rule, cal.undetermined,
                                                                 job.mechanism.reach())}
        if self.envelope is not None:
            resp["envelope"] = self.envelope.check(cal, job.mechanism)
            if not resp["envelope"]["ok"]:
                resp["success"] = False
        text = calibration_text(cal, SI, self.signing_key)
        doc = loads_yaml(text, "calibration", ValueError)
        resp["provenance"] = doc["provenance"]
        resp["signed_by"] = (doc.get("signature") or {}).get("key_id")
        resp["_text"] = text  # taken out by deliver, before the answer goes out
        return resp

    def deliver(self, job, resp):
        """Save the calibration (the text that is published); put it in force (``calibration``) when the
        plausibility checks and the envelope accept it."""
        text = resp.pop("_text")
        folder = self.folder(job)
        if folder is not None:
            name = "calibration.yaml" if resp["success"] else "calibration.refused.yaml"
            try:
                folder.mkdir(parents=True, exist_ok=True)
                (folder / name).write_text(text)
                resp["calibration_file"] = str(folder / name)
            except OSError as exc:
                resp.setdefault("warnings", []).append(f"the calibration could not be saved: {exc}")
        if resp["success"]:
            self.emit("calibration", {"id": job.id, "robot": job.robot, "text": text})
