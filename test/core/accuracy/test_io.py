"""Readers: CSV (units, bad rows), rosbag2 (sqlite3 and mcap) and stamp pairing (the campaign log is
tested with the monitor that writes it)."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy import io
from tolerance_ros.core.accuracy.io import (MAX_LINE, Measurements, MeasurementError, read_csv,
                                            read_measurements, read_rosbag, write_csv, write_rosbag)
from tolerance_ros.core.geometry import transform
from tolerance_ros.core.ingest import pair_by_stamp


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
    ("stamp[s],x[mm],y[mm],z[mm]\n0,1,nan,3\n", "line 2: y: 'nan' is not a number"),
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


# ---------------------------------------------------------------- malformed CSV files (issue 12)

H = "stamp[s],pose,cycle,x[mm],y[mm],z[mm],qx,qy,qz,qw\n"
ROW = "{t},P1,0,1,2,3,0,0,0,1\n"


def _write(path, content):
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _csv_around(bad_row, header=H):
    """A header, a good row (line 2), ``bad_row`` (line 3) and a good row (line 4)."""
    if isinstance(bad_row, bytes):
        return (header + ROW.format(t=0)).encode() + bad_row + ROW.format(t=2).encode()
    return header + ROW.format(t=0) + bad_row + ROW.format(t=2)


BAD_ROWS = [
    ("quoted field over the csv limit", '1,"' + "P" * 140_000 + '",0,1,2,3,0,0,0,1\n',
     "pose: longer than 131072 characters"),
    ("number over the csv limit", "1,P1,0," + "1" * 140_000 + ",2,3,0,0,0,1\n",
     "x: '1111111111111111111111111111111111111111'... (140000 characters) is not finite"),
    ("line over MAX_LINE", "1,P1,0,1,2,3,0,0,0,1" + " " * (MAX_LINE + 10) + "\n",
     f"line longer than {MAX_LINE} characters"),
    ("non-UTF-8 byte", b"1,P1,0,1,\xff2,3,0,0,0,1\n", "y: byte 0xff at character 10 is not UTF-8"),
    ("latin-1 pose name", b"1,P\xe91,0,1,2,3,0,0,0,1\n", "pose: byte 0xe9 at character 4 is not UTF-8"),
    ("zero quaternion", "1,P1,0,1,2,3,0,0,0,0\n", "qx, qy, qz, qw: quaternion with zero (or non-finite) norm"),
    ("underscore in a number", "1,P1,0,1_000,2,3,0,0,0,1\n", "x: '1_000' is not a number"),
    ("Arabic-Indic digits", "1,P1,0,\u0661\u0662,2,3,0,0,0,1\n", "x: '١٢' is not a number"),
    ("NaN position", "1,P1,0,1,NaN,3,0,0,0,1\n", "y: 'NaN' is not a number"),
    ("nan position", "1,P1,0,1,2,nan,0,0,0,1\n", "z: 'nan' is not a number"),
    ("Infinity stamp", "Infinity,P1,0,1,2,3,0,0,0,1\n", "stamp: 'Infinity' is not a number"),
    ("-inf quaternion", "1,P1,0,1,2,3,-inf,0,0,1\n", "qx: '-inf' is not a number"),
    ("overflowing number", "1,P1,0,1e999,2,3,0,0,0,1\n", "x: '1e999' is not finite"),
    ("hexadecimal", "1,P1,0,0x10,2,3,0,0,0,1\n", "x: '0x10' is not a number"),
    ("empty number", "1,P1,0,,2,3,0,0,0,1\n", "x: '' is not a number"),
    ("superscript cycle", "1,P1,\u00b2,1,2,3,0,0,0,1\n",
     "cycle: expected a non-negative integer below 10**9, got '²'"),
    ("fractional cycle", "1,P1,1.0,1,2,3,0,0,0,1\n", "cycle: expected a non-negative integer below 10**9, got '1.0'"),
    ("huge cycle", "1,P1," + "9" * 5000 + ",1,2,3,0,0,0,1\n", "cycle: expected a non-negative integer below 10**9"),
    ("missing column", "1,P1,0,1,2,3,0,0,0\n", "expected 10 columns, got 9"),
    ("decreasing stamp", "-1,P1,0,1,2,3,0,0,0,1\n", "stamp -1 s is earlier than the previous row's 0 s"),
    ("unclosed quote", '1,"P1,0,1,2,3,0,0,0,1\n', "expected 10 columns, got 2"),
]


@pytest.mark.parametrize("bad_row, message", [c[1:] for c in BAD_ROWS], ids=[c[0] for c in BAD_ROWS])
def test_a_bad_csv_row_is_named_or_skipped_and_listed(tmp_path, bad_row, message):
    p = _write(tmp_path / "m.csv", _csv_around(bad_row))
    with pytest.raises(MeasurementError) as err:
        read_csv(p)
    assert str(err.value).startswith(f"{p}, line 3: {message}")
    m = read_measurements(p, skip_bad=True)
    assert m.stamps.tolist() == [0.0, 2.0] and len(m.skipped) == 1
    assert m.skipped[0]["line"] == 3 and m.skipped[0]["reason"].startswith(message)
    chunks = list(read_csv(p, skip_bad=True, chunk_rows=1))
    assert [s["line"] for c in chunks for s in c.skipped] == [3]


BAD_HEADERS = [
    ("qx, qy, qz without qw", "stamp[s],x[mm],y[mm],z[mm],qx,qy,qz\n0,1,2,3,0,0,0\n",
     "header: orientation needs all of qx, qy, qz, qw; missing column(s) ['qw']"),
    ("roll and pitch without yaw", "stamp[s],x[mm],y[mm],z[mm],roll[deg],pitch[deg]\n0,1,2,3,0,0\n",
     "header: orientation needs all of roll, pitch, yaw; missing column(s) ['yaw']"),
    ("qw alone", "stamp[s],x[mm],y[mm],z[mm],qw\n0,1,2,3,1\n",
     "header: orientation needs all of qx, qy, qz, qw; missing column(s) ['qx', 'qy', 'qz']"),
    ("both orientations",
     "stamp[s],x[mm],y[mm],z[mm],roll[deg],pitch[deg],yaw[deg],qx,qy,qz,qw\n0,1,2,3,0,0,0,0,0,0,1\n",
     "header: give the orientation as roll, pitch, yaw or as qx, qy, qz, qw, not both"),
    ("non-UTF-8 header", b"stamp[s],x[\xb5m],y[mm],z[mm]\n0,1,2,3\n", "byte 0xb5 at character 12 is not UTF-8"),
]


@pytest.mark.parametrize("text, message", [c[1:] for c in BAD_HEADERS], ids=[c[0] for c in BAD_HEADERS])
def test_a_bad_header_stops_the_read_even_when_skipping(tmp_path, text, message):
    p = _write(tmp_path / "h.csv", text)
    for skip in (False, True):
        with pytest.raises(MeasurementError) as err:
            read_csv(p, skip_bad=skip)
        assert str(err.value) == f"{p}, line 1: {message}"


NUMBERS_READ = ["1", "-1.5", "+.5", "5.", "1e3", "1E-3", " 2 ", "\t2", "007"]
NUMBERS_REJECTED = ["1_000", "\u0661", "\u00b2", "nan", "NAN", "inf", "-Infinity", "iNfInItY", "0x10", "", " ",
                    "1e", "1.2.3", "1 000", "\u20032", "2\u00a0", "--1", "1e5.5", "\u0ce7", "\uff11"]


@pytest.mark.parametrize("text", NUMBERS_READ + NUMBERS_REJECTED)
def test_numbers_are_plain_ascii_on_the_fast_and_the_row_by_row_path(tmp_path, text):
    clean = _write(tmp_path / "clean.csv", f"stamp[s],x[m],y[m],z[m]\n0,{text},0,0\n1,0,0,0\n")
    mixed = _write(tmp_path / "mixed.csv", f"stamp[s],x[m],y[m],z[m]\n0,{text},0,0\n1,0,0,0\n2,x,0,0\n")
    if text in NUMBERS_READ:
        assert read_csv(clean).T[0, 0, 3] == float(text)
        assert read_csv(mixed, skip_bad=True).T[0, 0, 3] == float(text)
    else:
        with pytest.raises(MeasurementError, match=r"line 2: x: .* is not a number"):
            read_csv(clean)
        assert [s["line"] for s in read_csv(mixed, skip_bad=True).skipped] == [2, 4]


def test_a_clean_file_takes_the_fast_path(tmp_path, monkeypatch):
    m = _meas(3000)
    p = write_csv(tmp_path / "m.csv", m)
    monkeypatch.setattr(io, "_convert_slow", lambda *a: pytest.fail("a clean file was read row by row"))
    back = read_csv(p)
    assert len(back) == 3000 and np.allclose(back.T, m.T, atol=1e-8)


def test_odd_but_valid_csv_files_are_read(tmp_path):
    p = _write(tmp_path / "bom.csv",
               "\ufeffstamp[s],pose,x[mm],y[mm],z[mm]\r\n0,\"P 1\",1,2,3\r\n1,\u00c9tape,1,2,3\r\n")
    m = read_csv(p)
    assert m.pose.tolist() == ["P 1", "Étape"] and m.has_orientation is False
    p = _write(tmp_path / "m.csv", H + ROW.format(t=0) + "# a comment between rows\n\n" + ROW.format(t=1))
    assert len(read_csv(p)) == 2


def test_a_bad_comment_is_listed_when_skipping(tmp_path):
    p = _write(tmp_path / "c.csv", b"# made at 20\xb0C\n" + _csv_around(ROW.format(t=1)).encode())
    with pytest.raises(MeasurementError, match=r"c.csv, line 1: byte 0xb0 at character 13 is not UTF-8"):
        read_csv(p)
    m = read_csv(p, skip_bad=True)
    assert len(m) == 3 and m.skipped == [{"line": 1, "reason": "byte 0xb0 at character 13 is not UTF-8"}]


def test_all_rows_bad_says_how_many_were_skipped(tmp_path):
    p = _write(tmp_path / "m.csv", H + "0,P1,0,x,2,3,0,0,0,1\n1,P1,0,y,2,3,0,0,0,1\n")
    with pytest.raises(MeasurementError,
                       match=r"no measurements \(2 bad row\(s\) skipped, the first on line 2: x: 'x'"):
        read_csv(p, skip_bad=True)
