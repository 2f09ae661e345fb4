"""Accuracy monitor (node ``tolerance_accuracy_monitor``): pairs ``measured_pose`` (PoseStamped) with
``joint_states``, compares with nominal FK and the current budget (``tolerance_budget`` or a budget
file), publishes /diagnostics (DiagnosticArray) and a JSON report on ``/tolerance/accuracy_report``,
and appends every measurement to a campaign log as it arrives."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from ..core.budget import load_budget
from ..core.campaign import load_campaign
from ..core.geometry import transform
from ..core.jsonio import dumps_fast
from ..core.models import load_robot
from ..services.contracts import ContractError, budget_from_message
from ..services.monitor import MonitorLogic
from .common import BUDGET_QOS, MEASUREMENT_QOS, STATUS_QOS, SERVICE_NAMESPACE, declare, run


class AccuracyMonitor(Node):
    def __init__(self, **node_options):
        super().__init__("tolerance_accuracy_monitor", **node_options)
        robot = declare(self, "robot", "gao2023_7dof", "robot config: shipped name or YAML/URDF path")
        budget = declare(self, "budget", "", "budget file or shipped name; empty waits for tolerance_budget")
        campaign = declare(self, "campaign", "", "campaign config for per-test-pose ISO 9283 statistics")
        slop = declare(self, "slop", 0.02, "largest |stamp difference| between a measurement and its joint state, s")
        max_wait = declare(self, "max_wait", 1.0, "seconds a measurement waits for a later joint state")
        base = declare(self, "tracker_to_base", [0.0] * 6,
                       "registration: pose of the robot base in the tracker frame, [x y z roll pitch yaw] (m, rad)")
        tool = declare(self, "tool_offset", [0.0] * 3, "tool point offset in the tool frame, m")
        log_dir = declare(self, "log_dir", str(Path.home() / ".ros" / "tolerance_ros" / "campaigns"),
                          "directory of the campaign log (one JSON Lines file per run)")
        period = declare(self, "report_period", 1.0, "seconds between diagnostics and reports")
        tol = declare(self, "pose_tolerance", 1e-3, "joint distance (rad or m) to label a test pose")
        self.model = load_robot(robot)
        camp = load_campaign(campaign, self.model) if campaign else None
        bud = load_budget(budget, self.model) if budget else None
        log_path = Path(log_dir).expanduser() / f"{self.model.name}_{time.strftime('%Y%m%d_%H%M%S')}.jsonl"
        self.logic = MonitorLogic(self.model, bud, camp, slop, max_wait, transform(base[:3], base[3:]),
                                  np.asarray(tool, float) if np.any(tool) else None, log_path, tol)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.report_pub = self.create_publisher(String, f"{SERVICE_NAMESPACE}/accuracy_report", STATUS_QOS)
        self.create_subscription(PoseStamped, "measured_pose", self.on_pose, MEASUREMENT_QOS)
        self.create_subscription(JointState, "joint_states", self.on_joint_state, MEASUREMENT_QOS)
        self.create_subscription(String, "tolerance_budget", self.on_budget, BUDGET_QOS)
        self.create_timer(period, self.publish_status)
        self.get_logger().info(f"monitoring {self.model.name}; campaign log {log_path}")

    def on_pose(self, msg):
        self.logic.on_pose_msg(msg)

    def on_joint_state(self, msg):
        self.logic.on_joint_state_msg(msg)

    def on_budget(self, msg):
        try:
            _, budget = budget_from_message(msg.data, {self.model.name: self.model})
        except ContractError as exc:
            self.get_logger().error(f"budget message ignored: {exc.message}")
            return
        self.logic.set_budget(budget)
        self.get_logger().info(f"new budget: {budget.source or 'tolerance_budget'}")

    def publish_status(self):
        self.logic.resolve()
        d = self.logic.diagnostic()
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [DiagnosticStatus(level=bytes([d["level"]]), name=d["name"], message=d["message"],
                                       hardware_id=d["hardware_id"],
                                       values=[KeyValue(key=k, value=v) for k, v in d["values"].items()])]
        self.diag_pub.publish(arr)
        self.report_pub.publish(String(data=dumps_fast(self.logic.report())))

    def close(self):
        self.logic.close()


def main(args=None):
    run(AccuracyMonitor, args)


if __name__ == "__main__":
    main()
