"""Shared pieces of the nodes: parameters with descriptors, QoS profiles, the main loop.

QoS choices: requests, responses, progress, measured poses and joint states are reliable with
keep-last history (depth 10 for requests and joint states, 100 for responses and measurements, so
that bursts are not dropped); the budget topic is reliable and transient-local with depth 1, so a
late subscriber gets the latest budget; /diagnostics uses the default profile (reliable, depth 10),
as the diagnostic aggregator expects.
"""
from __future__ import annotations

import signal

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..core.models import load_robot

REQUEST_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
RESPONSE_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
STREAM_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
LATCHED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

SERVICE_NAMESPACE = "/tolerance"


def declare(node, name, default, description):
    """Declare a parameter with a description and a default; return its value."""
    node.declare_parameter(name, default, ParameterDescriptor(description=description))
    return node.get_parameter(name).value


def load_models(names):
    """{name: model} for robot names or paths; a bad entry raises with its name."""
    return {load_robot(n).name: load_robot(n) for n in names}


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
