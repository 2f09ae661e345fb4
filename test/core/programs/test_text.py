"""A program's text: bytes kept, comments and strings masked in place, numbers written with the digits they need and
unchanged where their value did not change."""
import pytest

from tolerance_ros.core.programs.text import (DECIMALS, Lines, ProgramError, formatted, mask, number_at, read_text,
                                              replaced, split_top, to_bytes)


def test_every_byte_survives_a_round_trip(tmp_path):
    raw = b"MODULE M\r\n  ! caf\xe9 in Latin-1\r\n  CONST num x:=1;\r\nENDMODULE"     # CRLF, no last newline
    (tmp_path / "m.mod").write_bytes(raw)
    assert to_bytes(read_text(tmp_path / "m.mod")) == raw


def test_a_file_too_large_is_refused(tmp_path, monkeypatch):
    from tolerance_ros.core.programs import text
    (tmp_path / "big.mod").write_bytes(b"!" * 2048)
    monkeypatch.setattr(text, "MAX_BYTES", 1024)
    with pytest.raises(ProgramError, match="big.mod:1: .* up to 0 MiB"):
        read_text(tmp_path / "big.mod")


def test_comments_and_strings_are_blanked_in_place():
    text = 'VAR string s := "a ! not a comment";  ! MoveL p10 in a comment\nMoveL p20;'
    code = mask(text, "!", '"')
    assert len(code) == len(text) and "MoveL p10" not in code and "not a comment" not in code
    assert code.index("MoveL p20") == text.index("MoveL p20")
    kept = mask(text, "!", '"', keep_strings=True)
    assert '"a ! not a comment"' in kept and "p10" not in kept


def test_numbers_keep_their_text_unless_their_value_changes():
    assert formatted(1200.0 + 1e-12, "1200", "mm") == "1200"              # unchanged: the text as written
    assert formatted(90.0000001, "90.000", "deg") == "90.000"             # below the digits written: unchanged
    assert formatted(1200.00042, "1200", "mm") == "1200.0004"             # changed: at least DECIMALS digits
    assert formatted(-0.43712, "-.437", "deg") == "-.43712"               # FANUC's style, no leading zero
    assert formatted(-1e-9, "0.000", "mm") == "0.000"                     # no negative zero
    assert formatted(-2e-5, "0.5", "mm") == "0.0000"
    assert formatted(0.12345678901, "0.12345678901", "m") == "0.12345678901"   # more digits than needed: kept
    assert formatted(0.70710678, "0.707107", "quat") == "0.70710678"
    assert all(v >= 4 for v in DECIMALS.values())


def test_numbers_are_found_exactly_or_refused():
    n = number_at("x = -.437 deg", 3, 9, "f:1")
    assert (n.text, n.value, n.start, n.end) == ("-.437", -0.437, 4, 9)
    for bad in ("1.2.3", "x", "9e999"):
        with pytest.raises(ProgramError, match="f:1"):
            number_at(bad, 0, len(bad), "f:1")


def test_edits_split_and_lines():
    assert replaced("abcdef", [(4, 5, "X"), (0, 1, "YY")]) == "YYbcdXf"
    with pytest.raises(ValueError):
        replaced("abcdef", [(0, 3, "a"), (2, 4, "b")])
    text = "f(a, [1, 2], {3, 4}), 5"
    assert [text[a:b].strip() for a, b in split_top(text, 0, len(text))] == ["f(a, [1, 2], {3, 4})", "5"]
    lines = Lines("a\r\nb\nc")
    assert [lines.line(i) for i in (0, 3, 5)] == [1, 2, 3] and lines.start(3) == 5
