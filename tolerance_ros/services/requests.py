"""Request fields the services share, parsed and checked (SI): joint configurations and tool poses. The
bottom of a request's way through ``services/``: the error model and compensation parse with it, and it
imports only the contracts below it."""
from __future__ import annotations

from itertools import chain
from operator import le

import numpy as np

from ..core.geometry import quat_to_matrices
from ..core.ingest import MAX_POSITION_M
from .contracts import ContractError, Limits

_NUMBERS = {int, float}
_FEW = 8  # poses checked against the limits in Python lists rather than numpy


def parse_joints(value, model, limits: Limits, allow_out_of_limits: bool) -> np.ndarray:
    """(n, dof) joints from one configuration (list of numbers) or many (list of lists)."""
    return _parse_joints(value, model, limits, allow_out_of_limits)[0]


def _parse_joints(value, model, limits: Limits, allow_out_of_limits: bool, bounds=None) -> tuple:
    """``parse_joints`` and the (n, dof) mask of joints outside their limits (None when there are none).
    ``bounds``: the model's (lower - 1e-12, upper + 1e-12), when the caller keeps them (optionally followed
    by the same two as lists of floats). The checks run over whole rows and arrays in C (``map``, numpy; a
    few poses against lists of floats, cheaper than numpy's calls; many in one numpy conversion, see
    ``_numbers_array``); the loops that name the offending entry run only on a failure."""
    if not isinstance(value, list) or not value:
        raise ContractError("invalid_request", "joints: expected a non-empty list (one configuration) or a list of lists")
    rows = value if isinstance(value[0], list) else [value]
    n = len(rows)
    if n > limits.max_poses:
        raise ContractError("too_large", f"joints: {n} configurations exceed the cap of {limits.max_poses}")
    dof = model.dof
    if bounds is None:
        bounds = (model.joint_limits[:, 0] - 1e-12, model.joint_limits[:, 1] + 1e-12)
    if n > _FEW:
        q = _numbers_array(rows, n, dof)
        if q is not None:
            return _within(q, model, allow_out_of_limits, bounds)
    if n == 1:
        shaped = type(rows[0]) is list and len(rows[0]) == dof
        kinds = set(map(type, rows[0])) if shaped else None
    else:
        shaped = set(map(type, rows)) == {list} and set(map(len, rows)) == {dof}
        kinds = set(map(type, chain.from_iterable(rows))) if shaped else None
    if not shaped:
        for i, r in enumerate(rows):
            if not isinstance(r, list) or len(r) != dof:
                got = len(r) if isinstance(r, list) else type(r).__name__
                raise ContractError("invalid_request", f"joints[{i}]: expected {dof} values "
                                                       f"({', '.join(model.joint_names)}), got {got}")
    if not kinds <= _NUMBERS:
        i, j = next((i, j) for i, r in enumerate(rows) for j, v in enumerate(r) if type(v) not in (int, float))
        raise ContractError("invalid_request", f"joints[{i}][{j}]: expected a number, got {type(rows[i][j]).__name__}")
    try:
        q = (np.array(rows, dtype=float) if n <= _FEW else
             np.fromiter(chain.from_iterable(rows), dtype=float, count=n * dof).reshape(n, dof))
    except OverflowError:
        raise ContractError("invalid_request", "joints: a value is too large for a float") from None
    if n <= _FEW and len(bounds) == 4:  # the numbers as given (an int compares exactly; limits are far below 2**53)
        lo, hi = bounds[2], bounds[3]
        if all([all(map(le, lo, r)) and all(map(le, r, hi)) for r in rows]):
            return q, None
    return _within(q, model, allow_out_of_limits, bounds)


_SUSPECTS = 64  # values of 0 or 1 whose type is looked at one by one; more: every value's type at once


