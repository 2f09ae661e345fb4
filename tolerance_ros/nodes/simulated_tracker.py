"""Simulated laser tracker (node ``tolerance_simulated_tracker``): an as-built robot drawn within a
tolerance budget (seeded), measurement noise and a base-frame offset; subscribes to ``joint_states``
and publishes ``measured_pose`` (PoseStamped, tracker frame) stamped like the joint state, or, with
``rate`` > 0, streams at that rate while the robot moves (readings between joint states at the joints of
their tick) stamped ``latency`` s late, as a real tracker does. The robot may come from
``robot_description``."""
from __future__ import annotations

from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from ..core.budget import tolerance_vector
from ..core.geometry import transform
from ..core.geometry import matrices_to_quat
from ..core.ingest import IngestError, stamp_seconds
from ..services.tracker import SimulatedTracker, stamp_fields
from .common import MEASUREMENT_QOS, declare, follow_robot, guarded, robot_set, run


class SimulatedTrackerNode(Node):
    NODE_NAME = "tolerance_simulated_tracker"

    def __init__(self, **node_options):
        super().__init__(self.NODE_NAME, **node_options)
        self.setup()

    def setup(self):
        """Parameters, robots, files, publishers, subscriptions and timers: what a managed node's configure does."""
        robot = declare(self, "robot", "gao2023_7dof", "robot: shipped name, robot file, or robot_description")
        self.budget_spec = declare(self, "budget", "gao2023_delta2", "budget within which the as-built errors are "
                                                                     "drawn")
        self.seed = declare(self, "seed", 0, "seed of the as-built robot and of the noise", (0, 2 ** 31 - 1))
        self.noise = (declare(self, "noise_position", 1e-5, "tracker position noise (1 sigma), m", (0.0, 1.0)),
                      declare(self, "noise_orientation", 1e-5, "tracker orientation noise (1 sigma), rad", (0.0, 1.0)))
        base = declare(self, "tracker_to_base", [0.0] * 6,
                       "pose of the robot base in the tracker frame, [x y z roll pitch yaw] (m, rad)")
        self.frame_id = declare(self, "frame_id", "tracker", "frame_id of the measured poses")
        self.every = declare(self, "measure_every", 1, "measure every n-th joint state", (1, 1_000_000))
        self.rate = declare(self, "rate", 0.0, "stream at this rate, Hz (0: one reading per measured joint state)",
                            (0.0, 100_000.0))
        self.latency = declare(self, "latency", 0.0, "streaming: how late the readings are stamped, s", (0.0, 10.0))
        self.T_tracker_base = transform(base[:3], base[3:])
        self.robots = robot_set(self, [robot], robot)
        self.sim = None
        self.pub = self.create_publisher(PoseStamped, "measured_pose", MEASUREMENT_QOS)
        self.create_subscription(JointState, "joint_states", guarded(self, self.on_joint_state), MEASUREMENT_QOS)
        self.count = 0
        follow_robot(self, self.robots, self.start, check=self.tolerances)

    def tolerances(self, model):
        """The budget's tolerances for ``model``: a budget, or uniform:LENGTH,ANGLE (BudgetError when it does not fit
        the robot)."""
        return tolerance_vector(self.budget_spec, model)

    def start(self, model):
        """Draw the as-built robot of the current model (again, when robot_description changes)."""
        self.sim = SimulatedTracker(model, self.tolerances(model), self.seed, *self.noise, self.T_tracker_base)
        self.get_logger().info(f"simulating {model.name} built within {self.budget_spec} (seed {self.seed})")

    def on_joint_state(self, msg):
        self.count += 1
        if self.sim is None or (self.count - 1) % self.every:
            return
        try:
            if self.rate > 0:
                t = stamp_seconds(msg.header.stamp)
                readings = self.sim.stream(t, self.sim.joint_order(msg.name, msg.position), self.rate, self.latency)
                for stamp, T in readings:
                    self.publish(stamp_fields(stamp), T[:3, 3], matrices_to_quat(T[None, :3, :3])[0])
                return
            _, p, q = self.sim.on_joint_state_msg(msg)
        except IngestError as exc:
            self.get_logger().warning(f"joint state ignored: {exc}", throttle_duration_sec=1.0)
            return
        self.publish((msg.header.stamp.sec, msg.header.stamp.nanosec), p, q)

    def publish(self, stamp, p, q):
        """A reading: stamp (sec, nanosec), position (3,) m, quaternion x y z w, tracker frame."""
        out = PoseStamped()
        out.header.stamp.sec, out.header.stamp.nanosec = int(stamp[0]), int(stamp[1])
        out.header.frame_id = self.frame_id
        out.pose.position.x, out.pose.position.y, out.pose.position.z = (float(v) for v in p)
        o = out.pose.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in q)
        self.pub.publish(out)


def main(args=None):
    run(SimulatedTrackerNode, args)


if __name__ == "__main__":
    main()
