"""Error-model server (node ``tolerance_error_model``): the JSON service ``compute_error_jacobian`` on
``/tolerance/compute_error_jacobian/request`` -> ``.../response`` (std_msgs/String, remappable), and
the predicted error bound at the current joint state on ``/tolerance/predicted_bound``."""
from __future__ import annotations

import json

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from ..core.budget import BudgetError, budget_from_dict
from ..core.contracts import ErrorModelService, Limits
from ..core.jsonio import dumps_fast
from ..core.models import load_robot
from .common import LATCHED_QOS, REQUEST_QOS, RESPONSE_QOS, SERVICE_NAMESPACE, declare, load_models, run

TOPIC = f"{SERVICE_NAMESPACE}/compute_error_jacobian"


class ErrorModelServer(Node):
    def __init__(self, **node_options):
        super().__init__("tolerance_error_model", **node_options)
        robots = declare(self, "robots", ["gao2023_7dof"], "robot configs served (names or paths)")
        default = declare(self, "default_robot", "gao2023_7dof", "robot used when a request names none")
        max_bytes = declare(self, "max_request_bytes", 1_000_000, "size cap of a request, bytes")
        max_poses = declare(self, "max_poses", 10_000, "size cap of a request, configurations")
        self.criterion = declare(self, "bound_criterion", "", "criterion of the predicted bound on joint states "
                                 "(paper | worst-case | rss); empty takes the budget's")
        models = load_models(list(robots) + [default])
        self.service = ErrorModelService(models, load_robot(default).name, Limits(max_bytes, max_poses))
        self.responses = self.create_publisher(String, f"{TOPIC}/response", RESPONSE_QOS)
        self.bound_pub = self.create_publisher(String, f"{SERVICE_NAMESPACE}/predicted_bound", REQUEST_QOS)
        self.create_subscription(String, f"{TOPIC}/request", self.on_request, REQUEST_QOS)
        self.create_subscription(JointState, "joint_states", self.on_joint_state, REQUEST_QOS)
        self.create_subscription(String, "tolerance_budget", self.on_budget, LATCHED_QOS)
        self.get_logger().info(f"serving {sorted(models)} on {TOPIC}/request")

    def on_request(self, msg):
        self.responses.publish(String(data=self.service.handle_text(msg.data)))

    def on_budget(self, msg):
        try:
            doc = json.loads(msg.data)
            robot = doc.get("robot")
            model = self.service.models.get(robot)
            if model is None:
                self.get_logger().warning(f"budget for unknown robot {robot!r} ignored")
                return
            self.service.current_budget = budget_from_dict(doc["budget"], dict(zip(model.param_names, model.param_kinds)))
        except (ValueError, KeyError, TypeError, BudgetError) as exc:
            self.get_logger().error(f"invalid budget message: {exc}")

    def on_joint_state(self, msg):
        found = self.service.bound_at(msg.name, msg.position, self.criterion or None)
        if found is None:
            return
        robot, crit, pos, ori = found
        out = {"stamp": msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, "robot": robot, "criterion": crit,
               "position_bound_m": pos, "orientation_bound_rad": ori}
        self.bound_pub.publish(String(data=dumps_fast(out)))


def main(args=None):
    run(ErrorModelServer, args)


if __name__ == "__main__":
    main()
