"""Reading the four formats: the example programs' targets, frames, tools and motions as their controllers read them,
and what each refuses (with its file and line) or leaves to run time."""
import shutil

import numpy as np
import pytest

from tolerance_ros.core.geometry import transform
from tolerance_ros.core.programs import fanuc, krl, rapid, urscript
from tolerance_ros.core.programs.model import BASE
from tolerance_ros.core.programs.orientation import to_matrix
from tolerance_ros.core.programs.text import ProgramError
from tolerance_ros.testing.programs import PROGRAMS


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


# ---------------------------------------------------------------- ABB RAPID

def test_rapid_example():
    prog = rapid.read([PROGRAMS / "pick_place.mod"])
    names = [t.name for t in prog.targets]
    assert names == ["jHome", "pPick", "pPlace", "pFlip", "pBack", "pUnder", "pArc{1}", "pArc{2}",
                     "MoveL at line 22", "MoveAbsJ at line 24"]
    by = {t.name: t for t in prog.targets}
    assert by["pPick"].uses[0].tool == "tGripper" and by["pPick"].uses[0].frame == "wobjTable"
    assert by["pFlip"].uses[0].frame == BASE and by["jHome"].kind == "joints"
    assert by["pBack"].config == {"cf1": 0, "cf4": 1, "cf6": -1, "cfx": 4}
    assert [u.line for u in by["pArc{1}"].uses] == [23] and by["pArc{2}"].uses[0].what == "MoveC"
    np.testing.assert_allclose(prog.tools["tgripper"], transform([0.2, 0, 0], [0, np.pi / 2, 0]), atol=1e-6)
    np.testing.assert_allclose(prog.frames["wobjtable"], transform([1.8, -0.4, 0.3]), atol=1e-12)
    assert not prog.unresolved


def test_rapid_quaternion_is_w_first():
    t = rapid._robtarget(rapid._aggregate("[[1,2,3],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]",
                                          "[[1,2,3],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]", 0, "f:1")[0],
                         "f", 1, "p")
    T, _, want, windows = rapid.decode(t, type("M", (), {"dof": 6, "name": "m"})(), None)
    np.testing.assert_allclose(T[:3, :3], np.diag([-1.0, 1.0, -1.0]), atol=1e-12)    # half a turn about y
    np.testing.assert_allclose(T[:3, 3], [1e-3, 2e-3, 3e-3])
    assert want.tolist() == [1, 1, 1] and np.degrees(windows[0]).tolist() == [0.0, 90.0]


def test_rapid_reads_what_the_controller_reads(tmp_path):
    text = """MODULE M
    ! CONST robtarget pFake:=[[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
    VAR string s:="MoveL pGhost, v10, z10, tool0;";
    PERS tooldata tFixed:=[FALSE,[[0,0,100],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
    TASK PERS wobjdata wMoving:=[FALSE,FALSE,"STN1",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    CONST robtarget P10:=[[1000,0,1000],[0,0,1,0],[0,0,0,1],[9E9,9E9,9E9,9E9,9E9,9E9]];
    VAR robtarget pNow;
    PROC MoveLinear()
        movel p10, v100, z10, tool0;
        MoveL Offs(p10,0,0,100), v100, z10, tool0;
        MoveL pNow, v100, fine, tool0;
        MoveL \\Conc, p10, v100, z10, tFixed;
        SearchL \\Stop, diSensor, pNow, p10, v100, tool0 \\WObj:=wMoving;
        MyRoutine p10;
    ENDPROC
ENDMODULE
"""
    prog = rapid.read([_write(tmp_path, "m.mod", text)])
    assert [t.name for t in prog.targets] == ["P10"]                  # the comment and the string hold none
    uses = prog.targets[0].uses
    assert [(u.line, u.tool, u.frame) for u in uses] == [(9, BASE, BASE), (12, "tFixed", BASE), (13, BASE, "wMoving")]
    assert [(u.line, u.why) for u in prog.unresolved] == [(10, "computed at run time"), (11, "computed at run time")]
    assert "stationary" in prog.refused_tools["tfixed"] and "moves" in prog.refused_frames["wmoving"]


