"""Joint-state source (node ``tolerance_joint_state_source``; a stand-in for the robot, or used with the
standard ``joint_state_publisher``): publishes sensor_msgs/JointState on ``joint_states`` from a
campaign, random or selected (index F) configurations. With ``compensated`` it stands in for a controller
that executes compensated motion: each configuration goes to the trajectory compensator as a one-point
JointTrajectory on ``joint_trajectory_in``, and what comes back on ``joint_trajectory`` is what it
publishes. The robot may come from ``robot_description``."""
from __future__ import annotations

import math

from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..core.accuracy.iso_paths import read_trajectory
from ..core.campaign import load_campaign
from ..services.joint_source import JointStateSequence
from .common import MEASUREMENT_QOS, STATUS_QOS, declare, follow_robot, guarded, robot_set, run


class JointStateSource(Node):
    NODE_NAME = "tolerance_joint_state_source"

    def __init__(self, **node_options):
        super().__init__(self.NODE_NAME, **node_options)
        self.setup()

    def setup(self):
        """Parameters, robots, files, publishers, subscriptions and timers: what a managed node's configure does."""
        robot = declare(self, "robot", "gao2023_7dof", "robot: shipped name, robot file, or robot_description")
        self.mode = declare(self, "mode", "random", "campaign | random | selected (highest pose-selection index F) | "
                                                    "trajectory (a joint trajectory file, the robot moving)")
        self.campaign = declare(self, "campaign", "", "campaign config (mode 'campaign'): shipped name or path")
        self.trajectory = declare(self, "trajectory", "", "joint trajectory file (mode 'trajectory'), e.g. from "
                                                          "tolerance-ros plan-campaign --path rectangle")
        self.count = declare(self, "count", 100, "configurations for modes random and selected", (1, 1_000_000))
        self.seed = declare(self, "seed", 0, "seed of the random and selected modes", (0, 2 ** 31 - 1))
        self.dwell = declare(self, "dwell", 0.0, "seconds at each configuration; 0 takes the campaign's dwell (or 2 s)",
                             (0.0, 86_400.0))
        rate = declare(self, "rate", 50.0, "publishing rate, Hz", (1e-3, 10_000.0))
        self.loop = declare(self, "loop", False, "repeat the sequence instead of holding the last configuration")
        self.compensated = declare(self, "compensated", False, "send each configuration through the trajectory "
                                                               "compensator and publish what comes back")
        if self.compensated and self.mode == "trajectory":
            raise ValueError("compensated: not with mode 'trajectory' (compensate the trajectory file first: "
                             "tolerance-ros compensate, or the trajectory_compensator node)")
        self.robots = robot_set(self, [robot], robot)
        self.sequence = None
        self.publisher = self.create_publisher(JointState, "joint_states", MEASUREMENT_QOS)
        self.commanded = None     # (step, joints) the compensator sent back for the configuration of ``step``
        self.sent_step = None
        if self.compensated:
            self.plan_pub = self.create_publisher(JointTrajectory, "joint_trajectory_in", STATUS_QOS)
            self.create_subscription(JointTrajectory, "joint_trajectory", guarded(self, self.on_compensated),
                                     STATUS_QOS)
        self.timer = self.create_timer(1.0 / rate, guarded(self, self.publish_joint_state))
        follow_robot(self, self.robots, self.start, check=self.sequence_for)

    def sequence_for(self, model):
        """The configurations to publish for ``model`` (CampaignError when the campaign does not fit it)."""
        camp = load_campaign(self.campaign, model) if self.campaign else None
        if self.mode == "trajectory" and not self.trajectory:
            raise ValueError("mode 'trajectory' needs the parameter trajectory (a joint trajectory file)")
        traj = read_trajectory(self.trajectory, model) if self.mode == "trajectory" else None
        return JointStateSequence(model, self.mode, camp, self.count, self.seed, self.dwell or None, self.loop,
                                  traj)

    def start(self, model):
        """The sequence of the current robot (again, when robot_description changes)."""
        self.sequence = self.sequence_for(model)
        self.names = list(model.joint_names)
        self.t0 = self.get_clock().now()
        self.finished_logged = False
        if self.sequence.trajectory is not None:
            traj = self.sequence.trajectory
            self.get_logger().info(f"trajectory {self.trajectory}: {len(traj.t)} knots of {model.name}, "
                                   f"{traj.cycles} cycle(s) of {traj.period:.2f} s")
        else:
            self.get_logger().info(f"{self.mode}: {len(self.sequence)} configurations of {model.name}, "
                                   f"{self.sequence.dwell:g} s each")

    def on_compensated(self, msg):
        """The compensator's answer to the configuration sent last: what the controller executes."""
        if not (msg.points and self.sent_step is not None and list(msg.joint_names) == self.names):
            return
        q = [float(v) for v in msg.points[0].positions]
        if len(q) != len(self.names) or not all(math.isfinite(v) for v in q):
            self.get_logger().warning(f"compensated command ignored: expected {len(self.names)} finite positions, "
                                      f"got {q[:12]}")
            return
        self.commanded = (self.sent_step, q)

    def publish_joint_state(self):
        if self.sequence is None:
            return
        now = self.get_clock().now()
        step, label, q, finished = self.sequence.at((now - self.t0).nanoseconds * 1e-9)
        if self.compensated:
            if step != self.sent_step:
                plan = JointTrajectory(joint_names=self.names,
                                       points=[JointTrajectoryPoint(positions=[float(v) for v in q])])
                plan.header.stamp = now.to_msg()
                self.plan_pub.publish(plan)
                self.sent_step = step
            if self.commanded is None or self.commanded[0] != step:
                return  # the compensated command of this configuration has not come back yet
            q = self.commanded[1]
        msg = JointState()
        msg.header.stamp = now.to_msg()
        msg.name = self.names
        msg.position = [float(v) for v in q]
        self.publisher.publish(msg)
        if finished and not self.finished_logged:
            self.finished_logged = True
            self.get_logger().info("sequence finished; holding the last configuration")


def main(args=None):
    run(JointStateSource, args)


if __name__ == "__main__":
    main()
