"""Programs corrected through a calibration: every target of the example programs, run through the nominal inverse
kinematics as the controller would, lands within 10 um of its intended pose on a simulated as-built arm (about
1 mm before); joint targets of the 7-joint arm too; the envelope, the configuration and the frames decide which
targets are left as written, each with its reason."""
import numpy as np
import pytest

from tolerance_ros.core.calibration.envelope import Envelope
from tolerance_ros.core.geometry import matrices_to_quat
from tolerance_ros.core.programs.filtering import Setup, dialect_for, filter_program, landing
from tolerance_ros.core.programs.text import read_text, to_bytes
from tolerance_ros.testing.programs import EXAMPLES, PROGRAMS, as_built, example_setup, robot

ERRORS = (1.5e-4, 4e-4)          # m and rad: each length within 0.15 mm, each angle within 0.4 mrad of nominal
BASE = np.array([2e-4, -1e-4, 3e-4, 2e-4, -1e-4, 3e-4])   # and the base frame off by 0.3 mm and 0.3 mrad


@pytest.fixture(scope="module")
def arms():
    return {"fanuc": robot("fanuc"), "ur5": robot("ur5")}


def _filter(paths, setup, tmp_path, name="out"):
    d = dialect_for(paths)
    before = d.read(paths)
    outcome = filter_program(before, setup, ["tolerance-ros filter: corrected (test)"])
    out = tmp_path / name
    out.mkdir(exist_ok=True)
    written = []
    for p, text in outcome.texts.items():
        (out / p.name).write_bytes(to_bytes(text))
        written.append(out / p.name)
    after = d.read([out / paths[0].name])
    return before, after, outcome, written


@pytest.mark.parametrize("kind", list(EXAMPLES))
def test_every_target_lands_within_10um(kind, arms, tmp_path):
    ex = EXAMPLES[kind]
    model = arms[ex["robot"]]
    truth = as_built(model, *ERRORS, seed=11, base=BASE)
    setup = example_setup(kind, model, truth)
    before, after, outcome, _ = _filter([PROGRAMS / f for f in ex["files"]], setup, tmp_path)
    assert not outcome.left and not outcome.unresolved
    land = landing(before, after, setup, truth.calibrated_chain(model))
    assert len(land["name"]) == len(before.targets) >= 7
    assert np.median(land["before_m"]) > 3e-4 and land["before_m"].max() > 6e-4       # about a millimetre before
    assert land["after_m"].max() < 10e-6                                                # within 10 um after
    assert land["after_rad"].max() < 2e-6                                               # and 2 urad
    kinds = set(land["kind"])
    assert kinds == {"pose", "joints"}


def test_joint_targets_of_the_seven_joint_arm(gao, tmp_path):
    """jointtargets (the 7th joint as eax_a), E6AXIS (as E1), FANUC J1-J6 and E1, URScript lists of seven; a
    Cartesian target of the same arm is left: its controller's inverse kinematics needs the arm angle."""
    truth = as_built(gao, *ERRORS, seed=3)
    q = np.degrees(gao.sample_joints(3, 2))
    fmt = lambda v: ",".join(f"{x:.3f}" for x in v)  # noqa: E731
    files = {
        "a.mod": "MODULE A\n" + "".join(f"  CONST jointtarget j{k}:=[[{fmt(r[:6])}],[{r[6]:.3f},9E9,9E9,9E9,9E9,9E9]];\n"
                                         for k, r in enumerate(q))
        + "  CONST robtarget p:=[[500,0,500],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
        + "  PROC main()\n    MoveAbsJ j0, v100, fine, tool0;\n    MoveL p, v100, fine, tool0;\n  ENDPROC\nENDMODULE\n",
        "b.dat": "DEFDAT B\n" + "".join(f"DECL E6AXIS X{k}={{A1 {r[0]:.3f},A2 {r[1]:.3f},A3 {r[2]:.3f},A4 {r[3]:.3f},"
                                        f"A5 {r[4]:.3f},A6 {r[5]:.3f},E1 {r[6]:.3f},E2 0.0}}\n" for k, r in enumerate(q))
        + "ENDDAT\n",
        "c.script": "def c():\n" + "".join(f"  movej([{fmt(np.radians(r))}])\n" for r in q) + "end\n",
        "d.ls": "/PROG D\n/MN\n   1:J P[1] 100% FINE    ;\n/POS\n" + "".join(
            f"P[{k + 1}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\n\tJ1= {r[0]:.3f} deg,\tJ2= {r[1]:.3f} deg,\tJ3= {r[2]:.3f} deg,\n"
            f"\tJ4= {r[3]:.3f} deg,\tJ5= {r[4]:.3f} deg,\tJ6= {r[5]:.3f} deg,\tE1= {r[6]:.3f} deg\n}};\n"
            for k, r in enumerate(q)) + "/END\n",
    }
    for name, text in files.items():
        path = tmp_path / name
        path.write_text(text)
        setup = Setup(gao, truth.calibrated_chain(gao), fanuc_j3_absolute=False)
        before, after, outcome, _ = _filter([path], setup, tmp_path, name.replace(".", "_"))
        land = landing(before, after, setup, truth.calibrated_chain(gao))
        assert len(land["name"]) == 3 and land["after_m"].max() < 10e-6 < 3e-4 < land["before_m"].min()
        if name == "a.mod":
            assert [t.name for t, _ in outcome.left] == ["p"] and "6-joint" in outcome.left[0][1]


