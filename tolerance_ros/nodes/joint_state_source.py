"""Joint-state source (node ``tolerance_joint_state_source``; a stand-in for the robot, or used with the
standard ``joint_state_publisher``): publishes sensor_msgs/JointState on ``joint_states`` from a
campaign, random or selected (index F) configurations. The robot may come from ``robot_description``."""
from __future__ import annotations

from rclpy.node import Node
from sensor_msgs.msg import JointState

from ..core.campaign import load_campaign
from ..services.joint_source import JointStateSequence
from .common import MEASUREMENT_QOS, declare, follow_robot, guarded, robot_set, run


class JointStateSource(Node):
    NODE_NAME = "tolerance_joint_state_source"

    def __init__(self, **node_options):
        super().__init__(self.NODE_NAME, **node_options)
        self.setup()

    def setup(self):
        """Parameters, robots, files, publishers, subscriptions and timers: what a managed node's configure does."""
        robot = declare(self, "robot", "gao2023_7dof", "robot: shipped name, robot file, or robot_description")
        self.mode = declare(self, "mode", "random", "campaign | random | selected (highest pose-selection index F)")
        self.campaign = declare(self, "campaign", "", "campaign config (mode 'campaign'): shipped name or path")
        self.count = declare(self, "count", 100, "configurations for modes random and selected")
        self.seed = declare(self, "seed", 0, "seed of the random and selected modes")
        self.dwell = declare(self, "dwell", 0.0, "seconds at each configuration; 0 takes the campaign's dwell (or 2 s)")
        rate = declare(self, "rate", 50.0, "publishing rate, Hz")
        self.loop = declare(self, "loop", False, "repeat the sequence instead of holding the last configuration")
        self.robots = robot_set(self, [robot], robot)
        self.sequence = None
        self.publisher = self.create_publisher(JointState, "joint_states", MEASUREMENT_QOS)
        self.timer = self.create_timer(1.0 / rate, guarded(self, self.publish_joint_state))
        follow_robot(self, self.robots, self.start, check=self.sequence_for)

    def sequence_for(self, model):
        """The configurations to publish for ``model`` (CampaignError when the campaign does not fit it)."""
        camp = load_campaign(self.campaign, model) if self.campaign else None
        return JointStateSequence(model, self.mode, camp, self.count, self.seed, self.dwell or None, self.loop)

    def start(self, model):
        """The sequence of the current robot (again, when robot_description changes)."""
        self.sequence = self.sequence_for(model)
        self.names = list(model.joint_names)
        self.t0 = self.get_clock().now()
        self.finished_logged = False
        self.get_logger().info(f"{self.mode}: {len(self.sequence)} configurations of {model.name}, "
                               f"{self.sequence.dwell:g} s each")

    def publish_joint_state(self):
        if self.sequence is None:
            return
        now = self.get_clock().now()
        step, label, q, finished = self.sequence.at((now - self.t0).nanoseconds * 1e-9)
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
