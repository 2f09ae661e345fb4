"""Shared pieces of the nodes: topic names, QoS profiles, parameters with descriptors, the robots a node
serves (including ``robot_description``), a last-resort handler for every callback, the main loop.

Every topic is relative (``tolerance/...``, ``joint_states``, ``robot_description``), so a namespace
moves the whole suite; ``/diagnostics`` is the one global topic. QoS profiles, named for what they
carry, all reliable with keep-last history: service requests (depth 10), service responses and
progress (100, so that bursts are not dropped), measurements (joint states and measured poses, 100),
status (predicted bound, accuracy report, markers, 10), and the latched topics (budget and
robot_description: depth 1, transient local, so a late subscriber gets the latest one, as
robot_state_publisher publishes it); /diagnostics uses the default profile, as the aggregator expects.

Parameters are read once, at start (a managed node's configure): they are declared read-only, with their
ranges in the descriptor, so that ``ros2 param set`` is refused with the reason instead of being accepted
and ignored. A calibration is put in force only through ``calibration_in_force`` (the node's
``services.guards.CalibrationGate``: trusted signatures, correction envelope; old -> new logged).
"""
from __future__ import annotations

import signal
import sys
import threading

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterUninitializedException
from rclpy.executors import ExternalShutdownException
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args
from std_msgs.msg import String

from ..core.budget import BudgetError
from ..core.campaign import CampaignError
from ..core.calibration.envelope import MAX_JOINT_CORRECTION, MAX_TOOL_CORRECTION, Envelope
from ..core.models import ModelError, warmup
from ..services.contracts import ContractError
from ..services.dependencies import MissingDependency, require
from ..services.guards import CalibrationGate, CalibrationRefused
from ..services.robots import RobotSet

SERVICE_REQUEST_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
SERVICE_RESPONSE_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
MEASUREMENT_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
"""Joint states and tracker points: 1 s of a 1 kHz stream is kept while a callback runs late."""
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
LATCHED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
BUDGET_QOS = ROBOT_DESCRIPTION_QOS = LATCHED_QOS

PREFIX = "tolerance"  # relative: under the node's namespace
JACOBIAN_TOPIC = f"{PREFIX}/compute_error_jacobian"
ALLOCATE_TOPIC = f"{PREFIX}/allocate_tolerances"
CALIBRATE_TOPIC = f"{PREFIX}/calibrate"
CONTACT_TOPIC = f"{PREFIX}/contact"     # requests to latch the joint state as a contact (calibration from contact)
CALIBRATION_TOPIC = "tolerance_calibration"  # latched: the calibration in force (a calibration file's text, SI)


READ_AT_START = "read once at start (configure): set it at launch (-p, a parameters file); ros2 param set is refused"


def declare(node, name, default, description, bounds=None):
    """Declare a read-only parameter with a description, a default and (``bounds``: (low, high), inclusive, in
    the parameter's unit) its range in the descriptor; return its value. ``default`` may be a
    ``Parameter.Type`` (an array that is empty unless set: its value is then []). A parameter declared before
    (a managed node configured again) keeps its value."""
    if not node.has_parameter(name):
        _declare(node, name, default, description, bounds)
    try:
        return node.get_parameter(name).value
    except ParameterUninitializedException:
        return []


def _declare(node, name, default, description, bounds):
    desc = ParameterDescriptor(description=description, read_only=True, additional_constraints=READ_AT_START)
    if bounds is not None:
        if isinstance(default, float):
            desc.floating_point_range = [FloatingPointRange(from_value=float(bounds[0]), to_value=float(bounds[1]),
                                                            step=0.0)]
        else:
            desc.integer_range = [IntegerRange(from_value=int(bounds[0]), to_value=int(bounds[1]), step=0)]
    node.declare_parameter(name, default, desc)


def require_packages(node, modules):
    """Refuse to start (MissingDependency, naming the package and how to install it) when a package the node
    imports later is missing (``services.dependencies``)."""
    require(modules, node.get_fully_qualified_name())


