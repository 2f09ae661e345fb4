"""Trajectory compensator (node ``tolerance_trajectory_compensator``): ``joint_trajectory_in``
(trajectory_msgs/JointTrajectory) in, the compensated trajectory out on ``joint_trajectory`` (remap it
onto a ros2_control JointTrajectoryController's ``~/joint_trajectory``); both relative, so a namespace
moves them. The calibration comes from the ``calibration`` file parameter or from the latched
``tolerance_calibration`` topic (the calibration file's content, SI), and can be swapped without a restart;
without one, trajectories pass through and the node says so. Flagged points follow ``on_flag``; every
refusal is logged and reported on /diagnostics. A calibration is put in force only when the node's gate
admits it (``services.guards``: its correction within ``max_joint_correction`` / ``max_tool_correction``,
signed by a trusted key when ``trusted_calibration_keys`` is set), and a point whose compensation would
change a joint by more than the envelope is flagged. The logic is ``services.trajectory``."""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from ..core.calibration.calibration_file import load_calibration
from ..services.trajectory import ON_FLAG, TrajectoryError, TrajectoryLogic
from .common import (CALIBRATION_TOPIC, LATCHED_QOS, STATUS_QOS, calibration_gate, calibration_in_force, declare,
                     follow_robot, guarded, robot_set, run, status_name)


class TrajectoryCompensator(Node):
    NODE_NAME = "tolerance_trajectory_compensator"

    def __init__(self, **node_options):
        super().__init__(self.NODE_NAME, **node_options)
        self.setup()

    def setup(self):
        """Parameters, robots, files, publishers, subscriptions and timers: what a managed node's configure does."""
        robot = declare(self, "robot", "gao2023_7dof", "robot: shipped name, robot file, or robot_description")
        self.calibration_file = declare(self, "calibration", "", "calibration file (tolerance-ros calibrate); empty "
                                                                 "waits for tolerance_calibration")
        self.on_flag = declare(self, "on_flag", "reject", "a point out of reach, near a singularity or out of limits: "
                                                          "reject (the whole trajectory is not sent) or nominal (that "
                                                          "point is sent as planned)")
        self.match = declare(self, "match", "pose", "match the tool's pose (pose) or its point (position)")
        if self.on_flag not in ON_FLAG:
            raise ValueError(f"on_flag: expected one of {list(ON_FLAG)}, got {self.on_flag!r}")
        if self.match not in ("pose", "position"):
            raise ValueError(f"match: expected pose or position, got {self.match!r}")
        period = declare(self, "report_period", 1.0, "seconds between diagnostics", (0.01, 3600.0))
        self.gate = calibration_gate(self)
        self.robots = robot_set(self, [robot], robot)
        self.logic = None
        self.calibration_text = None
        self.out = self.create_publisher(JointTrajectory, "joint_trajectory", STATUS_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(JointTrajectory, "joint_trajectory_in", guarded(self, self.on_trajectory), STATUS_QOS,
                                 raw=True)
        self.create_subscription(String, CALIBRATION_TOPIC, guarded(self, self.on_calibration), LATCHED_QOS)
        self.create_timer(period, guarded(self, self.publish_status))
        follow_robot(self, self.robots, self.start)

    def start(self, model):
        self.logic = TrajectoryLogic(model, on_flag=self.on_flag, match=self.match, envelope=self.gate.envelope)
        if self.calibration_file:
            cal = load_calibration(self.calibration_file, model)
            check = self.gate.admit(cal, model, self.calibration_file)   # refused: the node does not start
            self.logic.set_calibration(cal, self.calibration_file)
            self.get_logger().info(self.gate.swap(cal, self.calibration_file, check))
        if self.calibration_text is not None:
            self.on_calibration(String(data=self.calibration_text))
        self.get_logger().info(f"compensating trajectories of {model.name}: "
                               + (self.logic.source or "no calibration yet, passing them through"))

    def on_calibration(self, msg):
        """A calibration from the graph replaces the current one; one that does not fit the robot, or that the
        gate refuses, is refused (logged, and said on /diagnostics) and the current one stays."""
        self.calibration_text = msg.data
        if self.logic is None:
            return
        calibration_in_force(self, self.logic, msg.data, "the current one stays")

    def on_trajectory(self, raw):
        """A serialized JointTrajectory in, its compensation out (both as bytes: ``services.trajectory_cdr``)."""
        if self.logic is None:
            self.get_logger().error("trajectory refused: the robot is not known yet (robot_description)")
            return
        try:
            out, res = self.logic.compensate_raw(raw)
        except TrajectoryError as exc:
            self.get_logger().error(f"trajectory refused: {exc}")
            self.logic.counts["rejected"] += 1
            return
        if out is None:
            self.get_logger().error(res["message"])
            return
        if res["flagged"]:
            self.get_logger().warning(res["message"] + ": " + "; ".join(f"point {i}: {r}" for i, r in
                                                                     list(res["reasons"].items())[:5]))
        self.out.publish(out)

    def publish_status(self):
        d = self.logic.diagnostic() if self.logic is not None else \
            {"level": 1, "message": "waiting for robot_description", "values": {}}
        refused = self.gate.refusal_message()
        if refused is not None:
            d["level"], d["message"] = max(d["level"], 1), refused
        d["values"].update(self.gate.diagnostic_values())
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [DiagnosticStatus(level=bytes([d["level"]]), name=status_name(self, "trajectory compensator"),
                                       message=d["message"], hardware_id=self.logic.model.name if self.logic else "",
                                       values=[KeyValue(key=k, value=v) for k, v in d["values"].items()])]
        self.diag_pub.publish(arr)


def main(args=None):
    run(TrajectoryCompensator, args)


if __name__ == "__main__":
    main()
