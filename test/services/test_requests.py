"""Joint configurations of a request: many poses are converted and checked in one numpy pass, and every value
that is not a number (a bool among them, which numpy would take for 0 or 1) is refused by name, as for a few."""
import numpy as np
import pytest

from tolerance_ros.core.models import load_robot
from tolerance_ros.services.contracts import ContractError, Limits
from tolerance_ros.services.requests import _FEW, _SUSPECTS, parse_joints


@pytest.fixture(scope="module")
def gao():
    return load_robot("gao2023_7dof")


def rows(gao, n, seed=0):
    return gao.sample_joints(n, np.random.default_rng(seed)).tolist()


@pytest.mark.parametrize("n", [1, _FEW, _FEW + 1, 100])
def test_numbers_give_the_same_array_by_either_path(gao, n):
    value = rows(gao, n)
    value[-1][2] = 0  # an int zero: a number
    value[0][1] = 1
    q = parse_joints(value, gao, Limits(), False)
    assert q.dtype == float and q.shape == (n, 7) and np.array_equal(q, np.array(value, dtype=float))


@pytest.mark.parametrize("n", [_FEW + 1, 100])
@pytest.mark.parametrize("bad, name", [(True, "bool"), (False, "bool"), (None, "NoneType"), ("0.5", "str"),
                                       ([0.5], "list"), ({"a": 1}, "dict")])
def test_a_value_that_is_not_a_number_is_named_among_many_poses(gao, n, bad, name):
    value = rows(gao, n)
    value[n - 2][4] = bad
    with pytest.raises(ContractError, match=rf"^joints\[{n - 2}\]\[4\]: expected a number, got {name}$"):
        parse_joints(value, gao, Limits(), False)


def test_a_bool_among_more_zeros_than_are_looked_at_one_by_one_is_found(gao):
    value = [[0.0] * 7 for _ in range(_SUSPECTS)] + [[0.0] * 6 + [True]]
    with pytest.raises(ContractError, match=rf"^joints\[{_SUSPECTS}\]\[6\]: expected a number, got bool$"):
        parse_joints(value, gao, Limits(), False)
    value[-1][6] = 0
    assert not parse_joints(value, gao, Limits(), False).any()


def test_ragged_rows_and_huge_ints_among_many_poses_are_refused_by_name(gao):
    value = rows(gao, 20)
    value[7] = value[7][:6]
    with pytest.raises(ContractError, match=r"^joints\[7\]: expected 7 values \(joint1, .*\), got 6$"):
        parse_joints(value, gao, Limits(), False)
    value = rows(gao, 20)
    value[3][0] = 10 ** 400
    with pytest.raises(ContractError, match="joints: a value is too large for a float"):
        parse_joints(value, gao, Limits(), False)
    value = rows(gao, 20)
    value[5][1] = float("nan")
    with pytest.raises(ContractError, match=r"^joints\[5\]\[1\]: not a finite number$"):
        parse_joints(value, gao, Limits(), False)
