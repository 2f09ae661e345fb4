"""Importing exports with their own columns and units: the TIAGo file's columns, whitespace tables, MATLAB
arrays; every column mapped or deliberately ignored, never dropped silently."""
import numpy as np
import pytest

from helpers import SHARED_DATA
from tolerance_ros.core.accuracy.io import MeasurementError, read_csv, write_csv
from tolerance_ros.core.accuracy.io.importer import ColumnMap, parse_spec, read_table, to_measurements

TIAGO = SHARED_DATA / "tiago_mocap" / "qualisys_2021-11-30_static_postures.csv"
needs_tiago = pytest.mark.skipif(not TIAGO.is_file(), reason=f"public data set tiago_mocap not found at {TIAGO.parent}")
JOINTS = [("torso_lift_joint", "torso_lift_joint", "m")] + [(f"arm_{i}_joint", f"arm_{i}_joint", "rad")
                                                          for i in range(1, 8)]
POINTS = [(n, (f"x{k}", f"y{k}", f"z{k}"), "m") for k, n in enumerate(("BL", "BR", "TR", "TL"), 1)]


@needs_tiago
def test_the_tiago_files_own_columns_become_four_targets_per_posture(tmp_path):
    cols, n = read_table(TIAGO)
    assert n == 37 and "marker_std_mm" in cols
    cmap = ColumnMap(JOINTS, POINTS, stamp=("t_start_robot", "s"), ignore=["t_end_robot", "marker_std_mm",
                                                                           "shipped_row"])
    m = to_measurements(cols, n, cmap, str(TIAGO))
    assert len(m) == 148 and m.target_names == ("BL", "BR", "TR", "TL") and not m.has_orientation
    assert m.joint_names[0] == "torso_lift_joint" and m.joints[0, 0] == pytest.approx(cols["torso_lift_joint"][0])
    assert np.allclose(m.T[1, :3, 3], [cols["x2"][0], cols["y2"][0], cols["z2"][0]])
    assert np.all(m.stamps[:4] == cols["t_start_robot"][0])
    back = read_csv(write_csv(tmp_path / "t.csv", m, length_unit="m", angle_unit="rad",
                              joint_units=["m"] + ["rad"] * 7))
    assert np.allclose(back.T[:, :3, 3], m.T[:, :3, 3], atol=1e-6) and back.target.tolist() == m.target.tolist()
    assert "joint:torso_lift_joint[m]" in (tmp_path / "t.csv").read_text()


@needs_tiago
def test_a_column_neither_mapped_nor_ignored_is_an_error_naming_it():
    cols, n = read_table(TIAGO)
    cmap = ColumnMap(JOINTS, POINTS[:1], stamp=("t_start_robot", "s"))
    with pytest.raises(MeasurementError, match=r"column\(s\) \['x2', 'y2', .*'marker_std_mm'\] are not mapped"):
        to_measurements(cols, n, cmap, "tiago")
    with pytest.raises(MeasurementError, match="no column 'x9'"):
        to_measurements(cols, n, ColumnMap(JOINTS, [("", ("x9", "y1", "z1"), "m")]), "tiago")
    with pytest.raises(MeasurementError, match="needs a length unit"):
        to_measurements(cols, n, ColumnMap([], [("", ("x1", "y1", "z1"), "")], ignore=list(cols)[3:]), "tiago")


def test_a_whitespace_table_in_mm_and_degrees(tmp_path):
    p = tmp_path / "log.txt"
    p.write_text("# controller log\nt   j1    j2     X      Y     Z      A   B   C\n"
                 "0.0 10.0  -20.0  100.0  200.0  300.0  0.0 0.0 90.0\n"
                 "0.5 11.0  -21.0  101.0  201.0  301.0  0.0 0.0 91.0\n")
    cols, n = read_table(p)
    cmap = ColumnMap([("j1", "j1", "deg"), ("j2", "j2", "deg")], [("", ("X", "Y", "Z"), "mm")],
                     stamp=("t", "s"), orientation=(("A", "B", "C"), "deg"))
    m = to_measurements(cols, n, cmap, str(p))
    assert m.has_orientation and m.target is None
    assert m.joints[1] == pytest.approx(np.deg2rad([11.0, -21.0]))
    assert m.T[0, :3, 3] == pytest.approx([0.1, 0.2, 0.3]) and m.T[0, :3, :3] @ [1, 0, 0] == pytest.approx([0, 1, 0])


def test_matlab_arrays_are_columns_name_index(tmp_path):
    from scipy.io import savemat
    rng = np.random.default_rng(0)
    q, p, t = rng.normal(size=(5, 2)), rng.normal(size=(5, 3)), np.arange(5.0)
    savemat(tmp_path / "run.mat", {"q": q, "p": p, "t": t})
    cols, n = read_table(tmp_path / "run.mat")
    assert n == 5 and sorted(cols) == ["p:0", "p:1", "p:2", "q:0", "q:1", "t"]
    m = to_measurements(cols, n, ColumnMap([("a", "q:0", "rad"), ("b", "q:1", "rad")],
                                           [("", ("p:0", "p:1", "p:2"), "m")], stamp=("t", "s")), "run.mat")
    assert np.allclose(m.joints, q) and np.allclose(m.T[:, :3, 3], p)


