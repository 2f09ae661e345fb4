"""A calibrated UR arm for its ROS 2 driver: with no calibration, UR's default kinematics of the arm; calibrated, the
description built from the file (a URDF read by pinocchio, as the driver's robot_state_publisher would) puts tool0
where the calibrated robot does; another arm is refused."""
import numpy as np
import pinocchio as pin
import pytest
import yaml

from tolerance_ros.core.calibration.mechanism import calibrated_mechanism
from tolerance_ros.core.models import ModelError
from tolerance_ros.core.programs import ur_kinematics as uk
from tolerance_ros.testing.programs import as_built, robot

# UR's default kinematics of the UR5 (Universal_Robots_ROS2_Description, config/ur5/default_kinematics.yaml)
UR5_DEFAULT = {"shoulder": [0, 0, 0.089159, 0, 0, 0], "upper_arm": [0, 0, 0, np.pi / 2, 0, 0],
               "forearm": [-0.425, 0, 0, 0, 0, 0], "wrist_1": [-0.39225, 0, 0.10915, 0, 0, 0],
               "wrist_2": [0, -0.09465, 0, np.pi / 2, 0, 0], "wrist_3": [0, 0.0823, 0, -np.pi / 2, 0, 0]}


@pytest.fixture(scope="module")
def ur5():
    return robot("ur5")


def _urdf(doc) -> str:
    """The chain of ur_description's ur_macro.xacro, base_link to tool0, with ``doc``'s origins."""
    def origin(name):
        e = doc[name]
        return f'<origin xyz="{e["x"]!r} {e["y"]!r} {e["z"]!r}" rpy="{e["roll"]!r} {e["pitch"]!r} {e["yaw"]!r}"/>'
    links = ["base_link", "base_link_inertia", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
             "wrist_2_link", "wrist_3_link", "flange", "tool0"]
    joints = ['<joint name="base_link-base_link_inertia" type="fixed"><parent link="base_link"/>'
              '<child link="base_link_inertia"/><origin xyz="0 0 0" rpy="0 0 3.141592653589793"/></joint>']
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint"]
    for k, (jn, ln) in enumerate(zip(names, uk.LINKS)):
        joints.append(f'<joint name="{jn}" type="revolute"><parent link="{links[k + 1]}"/><child link="{links[k + 2]}"/>'
                      f'{origin(ln)}<axis xyz="0 0 1"/><limit lower="-6.3" upper="6.3" effort="1" velocity="1"/>'
                      f'</joint>')
    joints.append('<joint name="wrist_3-flange" type="fixed"><parent link="wrist_3_link"/><child link="flange"/>'
                  '<origin xyz="0 0 0" rpy="0 -1.5707963267948966 -1.5707963267948966"/></joint>')
    joints.append('<joint name="flange-tool0" type="fixed"><parent link="flange"/><child link="tool0"/>'
                  '<origin xyz="0 0 0" rpy="1.5707963267948966 0 1.5707963267948966"/></joint>')
    return ('<robot name="ur">' + "".join(f'<link name="{n}"/>' for n in links) + "".join(joints) + "</robot>")


def _tool0(urdf_text, q):
    model = pin.buildModelFromXML(urdf_text)
    data = model.createData()
    fid = model.getFrameId("tool0")
    out = []
    for row in q:
        pin.framesForwardKinematics(model, data, row)
        out.append(data.oMf[fid].homogeneous.copy())
    return np.array(out)


def test_no_calibration_gives_urs_default_kinematics(ur5):
    doc = uk.kinematics(ur5, ur5, "calib_0")["kinematics"]
    for name, values in UR5_DEFAULT.items():
        got = [doc[name][k] for k in ("x", "y", "z", "roll", "pitch", "yaw")]
        np.testing.assert_allclose(got, values, atol=2e-11, err_msg=name)


def test_the_description_built_from_the_file_is_the_calibrated_robot(ur5, tmp_path):
    cal = as_built(ur5, 2e-4, 5e-4, seed=9, base=[3e-4, -2e-4, 1e-4, 4e-4, -3e-4, 2e-4])
    chain = cal.calibrated_chain(ur5)
    result = uk.kinematics(ur5, chain, "calib_1")
    path = tmp_path / "k.yaml"
    path.write_text(uk.text(result, ["test"]))
    doc = yaml.safe_load(path.read_text())["kinematics"]                 # as the description reads it
    q = ur5.sample_joints(50, 3)
    ours = chain.fk(q)
    theirs = _tool0(_urdf(doc), q)            # base_link of the description is the model's base frame here
    assert np.abs(ours - theirs).max() < 1e-9
    nominal = _tool0(_urdf(uk.kinematics(ur5, ur5, "x")["kinematics"]), q)
    assert np.abs(nominal[:, :3, 3] - ours[:, :3, 3]).max() > 5e-4     # the calibration matters: it is carried


def test_another_arm_is_refused(ur5):
    with pytest.raises(ModelError, match="not UR's|do not turn"):
        uk.fit_convention(robot("fanuc"))
    bent = calibrated_mechanism(ur5, np.zeros(ur5.n_params))
    bent.joint_limits = ur5.joint_limits
    lengths, C = uk.fit_convention(bent)
    np.testing.assert_allclose(lengths, [0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823], atol=1e-9)
