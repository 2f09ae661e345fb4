"""URDF chains: our batched FK and Jacobian against pinocchio on real URDFs from example-robot-data."""
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from helpers import example_urdf, pin_fk, pose_difference
from tolerance_ros.core.models import ModelError, URDFChain, load_robot

CASES = [("ur5_robot.urdf", "tool0"), ("panda.urdf", "panda_hand")]


def _perturbed_xml(text, joint, field, h):
    """The URDF text with ``<origin xyz>`` of ``joint`` moved by h along the parent frame's axis ``field``."""
    root = ET.fromstring(text)
    j = next(e for e in root.findall("joint") if e.get("name") == joint)
    org = j.find("origin")
    if org is None:
        org = ET.SubElement(j, "origin")
    vals = [float(v) for v in (org.get("xyz") or "0 0 0").split()]
    vals["xyz".index(field)] += h
    org.set("xyz", " ".join(repr(v) for v in vals))
    return ET.tostring(root, encoding="unicode")


def _turned_fk(text, tip, chain, q, joint, axis, h):
    """(n, 4, 4) pinocchio's pose of ``tip`` with the origin of ``joint`` turned by h about its own ``axis``
    (0, 1, 2: x, y, z): the joint placement times the turn, exact in pinocchio's SE3 (an rpy in the text would
    lose digits near pitch +-pi/2, where the UR5's shoulder origin sits)."""
    model = pin.buildModelFromXML(text)
    data = model.createData()
    jid = model.getJointId(joint)
    model.jointPlacements[jid] = model.jointPlacements[jid] * pin.SE3(pin.exp3(np.eye(3)[axis] * h), np.zeros(3))
    fid = model.getFrameId(tip)
    out = []
    for qk in q:
        pin.framesForwardKinematics(model, data, chain.pinocchio_configuration(qk))
        out.append(data.oMf[fid].homogeneous.copy())
    return np.array(out)


@pytest.mark.parametrize("name, tip", CASES)
def test_fk_matches_pinocchio(name, tip):
    path = example_urdf(name)
    chain = URDFChain(path, tip_link=tip)
    q = chain.sample_joints(8, 1)
    ref = pin_fk(path.read_text(), chain.tip_link, chain, q)
    assert np.allclose(chain.fk(q), ref, atol=1e-12)


@pytest.mark.parametrize("name, tip", CASES)
def test_jacobian_matches_differences_of_pinocchio_fk_on_edited_urdf(name, tip):
    """Each origin shift is perturbed in the URDF text itself and the file re-parsed by pinocchio; each origin
    turn in pinocchio's joint placement."""
    path = example_urdf(name)
    text = path.read_text()
    chain = URDFChain(path, tip_link=tip)
    q = chain.sample_joints(3, 2)
    J = chain.error_jacobian(q).J
    h = 1e-6
    for c, pname in enumerate(chain.param_names):
        joint, field = pname.rsplit(".", 1)
        if field == "offset":
            k = chain.joint_names.index(joint)
            e = np.zeros(chain.dof)
            e[k] = h
            Tp = pin_fk(text, chain.tip_link, chain, q + e)
            Tm = pin_fk(text, chain.tip_link, chain, q - e)
        elif field in ("rx", "ry", "rz"):
            axis = ("rx", "ry", "rz").index(field)
            Tp = _turned_fk(text, chain.tip_link, chain, q, joint, axis, h)
            Tm = _turned_fk(text, chain.tip_link, chain, q, joint, axis, -h)
        else:
            Tp = pin_fk(_perturbed_xml(text, joint, field, h), chain.tip_link, chain, q)
            Tm = pin_fk(_perturbed_xml(text, joint, field, -h), chain.tip_link, chain, q)
        ref = pose_difference(Tp, Tm) / (2 * h)
        assert np.allclose(J[:, :, c], ref, atol=1e-7), pname


