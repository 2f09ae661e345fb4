"""Readers: CSV (units, bad rows), rosbag2 (sqlite3 and mcap) and stamp pairing (the campaign log is
tested with the monitor that writes it)."""
import numpy as np
import pytest

from tolerance_ros.core.ingest import pair_by_stamp
from tolerance_ros.core.accuracy.io import (Measurements, MeasurementError, read_csv, read_rosbag,
                                            write_csv, write_rosbag)
from tolerance_ros.core.geometry import transform


def _meas(n=12, seed=0, joints=True):
    rng = np.random.default_rng(seed)
    T = np.array([transform(rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)) for _ in range(n)])
    q = rng.uniform(-1, 1, (n, 2)) if joints else None
    return Measurements(np.arange(n) * 0.5, T, q, ("j1", "j2") if joints else (),
                        np.array([f"P{i % 3 + 1}" for i in range(n)], dtype=object), np.arange(n) // 3)


def test_csv_round_trip_and_chunks(tmp_path):
    m = _meas()
    path = write_csv(tmp_path / "m.csv", m, comments=["made in a test"])
    back = read_csv(path)
    assert np.allclose(back.T, m.T, atol=1e-8) and np.allclose(back.joints, m.joints, atol=1e-8)
    assert list(back.pose) == list(m.pose) and list(back.cycle) == list(m.cycle)
    chunks = list(read_csv(path, chunk_rows=5))
    assert [len(c) for c in chunks] == [5, 5, 2]
    assert np.allclose(np.concatenate([c.T for c in chunks]), back.T)


def test_units_in_the_header_are_honoured(tmp_path):
    p = tmp_path / "u.csv"
    p.write_text("stamp[ms],x[m],y[mm],z[um],qx,qy,qz,qw,joint:j1[deg]\n1000,1,2,3,0,0,0,1,90\n")
    m = read_csv(p)
    assert m.stamps[0] == pytest.approx(1.0)
    assert m.T[0, :3, 3] == pytest.approx([1.0, 0.002, 3e-6])
    assert m.joints[0, 0] == pytest.approx(np.pi / 2)


GOOD = "stamp[s],x[mm],y[mm],z[mm]\n0,1,2,3\n1,1,2,3\n"


@pytest.mark.parametrize("text, message", [
    ("stamp[s],x[mm],y[mm]\n0,1,2\n", "missing column"),
    ("stamp[s],x[mm],y[mm],z[mm]\n0,1,nan,3\n", "line 2: y: 'nan' is not finite"),
    ("stamp[s],x[mm],y[mm],z[mm]\n0,1,2,3\n1,1,2\n", "line 3: expected 4 columns"),
    ("stamp[s],x[mm],y[mm],z[mm]\n1,1,2,3\n0,1,2,3\n", "line 3: stamp 0 s is earlier"),
    ("stamp[s],x[furlong],y[mm],z[mm]\n0,1,2,3\n", "needs a length unit"),
    ("stamp[s],x,y[mm],z[mm]\n0,1,2,3\n", "needs a length unit"),
    ("stamp[h],x[mm],y[mm],z[mm]\n0,1,2,3\n", "time unit"),
    ("stamp[s],x[mm],y[mm],z[mm],roll[deg]\n0,1,2,3,4\n", "roll, pitch, yaw"),
    ("# only a comment\n", "empty file"),
])
def test_bad_files_fail_with_the_position(tmp_path, text, message):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(MeasurementError, match=message):
        read_csv(p)


def test_skipping_bad_rows_lists_them(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("# c\nstamp[s],x[mm],y[mm],z[mm]\n0,1,2,3\n1,x,2,3\n2,1,2,3\n")
    m = read_csv(p, skip_bad=True)
    assert len(m) == 2 and m.skipped == [{"line": 4, "reason": "x: 'x' is not a number"}]


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_rosbag_round_trip(tmp_path, storage):
    m = _meas(20)
    write_rosbag(tmp_path / "bag", m, storage, joint_offset_s=0.002)
    back = read_rosbag(tmp_path / "bag", slop=0.005)
    assert np.allclose(back.T, m.T, atol=1e-12) and np.allclose(back.joints, m.joints)
    with pytest.raises(MeasurementError, match="no joint state within 0.001 s"):
        read_rosbag(tmp_path / "bag", slop=0.001)
    skipped = read_rosbag(tmp_path / "bag", slop=0.001, skip_bad=True)
    assert len(skipped) == 0 and len(skipped.skipped) == 20


def test_pairing_by_stamp():
    idx = pair_by_stamp([0.0, 1.0, 2.04, 5.0], [0.01, 0.99, 2.0, 3.0], slop=0.02)
    assert idx.tolist() == [0, 1, -1, -1]
    assert pair_by_stamp([1.0], [], 0.1).tolist() == [-1]
