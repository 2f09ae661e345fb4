"""The robots a node serves: files at start, and the URDF that arrives (and changes) on robot_description."""
import pytest

from helpers import example_urdf
from tolerance_ros.core.budget import BudgetError
from tolerance_ros.core.models import ModelError
from tolerance_ros.services.contracts import ContractError
from tolerance_ros.services.robots import RobotSet


def test_shipped_robots_and_the_default():
    robots = RobotSet(["gao2023_7dof", "rong2018_3pups"], "gao2023_7dof")
    assert robots.select()[0] == "gao2023_7dof" and robots.select("rong2018_3pups")[1].dof == 9
    assert not robots.waiting and not robots.from_description
    with pytest.raises(ContractError) as exc:
        robots.select("ur5")
    assert exc.value.code == "unknown_robot" and "available: ['gao2023_7dof', 'rong2018_3pups']" in exc.value.message
    with pytest.raises(ContractError):
        robots.on_description(example_urdf("ur5_robot.urdf").read_text())


def test_the_robot_on_robot_description_arrives_is_replaced_and_survives_a_bad_one():
    robots = RobotSet(["robot_description", "gao2023_7dof"], "robot_description", tip_link="tool0")
    assert robots.waiting and robots.single() is None and robots.default_name is None
    with pytest.raises(ContractError) as exc:
        robots.select()
    assert exc.value.code == "unknown_robot" and "waiting for a URDF on robot_description" in exc.value.message
    with pytest.raises(ContractError, match="still waiting for robot_description"):
        robots.select("ur5")
    said = robots.on_description(example_urdf("ur5_robot.urdf").read_text())
    assert said.startswith("robot_description: loaded robot 'ur5': 6 joints") and "tip 'tool0'" in said
    assert robots.select()[0] == "ur5" and robots.select("robot_description")[0] == "ur5" and robots.version == 1
    for bad in ("<robot name='x'><link name='a'/>", "not xml at all"):
        with pytest.raises(ModelError):
            robots.on_description(bad)
    for path in (str(example_urdf("panda.urdf")), "x" * 5000):   # a path is never read, however long
        with pytest.raises(ModelError, match="not URDF XML text"):
            robots.on_description(path)
    entities = ('<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">' + "".join(
        f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi")) + ']><robot name="&i;"/>')
    for bad, why in ((entities, "entity declarations"), (example_urdf("ur5_robot.urdf").read_text() + "<extra/>",
                                                         "not well-formed XML")):
        with pytest.raises(ModelError, match=why):
            robots.on_description(bad)
    assert robots.select()[0] == "ur5" and robots.version == 1                      # the previous robot stays
    with pytest.raises(ContractError, match="empty"):
        robots.on_description("   ")
    robots.tip_link = "panda_hand"
    said = robots.on_description(example_urdf("panda.urdf").read_text())
    assert "replaced the robot 'panda'" in said and sorted(robots.models) == ["gao2023_7dof", "panda"]
    assert robots.single().dof == 7 and robots.version == 2


def test_a_branching_description_without_tip_link_names_the_leaves():
    robots = RobotSet(["robot_description"], "robot_description")
    with pytest.raises(ModelError, match=r"chains end in the links \['ee_link', 'tool0'\]"):
        robots.on_description(example_urdf("ur5_robot.urdf").read_text())
    assert robots.waiting


def test_a_description_the_node_cannot_use_is_refused_and_the_previous_robot_stays():
    robots = RobotSet(["robot_description"], "robot_description", tip_link="tool0")
    robots.on_description(example_urdf("ur5_robot.urdf").read_text())

    def check(model):
        raise BudgetError(f"budget is for robot 'ur5', not {model.name!r}")

    robots.tip_link = "panda_hand"
    with pytest.raises(BudgetError, match="not 'panda'"):
        robots.on_description(example_urdf("panda.urdf").read_text(), check)
    assert robots.select()[0] == "ur5" and sorted(robots.models) == ["ur5"] and robots.version == 1


def test_a_new_description_is_named_by_its_text_and_chain_hashes_and_a_changed_chain_is_said():
    import re
    from tolerance_ros.services.robots import chain_sha256
    text = example_urdf("ur5_robot.urdf").read_text()
    robots = RobotSet(["robot_description"], "robot_description", tip_link="tool0")
    first = robots.on_description(text)
    text_sha, chain = robots.description_hashes
    assert re.fullmatch(r"[0-9a-f]{64}", chain) and f"chain sha256 {chain[:12]}, text sha256 {text_sha[:12]}" in first
    assert robots.chain_changed is None and "CHAIN CHANGED" not in first
    same = robots.on_description(text + "\n<!-- a comment -->\n")     # another text, the same chain
    assert robots.description_hashes[1] == chain and robots.description_hashes[0] != text_sha
    assert robots.chain_changed is None and same.endswith("(the same chain as before)")
    moved = re.sub(r'(<joint name="shoulder_lift_joint".*?<origin[^>]*xyz=")([^"]*)"',
                   lambda m: m.group(1) + "0.0 0.13585 0.001" + '"', text, count=1, flags=re.S)
    assert moved != text
    said = robots.on_description(moved)
    new = robots.description_hashes[1]
    assert robots.chain_changed == (chain, new) and new != chain
    assert f"THE CHAIN CHANGED: {chain[:12]} -> {new[:12]}" in said
    assert chain_sha256(robots.single()) == new