def _one_target_program(tmp_path, model, q_deg, name="one.mod"):
    """A RAPID program with one robtarget: the nominal pose of ``q_deg`` (tool0, wobj0) in its configuration."""
    from tolerance_ros.core.programs import rapid
    from tolerance_ros.core.programs.configuration import ArmGeometry
    q = np.radians(q_deg)
    T = model.fk(q[None])[0]
    s = ArmGeometry(model).flags(q[None])[0][0]
    quat = matrices_to_quat(T[None, :3, :3])[0][[3, 0, 1, 2]]
    cf = [rapid.quadrant(q[0]), rapid.quadrant(q[3]), rapid.quadrant(q[5]), 4 * (s[0] < 0) + 2 * (s[1] < 0) + (s[2] < 0)]
    p = T[:3, 3] * 1e3
    text = (f"MODULE One\n  CONST robtarget p1:=[[{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}],[{','.join(f'{v:.8f}' for v in quat)}],"
            f"[{','.join(map(str, cf))}],[9E9,9E9,9E9,9E9,9E9,9E9]];\n  PROC main()\n    MoveL p1, v100, fine, tool0;\n"
            f"  ENDPROC\nENDMODULE\n")
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_quadrant_crossed_by_the_correction_is_rewritten(arms, tmp_path):
    """Joint 1 at +0.02 deg (quadrant 0) turned by the base's 1 mrad about z: the corrected target lies at -0.04 deg, in
    quadrant -1, which the controller must be told; it lands within 10 um."""
    model = arms["fanuc"]
    truth = as_built(model, 0, 0, base=[0, 0, 0, 0, 0, 1e-3])
    path = _one_target_program(tmp_path, model, [0.02, 20, -10, 30, -60, 40])
    setup = Setup(model, truth.calibrated_chain(model))
    before, after, outcome, written = _filter([path], setup, tmp_path)
    assert outcome.rows[0]["status"] == "corrected"
    assert after.targets[0].config["cf1"] == -1 and before.targets[0].config["cf1"] == 0
    land = landing(before, after, setup, truth.calibrated_chain(model))
    assert land["after_m"].max() < 10e-6 < 1e-3 < land["before_m"].max()


def test_a_correction_that_changes_the_configuration_is_refused(arms, tmp_path):
    """Joint 5 at 0.01 deg: the wrist's sign flips under a 1 mrad error of joint 5's zero; the target is left as
    written with the reason."""
    model = arms["fanuc"]
    truth = as_built(model, 0, 0)
    truth.dx[model.param_names.index("joint_5.offset")] = 1e-3
    path = _one_target_program(tmp_path, model, [10, 20, -10, 30, 0.01, 40])
    setup = Setup(model, truth.calibrated_chain(model), Envelope(0.05, 0.01))
    before, after, outcome, written = _filter([path], setup, tmp_path)
    assert [t.name for t, _ in outcome.left] == ["p1"]
    assert "changes the configuration (wrist)" in outcome.left[0][1]
    assert read_text(written[0]).split("\n", 2)[2] == read_text(path).split("\n", 1)[1]   # as written


