"""The launch and RViz files (ROS-free checks; the launches themselves run in test_ros2_cli.py)."""
import ast
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]


def test_the_rviz_layout_shows_the_robot_and_the_markers_on_relative_topics():
    doc = yaml.safe_load((ROOT / "config" / "tolerance.rviz").read_text())
    displays = {d["Class"]: d for d in doc["Visualization Manager"]["Displays"]}
    assert displays["rviz_default_plugins/RobotModel"]["Description Topic"]["Value"] == "robot_description"
    assert displays["rviz_default_plugins/RobotModel"]["Description Topic"]["Durability Policy"] == "Transient Local"
    assert displays["rviz_default_plugins/MarkerArray"]["Topic"]["Value"] == "tolerance/markers"


def test_every_topic_name_in_the_nodes_is_relative_but_diagnostics_and_tf():
    """A namespace must move the whole suite: no absolute topic literal in the nodes or services but the two
    that ROS keeps global by convention, /diagnostics and /tf_static."""
    for path in list((ROOT / "tolerance_ros" / "nodes").glob("*.py")) + list((ROOT / "tolerance_ros" / "services")
                                                                            .glob("*.py")):
        tree = ast.parse(path.read_text())
        inner = {id(n) for j in ast.walk(tree) if isinstance(j, ast.JoinedStr) for v in j.values[1:]
                 for n in ast.walk(v)}  # pieces after the start of an f-string continue a name
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in inner \
                    and node.value.startswith("/") and " " not in node.value and len(node.value) > 1:
                assert node.value in ("/diagnostics", "/tf_static"), f"{path.name}: absolute name {node.value!r}"


def test_the_two_arm_parameters_give_each_arm_its_own_budget():
    doc = yaml.safe_load((ROOT / "config" / "two_arms.yaml").read_text())
    left = doc["/arm_left/tolerance_accuracy_monitor"]["ros__parameters"]
    right = doc["/arm_right/tolerance_accuracy_monitor"]["ros__parameters"]
    assert (left["budget"], right["budget"]) == ("gao2023_delta1", "gao2023_delta2")
    assert {k.split("/")[1] for k in doc} == {"arm_left", "arm_right"}


def test_every_launch_file_takes_a_keystore_and_starts_each_node_in_its_enclave():
    """keystore:= in every launch file; every Node / LifecycleNode of the suite gets its enclave (security on only
    with a keystore: ``nodes/launch_security.py``)."""
    for path in sorted((ROOT / "launch").glob("*.launch.py")):
        text = path.read_text()
        tree = ast.parse(text)
        assert "keystore_argument()" in text, path.name
        calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") in
                 ("Node", "LifecycleNode")]
        for call in calls:
            env = [k for k in call.keywords if k.arg == "additional_env"]
            assert env and "enclave_env" in ast.unparse(env[0].value), (path.name, ast.unparse(call)[:120])
        if calls:
            assert "security_actions(" in text, path.name
        else:
            assert '"keystore": keystore' in text, path.name              # passed on to the suites it includes


def test_every_launch_file_takes_the_robot_and_its_tool_link_as_arguments():
    """Issue 49: robot:=, tip_link:=, base_link:=, budget:=, campaign:= in every launch file, each node's
    parameters laid over by the overrides of services/launch_robot.py (read at launch time)."""
    for path in sorted((ROOT / "launch").glob("*.launch.py")):
        text = path.read_text()
        assert "robot_arguments()" in text, path.name
        if "Node(" in text:
            assert "robot_parameters(context" in text and "OpaqueFunction(function=nodes)" in text, path.name
            assert "([robot[name]] if name in robot else [])" in text, path.name
        else:
            assert "**robot}" in text, path.name                           # passed on to the suites it includes
