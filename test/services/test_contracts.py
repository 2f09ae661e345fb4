"""The JSON envelope: safe parsing (size, UTF-8, depth), ids, error codes, and budget messages."""
import json
import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tolerance_ros.core.budget import load_budget
from tolerance_ros.services.contracts import (MAX_DEPTH, ContractError, Limits, answer_id, budget_from_message,
                                              error_code, error_response, nesting_depth, parse_request,
                                              request_id_of)

FIELDS = {"x": ((int,), False)}


@pytest.mark.parametrize("text, code, needle", [
    ('{"a":' * 52500 + '0' + '}' * 52500, "invalid_json", f"nested deeper than {MAX_DEPTH}"),
    ('[' * 17 + ']' * 17, "invalid_json", "nested deeper"),
    (b'{"id": 1, "x": 1}\xff', "invalid_json", "not UTF-8 text: byte 17"),
    ('{"id": "\ud800", "x": 1}', "invalid_json", "lone surrogate"),
    ('{"id": "\\ud800", "x": 1}', "invalid_", ""),
    ('{"id": 1, "x": 1}\ud800', "invalid_json", "lone surrogate"),
    ('{"id": 18446744073709551616}', "invalid_", ""),
    ('{"id": 1, "x": 1.5}', "invalid_request", "x: expected an integer, got a number"),
    ('{"id": "' + "i" * 300 + '"}', "invalid_request", "id: a string of at most 256"),
    ('{"id": 1, "x": ' + "[" * 10 + "]" * 10 + "}", "invalid_request", "x: expected an integer, got a list"),
    ("x" * 2_000, "too_large", "more than 1000 bytes"),
])
def test_hostile_envelopes_get_their_own_code(text, code, needle):
    with pytest.raises(ContractError) as exc:
        parse_request(text, FIELDS, Limits(max_bytes=1000 if code == "too_large" else 1_000_000))
    assert exc.value.code.startswith(code) and needle in exc.value.message


def test_depth_is_found_without_parsing_and_brackets_in_strings_do_not_count():
    assert nesting_depth('{"a": [1, {"b": [2]}]}') == 4
    assert nesting_depth('{"a": "' + "[" * 100 + '"}') == 1
    assert nesting_depth("[" * 100_000) == 100_000


def test_depth_of_long_texts_with_escapes_and_non_ascii_strings():
    """Past MAX_DEPTH brackets the strings are dropped, then every byte but the brackets."""
    many = "[" + ",".join(["[1.5, 2]"] * 50) + "]"
    assert nesting_depth(many) == 2
    assert nesting_depth('{"\u00e9[\\"[": ' + many + ', "\U0001f600{{": [[["x]"]]]}') == 4
    assert nesting_depth('{"a\\\\": ' + "[" * 20 + "]" * 20 + "}") == 21
    assert nesting_depth("[" * 17 + '"\ud800"' + "]" * 17) == 17


@pytest.mark.parametrize("text, rid", [
    ('{"id": "abc", "joints": [NaN]}', "abc"), ('{"id": 42, x', 42), ('{"id": "a\\"b", x', 'a"b'),
    ('{"id": 18446744073709551616, x}', None), ('{"id": ' + "9" * 4301 + ", x}", None), ("no id", None),
    ('{"id": "\ud800", x', None), ("x" * 100_000 + '{"id": 1}', None), (b'{"id": 7, \xff', 7),
])
def test_the_id_of_a_broken_request_is_recovered_safely(text, rid):
    assert request_id_of(text) == rid


@pytest.mark.parametrize("text", [
    '{"zz": {"id": "inner"}, "id": "abc", "joints": [NaN]}', '{"zz": [{"id": 5}], "s": "{\\"id\\": 6}", "id": "abc", x',
    '{"zz": {"id": "inner"}, "id": "abc", "pad": "' + "x" * 2000 + '"}',
])
def test_the_recovered_id_is_the_top_level_one(text):
    assert request_id_of(text) == "abc"


@pytest.mark.parametrize("text, rid", [
    ('{"zz": {"id": "inner"}, "id": "abc", "x": 1}', "abc"), ('{"zz": {"id": "inner"}, "id": true, "x": 1}', None),
    ('[{"id": "inner"}]', None), ('{"zz": {"id": "inner"}, "x": "no id"}', None),
])
def test_an_error_about_a_parsed_request_carries_its_own_top_level_id(text, rid):
    with pytest.raises(ContractError) as exc:
        parse_request(text, FIELDS, Limits())
    assert exc.value.request_id == rid and answer_id(exc.value, text) == rid