@pytest.mark.parametrize("value, message", [
    ("[[1000,0,1000],[0,0,1,0],[0,0,0,1]]", "4 components"),
    ("[[1000,0,x],[0,0,1,0],[0,0,0,1],[9E9,9E9,9E9,9E9,9E9,9E9]]", "a number"),
    ("[[1000,0,1000+1],[0,0,1,0],[0,0,0,1],[9E9,9E9,9E9,9E9,9E9,9E9]]", "not a literal"),
    ("[[1000,0,1000],[0,0,1,0],[0,0,0,9],[9E9,9E9,9E9,9E9,9E9,9E9]]", "cfx"),
    ("[[1000,0,1000],[0,0,1,0],[0,0,0,1],[9E9,9E9,9E9,9E9,9E9,9E9]", "never closed"),
])
def test_rapid_refuses_what_it_cannot_read_with_its_line(tmp_path, value, message):
    path = _write(tmp_path, "bad.mod", f"MODULE M\n\n  CONST robtarget p:={value};\nENDMODULE\n")
    with pytest.raises(ProgramError, match=rf"bad.mod:3: .*{message}"):
        rapid.read([path])


# ---------------------------------------------------------------- KUKA KRL

def test_krl_example_reads_the_dat_with_the_src():
    prog = krl.read([PROGRAMS / "weldcell.src"])
    assert [p.suffix for p in prog.texts] == [".src", ".dat"]
    by = {t.name: t for t in prog.targets}
    assert set(by) == {"XHOME", "XP1", "XP2", "XP3", "XP4", "XP5", "XP6", "XP7", "LIN at line 23"}
    assert [(u.tool, u.frame) for u in by["XP1"].uses] == [("1", "2")]      # FDAT_ACT=FP1
    assert [(u.tool, u.frame) for u in by["XP2"].uses] == [("1", "2")]      # still FP1
    assert [(u.tool, u.frame) for u in by["XP3"].uses] == [("1", BASE)]     # FDAT_ACT=FP3
    assert by["XP3"].config["S"][0] & 1 == 1 and "S" not in by["XP4"].config
    assert by["XHOME"].kind == "joints" and by["XHOME"].uses[0].line == 10
    assert [u.what for u in by["XP5"].uses] == ["CIRC"] and by["XP6"].uses[0].what == "CIRC"


def test_krl_tools_bases_and_what_runs_at_run_time(tmp_path):
    (tmp_path / "p.dat").write_text("DEFDAT P\nDECL E6POS XA={X 1000,Y 0,Z 1000,A 0,B 90,C 0,S 'B110',T 'B000010'}\n"
                                    "DECL FRAME TGRIP={X 0,Y 0,Z 150,A 0,B 0,C 0}\nDECL POS XPART={X 10}\nENDDAT\n")
    (tmp_path / "p.src").write_text("DEF P()\n$TOOL=TOOL_DATA[3]\n$BASE=BASE_DATA[4]\nLIN XA\n$TOOL=TGRIP\n"
                                    "$BASE=$NULLFRAME\nPTP XA C_PTP ; again\nLIN_REL {Z 10}\nPTP XPART\nBAS(#TOOL,0)\n"
                                    "PTP XA\nEND\n")
    prog = krl.read([tmp_path / "p.dat"])
    xa = next(t for t in prog.targets if t.name == "XA")
    assert [(u.line, u.tool, u.frame) for u in xa.uses] == [(4, "3", "4"), (7, "TGRIP", BASE), (11, BASE, BASE)]
    assert xa.config["S"][0] == 6 and xa.config["T"][0] == 2
    assert [u.line for u in prog.unresolved] == [8, 9]
    assert "TGRIP" in prog.tools and not any(t.name == "TGRIP" and t.uses for t in prog.targets)


# ---------------------------------------------------------------- FANUC

def test_fanuc_example():
    prog = fanuc.read([PROGRAMS / "pallet.ls"])
    by = {t.name: t for t in prog.targets}
    assert list(by) == [f"P[{k}]" for k in range(1, 9)]
    assert by["P[1]"].kind == "joints" and by["P[2]"].frame == "1" and by["P[2]"].tool == "1"
    assert by["P[4]"].config["flip"] == "F" and by["P[4]"].config["turns"] == [0, 0, 1]
    assert by["P[5]"].config["front"] == "B"
    assert [u.line for u in by["P[7]"].uses] == [32]                        # the circular motion's second point
    assert not prog.unresolved


