"""Robot YAML files: units converted to SI on load, invalid files rejected with the field named."""
import numpy as np
import pytest

from tolerance_ros.core.models import ModelError, URDFChain, load_robot

GOOD = """
name: two_link
kind: dh
convention: modified
units: {length: mm, angle: deg}
joints:
  - {name: shoulder, type: revolute, a: 0, alpha: 0, d: 100, theta: 90, limits: [-170, 170]}
  - {name: slide, type: prismatic, a: 250, alpha: -90, d: 50, theta: 0, limits: [0, 300]}
base: {xyz: [10, 0, 0], rpy: [0, 0, 180]}
tool: {xyz: [0, 0, 20]}
"""


def _write(tmp_path, text, name="robot.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_units_are_converted_to_si(tmp_path):
    m = load_robot(_write(tmp_path, GOOD))
    assert m.convention == "modified"
    assert m.d == pytest.approx([0.1, 0.05])
    assert m.a == pytest.approx([0.0, 0.25])
    assert m.theta == pytest.approx([np.pi / 2, 0.0])
    assert m.alpha == pytest.approx([0.0, -np.pi / 2])
    assert m.joint_limits == pytest.approx(np.array([[-170 * np.pi / 180, 170 * np.pi / 180], [0.0, 0.3]]))
    assert m.base[:3, 3] == pytest.approx([0.01, 0, 0])
    assert m.tool[:3, 3] == pytest.approx([0, 0, 0.02])
    assert m.joint_names == ("shoulder", "slide")


def test_same_robot_in_si_gives_the_same_kinematics(tmp_path):
    si = GOOD.replace("{length: mm, angle: deg}", "{length: m, angle: rad}")
    for a, b in (("100", "0.1"), ("90,", "pi/2,"), ("-170, 170", "-170*pi/180, 170*pi/180"),
                 ("250", "0.25"), ("-90", "-pi/2"), ("d: 50", "d: 0.05"), ("[0, 300]", "[0, 0.3]"),
                 ("[10, 0, 0]", "[0.01, 0, 0]"), ("180]", "pi]"), ("[0, 0, 20]", "[0, 0, 0.02]")):
        si = si.replace(a, b)
    m1 = load_robot(_write(tmp_path, GOOD, "a.yaml"))
    m2 = load_robot(_write(tmp_path, si, "b.yaml"))
    q = m1.sample_joints(5, 0)
    assert np.allclose(m1.fk(q), m2.fk(q), atol=1e-12)


@pytest.mark.parametrize("edit, field", [
    (("length: mm", "length: furlong"), "units.length"),
    (("angle: deg", "angle: grad"), "units.angle"),
    (("d: 100", "d: .nan"), "joints[0].d"),
    (("a: 250", "a: abc"), "joints[1].a"),
    (("alpha: 0, d: 100", "d: 100"), "joints[0].alpha: missing"),
    (("limits: [0, 300]", "limits: [0]"), "joints[1].limits"),
    (("type: prismatic", "type: screw"), "joints[1].type"),
    (("kind: dh", "kind: delta"), "kind"),
    (("convention: modified", "convetion: modified"), "unknown key"),
    (("theta: 90,", "theta: 90, alpah: 3,"), "joints[0]: unknown key"),
    (("base: {xyz: [10, 0, 0], rpy: [0, 0, 180]}", "base: {xyz: [10, 0]}"), "base.xyz"),
])
def test_invalid_files_name_the_field(tmp_path, edit, field):
    text = GOOD.replace(*edit)
    assert text != GOOD
    with pytest.raises(ModelError) as exc:
        load_robot(_write(tmp_path, text))
    assert field in str(exc.value)
    assert "robot.yaml" in str(exc.value)


def test_unknown_robot_name_lists_the_shipped_ones():
    with pytest.raises(FileNotFoundError, match="gao2023_7dof"):
        load_robot("no_such_robot")


def test_shipped_paper_robot(gao):
    assert gao.dof == 7 and gao.n_params == 28
    assert gao.d[1:] == pytest.approx([0.177, 0.415, 0.1478, 0.40362, 0.13062, 0.09112])
    assert gao.joint_limits == pytest.approx(np.tile([-np.pi, np.pi], (7, 1)))


@pytest.mark.parametrize("content, message", [
    (GOOD.encode().replace(b"shoulder", b"sh\xf6ulder"), r", line 7, column 14: not UTF-8 text \(byte 0xf6\)"),
    ("name: x\nkind: dh\njoints: " + "[" * 5000 + "]" * 5000 + "\n", r", line 3: nested deeper than 32 levels"),
    (GOOD + "name: again\n", r", line 11: key 'name' given twice in one mapping"),
    (GOOD.replace("d: 100", "d: 1_00"), r", line 7: '1_00' is a number with digit separators"),
])
def test_files_that_would_trace_back_or_change_are_the_models_error(tmp_path, content, message):
    p = tmp_path / "robot.yaml"
    p.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(ModelError, match=rf"^{p}{message}"):
        load_robot(p)


def test_an_error_of_a_urdf_robot_file_names_the_file(tmp_path):
    from helpers import example_urdf
    p = tmp_path / "panda.urdf"
    p.write_text(example_urdf("panda.urdf").read_text())
    with pytest.raises(ModelError, match=rf"^{p} \(robot 'panda'\): the URDF branches, its chains end in the links"):
        load_robot(p)
    with pytest.raises(ModelError, match=r"^robot 'panda': the URDF branches"):  # a URDF given as text
        URDFChain(p.read_text())


@pytest.mark.parametrize("kind", ["{a: 1}", "[dh]", "7"])
def test_a_kind_that_is_not_a_name_is_the_models_error(tmp_path, kind):
    p = _write(tmp_path, GOOD.replace("kind: dh", f"kind: {kind}"))
    with pytest.raises(ModelError, match=rf"^{p}: kind: expected one of \['3pups', 'dh', 'urdf'\]"):
        load_robot(p)


def test_unknown_keys_of_a_3pups_robot_file_are_named(tmp_path):
    import yaml
    from tolerance_ros.core.models import ModelError, load_robot
    doc = yaml.safe_load(open("config/robots/rong2018_3pups.yaml"))
    doc["colour"] = "red"
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(ModelError, match=r"robot: unknown key\(s\) \['colour'\]"):
        load_robot(tmp_path / "p.yaml")