@pytest.mark.parametrize("payload", [None, 42, 1.5, ["{}"], {"id": 1}, object()])
def test_a_payload_that_is_not_text_is_an_invalid_request(payload):
    with pytest.raises(ContractError) as exc:
        parse_request(payload, FIELDS, Limits())
    assert exc.value.code == "invalid_request" and "expected the request as text" in exc.value.message


def test_error_codes_come_from_the_exception_type():
    from tolerance_ros.core.budget import BudgetError
    from tolerance_ros.core.synthesis import InfeasibleError, SynthesisError
    assert error_code(InfeasibleError("x")) == "infeasible"
    assert error_code(SynthesisError("infeasible, says the text")) == "invalid_request"
    assert error_code(BudgetError("x")) == "invalid_request" and error_code(KeyError("x")) == "internal"
    r = error_response(3, RuntimeError("y" * 2000))
    assert r["error"]["message"].startswith("RuntimeError: yyy") and len(r["error"]["message"]) < 600


def test_budget_messages(gao):
    budget = load_budget("gao2023_delta2", gao)
    text = json.dumps({"robot": "gao2023_7dof", "budget": budget.to_dict()})
    robot, got = budget_from_message(text, {"gao2023_7dof": gao})
    assert robot == "gao2023_7dof" and got.tolerances == pytest.approx(budget.tolerances)
    for bad, code in ([1], "invalid_request"), (5, "invalid_request"), ("x", "invalid_json"), (None, "invalid_request"):
        with pytest.raises(ContractError) as exc:
            budget_from_message(json.dumps(bad) if bad != "x" else "x", {"gao2023_7dof": gao})
        assert exc.value.code == code
    only_a1 = json.dumps({"robot": "gao2023_7dof", "budget": {"tolerances": {"a1": 1e-4}}})
    with pytest.raises(ContractError, match="no tolerance for"):
        budget_from_message(only_a1, {"gao2023_7dof": gao})
    for name, value, needle in (("a1", 1e308, "a1: 1e+308 is beyond 1 m"), ("alpha1", 4.0, "alpha1: 4.0 is beyond 3.14159 rad"),
                                ("a1", -1e-3, "a1: must be >= 0"),
                                ("a1", "1+" * 30000 + "1", "more than 100 characters"),
                                ("a1", "1" + "0" * 400, "more than 100 characters")):
        doc = budget.to_dict()
        doc["tolerances"][name] = value
        with pytest.raises(ContractError, match=re.escape(needle)) as exc:
            budget_from_message(json.dumps({"robot": "gao2023_7dof", "budget": doc}), {"gao2023_7dof": gao})
        assert exc.value.code == "invalid_request"
    with pytest.raises(ContractError) as exc:
        budget_from_message('{"robot": "ur5", "budget": {}}', {"gao2023_7dof": gao})
    assert exc.value.code == "unknown_robot"
    with pytest.raises(ContractError) as exc:
        budget_from_message('{"a":' * 1000 + '0' + '}' * 1000, {"gao2023_7dof": gao})
    assert exc.value.code == "invalid_json"


def _depth_by_hand(text):
    """The deepest nesting, character by character (strings and their escapes skipped)."""
    depth = best = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            escaped, in_string = (False, True) if escaped else (ch == "\\", ch != '"')
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            best = max(best, depth)
        elif ch in "]}":
            depth -= 1
    return best


@settings(max_examples=400, deadline=None)
@given(st.lists(st.sampled_from(["[", "]", "{", "}", ",", "1.5", '"a"', '"[{"', '"\\\\"', '"\\""', " "]),
                max_size=300),
       st.integers(0, 40))
def test_the_depth_of_any_text_is_the_depth_counted_by_hand(parts, nest):
    """Exact past MAX_DEPTH; within it, a bound that never crosses it (the count of openings)."""
    text = "[" * nest + "".join(parts) + "]" * nest
    depth, by_hand = nesting_depth(text), _depth_by_hand(text)
    assert depth == by_hand if by_hand > MAX_DEPTH else by_hand <= depth <= MAX_DEPTH


def test_request_ids_are_uuid4_not_the_process_id():
    import os
    import re
    from tolerance_ros.services.contracts import request_id, valid_id
    ids = {request_id() for _ in range(1000)}
    assert len(ids) == 1000 and all(re.fullmatch(r"[0-9a-f]{32}", i) and i[12] == "4" for i in ids)
    assert not any(i.startswith(f"{os.getpid()}-") for i in ids) and all(valid_id(i) for i in ids)