def test_offset_columns_are_pinocchio_joint_jacobian():
    path = example_urdf("ur5_robot.urdf")
    chain = URDFChain(path, tip_link="tool0")
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    fid = model.getFrameId(chain.tip_link)
    q = chain.sample_joints(4, 5)
    J = chain.error_jacobian(q).J
    offsets = [chain.param_names.index(f"{j}.offset") for j in chain.joint_names]
    for k in range(4):
        pin.computeJointJacobians(model, data, chain.pinocchio_configuration(q[k]))
        pin.updateFramePlacements(model, data)
        Jp = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        cols = [model.idx_vs[model.getJointId(j)] for j in chain.joint_names]
        assert np.allclose(Jp[:, cols], J[k][:, offsets], atol=1e-12)


def test_names_units_and_limits():
    chain = URDFChain(example_urdf("ur5_robot.urdf"), tip_link="tool0")
    assert (chain.base_link, chain.tip_link) == ("world", "tool0")   # the URDF's root link: where FK is expressed
    assert chain.param_names[:7] == tuple(f"shoulder_pan_joint.{f}" for f in
                                          ("x", "y", "z", "rx", "ry", "rz", "offset"))
    assert chain.param_units[:7] == ("m", "m", "m", "rad", "rad", "rad", "rad")
    assert chain.joint_limits.shape == (6, 2)
    assert np.all(chain.joint_limits[:, 0] < chain.joint_limits[:, 1])


def test_branching_urdf_needs_a_tip_and_names_the_leaves():
    with pytest.raises(ModelError, match="LF_FOOT"):
        URDFChain(example_urdf("anymal-kinova.urdf"))
    chain = URDFChain(example_urdf("anymal-kinova.urdf"), tip_link="LF_FOOT")
    assert chain.dof == 3 and not chain.tip_chosen
    with pytest.raises(ModelError, match=r"chains end in the links \['ee_link', 'tool0'\]"):
        URDFChain(example_urdf("ur5_robot.urdf"))      # the fixed tool0 and ee_link both hang off wrist_3_link
    with pytest.raises(ModelError, match="panda_leftfinger"):
        URDFChain(example_urdf("panda.urdf"))


def test_a_single_leaf_is_taken_as_the_tip_and_said_so(tmp_path):
    root = ET.parse(example_urdf("ur5_robot.urdf")).getroot()
    for j in list(root.findall("joint")):
        if j.find("child").get("link") in ("ee_link", "base"):
            root.remove(j)
    for link in list(root.findall("link")):
        if link.get("name") in ("ee_link", "base"):
            root.remove(link)
    chain = URDFChain(ET.tostring(root, encoding="unicode"))
    assert chain.tip_link == "tool0" and chain.tip_chosen


def test_bad_urdf_inputs(tmp_path):
    with pytest.raises(ModelError, match="tip_link"):
        URDFChain(example_urdf("ur5_robot.urdf"), tip_link="no_such_link")
    with pytest.raises(ModelError, match="file not found"):
        URDFChain(tmp_path / "missing.urdf")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/>")
    with pytest.raises(ModelError, match="urdf"):
        URDFChain(bad)


def test_a_broken_urdf_says_why_in_the_error_and_nothing_on_stderr(tmp_path, capfd):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'><parent link='a'/>"
                   "<child link='missing'/></joint></robot>")
    with pytest.raises(ModelError, match=f"urdf \\({bad}\\): not a valid URDF") as exc:
        URDFChain(bad)
    assert "joint xml is not initialized" in str(exc.value) and ".cpp" not in str(exc.value)
    assert capfd.readouterr().err == ""


def test_yaml_robot_file_with_relative_urdf(tmp_path):
    src = example_urdf("ur5_robot.urdf")
    (tmp_path / "ur5.urdf").write_text(src.read_text())
    cfg = tmp_path / "ur5.yaml"
    cfg.write_text("name: ur5\nkind: urdf\nurdf: ur5.urdf\ntip_link: tool0\n")
    model = load_robot(cfg)
    assert model.name == "ur5" and model.dof == 6