def _numbers_array(rows, n, dof):
    """(n, dof) float array of n rows of dof numbers (int or float), or None when some value is not one or
    the rows are not of that shape (the caller's exact checks then say which). numpy's conversion without
    a dtype does the checks in one pass: a str, None, a list or an object gives a dtype that is not a
    number's, ragged rows an error; only a bool among numbers passes, as 0 or 1, so the values equal to
    0 or 1 have their types checked."""
    try:
        q = np.array(rows)
    except (ValueError, OverflowError):  # ragged rows, an int beyond 64 bits
        return None
    if q.dtype.kind not in "fi" or q.shape != (n, dof):
        return None
    suspects = np.flatnonzero((q == 0) | (q == 1))
    if suspects.size > _SUSPECTS:
        if not set(map(type, chain.from_iterable(rows))) <= _NUMBERS:
            return None
    elif suspects.size and not all(type(rows[k // dof][k % dof]) in _NUMBERS for k in suspects.tolist()):
        return None
    return q.astype(float, copy=False)


def _within(q, model, allow_out_of_limits, bounds):
    """(q, mask of joints outside their limits or None), or the error naming the first that is not finite
    or (without ``allow_out_of_limits``) outside its limits."""
    lo, hi = bounds[0], bounds[1]
    wrapped = model.within_turn(q)   # a continuous joint's angle modulo 2 pi
    within = (wrapped >= lo) & (wrapped <= hi)  # False for NaN too: all True means finite and within the limits
    if np.count_nonzero(within) == within.size:
        return q, None
    if not np.isfinite(q).all():
        i, j = np.argwhere(~np.isfinite(q))[0]
        raise ContractError("invalid_request", f"joints[{i}][{j}]: not a finite number")
    out = ~within
    if not allow_out_of_limits:
        i, j = np.argwhere(out)[0]
        lo, hi = model.joint_limits[j]
        raise ContractError("out_of_limits", f"joints[{i}][{j}] ({model.joint_names[j]}) = {q[i, j]:.6g} is outside "
                                             f"[{lo:.6g}, {hi:.6g}] ({int(out.any(axis=1).sum())} configuration(s) "
                                             f"affected); set allow_out_of_limits to accept")
    return q, out


def parse_poses(value, limits: Limits) -> np.ndarray:
    """(n, 4, 4) tool poses from a list of 4x4 matrices or of [x, y, z, qx, qy, qz, qw] (m)."""
    if not isinstance(value, list) or not value:
        raise ContractError("invalid_request", "poses: expected a non-empty list of 4x4 matrices or of "
                                               "[x, y, z, qx, qy, qz, qw]")
    cap = min(limits.max_poses, limits.max_compensate_poses)
    if len(value) > cap:
        raise ContractError("too_large", f"poses: {len(value)} targets exceed the cap of {cap} (each tool pose is "
                                         f"solved from 9 starts first; give joint targets for more)")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ContractError("invalid_request", "poses: every pose must be numbers of one shape, 4x4 or 7") from None
    if not ((arr.ndim == 2 and arr.shape[1] == 7) or (arr.ndim == 3 and arr.shape[1:] == (4, 4))):
        raise ContractError("invalid_request", f"poses: expected (n, 4, 4) matrices or (n, 7) position + "
                                               f"quaternion, got shape {list(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise ContractError("invalid_request", f"poses[{int(np.argwhere(~np.isfinite(arr))[0][0])}]: not finite")
    position = arr[:, :3] if arr.ndim == 2 else arr[:, :3, 3]
    far = np.flatnonzero(np.abs(position).max(axis=1) > MAX_POSITION_M)
    if far.size:
        raise ContractError("invalid_request", f"poses[{far[0]}]: a target {np.abs(position[far[0]]).max():.3g} m "
                                               f"from the base is beyond {MAX_POSITION_M:g} m")
    if arr.ndim == 2 and arr.shape[1] == 7:
        try:
            R = quat_to_matrices(arr[:, 3:])
        except ValueError:
            raise ContractError("invalid_request", "poses: a quaternion has zero norm") from None
        T = np.tile(np.eye(4), (len(arr), 1, 1))
        T[:, :3, :3], T[:, :3, 3] = R, arr[:, :3]
        return T
    R = arr[:, :3, :3]
    bad = np.flatnonzero((np.abs(np.einsum("nij,nkj->nik", R, R) - np.eye(3)).max(axis=(1, 2)) > 1e-6)
                         | (np.linalg.det(R) < 0) | (np.abs(arr[:, 3] - [0, 0, 0, 1]).max(axis=1) > 0))
    if bad.size:
        raise ContractError("invalid_request", f"poses[{bad[0]}]: not a rigid transform (rotation part not "
                                               f"orthonormal, or last row not [0, 0, 0, 1])")
    return arr
