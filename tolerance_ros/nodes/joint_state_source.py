"""Joint-state publisher of the suite (node ``tolerance_joint_state_source``, so it cannot clash with
the standard ``joint_state_publisher``): publishes sensor_msgs/JointState on ``joint_states``."""
from __future__ import annotations

from rclpy.node import Node
from sensor_msgs.msg import JointState

from ..core.campaign import load_campaign
from ..services.joint_source import JointStateSequence
from ..core.models import load_robot
from .common import MEASUREMENT_QOS, declare, run


class JointStateSource(Node):
    def __init__(self, **node_options):
        super().__init__("tolerance_joint_state_source", **node_options)
        robot = declare(self, "robot", "gao2023_7dof", "robot config: shipped name or YAML/URDF path")
        mode = declare(self, "mode", "random", "campaign | random | selected (highest pose-selection index F)")
        campaign = declare(self, "campaign", "", "campaign config (mode 'campaign'): shipped name or path")
        count = declare(self, "count", 100, "configurations for modes random and selected")
        seed = declare(self, "seed", 0, "seed of the random and selected modes")
        dwell = declare(self, "dwell", 0.0, "seconds at each configuration; 0 takes the campaign's dwell (or 2 s)")
        rate = declare(self, "rate", 50.0, "publishing rate, Hz")
        loop = declare(self, "loop", False, "repeat the sequence instead of holding the last configuration")
        self.model = load_robot(robot)
        camp = load_campaign(campaign, self.model) if campaign else None
        self.sequence = JointStateSequence(self.model, mode, camp, count, seed, dwell or None, loop)
        self.publisher = self.create_publisher(JointState, "joint_states", MEASUREMENT_QOS)
        self.start = self.get_clock().now()
        self.finished_logged = False
        self.timer = self.create_timer(1.0 / rate, self.publish_joint_state)
        self.get_logger().info(f"{mode}: {len(self.sequence)} configurations of {self.model.name}, "
                               f"{self.sequence.dwell:g} s each, {rate:g} Hz")

    def publish_joint_state(self):
        now = self.get_clock().now()
        step, label, q, finished = self.sequence.at((now - self.start).nanoseconds * 1e-9)
        msg = JointState()
        msg.header.stamp = now.to_msg()
        msg.name = list(self.model.joint_names)
        msg.position = [float(v) for v in q]
        self.publisher.publish(msg)
        if finished and not self.finished_logged:
            self.finished_logged = True
            self.get_logger().info("sequence finished; holding the last configuration")


def main(args=None):
    run(JointStateSource, args)


if __name__ == "__main__":
    main()