def test_an_axis_of_any_finite_length_is_normalised_without_overflow():
    def two_links(axis):
        return (f"<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/>"
                f"<child link='b'/><axis xyz='{axis}'/><limit lower='-1' upper='1' effort='1' velocity='1'/></joint>"
                f"</robot>")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        chain = URDFChain(two_links("0 0 1e200"))
        diagonal = URDFChain(two_links("0 1.2711736833351983e+308 1.2711736833351983e+308"))  # length > max float
        tiny = URDFChain(two_links("3e-310 0 4e-310"))  # subnormal components, a length of 5e-310
    np.testing.assert_array_equal(chain._axes[0], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(diagonal._axes[0], [0.0, np.sqrt(0.5), np.sqrt(0.5)], rtol=1e-15)
    np.testing.assert_allclose(tiny._axes[0], [0.6, 0.0, 0.8], rtol=1e-12)
    with pytest.raises(ModelError, match="zero axis"):
        URDFChain(two_links("0 0 0"))


def _chain_urdf(joints, limits=None):
    """URDF text of revolute joints (name, parent link, child link), each at 0.1 m along z of its parent."""
    links = sorted({link for _, p, c in joints for link in (p, c)})
    text = '<robot name="r">' + "".join(f'<link name="{link}"/>' for link in links)
    for name, p, c in joints:
        lo, hi = (limits or {}).get(name, ("-1", "1"))
        text += (f'<joint name="{name}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
                 f'<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="{lo}" upper="{hi}" effort="1" '
                 f'velocity="1"/></joint>')
    return text + "</robot>"


def test_a_revolute_limit_whose_lower_is_above_its_upper_is_refused():
    text = _chain_urdf([("j1", "a", "b"), ("j2", "b", "c")], {"j2": ("1", "-1")})
    with pytest.raises(ModelError, match=r"joint 'j2': <limit lower=\"1\" upper=\"-1\">: the lower limit is above"):
        URDFChain(text)


def test_a_kinematic_cycle_is_refused_naming_its_joints():
    """a -> b -> c -> d with j2 turned b -> a: urdfdom rooted the tree at c and gave a model of j3 alone."""
    with pytest.raises(ModelError, match=r"joints \['j2', 'j1'\] form a kinematic cycle \(b -> a -> b\)"):
        URDFChain(_chain_urdf([("j1", "a", "b"), ("j2", "b", "a"), ("j3", "c", "d")]), tip_link="d")
    with pytest.raises(ModelError, match=r"link 'b' is the child of two joints, 'j1' and 'j2'"):
        URDFChain(_chain_urdf([("j1", "a", "b"), ("j2", "c", "b"), ("j3", "b", "d")]))


def test_a_byte_order_mark_gives_one_answer_from_a_file_and_from_text(tmp_path):
    from tolerance_ros.services.robots import RobotSet
    text = "\ufeff" + example_urdf("ur5_robot.urdf").read_text()
    path = tmp_path / "bom.urdf"
    path.write_text(text, encoding="utf-8")
    robots = RobotSet(["robot_description"], "robot_description", tip_link="tool0")
    robots.on_description(text)
    q = robots.single().sample_joints(3, 0)
    for chain in (URDFChain(path, tip_link="tool0"), URDFChain(text, tip_link="tool0")):
        np.testing.assert_array_equal(chain.fk(q), robots.single().fk(q))


@pytest.mark.parametrize("text, message", [
    ('<robot name="r"><link name="a">' + "<visual>" * 100_000 + "</visual>" * 100_000 + "</link></robot>",
     "elements nested deeper than 64 levels"),
    (_chain_urdf([(f"j{i}", f"l{i}", f"l{i + 1}") for i in range(1001)]), "1001 joints; a URDF may have at most 1000"),
    ('<!DOCTYPE r [<!ENTITY a "x">]><robot name="&a;"/>', r"entity declarations \(<!ENTITY ...>\) are not supported"),
])
def test_a_hostile_urdf_is_refused_before_pinocchio_reads_it(text, message, monkeypatch):
    def reads(*args, **kwargs):
        raise AssertionError("pinocchio was given the hostile URDF")
    monkeypatch.setattr(pin, "buildModelFromXML", reads)
    with pytest.raises(ModelError, match=message):
        URDFChain(text)


def test_a_urdf_file_is_bounded_and_utf8(tmp_path):
    big = tmp_path / "big.urdf"
    big.write_bytes(b"<robot name='r'>" + b" " * (9 * 1024 * 1024) + b"</robot>")
    with pytest.raises(ModelError, match=rf"{big}: \d+ bytes; a URDF may have at most 8388608 bytes"):
        URDFChain(big)
    latin = tmp_path / "latin.urdf"
    latin.write_bytes(b"<robot name='r'>\n<link name='caf\xe9'/></robot>")
    with pytest.raises(ModelError, match=rf"{latin}, line 2, column 16: not UTF-8 text"):
        URDFChain(latin)


FANUC = Path(__file__).resolve().parents[2] / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"


def test_origins_at_pitch_plus_minus_half_pi_keep_three_independent_rotation_errors():
    """The FANUC's joint_2 and joint_3 origins have pitch -pi/2 and +pi/2, where roll and yaw turn about the same
    axis: their turns rx, ry, rz about the origin's own axes are three independent columns (the joint's own
    axis, z here, is the offset's), and each is a unit turn about the origin frame's axis."""
    chain = URDFChain(FANUC)
    assert chain.origin_rpy[1, 1] == pytest.approx(-np.pi / 2) and chain.origin_rpy[2, 1] == pytest.approx(np.pi / 2)
    q = chain.sample_joints(40, 3)
    J = chain.error_jacobian(q).J
    for joint in ("joint_2", "joint_3"):
        cols = chain.param_index([f"{joint}.{f}" for f in ("rx", "ry", "rz")])
        s = np.linalg.svd(J[:, :, cols].reshape(-1, 3), compute_uv=False)
        assert s.min() > 0.3 * s.max(), (joint, s)
        rot = J[:, 3:, cols]                        # orientation rows: unit turn axes, mutually perpendicular
        np.testing.assert_allclose(np.einsum("nik,nil->nkl", rot, rot), np.broadcast_to(np.eye(3), (40, 3, 3)),
                                   atol=1e-12)


def _random_origins_urdf(rng, pitches):
    joints = []
    for k, pitch in enumerate(pitches):
        rpy = (float(rng.uniform(-np.pi, np.pi)), float(pitch), float(rng.uniform(-np.pi, np.pi)))
        axis = rng.normal(size=3)
        xyz = " ".join(map(repr, rng.uniform(-0.3, 0.3, 3).tolist()))
        joints.append(f'<joint name="j{k}" type="revolute"><parent link="l{k}"/><child link="l{k + 1}"/>'
                      f'<origin xyz="{xyz}" rpy="{" ".join(map(repr, rpy))}"/>'
                      f'<axis xyz="{" ".join(map(repr, (axis / np.linalg.norm(axis)).tolist()))}"/>'
                      f'<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>')
    links = "".join(f'<link name="l{k}"/>' for k in range(len(pitches) + 1))
    return f'<robot name="random">{links}{"".join(joints)}</robot>'


@pytest.mark.parametrize("seed", range(4))
def test_corrected_origins_round_trip_through_the_urdf_exactly(seed, tmp_path):
    """The calibrated URDF (each changed origin written as the rpy of its exact rotation) re-parsed by pinocchio
    gives the calibrated chain's poses, at pitch +-pi/2 and at random origins."""
    from tolerance_ros.core.calibration.calibrate import calibrated_mechanism
    from tolerance_ros.core.calibration.calibrated_robot import calibrated_urdf_text
    rng = np.random.default_rng(seed)
    pitches = [np.pi / 2, -np.pi / 2, rng.uniform(-1.5, 1.5), np.pi / 2 - 1e-9, rng.uniform(-1.5, 1.5)]
    text = _random_origins_urdf(rng, pitches)
    path = tmp_path / "r.urdf"
    path.write_text(text)
    chain = URDFChain(path)
    dx = rng.normal(0, 3e-3, chain.n_params)
    base = rng.normal(0, 1e-3, 6)
    q = chain.sample_joints(25, seed)
    want = calibrated_mechanism(chain, dx, base).fk(q)
    from tolerance_ros.core.identification import base_matrix
    np.testing.assert_allclose(want, base_matrix(base) @ chain.fk(q, dx), atol=1e-13, rtol=0)
    np.testing.assert_allclose(pin_fk(calibrated_urdf_text(chain, text, dx, base), chain.tip_link, chain, q), want,
                               atol=1e-13, rtol=0)


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace('<limit lower="-3.1416" upper="3.1416" effort="1" velocity="1"/></joint>\n  <joint name="joint_2"',
                         '<limit lower="0.5" upper="0.5" effort="1" velocity="1"/></joint>\n  <joint name="joint_2"'),
     "joint 'joint_1'.*leave it no motion"),
    (lambda t: t.replace('<parent link="link2"/><child link="link3"/>', '<parent link="link3"/><child link="link3"/>'),
     "joint 'joint_3' has link 'link3' as both its parent and its child")])
