"""Shared pieces of the nodes: parameters with descriptors, QoS profiles, the main loop.

QoS profiles, named for what they carry, all reliable with keep-last history: service requests
(depth 10), service responses and progress (100, so that bursts are not dropped), measurements
(joint states and measured poses, 100), status (predicted bound, accuracy report, 10), and the
budget (depth 1, transient local, so a late subscriber gets the latest one); /diagnostics uses the
default profile (reliable, depth 10), as the diagnostic aggregator expects.
"""
from __future__ import annotations

import signal

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..core.models import load_robot

SERVICE_REQUEST_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
SERVICE_RESPONSE_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
MEASUREMENT_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
BUDGET_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)

SERVICE_NAMESPACE = "/tolerance"


def declare(node, name, default, description):
    """Declare a parameter with a description and a default; return its value."""
    node.declare_parameter(name, default, ParameterDescriptor(description=description))
    return node.get_parameter(name).value


def load_models(specs, default):
    """({robot name: model}, the default robot's name) for robot names or paths, each parsed once (the
    default is loaded too when it is not among ``specs``); a bad entry raises with its name."""
    loaded = {}
    for spec in list(specs) + [default]:
        if spec not in loaded:
            loaded[spec] = load_robot(spec)
    return {m.name: m for m in loaded.values()}, loaded[default].name


def run(node_factory, args=None):
    """Initialise rclpy, spin the node until Ctrl-C or an external shutdown, clean up.

    Under ``ros2 launch`` a Ctrl-C reaches a node twice (from the terminal and from launch); further
    SIGINTs are ignored once shutdown has begun, so that clean-up is not interrupted.
    """
    rclpy.init(args=args)
    node = None
    try:
        node = node_factory()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if node is not None:
            close = getattr(node, "close", None)
            if close:
                close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