def test_text_where_a_number_belongs_and_the_command_line_spec():
    cols = {"x": np.array(["1", "two"], dtype=object), "y": np.zeros(2), "z": np.zeros(2)}
    with pytest.raises(MeasurementError, match="column 'x': 'two' is not a number"):
        to_measurements(cols, 2, ColumnMap([], [("", ("x", "y", "z"), "m")]), "t")
    assert parse_spec("BL=x1,y1,z1[m]", "--point") == ("BL", ["x1", "y1", "z1"], "m")
    assert parse_spec("arm_1_joint[rad]", "--joint") == (None, ["arm_1_joint"], "rad")
    with pytest.raises(MeasurementError, match="expected"):
        parse_spec("a=b=c", "--point")


@needs_tiago
def test_a_rigid_bodys_pose_with_its_markers_is_the_same_campaign_as_the_markers(tmp_path, capsys):
    """TIAGo's four points are one rigid body: written as the body's pose (position + quaternion per row)
    with the markers' coordinates in the body frame, the import gives the same four points, and the same
    calibration, as the four points imported directly."""
    from tolerance_ros.cli import main
    from tolerance_ros.core.accuracy.registration import kabsch
    from tolerance_ros.core.geometry import matrices_to_quat
    cols, n = read_table(TIAGO)
    P = np.stack([np.column_stack([cols[f"{c}{k}"] for c in "xyz"]) for k in range(1, 5)], axis=1)  # (n, 4, 3)
    body = P[0] - P[0].mean(axis=0)                         # the markers in a body frame at row 0's pose
    rows = []
    for i in range(n):
        R, tr, _ = kabsch(body, P[i])
        rows.append(np.r_[tr, matrices_to_quat(R[None])[0]])
    assert np.abs(np.einsum("nij,mj->nmi", [kabsch(body, P[i])[0] for i in range(n)], body)
                  + np.array(rows)[:, None, :3] - P).max() < 2e-5   # rigid to a few um
    joints = [c for c in cols if "joint" in c]
    pose_csv = tmp_path / "pose.csv"
    pose_csv.write_text("t," + ",".join(joints) + ",bx,by,bz,qx,qy,qz,qw\n" + "".join(
        f"{float(cols['t_start_robot'][i])!r}," + ",".join(repr(float(cols[j][i])) for j in joints) + ","
        + ",".join(repr(float(v)) for v in rows[i]) + "\n" for i in range(n)))
    J = [a for j in joints for a in ("--joint", f"{j}[{'m' if j.startswith('torso') else 'rad'}]")]
    names = ("BL", "BR", "TR", "TL")
    assert main(["import", "--input", str(pose_csv), "--out", str(tmp_path / "from_pose.csv"), "--stamp", "t[s]", *J,
                 "--point", "bx,by,bz[m]", "--orientation", "qx,qy,qz,qw", "--quiet"]
                + [a for k, nm in enumerate(names) for a in ("--marker", f"{nm}={','.join(repr(float(v)) for v in body[k])}[m]")]) == 0
    points = [a for k, nm in enumerate(names, 1) for a in ("--point", f"{nm}=x{k},y{k},z{k}[m]")]
    assert main(["import", "--input", str(TIAGO), "--out", str(tmp_path / "points.csv"), "--stamp", "t_start_robot[s]",
                 *J, *points, "--ignore", "t_end_robot,marker_std_mm,shipped_row", "--quiet"]) == 0
    a, b = read_csv(tmp_path / "from_pose.csv"), read_csv(tmp_path / "points.csv")
    assert a.target.tolist() == b.target.tolist() and not a.has_orientation
    assert np.abs(a.T[:, :3, 3] - b.T[:, :3, 3]).max() < 2e-5
    from tolerance_ros.core.calibration.calibrate import calibrate_measurements
    from tolerance_ros.core.models import load_robot
    model = load_robot(TIAGO.parent / "tiago_48_schunk.urdf", tip_link="wrist_ft_tool_link")
    ca, cb = (calibrate_measurements(model, m, registration="base+tool", sigma_position=1e-3,
                                     parameters="joint-offsets", folds=4) for m in (a, b))
    assert ca.validation["after"]["position_rms_m"] == pytest.approx(cb.validation["after"]["position_rms_m"], rel=1e-3)
    assert np.allclose(ca.dx, cb.dx, atol=1e-5) and np.allclose(ca.targets.offsets, cb.targets.offsets, atol=2e-5)
    capsys.readouterr()