def test_a_joint_that_cannot_move_or_is_its_own_parent_is_refused(edit, message):
    text = FANUC.read_text()
    edited = edit(text)
    assert edited != text
    with pytest.raises(ModelError, match=message):
        URDFChain(edited)


def test_continuous_joints_take_unwrapped_angles_and_compare_them_modulo_a_turn():
    """The Kinova's continuous joints logged unwrapped (4.79 rad): the same pose as their wrap, within the limits
    for every check, and a compensation keeps them on the turn they were commanded on."""
    from tolerance_ros.core.accuracy.checks import screen
    from tolerance_ros.core.models.ik import into_limits
    chain = URDFChain(example_urdf("kinova.urdf"), tip_link="j2s6s200_end_effector")
    assert chain.continuous.tolist() == [True, False, False, True, False, True]
    q = np.mean(chain.joint_limits, axis=1)[None].repeat(3, axis=0)
    q[:, 0] = [4.79, -4.79, 4.79 + 2 * np.pi]
    wrapped = chain.within_turn(q)
    assert np.allclose(chain.fk(q), chain.fk(wrapped), atol=1e-12) and np.all(np.abs(wrapped[:, 0]) <= np.pi)
    assert not chain.out_of_limits(q).any()
    chain.check_joints(q, allow_out_of_limits=False)
    assert screen(chain, q).keep.all()
    from tolerance_ros.core.campaign import Campaign, TestPose
    wrapped_campaign = Campaign("k", [TestPose(f"P{i}", joints=qi) for i, qi in enumerate(chain.within_turn(q))])
    labels = np.array([f"P{i}" for i in range(len(q))], dtype=object)
    assert screen(chain, q, None, wrapped_campaign, labels).keep.all()     # measured a turn up: the same pose
    assert into_limits(chain, q + 0.01, near=q)[:, 0] == pytest.approx(q[:, 0] + 0.01)
    q[0, 1] = 6.0                                  # a limited joint beyond its limits is still refused
    assert chain.out_of_limits(q)[0].tolist() == [False, True, False, False, False, False]
    with pytest.raises(ModelError, match="outside the joint limits"):
        chain.check_joints(q, allow_out_of_limits=False)