def test_fanuc_registers_offsets_and_malformed_positions(tmp_path):
    text = ("/PROG  T\n/MN\n   1:J P[1] 100% FINE    ;\n   2:L PR[3] 100mm/sec FINE    ;\n"
            "   3:L P[1] 100mm/sec FINE Offset,PR[4]    ;\n   4:  PR[5]=P[1]    ;\n/POS\n"
            "P[1]{\n   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n"
            "\tX =  1000.000  mm,\tY =     -.500  mm,\tZ =  1200.000  mm,\n\tW =   180.000 deg,\tP =     0.000 deg,"
            "\tR =     0.000 deg\n   GP2:\n\tUF : 0, UT : 1,\t\n\tJ1=     0.000  mm\n};\n/END\n")
    prog = fanuc.read([_write(tmp_path, "t.ls", text)])
    assert prog.targets[0].values["Y"] == -0.5 and set(prog.targets[0].fields) == set("XYZWPR")   # GP2 untouched
    assert [(u.line, u.why.split(":")[0]) for u in prog.unresolved] == [(4, "a position register"), (5, "Offset")]
    bad = text.replace("'N U T, 0, 0, 0'", "'N U, 0, 0'")
    with pytest.raises(ProgramError, match=r"t2.ls:8: P\[1\]: CONFIG"):
        fanuc.read([_write(tmp_path, "t2.ls", bad)])
    with pytest.raises(ProgramError, match="t3.ls:1: not a TP program"):
        fanuc.read([_write(tmp_path, "t3.ls", "hello\n")])


def test_fanuc_header_is_remarks_numbered_after_the_last_line():
    text = (PROGRAMS / "pallet.ls").read_bytes().decode()
    out = fanuc.header(text, ["tolerance-ros filter: corrected through a calibration of 64 characters",
                              "short; line"], "\r\n")
    added = [line for line in out.split("\r\n") if line not in text.split("\r\n")]
    assert added == ["  12:  !tolerance-ros filter: corrected ;", "  13:  !through a calibration of 64 ;",
                     "  14:  !characters ;", "  15:  !short, line ;"]
    assert out.index("  15:  !short") < out.index("/POS")


# ---------------------------------------------------------------- URScript

def test_urscript_example():
    prog = urscript.read([PROGRAMS / "pick_place.script"])
    names = [t.name for t in prog.targets]
    assert names == ["home", "approach", "movel at line 9", "movel at line 10", "movec at line 11",
                     "movec at line 11", "movej at line 12"]
    by = {t.name: t for t in prog.targets}
    assert [u.line for u in by["approach"].uses] == [8, 13]
    assert by["movel at line 10"].uses[0].frame == "Plane_1" and "Plane_1" in prog.frames
    assert by["approach"].uses[0].tool == "set_tcp at line 3"
    np.testing.assert_allclose(prog.tools["set_tcp at line 3"], transform([0, 0, 0.15]))


def test_urscript_computed_targets_are_listed(tmp_path):
    text = ("def p():\n  q = [0,-1.57,1.57,-1.57,-1.57,0]\n  movej(q)\n  x = p[0.4,0,0.3,3.14159,0,0]\n"
            "  x = pose_add(x, p[0,0,0.1,0,0,0])\n  movel(x)\n  movel(pose_trans(get_actual_tcp_pose(), p[0,0,0.1,0,0,0]))\n"
            "  movej(get_inverse_kin(p[0.4,0.1,0.3,3.14159,0,0]), a=1)\n  set_tcp(get_tcp_offset())\nend\n")
    prog = urscript.read([_write(tmp_path, "p.script", text)])
    assert [t.name for t in prog.targets] == ["q", "movej at line 8"]
    assert [u.line for u in prog.unresolved] == [6, 7, 9]
    T, _, _, _ = urscript.decode(prog.targets[1], type("M", (), {"dof": 6, "name": "m"})(), None)
    np.testing.assert_allclose(T[:3, :3], to_matrix("rotvec", [[3.14159, 0, 0]])[0])


def test_a_program_is_copied_then_read(tmp_path):
    for name in ("pick_place.mod", "weldcell.src", "weldcell.dat", "pallet.ls", "pick_place.script"):
        shutil.copy(PROGRAMS / name, tmp_path / name)
    assert len(krl.read([tmp_path / "weldcell.dat"]).texts) == 2       # the .src found beside the .dat
