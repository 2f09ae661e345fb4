"""Readers: CSV (units, bad rows), the campaign log, rosbag2 (sqlite3 and mcap) and stamp pairing; every
malformed file of issue 12 is one MeasurementError naming file, line and field, or a listed skip (the
monitor that writes the log has its own tests)."""
import functools
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tolerance_ros.core.accuracy.io import campaign_log, csv_format
from tolerance_ros.core.accuracy.io import (MAX_LINE, Measurements, MeasurementError, read_csv, read_log,
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
    ("stamp,x[mm],y[mm],z[mm]\n0,1,2,3\n", r"column 'stamp' needs a time unit in brackets \(s, ms, us, ns\), got ''"),
    ("stamp[s],x[mm],y[mm],z[mm],marker_std[mm]\n0,1,2,3,0.2\n",
     r"line 1: header: column 'marker_std' is not a measurement column .*'tolerance-ros import'"),
    ("stamp[s],target,x[mm],y[mm],z[mm]\n0,A,1,2,3\n1, ,1,2,3\n", "line 3: target: empty"),
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
    ("the same record twice", ROW.format(t=0), "the same record as line 2 (a measurement written twice)"),
    ("the same record with other spacing", ROW.format(t=0).replace(",", " , "),
     "the same record as line 2 (a measurement written twice)"),
    ("the same record with its numbers written otherwise", "0.0,P1,0,1.00,2e0,3.000,0,0,0,1.0\n",
     "the same record as line 2 (a measurement written twice)"),
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
    ("a load without fz", "stamp[s],x[mm],y[mm],z[mm],load:fx[N],load:fy[N]\n0,1,2,3,0,0\n",
     "header: the load needs all of load:fx, load:fy, load:fz; missing column(s) ['load:fz']"),
    ("a load in kilograms", "stamp[s],x[mm],y[mm],z[mm],load:fx[kg],load:fy[N],load:fz[N]\n0,1,2,3,0,0,0\n",
     "header: column 'load:fx' needs a force unit in brackets (N, kN), got 'kg'"),
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
    monkeypatch.setattr(csv_format, "_convert_slow", lambda *a: pytest.fail("a clean file was read row by row"))
    back = read_csv(p)
    assert len(back) == 3000 and np.allclose(back.T, m.T, atol=1e-8)


def test_equal_stamps_or_equal_values_alone_are_two_measurements(tmp_path):
    rows = [ROW.format(t=0), ROW.format(t=0).replace(",1,2,3,", ",1,2,3.001,"), ROW.format(t=1)]
    m = read_csv(_write(tmp_path / "m.csv", H + "".join(rows)))
    assert m.stamps.tolist() == [0.0, 0.0, 1.0] and not m.skipped


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


# ---------------------------------------------------------------- malformed campaign logs (issue 12)


def _m(seq, **kw):
    return json.dumps({"event": "measurement", "seq": seq, "stamp": 10.0 + int(seq), "frame": "tracker",
                       "position": [0.5, 0.1, 0.2], "quaternion": [0.0, 0.0, 0.0, 1.0], **kw})


def _p(seq, **kw):
    return json.dumps({"event": "paired", "seq": seq, "joint_stamp": 10.0 + seq, "joint_names": ["j1", "j2"],
                       "joints": [0.1 * seq, 0.2], "pose": "P1", "verdict": "within", **kw})


def _log_around(*bad_lines):
    """Good records 0 (lines 1-2) and 1 (after ``bad_lines``, which start on line 3)."""
    lines = [_m(0), _p(0), *bad_lines, _m(1), _p(1)]
    if any(isinstance(x, bytes) for x in lines):
        return b"".join((x if isinstance(x, bytes) else x.encode()) + b"\n" for x in lines)
    return "".join(x + "\n" for x in lines)


BAD_LOG_LINES = [
    ("not an object", ["[1, 2]"], "expected a JSON object, got a JSON array"),
    ("a number", ["7"], "expected a JSON object, got 7"),
    ("100,000 deep array", ["[" * 100_000 + "]" * 100_000], "nested deeper than 64 levels"),
    ("100,000 deep object", ['{"a":' * 100_000 + "1" + "}" * 100_000], "nested deeper than 64 levels"),
    ("65 deep", [_m(5, frame=json.loads("[" * 64 + "]" * 64))], "nested deeper than 64 levels"),
    ("line over MAX_LINE", [_m(5, frame="t" * MAX_LINE)], f"line longer than {MAX_LINE} characters"),
    ("non-UTF-8 byte", [_m(5).encode().replace(b'"tracker"', b'"tr\xe4cker"')],
     "byte 0xe4 at character 63 is not UTF-8"),
    ("truncated line", [_m(5)[:-10]], "not valid JSON (Expecting value at character 126)"),
    ("3-value quaternion", [_m(5, quaternion=[0, 0, 1])], "quaternion: expected 4 numbers, got 3"),
    ("zero quaternion", [_m(5, quaternion=[0, 0, 0, 0])], "quaternion: zero norm"),
    ("position as a number", [_m(5, position=3)], "position: expected a list of 3 numbers, got 3"),
    ("joints as strings", [_m(5), _p(5, joints=["0.1", "0.2"])], "joints: expected numbers, got '0.1'"),
    ("joints as booleans", [_m(5), _p(5, joints=[True, 0.2])], "joints: expected numbers, got true"),
    ("a null joint", [_m(5), _p(5, joints=[0.1, None])], "joints: expected numbers, got null"),
    ("a null position", [_m(5, position=[None, 0, 0])], "position: expected numbers, got null"),
    ("a joint missing", [_m(5), _p(5, joint_names=["j1", "j3"])],
     "joints: no value for joint(s) ['j2'] (have ['j1', 'j3'])"),
    ("fewer joints than names", [_m(5), _p(5, joints=[0.1])], "joints: expected 2 numbers, got 1"),
    ("underscore stamp", [_m(5, stamp="1_000")], "stamp: expected a number, got '1_000'"),
    ("Arabic-Indic stamp", [_m(5, stamp="\u0661\u0662")], "stamp: expected a number, got '١٢'"),
    ("stamp missing", [_m(5, stamp=None).replace('"stamp": null, ', "")], "stamp: missing"),
    ("duplicate measurement seq", [_m(0)], "seq: measurement 0 already logged on line 1"),
    ("duplicate pairing", [_p(0)], "seq: measurement 0 already paired on line 2"),
    ("unpaired after paired", ['{"event": "unpaired", "seq": 0, "reason": "late"}'],
     "seq: measurement 0 already paired on line 2"),
    ("paired before its measurement", [_p(7)], "seq: no measurement 7 logged before this paired event"),
    ("NaN position", [_m(5).replace("[0.5, 0.1, 0.2]", "[0.5, NaN, 0.2]")],
     "position: NaN is not valid JSON (numbers must be finite)"),
    ("Infinity stamp", [_m(5).replace('"stamp": 15.0', '"stamp": Infinity')],
     "stamp: Infinity is not valid JSON (numbers must be finite)"),
    ("NaN in a field the reader does not use", [_m(5), _p(5).replace('"within"', "NaN")],
     "verdict: NaN is not valid JSON"),
    ("overflowing stamp", [_m(5).replace('"stamp": 15.0', '"stamp": 1e999')],
     "stamp: a number beyond the range of a float (not finite)"),
    ("huge integer stamp", [_m(5).replace('"stamp": 15.0', '"stamp": ' + "9" * 400)],
     "stamp: a number beyond the range of a float (not finite)"),
    ("repeated key", [_m(5).replace('"seq": 5', '"seq": 5, "seq": 0')], "seq: appears twice in one object"),
    ("seq as a string", [_m("5")], "seq: expected a non-negative integer, got '5'"),
    ("negative seq", [_m(-5)], "seq: expected a non-negative integer, got -5"),
    ("unknown event", ['{"event": "measurment", "seq": 5}'],
     "event: expected start, budget, calibration, measurement, paired or unpaired, got 'measurment'"),
    ("pose label as a list", [_m(5), _p(5, pose=["P1"])],
     "pose: expected a test pose name of at most 100 characters or null, got a JSON array"),
]


@pytest.mark.parametrize("bad_lines, message", [c[1:] for c in BAD_LOG_LINES], ids=[c[0] for c in BAD_LOG_LINES])
def test_a_bad_log_line_is_named_or_skipped_and_listed(tmp_path, bad_lines, message):
    p = _write(tmp_path / "campaign.jsonl", _log_around(*bad_lines))
    bad_line = 2 + len(bad_lines)
    with pytest.raises(MeasurementError) as err:
        read_log(p)
    assert str(err.value).startswith(f"{p}, line {bad_line}: {message}")
    m = read_measurements(p, skip_bad=True)
    assert m.stamps.tolist() == [10.0, 11.0] and m.joints.tolist() == [[0.0, 0.2], [0.1, 0.2]]
    assert [s["line"] for s in m.skipped] == list(range(3, bad_line + 1))  # the bad line, and what it leaves undecided
    assert m.skipped[-1]["reason"].startswith(message)


def test_a_deep_log_line_never_reaches_the_parser(tmp_path, monkeypatch):
    p = _write(tmp_path / "campaign.jsonl", _log_around("[" * 100_000 + "]" * 100_000))
    parsed = []
    real = json.loads
    monkeypatch.setattr(campaign_log.json, "loads", lambda s, **kw: parsed.append(len(s)) or real(s, **kw))
    with pytest.raises(MeasurementError, match="line 3: nested deeper than 64 levels"):
        read_log(p)
    assert parsed and max(parsed) < 1000


def test_brackets_inside_strings_are_not_nesting(tmp_path):
    deep_text = "[{" * 100 + '\\"' + "}]" * 100
    p = _write(tmp_path / "campaign.jsonl",
               _log_around(_m(5, frame=deep_text), '{"event": "unpaired", "seq": 5, "reason": "none"}'))
    m = read_log(p)
    assert len(m) == 2 and m.skipped == [{"line": 4, "seq": 5, "reason": "unpaired: none"}]


def test_a_log_with_two_monitor_runs_keeps_both(tmp_path):
    start = json.dumps({"event": "start", "robot": "r", "joint_names": ["j1", "j2"]})
    second = _p(0, joint_names=["j2", "j1"], joints=[0.2, 0.7]).replace('"P1"', '"P2"')
    p = _write(tmp_path / "campaign.jsonl", "\n".join([start, _m(0), _p(0), start, _m(0, stamp=20.0), second,
                                                       _m(1)]) + "\n")
    m = read_log(p)
    assert m.stamps.tolist() == [10.0, 20.0] and m.pose.tolist() == ["P1", "P2"]
    assert m.joints.tolist() == [[0.0, 0.2], [0.7, 0.2]]
    assert m.skipped == [{"line": 7, "seq": 1, "reason": "pairing not decided before the log ended"}]


def test_a_log_without_pairs_says_what_was_skipped(tmp_path):
    p = _write(tmp_path / "campaign.jsonl", _m(0, rejected="pose: non-finite position or quaternion") + "\n")
    with pytest.raises(MeasurementError, match=r"no paired measurements \(1 skipped, the first on line 1: rejected: "):
        read_log(p)


# ---------------------------------------------------------------- malformed rosbags


def test_a_bag_with_a_non_finite_pose_or_missing_joints_names_the_message(tmp_path):
    m = _meas(4)
    m.T[2, 1, 3] = np.nan
    write_rosbag(tmp_path / "nan", m, "mcap")
    with pytest.raises(MeasurementError, match=r"nan: message 5 on /measured_pose: pose: non-finite position"):
        read_rosbag(tmp_path / "nan")
    back = read_rosbag(tmp_path / "nan", skip_bad=True)
    assert len(back) == 3 and back.skipped[0]["message"] == 5
    write_rosbag(tmp_path / "ok", _meas(4), "sqlite3")
    with pytest.raises(MeasurementError, match=r"ok: message 0 on /joint_states: no value for joint\(s\) \['j3'\]"):
        read_rosbag(tmp_path / "ok", joint_names=("j1", "j2", "j3"))


def test_a_bag_that_is_not_what_it_claims_is_one_error(tmp_path):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    with Writer(tmp_path / "garbage", version=9) as w:
        w.write(w.add_connection("/measured_pose", "geometry_msgs/msg/PoseStamped", typestore=ts), 1, b"\x00\x01\x00")
    with pytest.raises(MeasurementError, match="message 0 on /measured_pose: cannot be decoded as geometry_msgs"):
        read_rosbag(tmp_path / "garbage")
    String = ts.types["std_msgs/msg/String"]
    with Writer(tmp_path / "string", version=9) as w:
        c = w.add_connection("/measured_pose", String.__msgtype__, typestore=ts)
        w.write(c, 1, ts.serialize_cdr(String(data="hi"), String.__msgtype__))
    with pytest.raises(MeasurementError, match="topic /measured_pose carries std_msgs/msg/String, expected"):
        read_rosbag(tmp_path / "string")
    _write(tmp_path / "x.db3", b"\x00" * 200)
    with pytest.raises(MeasurementError, match="x.db3: not a readable rosbag2 recording"):
        read_measurements(tmp_path / "x.db3")
    (tmp_path / "empty").mkdir()
    with pytest.raises(MeasurementError, match="empty: not a readable rosbag2 recording"):
        read_measurements(tmp_path / "empty")


# ---------------------------------------------------------------- random bytes and mutations

@functools.cache
def _valid_files():
    with tempfile.TemporaryDirectory() as tmp:
        csv_text = write_csv(Path(tmp) / "valid.csv", _meas(6)).read_bytes()
    log = _log_around(_m(2), '{"event": "unpaired", "seq": 2, "reason": "none"}').encode()
    return csv_text, log


TOKENS = [b"NaN", b"Infinity", b"-inf", b"1_000", "\u0661".encode(), b"\xff", b"\xc3", b'"', b",", b"\n", b"\r",
          b"[" * 70, b"\n" + b"[" * 5000 + b"\n", b"{", b"}", b"]", b"#", b"1e999", b"", b" ", b"\x00", b"\\",
          b'"seq": 0, "seq": 1', b"null", b"true", "\ufeff".encode(), b"\n[1, 2]\n", b"\n7\n",
          b'"' + b"p" * 140_000 + b'"']


@st.composite
def _mutated(draw, base):
    data = bytearray(base)
    for _ in range(draw(st.integers(1, 6))):
        i = draw(st.integers(0, len(data)))
        kind = draw(st.sampled_from(["insert", "delete", "replace", "duplicate-line"]))
        if kind == "insert":
            data[i:i] = draw(st.sampled_from(TOKENS) | st.binary(max_size=8))
        elif kind == "delete":
            del data[i:i + draw(st.integers(1, 20))]
        elif kind == "replace":
            data[i:i + 1] = draw(st.sampled_from(TOKENS) | st.binary(min_size=1, max_size=1))
        else:
            lines = bytes(data).split(b"\n")
            k = draw(st.integers(0, len(lines) - 1))
            data = bytearray(b"\n".join(lines[:k + 1] + lines[k:]))
    return bytes(data)


_FUZZ = settings(max_examples=300, deadline=None, database=None,
                 suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _read_or_measurement_error(path, reader):
    for skip in (False, True):
        try:
            m = reader(path, skip_bad=skip)
        except MeasurementError:
            continue
        assert isinstance(m, Measurements) and len(m.T) == len(m.stamps)
        assert np.all(np.isfinite(m.T)) and np.all(np.isfinite(m.stamps))


@_FUZZ
@given(content=st.binary(max_size=600))
def test_random_bytes_are_read_or_refused(tmp_path, content):
    for name, reader in (("f.csv", read_csv), ("f.jsonl", read_log)):
        _read_or_measurement_error(_write(tmp_path / name, content), reader)


@_FUZZ
@given(data=st.data())
def test_mutated_files_are_read_or_refused(tmp_path, data):
    csv_text, log = _valid_files()
    _read_or_measurement_error(_write(tmp_path / "m.csv", data.draw(_mutated(csv_text))), read_csv)
    _read_or_measurement_error(_write(tmp_path / "m.jsonl", data.draw(_mutated(log))), read_log)


def test_targets_are_read_written_and_indexed(tmp_path):
    p = _write(tmp_path / "t.csv", "stamp[s],pose,target,x[mm],y[mm],z[mm],joint:j1[rad]\n"
                                  "0,P1,A,1,2,3,0.1\n0,P1,B,4,5,6,0.1\n1,P2,A,7,8,9,0.2\n1,P2,C,1,1,1,0.2\n")
    m = read_csv(p)
    assert m.target.tolist() == ["A", "B", "A", "C"] and m.target_names == ("A", "B", "C")
    assert m.target_index().tolist() == [0, 1, 0, 2] and m.has_orientation is False
    back = read_csv(write_csv(tmp_path / "back.csv", m))
    assert back.target.tolist() == m.target.tolist() and back.has_orientation is False
    assert np.allclose(back.T[:, :3, 3], m.T[:, :3, 3])
    assert read_csv(write_csv(tmp_path / "one.csv", _meas())).target_names == ("",)
    with pytest.raises(MeasurementError, match=r"target\(s\) \['C'\] are not among \['A', 'B'\]"):
        m.target_index(("A", "B"))


def test_position_only_measurements_are_written_without_orientation(tmp_path):
    m = _meas()
    m.has_orientation = False
    text = write_csv(tmp_path / "p.csv", m).read_text()
    assert "roll" not in text and read_csv(tmp_path / "p.csv").has_orientation is False


def test_loads_are_read_in_newtons_and_written_back(tmp_path):
    text = ("stamp[s],pose,x[mm],y[mm],z[mm],load:fx[kN],load:fy[N],load:fz[N]\n"
            "0,P1,1,2,3,0,0,0\n1,P1,1,2,3.2,0.2,0,-50\n")
    m = read_csv(_write(tmp_path / "l.csv", text))
    assert m.load.tolist() == [[0, 0, 0], [200, 0, -50]] and m.select([1]).load.tolist() == [[200, 0, -50]]
    again = read_csv(write_csv(tmp_path / "again.csv", m))
    assert np.allclose(again.load, m.load) and np.allclose(again.T, m.T)
    slow = read_csv(_write(tmp_path / "s.csv", text + "2,P1,1,2,x,0,0,0\n"), skip_bad=True)   # row by row
    assert slow.load.tolist() == m.load.tolist() and slow.skipped[0]["line"] == 4
    assert read_csv(_write(tmp_path / "n.csv", "stamp[s],x[mm],y[mm],z[mm]\n0,1,2,3\n")).load is None
    wrench = read_csv(_write(tmp_path / "w.csv", "stamp[s],x[mm],y[mm],z[mm],load:fx[N],load:fy[N],load:fz[N],"
                                                 "load:mx[kNm],load:my[Nm],load:mz[Nm]\n0,1,2,3,0,0,5,0.02,0,-3\n"))
    assert wrench.load.tolist() == [[0, 0, 5, 20, 0, -3]]
    assert np.allclose(read_csv(write_csv(tmp_path / "w2.csv", wrench)).load, wrench.load)
    with pytest.raises(MeasurementError, match=r"the load needs all of load:fx, .*load:mz; missing column\(s\) "
                                               r"\['load:fx', 'load:fy', 'load:fz', 'load:my', 'load:mz'\]"):
        read_csv(_write(tmp_path / "m.csv", "stamp[s],x[mm],y[mm],z[mm],load:mx[Nm]\n0,1,2,3,0\n"))