EITHER_WAY = [("talos_reduced.urdf", "left_sole_link", "gripper_left_base_link"),   # foot back through leg, torso
              ("talos_reduced.urdf", "arm_left_2_link", "gripper_left_base_link"),  # a base moved by joints
              ("ur5_robot.urdf", "tool0", "base_link")]                             # the arm run backwards


def _between(text, base, tip, chain, q, edit=None):
    """(n, 4, 4) pinocchio's pose of ``tip`` in ``base`` at chain configurations q; ``edit(model)`` first."""
    model = pin.buildModelFromXML(text)
    if edit is not None:
        edit(model)
    data = model.createData()
    b, e = model.getFrameId(base), model.getFrameId(tip)
    out = []
    for qk in q:
        pin.framesForwardKinematics(model, data, chain.pinocchio_configuration(qk))
        out.append((data.oMf[b].inverse() * data.oMf[e]).homogeneous)
    return np.array(out)


@pytest.mark.parametrize("name, base, tip", EITHER_WAY)
def test_a_chain_runs_either_way_through_the_tree_as_pinocchio_says(name, base, tip):
    """FK against pinocchio at random configurations, and each column against pinocchio's FK of the URDF with that
    origin edited (shifts in the text, turns in the joint placement), whichever way the joint is traversed; the
    compiled and numpy paths agree where the chain takes the kernel."""
    path = example_urdf(name)
    text = path.read_text()
    chain = URDFChain(path, tip_link=tip, base_link=base)
    q = chain.sample_joints(3, 4)
    assert np.allclose(chain.fk(q), _between(text, base, tip, chain, q), atol=1e-12)
    J = chain.error_jacobian(q).J
    h = 1e-6
    for c, pname in enumerate(chain.param_names):
        joint, field = pname.rsplit(".", 1)
        if field == "offset":
            e = np.zeros(chain.dof)
            e[chain.joint_names.index(joint)] = h
            Tp, Tm = _between(text, base, tip, chain, q + e), _between(text, base, tip, chain, q - e)
        elif field in ("rx", "ry", "rz"):
            axis = ("rx", "ry", "rz").index(field)

            def turned(s):
                def edit(model):
                    jid = model.getJointId(joint)
                    model.jointPlacements[jid] = model.jointPlacements[jid] * pin.SE3(pin.exp3(np.eye(3)[axis] * s),
                                                                                      np.zeros(3))
                return edit
            Tp, Tm = _between(text, base, tip, chain, q, turned(h)), _between(text, base, tip, chain, q, turned(-h))
        else:
            Tp = _between(_perturbed_xml(text, joint, field, h), base, tip, chain, q)
            Tm = _between(_perturbed_xml(text, joint, field, -h), base, tip, chain, q)
        assert np.allclose(J[:, :, c], pose_difference(Tp, Tm) / (2 * h), atol=1e-7), pname
    rng = np.random.default_rng(1)
    for dx in (rng.standard_normal(chain.n_params) * 1e-3, rng.standard_normal((len(q), chain.n_params)) * 1e-3):
        chain.backend = "numba" if chain.compiled and pytest.importorskip("numba") else "numpy"
        T1, J1 = chain.fk_and_jacobian(q, dx)
        chain.backend = "numpy"
        T2, J2 = chain.fk_and_jacobian(q, dx)
        assert np.allclose(T1, T2, atol=1e-13) and np.allclose(J1.J, J2.J, atol=1e-12)


