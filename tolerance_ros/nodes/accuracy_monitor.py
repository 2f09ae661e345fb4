"""Accuracy monitor (node ``tolerance_accuracy_monitor``): pairs ``measured_pose`` (PoseStamped) or
``measured_point`` (PointStamped, parameter ``measurement: point``) with ``joint_states``, compares with
nominal FK at each measured target and the current budget (``tolerance_budget`` or a budget file),
publishes /diagnostics (DiagnosticArray, the namespace in the status name), a JSON report on
``tolerance/accuracy_report`` and RViz markers on ``tolerance/markers`` (MarkerArray), and appends every
measurement to a campaign log as it arrives. Several targets (parameter ``targets: "A,B,C"``) each have
their own topic, ``measured_pose/A`` ... (relative, so a namespace moves them). The registration and the
targets' offsets come from parameters or from a calibration file. The robot may come from
``robot_description``. The same streams feed the path monitor (``services.path_monitor``, parameter
``path_monitor``): when a motion of the robot ends it publishes the ISO 9283 path figures of its path on
``tolerance/path_report`` (std_msgs/String, JSON, SI) and a second /diagnostics status against the budget.
A ``tolerance/contact`` request (std_msgs/String JSON, ``services.monitor.parse_contact``) latches the newest joint
state into the campaign log as contacts with a plane or a point (calibration without a tracker); the answer is on
``tolerance/contact/result``.

The calibrate service (``services.calibration``) reads only logs under ``log_dir``, stamps each calibration
with its provenance (made by this node, from a log of known SHA-256), signs it with ``signing_key`` when one
is set, and puts in force only one within the node's correction envelope. A calibration on
``tolerance_calibration`` (this node's own or another's) is compared with only when the node's gate admits it
(``services.guards``); the one in force and the last refusal are on /diagnostics and in the report."""
from __future__ import annotations

import time
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PointStamped, PoseStamped, TransformStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from ..core.budget import load_budget
from ..core.calibration.provenance import load_signing_key
from ..core.calibration.calibration_file import load_calibration
from ..core.campaign import load_campaign
from ..core.geometry import transform
from ..core.jsonio import dumps_fast
from ..services.contracts import ContractError, budget_from_message
from ..services.calibration import CalibrationService
from ..services.jobs import Outbox
from ..core.units import parse_quantity
from ..services.monitor import WARN, MonitorLogic, monitor_targets, tracker_frame
from ..services.path_monitor import PathMonitor
from .common import (BUDGET_QOS, CALIBRATE_TOPIC, CALIBRATION_TOPIC, CONTACT_TOPIC, LATCHED_QOS, MEASUREMENT_QOS,
                     PREFIX, SERVICE_REQUEST_QOS, SERVICE_RESPONSE_QOS, STATUS_QOS, calibration_gate, calibration_in_force,
                     declare, follow_robot, guarded, require_packages, robot_set, run, status_name)

MARKER_TYPES = {"sphere": Marker.SPHERE, "arrow": Marker.ARROW, "text": Marker.TEXT_VIEW_FACING}


