"""`tolerance-ros filter` and `tolerance-ros ur-kinematics` from the command line: a zero calibration gives every
example program back byte for byte apart from its header; the header names the calibration and the command; the
input is never written over unless asked; what is left or unreadable is said with its exit code."""
import difflib
import json
import re
import shutil

import pytest
import yaml

from helpers import run_cli as run
from tolerance_ros.core.calibration.calibration_file import save_calibration
from tolerance_ros.testing.programs import EXAMPLES, PROGRAMS, as_built, robot, robot_args


@pytest.fixture(scope="module")
def cals(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cals")
    out = {}
    for kind in ("fanuc", "ur5"):
        model = robot(kind)
        out[kind, "zero"] = save_calibration(as_built(model, 0, 0), tmp / f"{kind}_zero.yaml")
        out[kind, "built"] = save_calibration(as_built(model, 1.5e-4, 4e-4, seed=11), tmp / f"{kind}_built.yaml")
    return out


def _copy(tmp_path, kind):
    names = list(EXAMPLES[kind]["files"])
    if kind == "krl":
        names.append("weldcell.dat")
    for n in names:
        shutil.copy(PROGRAMS / n, tmp_path / n)
    return [tmp_path / n for n in EXAMPLES[kind]["files"]]


def _args(kind, cals, which, files, *more):
    ex = EXAMPLES[kind]
    return ["filter", *files, *robot_args(ex["robot"]), "--calibration", cals[ex["robot"], which], *ex["options"],
            *more]


@pytest.mark.parametrize("kind", list(EXAMPLES))
def test_a_zero_calibration_gives_the_program_back_byte_for_byte(kind, cals, capsys, tmp_path):
    files = _copy(tmp_path, kind)
    code, out, err = run(capsys, *_args(kind, cals, "zero", files, "--out", tmp_path / "out", "--quiet"))
    assert code == 0, err
    originals = sorted(p for p in tmp_path.iterdir() if p.is_file())
    assert originals
    for src in originals:
        before = src.read_bytes().decode("latin-1").splitlines(keepends=True)
        after = (tmp_path / "out" / src.name).read_bytes().decode("latin-1").splitlines(keepends=True)
        ops = difflib.SequenceMatcher(None, before, after, autojunk=False).get_opcodes()
        assert {op for op, *_ in ops} <= {"equal", "insert"}, src.name
        inserted = [line for op, _, _, j1, j2 in ops if op == "insert" for line in after[j1:j2]]
        text = "".join(inserted)
        assert "tolerance-ros filter: corrected" in text and "sha256" in text and "command: tolerance-ros filter" in text
        kept = [line for op, i1, i2, *_ in ops if op == "equal" for line in before[i1:i2]]
        assert "".join(kept) == "".join(before)                    # every other byte as it was, CRLF included


def test_the_command_corrects_and_says_what_it_did(cals, capsys, tmp_path):
    files = _copy(tmp_path, "rapid")
    code, out, err = run(capsys, *_args("rapid", cals, "built", files, "--out", tmp_path / "corr.mod", "--json"))
    doc = json.loads(out)
    assert code == 0 and doc["ok"] and doc["counts"] == {"corrected": 10, "unchanged": 0, "left": 0}
    text = (tmp_path / "corr.mod").read_text()
    sha = yaml.safe_load((cals["fanuc", "built"]).read_text())["provenance"]["content_sha256"]
    assert f"sha256 {sha}" in text and doc["calibration_sha256"] == sha
    assert f"--out {tmp_path / 'corr.mod'}" in text and files[0].read_text() != text
    code, out, err = run(capsys, *_args("rapid", cals, "built", files, "--out", tmp_path / "h"))
    assert code == 0 and "10 corrected" in out and "pBack" in out and "mdeg" in out


def test_the_input_is_written_over_only_when_asked(cals, capsys, tmp_path):
    files = _copy(tmp_path, "fanuc")
    original = files[0].read_bytes()
    code, out, err = run(capsys, *_args("fanuc", cals, "built", files))
    assert code == 2 and "--out" in err.splitlines()[-1] and files[0].read_bytes() == original
    code, out, err = run(capsys, *_args("fanuc", cals, "built", files, "--out", files[0]))
    assert code == 2 and "--in-place" in err.splitlines()[-1]
    code, out, err = run(capsys, *_args("fanuc", cals, "built", files, "--in-place", "--quiet"))
    assert code == 0 and (tmp_path / "pallet.ls.orig").read_bytes() == original and files[0].read_bytes() != original
    code, out, err = run(capsys, *_args("fanuc", cals, "built", files, "--in-place"))
    assert code == 2 and ".orig exists" in err.splitlines()[-1]
    code, out, err = run(capsys, *_args("fanuc", cals, "built", files, "--out", tmp_path / "again.ls"))
    assert code == 2 and "already corrected" in err.splitlines()[-1] and not (tmp_path / "again.ls").exists()


def test_a_program_of_two_files_needs_a_folder(cals, capsys, tmp_path):
    files = _copy(tmp_path, "krl")
    code, out, err = run(capsys, *_args("krl", cals, "built", files, "--out", tmp_path / "x.src"))
    assert code == 2 and "weldcell.src, weldcell.dat" in err
    code, out, err = run(capsys, *_args("krl", cals, "built", files, "--out", tmp_path / "out", "--quiet"))
    assert code == 0 and sorted(p.name for p in (tmp_path / "out").iterdir()) == ["weldcell.dat", "weldcell.src"]


def test_left_targets_exit_3_and_unreadable_programs_exit_2(cals, capsys, tmp_path):
    files = _copy(tmp_path, "krl")
    ex = EXAMPLES["krl"]
    no_frame = [o for o in ex["options"] if not o.startswith("2=") and o != "--frame"]
    code, out, err = run(capsys, "filter", *files, *robot_args("fanuc"), "--calibration", cals["fanuc", "built"],
                         *no_frame, "--out", tmp_path / "o", "--json")
    doc = json.loads(out)
    last = err.strip().splitlines()[-1]
    assert code == 3 and not doc["ok"] and last.startswith("tolerance-ros filter: FAILED: 2 target(s) left")
    assert "--frame 2=" in last and {t["name"] for t in doc["left"]} == {"XP1", "XP2"}
    dat = (tmp_path / "o" / "weldcell.dat").read_text()
    assert re.search(r"DECL E6POS XP1=\{X [-0-9.]+,", dat).group() in (tmp_path / "weldcell.dat").read_text()
    bad = tmp_path / "bad.mod"
    bad.write_text("MODULE B\n  CONST robtarget p:=[[1,2,3],[1,0,0,0],[0,0,0,0]];\nENDMODULE\n")
    code, out, err = run(capsys, "filter", bad, *robot_args("fanuc"), "--calibration", cals["fanuc", "built"],
                         "--out", tmp_path / "b.mod")
    assert code == 2 and f"{bad}:2:" in err.splitlines()[-1] and not (tmp_path / "b.mod").exists()
    code, out, err = run(capsys, "filter", bad, *robot_args("fanuc"), "--calibration", cals["fanuc", "built"],
                         "--out", tmp_path / "b.mod", "--tool", "200,0,0,0,0,0")
    assert code == 2 and "--tool" in err.splitlines()[-1]


def test_ur_kinematics(cals, capsys, tmp_path):
    code, out, err = run(capsys, "ur-kinematics", *robot_args("ur5"), "--calibration", cals["ur5", "built"], "--out",
                         tmp_path / "ur5_calibration.yaml")
    assert code == 0 and "reproduces the calibrated robot" in out
    doc = yaml.safe_load((tmp_path / "ur5_calibration.yaml").read_text())["kinematics"]
    assert list(doc) == ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3", "hash"]
    assert re.fullmatch(r"calib_\d+", doc["hash"]) and abs(doc["forearm"]["x"] + 0.425) < 1e-3
    code, out, err = run(capsys, "ur-kinematics", *robot_args("fanuc"), "--calibration", cals["fanuc", "built"],
                         "--out", tmp_path / "no.yaml")
    assert code == 2 and "not UR's" in err.splitlines()[-1] or "do not turn" in err.splitlines()[-1]