def test_the_envelope_leaves_targets_as_written_with_the_reason(arms, tmp_path):
    model = arms["fanuc"]
    truth = as_built(model, *ERRORS, seed=11, base=BASE)
    setup = example_setup("rapid", model, truth, envelope=Envelope(0.02, 0.4e-3))
    before, after, outcome, written = _filter([PROGRAMS / "pick_place.mod"], setup, tmp_path)
    left = {t.name: why for t, why in outcome.left}
    assert left and all("max_tool_correction" in why for why in left.values())
    moved = {r["name"]: r for r in outcome.rows if r["status"] == "corrected"}
    assert all(r["shift_m"] <= 0.4e-3 for r in moved.values() if r["kind"] == "pose")
    text = read_text(written[0])
    for t in before.targets:
        if t.name in left:
            assert read_text(PROGRAMS / "pick_place.mod").splitlines()[t.line - 1] in text    # its line unchanged
    setup = example_setup("rapid", model, truth, envelope=Envelope(1e-4, 5e-3))
    _, _, outcome, _ = _filter([PROGRAMS / "pick_place.mod"], setup, tmp_path, "joint")
    assert all("max_joint_correction" in why for _, why in outcome.left) and len(outcome.left) == 10


def test_tools_and_frames_decide_what_can_be_corrected(arms, tmp_path):
    model = arms["fanuc"]
    truth = as_built(model, *ERRORS, seed=2)
    text = read_text(PROGRAMS / "pick_place.mod")
    text = text.replace("    PERS tooldata tGripper", "    ! PERS tooldata tGripper").replace(
        "        MoveJ pFlip, v1000, z50, tGripper;", "        MoveJ pFlip, v1000, z50, tGripper;\n"
                                                     "        MoveL pFlip, v100, z10, tool0;")
    path = tmp_path / "p.mod"
    path.write_text(text)
    setup = Setup(model, truth.calibrated_chain(model))
    _, _, outcome, _ = _filter([path], setup, tmp_path)
    left = dict((t.name, why) for t, why in outcome.left)
    assert "tGripper is not declared" in left["pPick"] and "--tool tGripper=" in left["pPick"]
    assert "tGripper" in left["pFlip"]
    from tolerance_ros.cli.filter import pose_option
    setup = Setup(model, truth.calibrated_chain(model), tools={"tGripper": pose_option(
        "200mm,0mm,0mm,0deg,90deg,0deg", "--tool")})
    _, _, outcome, _ = _filter([path], setup, tmp_path, "given")
    left = dict((t.name, why) for t, why in outcome.left)
    assert set(left) == {"pFlip"} and "different tools" in left["pFlip"]
    assert {r["name"] for r in outcome.rows if r["status"] == "corrected"} >= {"pPick", "pPlace", "pBack"}


def test_a_pose_with_no_configuration_takes_the_one_before_it(arms, tmp_path):
    """URScript: the first pose of a script that starts with no joint target is left (its solution depends on where the
    robot is); after a joint target, poses are solved near it and land within 10 um."""
    model = arms["ur5"]
    truth = as_built(model, *ERRORS, seed=5)
    text = read_text(PROGRAMS / "pick_place.script")
    lines = text.splitlines(keepends=True)
    moved = lines[:6] + [lines[7], lines[6]] + lines[8:]          # movej(approach) before movej(home)
    path = tmp_path / "p.script"
    path.write_text("".join(moved))
    setup = example_setup("urscript", model, truth)
    before, after, outcome, _ = _filter([path], setup, tmp_path)
    assert [t.name for t, _ in outcome.left] == ["approach"] and "move to joints before it" in outcome.left[0][1]