class AccuracyMonitor(Node):
    NODE_NAME = "tolerance_accuracy_monitor"

    def __init__(self, **node_options):
        super().__init__(self.NODE_NAME, **node_options)
        self.setup()

    def setup(self):
        """Parameters, robots, files, publishers, subscriptions and timers: what a managed node's configure does."""
        require_packages(self, ["scipy", "rosbags"])
        robot = declare(self, "robot", "gao2023_7dof", "robot: shipped name, robot file, or robot_description")
        self.budget_spec = declare(self, "budget", "", "budget file or shipped name; empty waits for tolerance_budget")
        self.campaign_spec = declare(self, "campaign", "", "campaign config for per-test-pose ISO 9283 statistics")
        self.slop = declare(self, "slop", 0.02, "largest |stamp difference| between a measurement and its joint "
                                                "state, s", (0.0, 60.0))
        self.max_wait = declare(self, "max_wait", 1.0, "seconds a measurement waits for a later joint state",
                                (0.0, 600.0))
        base = declare(self, "tracker_to_base", [0.0] * 6,
                       "registration: pose of the robot base in the tracker frame, [x y z roll pitch yaw] (m, rad)")
        self.measurement = declare(self, "measurement", "pose", "what the tracker measures: pose (PoseStamped on "
                                                                "measured_pose) or point (PointStamped on measured_point)")
        names = declare(self, "targets", "", "measured targets, comma-separated names (topics measured_pose/<name>); "
                                             "empty: one target on measured_pose")
        offsets = declare(self, "target_offsets", [0.0] * 3, "each target's point in the tool frame, m (3 per target; "
                                                             "three zeros: every target at the tool point)")
        self.calibration = declare(self, "calibration", "", "calibration file: its registration and targets replace "
                                                            "tracker_to_base, targets and target_offsets")
        self.log_dir = Path(declare(self, "log_dir", str(Path.home() / ".ros" / "tolerance_ros" / "campaigns"),
                                    "directory of the campaign log (one JSON Lines file per run) and of the "
                                    "calibrations; the calibrate service reads only logs under it")).expanduser()
        signing_key = declare(self, "signing_key", "", "Ed25519 private key (PEM file) that signs the calibrations this "
                                                       "node publishes; empty: unsigned")
        period = declare(self, "report_period", 1.0, "seconds between diagnostics and reports", (0.01, 3600.0))
        self.pose_tolerance = declare(self, "pose_tolerance", 1e-3, "joint distance (rad or m) to label a test pose",
                                      (0.0, 10.0))
        marker_period = declare(self, "marker_period", 0.2, "seconds between RViz marker updates", (0.01, 3600.0))
        self.marker_scale = declare(self, "marker_scale", 100.0, "RViz: error lengths drawn this many times enlarged",
                                    (1e-3, 1e6))
        self.marker_frame = declare(self, "marker_frame", "", "RViz: frame of the markers (empty: the URDF's base "
                                                              "link, or base_link)")
        self.tf_base = declare(self, "tf_base_frame", "", "/tf_static: the robot's base frame (empty: the URDF's base "
                                                          "link, or base_link as REP 105 names it)")
        self.tf_tracker = declare(self, "tf_tracker_frame", "tracker", "/tf_static: the tracker's frame, registered "
                                                                       "to the base")
        self.drift_window = declare(self, "drift_window", 600.0, "seconds over which each test pose's mean error is "
                                    "compared with its first window's (ISO 9283 drift)", (1.0, 86400.0))
        self.drift_limit = declare(self, "drift_limit", 0.0, "drift of a test pose's barycentre (m) beyond which "
                                   "/diagnostics warns; 0: no limit", (0.0, 1.0))
        self.path_on = declare(self, "path_monitor", True, "judge the paths too: ISO 9283 path figures on "
                                                           "tolerance/path_report when a motion ends")
        self.path_latency = declare(self, "path_latency", "", "the tracker's latency against the joint states (e.g. "
                                                              "8ms); empty: estimated from the streams")
        self.path_band = declare(self, "path_band", 1e-4, "the stabilisation band (m) of the pose stabilisation time "
                                 "and overshoot at each stop of the path monitor", (1e-7, 0.1))
        self.path_registration = declare(self, "path_registration", "given",
                                         "given: the path monitor uses tracker_to_base (or the calibration's); "
                                         "estimate: it fits the tracker's placement from the streams")
        self.T_tracker_base = transform(base[:3], base[3:])
        self.targets = monitor_targets(self.measurement, names, offsets)
        self.gate = calibration_gate(self)
        if signing_key:
            require_packages(self, ["cryptography"])
        self.signing_key = load_signing_key(signing_key) if signing_key else None
        self.robots = robot_set(self, [robot], robot)
        self.logic = None
        self.budget_text = None   # the latest tolerance_budget message, applied once the robot is known
        self.waiting = {"measurements": 0, "joint_states": 0}  # what arrived before the robot did
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.report_pub = self.create_publisher(String, f"{PREFIX}/accuracy_report", STATUS_QOS)
        self.path_pub = self.create_publisher(String, f"{PREFIX}/path_report", STATUS_QOS)
        self.path = None
        self.create_timer(0.1, guarded(self, self.flush_path))
        self.marker_pub = self.create_publisher(MarkerArray, f"{PREFIX}/markers", STATUS_QOS)
        self.tf_pub = self.create_publisher(TFMessage, "/tf_static", LATCHED_QOS)
        kind, topic = (PointStamped, "measured_point") if self.measurement == "point" else (PoseStamped, "measured_pose")
        for name in self.targets.names:
            callback = guarded(self, self._on_measurement(name))
            self.create_subscription(kind, f"{topic}/{name}" if name else topic, callback, MEASUREMENT_QOS)
        self.create_subscription(JointState, "joint_states", guarded(self, self.on_joint_state), MEASUREMENT_QOS)
        self.create_subscription(String, "tolerance_budget", guarded(self, self.on_budget), BUDGET_QOS)
        self.create_timer(period, guarded(self, self.publish_status))
        self.create_timer(marker_period, guarded(self, self.publish_markers))
        self.calibrate_outbox = Outbox()
        self.calibrator = CalibrationService(self.robots, self.calibrate_outbox, self.current_log,
                                             save_dir=self.log_dir / "calibrations", log_dir=self.log_dir,
                                             made_by=self.get_fully_qualified_name(), envelope=self.gate.envelope,
                                             signing_key=self.signing_key, budget=self.current_budget)
        self.calibrate_pubs = {"response": self.create_publisher(String, f"{CALIBRATE_TOPIC}/response",
                                                                 SERVICE_RESPONSE_QOS),
                               "progress": self.create_publisher(String, f"{CALIBRATE_TOPIC}/progress",
                                                                 SERVICE_RESPONSE_QOS),
                               "calibration": self.create_publisher(String, CALIBRATION_TOPIC, LATCHED_QOS)}
        self.create_subscription(String, f"{CALIBRATE_TOPIC}/request", guarded(self, self.on_calibrate_request),
                                 SERVICE_REQUEST_QOS)
        self.create_subscription(String, CALIBRATION_TOPIC, guarded(self, self.on_calibration), LATCHED_QOS)
        self.contact_pub = self.create_publisher(String, f"{CONTACT_TOPIC}/result", SERVICE_RESPONSE_QOS)
        self.create_subscription(String, CONTACT_TOPIC, guarded(self, self.on_contact), SERVICE_REQUEST_QOS)
        self.create_timer(0.05, guarded(self, self.flush_calibrate_outbox))
        self.calibration_text = None
        follow_robot(self, self.robots, self.start, check=self.files_for)

    def files_for(self, model):
        """(campaign, budget) of the configured files for ``model``; raises when they do not fit it."""
        camp = load_campaign(self.campaign_spec, model) if self.campaign_spec else None
        budget = load_budget(self.budget_spec, model) if self.budget_spec else None
        if camp is not None:
            camp.joints_for(model)
        if budget is not None:
            budget.vector_for(model)
        return camp, budget

    def start(self, model):
        """(Re)build the monitor for the current robot: budget, campaign and a new campaign log."""
        camp, budget = self.files_for(model)
        if self.logic is not None:
            self.logic.close()
        log_path = self.log_dir / f"{model.name}_{time.strftime('%Y%m%d_%H%M%S')}.jsonl"
        T_tracker_base, targets = self.T_tracker_base, self.targets
        if self.calibration:
            cal = load_calibration(self.calibration, model)
            check = self.gate.admit(cal, model, self.calibration)   # refused: the node does not start
            self.get_logger().info(self.gate.swap(cal, self.calibration, check) + " (registration and targets)")
            T_tracker_base, targets = cal.T_tracker_base, cal.targets
            missing = sorted(set(self.targets.names) - set(targets.names))
            if missing:
                raise ValueError(f"calibration {self.calibration}: no target(s) {missing} (it has "
                                 f"{list(targets.names)})")
        self.logic = MonitorLogic(model, budget, camp, self.slop, self.max_wait, T_tracker_base, targets, log_path,
                                  self.pose_tolerance, name=status_name(self, "accuracy monitor"),
                                  orientation=self.measurement == "pose", drift_window=self.drift_window,
                                  drift_limit=self.drift_limit or None)
        self.path = self.path_monitor(model, budget, T_tracker_base, targets) if self.path_on else None
        if self.budget_text is not None:
            self.on_budget(String(data=self.budget_text))
        if self.calibration_text is not None:
            self.on_calibration(String(data=self.calibration_text))
        self.frame = self.marker_frame or getattr(model, "base_link", None) or "base_link"
        self.publish_tracker_frame(T_tracker_base)
        self.get_logger().info(f"monitoring {model.name}; campaign log {log_path}")

    def path_monitor(self, model, budget, T_tracker_base, targets) -> PathMonitor:
        """The path monitor of the first target (its offset on the tool), with the node's registration when
        ``path_registration`` is given."""
        if self.path_registration not in ("given", "estimate"):
            raise ValueError(f"path_registration: expected given or estimate, got {self.path_registration!r}")
        latency = parse_quantity(self.path_latency, "time", "path_latency") if self.path_latency else None
        return PathMonitor(model, budget, latency, T_tracker_base if self.path_registration == "given" else None,
                           offset=targets.offsets[0], name=status_name(self, "path monitor"), band=self.path_band)

    def flush_path(self):
        """Judge the queued streams; publish the report of each path that ended."""
        if self.path is None:
            return
        for doc in self.path.flush():
            self.path_pub.publish(String(data=dumps_fast(doc)))

    def publish_tracker_frame(self, T_tracker_base):
        """The registered tracker frame on /tf_static (latched), so RViz shows tracker, robot and markers."""
        xyz, quat = tracker_frame(T_tracker_base)
        tf = TransformStamped()
        tf.header.stamp = self.get_clock().now().to_msg()
        tf.header.frame_id = self.tf_base or self.frame
        tf.child_frame_id = self.tf_tracker
        tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = (float(v) for v in xyz)
        r = tf.transform.rotation
        r.x, r.y, r.z, r.w = (float(v) for v in quat)
        self.tf_pub.publish(TFMessage(transforms=[tf]))

    def _on_measurement(self, target):
        def on_measurement(msg):
            if self.logic is None:
                self.waiting["measurements"] += 1
                return
            received = self.get_clock().now().nanoseconds * 1e-9
            if self.measurement == "point":
                self.logic.on_point_msg(msg, target, received)
            else:
                self.logic.on_pose_msg(msg, target, received)
            if self.path is not None and target == self.targets.names[0]:
                (self.path.on_point_msg if self.measurement == "point" else self.path.on_pose_msg)(msg)
        on_measurement.__name__ = f"on_measurement{'_' + target if target else ''}"
        return on_measurement

    def on_joint_state(self, msg):
        if self.logic is None:
            self.waiting["joint_states"] += 1
            return
        self.logic.on_joint_state_msg(msg, self.get_clock().now().nanoseconds * 1e-9)
        if self.path is not None:
            self.path.on_joint_state_msg(msg)

    def on_budget(self, msg):
        self.budget_text = msg.data
        if self.logic is None:
            return
        model = self.logic.model
        try:
            _, budget = budget_from_message(msg.data, {model.name: model})
            self.logic.set_budget(budget)
            if self.path is not None:
                self.path.budget = budget
        except ContractError as exc:
            self.get_logger().error(f"budget message ignored: {exc.message}")
            return
        self.get_logger().info(f"new budget: {budget.source or 'tolerance_budget'}")

    def diagnostic(self) -> dict:
        if self.logic is not None:
            self.logic.resolve()
            d = self.logic.diagnostic()
        else:
            d = {"level": WARN, "name": status_name(self, "accuracy monitor"), "hardware_id": "",
                 "message": f"waiting for robot_description ({self.waiting['measurements']} measurements and "
                            f"{self.waiting['joint_states']} joint states could not be used yet)",
                 "values": {k: str(v) for k, v in self.waiting.items()}}
        refused = self.gate.refusal_message()
        if refused is not None and d["level"] == 0:
            d["level"], d["message"] = WARN, refused
        d["values"].update(self.gate.diagnostic_values())
        return d

    def publish_status(self):
        d = self.diagnostic()
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        statuses = [d] + ([self.path.diagnostic()] if self.path is not None else [])
        arr.status = [DiagnosticStatus(level=bytes([s["level"]]), name=s["name"], message=s["message"],
                                       hardware_id=s["hardware_id"],
                                       values=[KeyValue(key=k, value=v) for k, v in s["values"].items()])
                      for s in statuses]
        self.diag_pub.publish(arr)
        if self.logic is not None:
            self.report_pub.publish(String(data=dumps_fast(self.logic.report())))

    def publish_markers(self):
        if self.logic is None:
            return
        stamp = self.get_clock().now().to_msg()
        out = MarkerArray()
        for m in self.logic.markers(self.marker_scale):
            marker = Marker()
            marker.header.frame_id, marker.header.stamp = self.frame, stamp
            marker.ns, marker.id = m["ns"], m["id"]
            if m["type"] == "delete_all":
                marker.action = Marker.DELETEALL
            else:
                marker.type, marker.action = MARKER_TYPES[m["type"]], Marker.ADD
                p, o = marker.pose.position, marker.pose.orientation
                p.x, p.y, p.z = m["position"]
                o.x, o.y, o.z, o.w = m["orientation"]
                marker.scale.x, marker.scale.y, marker.scale.z = m["scale"]
                marker.color.r, marker.color.g, marker.color.b, marker.color.a = m["color"]
                for point in m.get("points", []):
                    marker.points.append(Point(x=point[0], y=point[1], z=point[2]))
                marker.text = m.get("text", "")
            out.markers.append(marker)
        self.marker_pub.publish(out)

    def current_budget(self):
        """The budget in force (the calibrate service judges the parts it identifies against it), or None."""
        return None if self.logic is None else self.logic.budget

    def current_log(self):
        """The campaign log being written (what a calibrate request's ``"log": "current"`` means)."""
        return None if self.logic is None or self.logic.log is None else self.logic.log.name

    def on_contact(self, msg):
        """A ``tolerance/contact`` request: the joint state latched into the campaign log (``MonitorLogic.on_contact``),
        the answer on ``tolerance/contact/result``."""
        answer = (self.logic.on_contact(msg.data) if self.logic is not None else
                  {"ok": False, "error": "not_ready", "message": "the robot is not known yet (robot_description)"})
        self.contact_pub.publish(String(data=dumps_fast(answer)))

    def on_calibrate_request(self, msg):
        self.calibrator.handle(msg.data)

    def flush_calibrate_outbox(self):
        for kind, doc in self.calibrate_outbox.drain():
            self.calibrate_pubs[kind].publish(String(data=doc["text"] if kind == "calibration" else dumps_fast(doc)))

    def on_calibration(self, msg):
        """A calibration on the graph (this node's own service's, or another's): compare with the calibrated
        robot from now on, its registration and targets too; one that does not fit is refused, logged."""
        self.calibration_text = msg.data
        if self.logic is None:
            return
        cal = calibration_in_force(self, self.logic, msg.data, "the current reference stays")
        if cal is None:
            return
        self.publish_tracker_frame(cal.T_tracker_base)
        self.get_logger().info(f"measurements are compared with the calibrated robot ({cal.model.get('label', 'identified')}) "
                               f"from now on")

    def close(self):
        self.calibrator.close()
        if self.logic is not None:
            self.logic.close()


def main(args=None):
    run(AccuracyMonitor, args)


if __name__ == "__main__":
    main()
