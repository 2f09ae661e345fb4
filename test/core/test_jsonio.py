"""JSON encoding: compact base64 arrays are standard base64 of the little-endian bytes, with pybase64 or not."""
import base64

import numpy as np
import pytest

from tolerance_ros.core import jsonio


@pytest.mark.parametrize("size", [0, 1, 2, 3, 3071, 3072, 3073, 3074, 3075, 100_000])
def test_b64encode_is_standard_base64(size):
    data = np.random.default_rng(size).integers(0, 256, size).astype(np.uint8)
    expected = base64.b64encode(data.tobytes()).decode()
    assert jsonio.b64encode(data) == expected
    assert jsonio.b64encode(data.tobytes()) == expected


def test_compact_arrays_round_trip_with_and_without_pybase64(monkeypatch):
    doc = {"J": np.random.default_rng(0).normal(size=(100, 6, 28)), "i": np.arange(5), "b": np.array([True, False]),
           "names": ["a", "b"], "nested": [{"x": np.eye(2)}]}
    compiled = jsonio.encode_arrays(doc)
    assert compiled["J"]["data"] == base64.b64encode(doc["J"].astype("<f8").tobytes()).decode()
    monkeypatch.setattr(jsonio, "_b64", base64)  # as when pybase64 is not installed
    assert jsonio.encode_arrays(doc) == compiled
    back = jsonio.decode_arrays(compiled)
    np.testing.assert_array_equal(back["J"], doc["J"])
    np.testing.assert_array_equal(back["i"], doc["i"])
    np.testing.assert_array_equal(back["b"], [1, 0])
    np.testing.assert_array_equal(back["nested"][0]["x"], np.eye(2))
    assert back["names"] == ["a", "b"]


@pytest.mark.parametrize("size", [0, 1, 2, 3, 3072, 3073, 3074, 3075, 100_000])
def test_b64decode_reads_what_b64encode_writes(size):
    data = np.random.default_rng(size).integers(0, 256, size).astype(np.uint8)
    text = jsonio.b64encode(data)
    assert jsonio.b64decode(text).tobytes() == data.tobytes()
    assert jsonio.b64decode(text.encode()).tobytes() == data.tobytes()


@pytest.mark.parametrize("library", ["pybase64", "base64"])
def test_b64decode_reads_malformed_text_as_base64_does(library, monkeypatch):
    """A character outside the alphabet, padding inside, too much padding, a line break, non-ASCII text: with
    pybase64 and with the standard library."""
    import importlib
    monkeypatch.setattr(jsonio, "_b64", importlib.import_module(library))
    good = base64.b64encode(bytes(range(256)) * 20).decode()
    for text in (good[:100] + "!" + good[101:], good[:100] + "=" + good[101:], good + "====", good[:-4] + "A===",
                 good[:2000] + "\n" + good[2000:], good[:-4] + "\u00e9AAA"):
        try:
            expected = base64.b64decode(text)
        except ValueError as exc:
            with pytest.raises(type(exc)):
                jsonio.b64decode(text)
        else:
            assert jsonio.b64decode(text).tobytes() == expected


def test_an_int_beyond_64_bits_is_written_not_refused():
    """orjson refuses such an int; the answer is still the strict JSON of the value (a fuzzed calibration carried
    one into the monitor's report)."""
    import json as std_json
    from tolerance_ros.core.jsonio import dumps_fast
    doc = {"n": 10 ** 30, "x": np.array([1.5, np.nan]), "m": -2 ** 70}
    assert std_json.loads(dumps_fast(doc)) == {"n": 10 ** 30, "x": [1.5, None], "m": -2 ** 70}