def calibration_gate(node) -> CalibrationGate:
    """The node's CalibrationGate from its parameters ``max_joint_correction`` (rad), ``max_tool_correction``
    (m) and ``trusted_calibration_keys`` (Ed25519 public keys, PEM files)."""
    max_joint = declare(node, "max_joint_correction", MAX_JOINT_CORRECTION,
                        "correction envelope: largest change of a revolute joint a calibration may make (over its "
                        "campaign's postures and the joint range) and the compensator may send for one point, rad",
                        (1e-6, 3.14159))
    max_tool = declare(node, "max_tool_correction", MAX_TOOL_CORRECTION,
                       "correction envelope: largest displacement of the tool point a calibration may make (and "
                       "largest change of a prismatic joint), m", (1e-6, 1.0))
    keys = declare(node, "trusted_calibration_keys", Parameter.Type.STRING_ARRAY,
                   "Ed25519 public keys (PEM files): when set, only calibrations signed by one of them are put in "
                   "force; unset: signatures are not required")
    if keys:
        require_packages(node, ["cryptography"])
    return CalibrationGate(Envelope(max_joint, max_tool), [k for k in keys if k])


def calibration_in_force(node, logic, text, keeps: str, source=None):
    """The Calibration of ``text`` (from ``CALIBRATION_TOPIC``) put in force with ``logic.set_calibration`` once
    ``node.gate`` admits it (logged old -> new); None, logged, when it does not fit ``logic.model`` or the gate
    refuses it (``keeps`` says what stays)."""
    from ..core.calibration.calibration_file import calibration_from_text
    source = source or CALIBRATION_TOPIC
    try:
        cal = calibration_from_text(text, logic.model)
        check = node.gate.admit(cal, logic.model, source)
        logic.set_calibration(cal, source)
    except ValueError as exc:  # CalibrationError and CalibrationRefused included
        if not isinstance(exc, CalibrationRefused):  # refused while reading it: said on /diagnostics too
            node.gate.record(str(exc)[:400], None, source)
        node.get_logger().error(f"calibration on {CALIBRATION_TOPIC} refused, {keeps}: {exc}")
        return None
    node.get_logger().info(node.gate.swap(cal, source, check))
    return cal


def take_latest(subscription):
    """The newest message waiting on a subscription that no executor spins (serialized bytes), or None; the older
    ones are dropped. It calls rclpy's own ``subscription.handle.take_message(msg_type, raw)`` (rclpy internals,
    Jazzy): ``test/nodes/test_guards_ros.py::test_take_latest_reads_rclpys_subscription_handle`` fails when rclpy
    changes it."""
    raw = None
    with subscription.handle:
        while (taken := subscription.handle.take_message(subscription.msg_type, True)) is not None:
            raw = taken[0]
    return raw


def guarded(node, callback):
    """``callback`` with a last-resort handler: any exception is logged (type and message, at most once a
    second) and counted in ``node.callback_errors``; the node keeps serving."""
    def run(*args):
        try:
            return callback(*args)
        except Exception as exc:  # the last resort: nothing a message does may stop the node
            node.callback_errors = getattr(node, "callback_errors", 0) + 1
            node.get_logger().error(f"{callback.__name__}: {type(exc).__name__}: {str(exc)[:300]}",
                                    throttle_duration_sec=1.0)
    run.__name__ = callback.__name__
    return run


def served_robots(node) -> tuple:
    """(``robots``, ``default_robot``) of a node that serves requests for robots (scipy required): its
    parameters, declared."""
    require_packages(node, ["scipy"])
    specs = declare(node, "robots", ["gao2023_7dof"], "robots served: shipped names, robot files, or "
                                                      "robot_description (the URDF on that topic)")
    return specs, declare(node, "default_robot", "gao2023_7dof", "robot used when a request names none")


