"""Error-model server (node ``tolerance_error_model``): the JSON service ``compute_error_jacobian`` on
``tolerance/compute_error_jacobian/request`` -> ``.../response`` (std_msgs/String, relative to the
namespace), and the predicted error bound of the current budget at the current joint state on
``tolerance/predicted_bound``. Robots: shipped names, robot files or ``robot_description``.

The predicted bound is computed on a timer, ``bound_rate`` times a second (default 20 Hz), from the latest
joint state received since the last bound (none when no new state came). Joint states are not delivered
one by one: the subscription (``joint_states``, resolved with this node's namespace and remappings, keep
the last 1) belongs to a helper node, ``<name>_joint_states``, that no executor spins, and the timer takes
the latest state from it, still serialized, and decodes only that one. A 1 kHz stream thus costs the
middleware's receipt of each message and ``bound_rate`` bounds a second, not one Python callback per state.

A calibration (the ``calibration`` file, or the latched ``tolerance_calibration`` topic) is put in force only
when the node's gate admits it (``services.guards``: correction envelope, trusted signatures); the one in
force (its content hash, old -> new in the log) and the last refusal are on /diagnostics.
"""
from __future__ import annotations

import math

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from ..core.errors import CRITERIA
from ..core.jsonio import dumps_fast
from ..services.contracts import ContractError, Limits, budget_from_message
from ..core.calibration.calibration_file import calibration_robot_name, load_calibration
from ..services.compensation import calibration_from_graph
from ..services.error_model import ErrorModelService
from ..services.guards import CalibrationRefused
from .common import (BUDGET_QOS, CALIBRATION_TOPIC, JACOBIAN_TOPIC, LATCHED_QOS, MEASUREMENT_QOS, PREFIX,
                     SERVICE_REQUEST_QOS, SERVICE_RESPONSE_QOS, STATUS_QOS, calibration_gate, declare,
                     follow_robot_description, guarded, robot_set, run, served_robots, status_name,
                     take_latest)


