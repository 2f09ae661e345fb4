"""The shipped SROS2 policy and its specialisation for a namespace (services/security.py), ROS-free: who may
publish what changes the robot, and the ros2 security commands of a keystore."""
import pytest

from tolerance_ros.services.security import (ENCLAVES, LAUNCH, OPERATOR, SUITE_NODES, SecurityError, enclave,
                                             enclave_paths, grants, keystore_plan, namespace, policy_path, remapping,
                                             resolve, specialise)

POLICY = policy_path().read_text()
CONTROLS = {"tolerance_calibration": "tolerance_accuracy_monitor", "tolerance_budget": "tolerance_allocator",
            "tolerance/calibrate/request": OPERATOR, "joint_trajectory": "tolerance_trajectory_compensator",
            "robot_description": None}


def test_namespaces_and_enclaves():
    assert [namespace(n) for n in ("", "/", "arm_left", "/arm_left/", "a/b")] == ["/", "/", "/arm_left", "/arm_left",
                                                                                "/a/b"]
    assert enclave("", "tolerance_error_model") == "/tolerance_error_model"
    assert enclave("arm_left", "tolerance_error_model") == "/arm_left/tolerance_error_model"
    for bad in ("arm-left", "/1arm", "a b"):
        with pytest.raises(SecurityError, match="is not a ROS name token"):
            namespace(bad)


def test_the_shipped_policy_has_an_enclave_per_node_and_the_operators():
    assert enclave_paths(POLICY) == [f"/{n}" for n in ENCLAVES]


@pytest.mark.parametrize("ns", ["/", "/arm_left", "/cell/arm"])
def test_in_any_namespace_only_one_enclave_may_publish_what_changes_the_robot(ns):
    text = specialise(POLICY, ns)
    base = "" if ns == "/" else ns
    assert enclave_paths(text) == [enclave(ns, n) for n in ENCLAVES]
    for topic, owner in CONTROLS.items():
        may = sorted(e.rsplit("/", 1)[1] for e in enclave_paths(text) if f"{base}/{topic}" in grants(text, e)["publish"])
        assert may == ([owner] if owner else []), (topic, may)
    monitor = grants(text, enclave(ns, "tolerance_accuracy_monitor"))
    assert f"{base}/tolerance_accuracy_monitor/get_parameters" in monitor["reply"]
    assert f"{base}/measured_pose/*" in monitor["subscribe"] and "/diagnostics" in monitor["publish"]
    assert not any(t.startswith("/arm_right") for t in monitor["subscribe"] | monitor["publish"])


def test_the_operator_and_launch_serve_their_own_nodes_anywhere_and_drive_only_the_suite():
    text = specialise(POLICY, "/arm")
    operator, launch = grants(text, "/arm/tolerance_operator"), grants(text, "/arm/tolerance_launch")
    assert "/*_ros2cli_*/get_type_description" in operator["reply"] and "/*launch_ros_*/get_parameters" in launch["reply"]
    assert {f"/arm/{n}/change_state" for n in SUITE_NODES} <= launch["request"] <= operator["request"]
    assert launch["publish"] == {"/rosout", "/parameter_events"}
    assert operator["publish"] == {"/rosout", "/parameter_events", "/arm/tolerance/compute_error_jacobian/request",
                                   "/arm/tolerance/allocate_tolerances/request", "/arm/tolerance/calibrate/request",
                                   "/arm/tolerance/contact"}
    assert LAUNCH in ENCLAVES


def test_a_remapped_topic_is_granted_under_its_new_name():
    frm, to = remapping("joint_trajectory:=/arm_controller/joint_trajectory")
    text = specialise(POLICY, "/arm", [(frm, to)])
    g = grants(text, "/arm/tolerance_trajectory_compensator")
    assert "/arm_controller/joint_trajectory" in g["publish"] and "/arm/joint_trajectory" not in g["publish"]
    for bad in ("joint_trajectory", "a:=", "a b:=c"):
        with pytest.raises(SecurityError, match="expected FROM:=TO"):
            remapping(bad)


def test_names_resolve_as_sros2_resolves_them():
    assert resolve("x/y", "/arm", "n") == "/arm/x/y" and resolve("~/s", "/arm", "n") == "/arm/n/s"
    assert resolve("/abs", "/arm", "n") == "/abs" and resolve("x", "/", "n") == "/x"


def test_the_keystore_plan_creates_each_enclave_then_its_permissions(tmp_path):
    text = specialise(POLICY, "/arm")
    plan = keystore_plan(tmp_path, {tmp_path / "p.xml": text}, new_keystore=True)
    assert plan[0] == ["ros2", "security", "create_keystore", str(tmp_path)] and len(plan) == 1 + 2 * len(ENCLAVES)
    assert plan[1] == ["ros2", "security", "create_enclave", str(tmp_path), "/arm/tolerance_joint_state_source"]
    assert plan[2] == ["ros2", "security", "create_permission", str(tmp_path), "/arm/tolerance_joint_state_source",
                       str(tmp_path / "p.xml")]
    assert keystore_plan(tmp_path, {tmp_path / "p.xml": text}, new_keystore=False)[0][2] == "create_enclave"
    with pytest.raises(SecurityError, match="not well-formed"):
        specialise("<policy>", "/")