def robot_set(node, specs, default) -> RobotSet:
    """The robots a node serves, with the ``tip_link`` / ``base_link`` parameters for its URDF robots (a URDF file or
    ``robot_description``) (MissingDependency when the reader of a URDF robot, pinocchio, is missing).
    The compiled kernels are prepared in the background (``core.models.warmup``): the node serves from the
    numpy path at once and switches to them when they are loaded (compiled first in a child process when
    the cache is cold), so that no request waits for a compilation."""
    tip = declare(node, "tip_link", "", "URDF robots (a file or robot_description): link the chain ends in (empty: "
                                        "the only moving leaf)")
    base = declare(node, "base_link", "", "URDF robots (a file or robot_description): link the chain starts from "
                                          "(empty: the URDF root)")
    if "robot_description" in list(specs) + [default]:
        require_packages(node, ["pinocchio"])   # URDF robots: the description arrives later, its reader must be there
    try:
        robots = RobotSet(specs, default, tip or None, base or None)
    except ModuleNotFoundError as exc:          # a URDF robot file without pinocchio, say
        require_packages(node, [exc.name or str(exc)])
        raise
    needs = [getattr(m, "kernel_family", None) for m in robots.models.values()] + ["zonotope"]
    state = warmup.start(background=True, log=node.get_logger().info, needs=[f for f in needs if f])
    if state == "compiling":
        node.get_logger().info("compiling the kernels in the background (an empty cache: about a minute); the numpy "
                               "path answers meanwhile")
    for model in robots.models.values():
        model.warm_up()
    return robots


def follow_robot_description(node, robots: RobotSet, on_change=None, check=None):
    """Subscribe to ``robot_description`` (URDF text, latched) when the node takes its robot from it.
    A new description replaces the model (logged); a malformed one, or one that ``check(model)`` refuses
    (BudgetError, CampaignError: the node's files do not fit it), is logged and the previous kept."""
    if not robots.from_description:
        return

    def on_robot_description(msg):
        try:
            said = robots.on_description(msg.data, check)
        except (ModelError, ContractError, BudgetError, CampaignError) as exc:
            node.get_logger().error(f"robot_description ignored, the previous robot stays: {exc}")
            return
        robots.models[robots.description_name].warm_up()
        (node.get_logger().warning if robots.chain_changed else node.get_logger().info)(said)
        if on_change is not None:
            on_change()

    node.create_subscription(String, "robot_description", guarded(node, on_robot_description), ROBOT_DESCRIPTION_QOS)
    node.get_logger().info(f"waiting for the robot on {node.resolve_topic_name('robot_description')}")


def follow_robot(node, robots: RobotSet, start, check=None):
    """For a node with one robot: ``start(model)`` now when the robot is known, and again with each new
    robot_description that ``check`` accepts (see ``follow_robot_description``)."""
    def restart():
        model = robots.single()
        if model is not None:
            start(model)

    follow_robot_description(node, robots, restart, check)
    restart()


def status_name(node, what: str) -> str:
    """DiagnosticStatus name with the node's namespace in it: '/arm_left/tolerance_ros: accuracy monitor'."""
    return f"{node.get_namespace().rstrip('/')}/tolerance_ros: {what}"


_interrupted = threading.Event()
_spinning = threading.Event()


def _interrupt_once(signum, frame):
    """The first Ctrl-C stops the node; later ones (``ros2 launch`` forwards one more) are ignored, so that
    clean-up is not interrupted. While the node spins, rclpy's own handler (which calls this one) has shut
    the context down and ``spin`` ends with ``ExternalShutdownException``: a KeyboardInterrupt raised there
    could land inside rclpy (a half-made executor Task, whose ``__del__`` then prints a traceback), so it is
    raised only before the spin (loading robots, warming up)."""
    _interrupted.set()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if not _spinning.is_set():
        raise KeyboardInterrupt


def run(node_factory, args=None):
    """Initialise rclpy, spin the node until Ctrl-C or an external shutdown, clean up. With ``--managed``
    among the program's own arguments the node is its lifecycle-managed version (``nodes.lifecycle``)."""
    signal.signal(signal.SIGINT, _interrupt_once)  # rclpy's own handler, installed by init, calls it after its own
    argv = sys.argv if args is None else list(args)
    if "--managed" in remove_ros_args(argv):
        from .lifecycle import managed
        node_factory = managed(node_factory)
    rclpy.init(args=args)
    node = None
    try:
        node = node_factory()
        _spinning.set()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except MissingDependency as exc:
        rclpy.logging.get_logger(getattr(node_factory, "NODE_NAME", "tolerance_ros")).fatal(str(exc))
        raise SystemExit(1) from None
    except RuntimeError:
        # A Ctrl-C that lands while pybind11 converts the arguments of an rclpy call (take_message, say)
        # reaches us as "Unable to convert call argument": it is still the Ctrl-C.
        if not _interrupted.is_set():
            raise
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if node is not None:
            close = getattr(node, "close", None)
            if close:
                close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