class ErrorModelServer(Node):
    NODE_NAME = "tolerance_error_model"

    def __init__(self, **node_options):
        super().__init__(self.NODE_NAME, **node_options)
        self.setup()

    def setup(self):
        """Parameters, robots, files, publishers, subscriptions and timers: what a managed node's configure does."""
        specs, default = served_robots(self)
        max_bytes = declare(self, "max_request_bytes", 1_000_000, "size cap of a request, bytes", (1, 1 << 30))
        max_poses = declare(self, "max_poses", 10_000, "size cap of a request, configurations", (1, 10_000_000))
        max_worst = declare(self, "max_worst_case_poses", 1_000, "configurations per request with the 'worst-case' "
                                                                 "criterion (O(p^3) work per configuration)",
                            (1, 10_000_000))
        max_comp_joints = declare(self, "max_compensate_joints", 1_000, "targets of a compensate request given as "
                                                                        "joints", (1, 10_000_000))
        max_comp_poses = declare(self, "max_compensate_poses", 100, "targets of a compensate request given as tool "
                                                                    "poses (each solved from 9 starts)", (1, 1_000_000))
        self.criterion = declare(self, "bound_criterion", "", "criterion of the predicted bound on joint states "
                                 "(paper | worst-case | rss); empty takes the budget's")
        self.calibration = declare(self, "calibration", "", "calibration file (tolerance-ros calibrate) of a served robot: "
                                   "requests with \"model\": \"calibrated\" and \"command\": \"compensate\" use it")
        rate = declare(self, "bound_rate", 20.0, "predicted bound: computed and published at most this many times "
                                                 "a second (Hz), from the latest joint state", (1e-3, 10_000.0))
        period = declare(self, "report_period", 1.0, "seconds between diagnostics", (0.01, 3600.0))
        if not (isinstance(rate, (int, float)) and math.isfinite(rate) and 0.0 < rate <= 10_000.0):
            raise ValueError(f"bound_rate: expected a rate in (0, 10000] Hz, got {rate!r}")
        self.gate = calibration_gate(self)
        if self.criterion and self.criterion not in CRITERIA:
            raise ValueError(f"bound_criterion: expected one of {list(CRITERIA)} or empty, got {self.criterion!r}")
        limits = Limits(max_bytes, max_poses, max_worst, max_comp_joints, max_comp_poses)
        self.service = ErrorModelService(robot_set(self, specs, default), limits=limits)
        self.load_calibration()
        self.responses = self.create_publisher(String, f"{JACOBIAN_TOPIC}/response", SERVICE_RESPONSE_QOS)
        self.bound_pub = self.create_publisher(String, f"{PREFIX}/predicted_bound", STATUS_QOS)
        self.create_subscription(String, f"{JACOBIAN_TOPIC}/request", guarded(self, self.on_request),
                                 SERVICE_REQUEST_QOS)
        self.joint_state_node = rclpy.create_node(f"{self.get_name()}_joint_states", namespace=self.get_namespace(),
                                                  context=self.context, use_global_arguments=False,
                                                  enable_rosout=False, start_parameter_services=False)
        qos = QoSProfile(depth=1, reliability=MEASUREMENT_QOS.reliability, history=MEASUREMENT_QOS.history)
        self.joint_states = self.joint_state_node.create_subscription(
            JointState, self.resolve_topic_name("joint_states"), lambda msg: None, qos, raw=True)
        self.create_timer(1.0 / rate, guarded(self, self.publish_bound))
        self.create_subscription(String, "tolerance_budget", guarded(self, self.on_budget), BUDGET_QOS)
        self.create_subscription(String, CALIBRATION_TOPIC, guarded(self, self.on_calibration), LATCHED_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(period, guarded(self, self.publish_status))
        follow_robot_description(self, self.service.robots, self.on_robots_changed)
        self.get_logger().info(f"serving {sorted(self.service.models) or 'robot_description'} on "
                               f"{self.resolve_topic_name(JACOBIAN_TOPIC + '/request')}")

    def load_calibration(self):
        """Load the calibration file for its robot once that robot is served (robot_description may come later);
        the gate must admit it (ValueError naming why: the node does not start)."""
        if not self.calibration:
            return
        robot = calibration_robot_name(self.calibration)
        if robot not in self.service.models:
            message = f"calibration {self.calibration}: robot {robot!r} is not served ({sorted(self.service.models)})"
            if not self.service.robots.waiting:
                raise ValueError(message)
            self.get_logger().info(f"calibration waits for its robot: {message}")
            return
        model = self.service.models[robot]
        cal = load_calibration(self.calibration, model)
        check = self.gate.admit(cal, model, self.calibration)
        self.service.calibrations = {robot: cal.mechanism(model)}
        self.get_logger().info(self.gate.swap(cal, self.calibration, check) + f" (calibrated model of {robot})")

    def on_robots_changed(self):
        """robot_description brought a robot: load the calibration for it; one that no longer fits the robots
        served is dropped (logged), and requests for the calibrated model are refused until it fits again."""
        try:
            self.load_calibration()
        except ValueError as exc:
            self.service.calibrations = {}
            self.get_logger().error(f"calibration dropped, it does not fit the robots served now: {exc}")
            self.get_logger().info(self.gate.clear("it does not fit the robots served now"))

    def on_request(self, msg):
        self.responses.publish(String(data=self.service.handle_text(msg.data)))

    def on_calibration(self, msg):
        """A calibration on the graph replaces the file's for its robot (requests with "model": "calibrated",
        compensate, and the predicted bound, which then comes from the calibrated robot)."""
        try:
            robot, cal = calibration_from_graph(msg.data, self.service.models)
            model = self.service.models[robot]
            check = self.gate.admit(cal, model, CALIBRATION_TOPIC)
            calibrated = cal.mechanism(model)
        except ValueError as exc:  # CalibrationError and CalibrationRefused included
            if not isinstance(exc, CalibrationRefused):  # refused while reading it: said on /diagnostics too
                self.gate.record(str(exc)[:400], None, CALIBRATION_TOPIC)
            self.get_logger().error(f"calibration on {CALIBRATION_TOPIC} refused, the one in force stays: {exc}")
            return
        self.service.calibrations[robot] = calibrated
        self.get_logger().info(self.gate.swap(cal, CALIBRATION_TOPIC, check) + f" (calibrated model of {robot})")

    def publish_status(self):
        """/diagnostics: the calibration in force (its content hash) and the last calibration refused."""
        refused = self.gate.refusal_message()
        served = sorted(self.service.models) or ["waiting for robot_description"]
        message = refused or (f"serving {', '.join(served)}; calibrated model: "
                              f"{', '.join(sorted(self.service.calibrations)) or 'none'}")
        values = {"robots": ", ".join(served), "calibrated": ", ".join(sorted(self.service.calibrations)) or "none",
                  **self.gate.diagnostic_values()}
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [DiagnosticStatus(level=bytes([1 if refused else 0]), name=status_name(self, "error model"),
                                       message=message, hardware_id=", ".join(served),
                                       values=[KeyValue(key=k, value=v) for k, v in values.items()])]
        self.diag_pub.publish(arr)

    def on_budget(self, msg):
        try:
            _, self.service.current_budget = budget_from_message(msg.data, self.service.models)
        except ContractError as exc:
            self.get_logger().error(f"budget message ignored: {exc.message}")

    def latest_joint_state(self):
        """The newest joint state waiting on the helper node's subscription (serialized), or None."""
        return take_latest(self.joint_states)

    def publish_bound(self):
        """The predicted bound at the latest joint state, when one came since the last bound."""
        raw = self.latest_joint_state()
        if raw is None or self.service.current_budget is None:
            return
        bound = self.service.bound_at_message(deserialize_message(raw, JointState), self.criterion or None)
        if bound is not None:
            self.bound_pub.publish(String(data=dumps_fast(bound)))

    def close(self):
        self.joint_state_node.destroy_node()


def main(args=None):
    run(ErrorModelServer, args)


if __name__ == "__main__":
    main()
