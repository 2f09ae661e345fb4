"""The bounded YAML/JSON reader: what it refuses (with the file and line), what it reads as YAML 1.1 does,
and how fast it answers a hostile file."""
import time

import pytest
import yaml

from tolerance_ros.core import yamlio
from tolerance_ros.core.yamlio import loads_yaml, read_json, read_yaml


class FileError(ValueError):
    """Stands for a reader's own exception class."""


def _file(tmp_path, content, name="f.yaml"):
    p = tmp_path / name
    if isinstance(content, bytes):
        p.write_bytes(content)
    else:
        p.write_text(content)
    return p


def test_the_shipped_files_read_as_pyyaml_reads_them():
    root = yamlio.Path(__file__).resolve().parents[2] / "config"
    files = sorted(root.rglob("*.yaml"))
    assert len(files) >= 9
    for f in files:
        assert read_yaml(f) == yaml.safe_load(f.read_text()), f


@pytest.mark.parametrize("text, message", [
    ("[" * 100_000 + "]" * 100_000, r"line 1: nested deeper than 32 levels"),
    ("".join("  " * i + f"k{i}:\n" for i in range(200)), r"line 33: nested deeper than 32 levels"),
    ("- " * 100_000 + "x", r"line 1: nested deeper than 32 levels"),
    ("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(9)),
     r"line \d+: more than 500000 values \(counting what the aliases repeat\)"),
    ("a: &a [1, *a]", r"line 1: alias \*a refers to a collection that contains it"),
    ("a: *nowhere", r"line 1: alias \*nowhere refers to no anchor before it"),
    ("a: 1\nb: 2\na: 3\n", r"line 3: key 'a' given twice in one mapping"),
    ("x: 1_000", r"line 1: '1_000' is a number with digit separators.*YAML 1.1 reads 1000"),
    ("x: [0, 1:30]", r"line 1: '1:30' is a sexagesimal.*YAML 1.1 reads 90"),
    ("x: 017", r"'017' is an octal number.*YAML 1.1 reads 15"),
    ("x: 0x1F", r"'0x1F' is a hexadecimal number"),
    ("x: 0b11", r"'0b11' is a binary number"),
    ("a: 1\n---\nb: 2\n", r"line 2: more than one YAML document"),
    ("a: !!python/object:os.system x", r"line 1: tag .*python/object.* is not supported"),
    ("a: !!set {x}", r"tag .*set' is not supported"),
    ("a: !!int x", r"'x' is not a valid int"),
    ("? [a, b]\n: 1", r"a mapping key that is a collection; keys are text"),
    ("a: " + "9" * 5000, r"a number of 5000 digits"),
    ("a: 1\nb: \x00", r"line 2: not valid YAML: character #x0000 is not allowed"),
    ("a: [1, 2", r"line 2, column 1: not valid YAML: .*flow sequence"),
    ("a: x" * (yamlio.MAX_FILE_BYTES // 4 + 1), r"more than 4194304 characters"),
])
def test_hostile_text_is_refused_quickly_with_the_line(text, message):
    t0 = time.perf_counter()
    with pytest.raises(FileError, match=r"^src(, line \d+)?.*" + message):
        loads_yaml(text, "src", FileError)
    assert time.perf_counter() - t0 < 1.0


def test_values_read_as_yaml_1_1_reads_them_except_the_disputed_numbers():
    doc = loads_yaml("a: [1, -2, 3.5, .5, 1e3, -1.5e-3, .inf, 0, 08, 1.]\nb: [~, null, '', yes, off, True]\n"
                     "c: 2001-12-14\nd: '1_000'\ne: !!float 3\nf: !!str 5\n1: one\ntrue: t\n")
    assert doc["a"][:6] == [1, -2, 3.5, 0.5, 1000.0, -0.0015] and doc["a"][6] == float("inf")
    assert doc["a"][7:] == [0, "08", 1.0]
    assert doc["b"] == [None, None, "", True, False, True]
    assert doc["c"] == "2001-12-14" and doc["d"] == "1_000" and doc["e"] == 3.0 and doc["f"] == "5"
    assert doc["1"] == "one" and doc["true"] == "t"  # keys are text as written


def test_merge_keys_and_aliases_read_as_yaml_says():
    doc = loads_yaml("base: &b {a: 1, b: 2}\nm: {<<: *b, b: 3}\nn: {<<: [{x: 1}, *b], a: 0}\nk: &k name\ns: {*k : 1}\n")
    assert doc["m"] == {"a": 1, "b": 3} and doc["n"] == {"x": 1, "a": 0, "b": 2} and doc["s"] == {"name": 1}
    with pytest.raises(ValueError, match="a merge key '<<' needs a mapping"):
        loads_yaml("a: {<<: 5}")


def test_a_file_names_itself_and_its_bad_bytes(tmp_path):
    p = _file(tmp_path, b"a: 1\nname: caf\xe9\n")
    with pytest.raises(FileError, match=rf"^{p}, line 2, column 10: not UTF-8 text \(byte 0xe9\)"):
        read_yaml(p, FileError)
    assert read_yaml(_file(tmp_path, b"\xef\xbb\xbfa: 1\n")) == {"a": 1}  # a byte-order mark is allowed
    with pytest.raises(FileError, match=rf"^{tmp_path / 'nothing.yaml'}: cannot read"):
        read_yaml(tmp_path / "nothing.yaml", FileError)
    with pytest.raises(FileError, match="not a regular file"):
        read_yaml(tmp_path, FileError)


def test_an_oversized_file_is_refused_before_it_is_read(tmp_path):
    p = _file(tmp_path, "a: '" + "x" * (20 * 1024 * 1024) + "'\n")
    t0 = time.perf_counter()
    with pytest.raises(FileError, match=rf"^{p}: 20971526 bytes; a YAML file may have at most 4194304 bytes"):
        read_yaml(p, FileError)
    assert time.perf_counter() - t0 < 0.1


def test_json_files_have_the_same_bounds(tmp_path):
    assert read_json(_file(tmp_path, '{"a": [1, 2]}', "a.json")) == {"a": [1, 2]}
    with pytest.raises(FileError, match=r"b.json: key 'a' given twice in one object"):
        read_json(_file(tmp_path, '{"a": 1, "a": 2}', "b.json"), FileError)
    with pytest.raises(FileError, match=r"c.json: nested (deeper than 32|\d+ levels deep)"):
        read_json(_file(tmp_path, "[" * 100 + "]" * 100, "c.json"), FileError)
    with pytest.raises(FileError, match=r"d.json: nested deeper than 32"):
        read_json(_file(tmp_path, "[" * 100_000 + "]" * 100_000, "d.json"), FileError)
    with pytest.raises(FileError, match=r"e.json, line 2, column 1: not valid JSON"):
        read_json(_file(tmp_path, '{"a": 1,\n', "e.json"), FileError)
    with pytest.raises(FileError, match=r"f.json, line 1, column 8: not UTF-8"):
        read_json(_file(tmp_path, b'{"a": "\xff"}', "f.json"), FileError)


def test_a_large_campaign_loads_fast():
    """20,000 poses in about 1 MB: the C parser's events, one loop. The pure-Python loader took 12 s; timed
    against it on a twentieth of the text, in the same process, so that the machine's load cancels out."""
    text = "poses:\n" + "".join(f"  - {{name: P{i}, joints: [10, 20, 30, 40, 50, 60, {i % 90}]}}\n"
                                for i in range(20_000))
    assert 1.0e6 < len(text) < 1.2e6
    t0 = time.perf_counter()
    doc = loads_yaml(text)
    ours = time.perf_counter() - t0
    part = text[:text.index("\n", len(text) // 20) + 1]
    t0 = time.perf_counter()
    yaml.load(part, yaml.SafeLoader)
    pure = time.perf_counter() - t0
    assert ours < 5 * pure, f"{ours:.2f} s for the whole text, the pure-Python loader {pure:.2f} s for a twentieth"
    assert len(doc["poses"]) == 20_000 and doc["poses"][-1]["joints"][-1] == 19_999 % 90


@pytest.mark.parametrize("text", ["2e89134567890123", "1e5", "0123", "1_000", "12:30", "yes", "null", "0x1f", "-.5",
                                  "+7", "abc", "0a1b2c3d4e5f6071"])
def test_every_string_written_reads_back_as_written(text):
    """dump_yaml quotes what loads_yaml would read as a number or a word: a signing key's id of hex digits such as
    2e89134567890123 had been written plain by PyYAML and read back as a float (inf), failing its calibration."""
    from tolerance_ros.core.yamlio import dump_yaml, loads_yaml
    doc = {"key_id": text, "nested": [{"name": text}]}
    assert loads_yaml(dump_yaml(doc, default_flow_style=None)) == doc