def test_a_chain_against_a_joint_names_its_direction_and_has_a_compiled_kernel():
    chain = URDFChain(example_urdf("talos_reduced.urdf"), tip_link="gripper_left_base_link", base_link="left_sole_link")
    assert chain.joint_names[:6] == tuple(f"leg_left_{k}_joint" for k in range(6, 0, -1))
    assert chain._reversed[:6].all() and not chain._reversed[6:].any() and chain.base_moves
    pytest.importorskip("numba")
    assert chain.backend == "numba"
    with pytest.raises(ModelError, match="not moved against base_link"):
        URDFChain(example_urdf("talos_reduced.urdf"), tip_link="arm_left_2_link", base_link="arm_left_2_link")


def test_a_chain_run_against_its_joints_writes_a_calibrated_urdf_that_gives_its_poses():
    """The origin errors of a joint traversed upward are the same physical errors: written into the URDF, they give
    the calibrated chain's poses; a base correction cannot go into such a first joint's origin and is refused."""
    from tolerance_ros.core.calibration.calibrated_robot import calibrated_urdf_text
    path = example_urdf("talos_reduced.urdf")
    chain = URDFChain(path, tip_link="gripper_left_base_link", base_link="left_sole_link")
    dx = np.random.default_rng(2).normal(0, 2e-3, chain.n_params)
    q = chain.sample_joints(10, 3)
    text = calibrated_urdf_text(chain, path.read_text(), dx, np.zeros(6))
    edited = URDFChain(text, tip_link="gripper_left_base_link", base_link="left_sole_link")
    np.testing.assert_allclose(edited.fk(q), chain.fk(q, dx), atol=1e-13, rtol=0)
    with pytest.raises(ValueError, match="base correction cannot go"):
        calibrated_urdf_text(chain, path.read_text(), dx, np.r_[1e-3, 0, 0, 0, 0, 0])
