"""The mechanism interface shared by every model: serial D-H chains, URDF chains, the 3-PUPS platform.

Conventions (SI, REP 103):
- joints ``q``: ``(n, dof)`` array, rad for revolute joints, m for prismatic joints;
- poses: ``(n, 4, 4)`` homogeneous transforms of the end effector in the base frame, metres;
- parameter errors ``dx``: ``(p,)`` or ``(n, p)`` deviations from nominal, m or rad per parameter;
- the parameter-error Jacobian ``J``: ``(n, 6, p)``, rows 0-2 the position error (m per unit of the
  parameter), rows 3-5 the orientation error as a small rotation vector in the base frame
  (rad per unit), so that ``T_actual ~ (I + [[dphi]x, dp; 0, 0]) T_nominal`` with ``[dp; dphi] = J dx``.
"""
from __future__ import annotations

import contextlib
import copy
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from . import kernels

REVOLUTE = "revolute"
PRISMATIC = "prismatic"
UNIT_OF_KIND = {"length": "m", "angle": "rad"}
BACKENDS = ("numba", "numpy")
_FLOAT64 = np.dtype(np.float64)


def warm_up_kernels(which=None) -> float:
    """Compile, or load from the cache, the compiled kernel families in ``which`` (``kernels.FAMILIES`` by
    default; none without numba); returns seconds."""
    if not kernels.available():
        return 0.0
    try:
        return kernels.warm_up(kernels.FAMILIES if which is None else which)
    except ImportError:
        kernels.mark_unavailable()
        return 0.0


MAX_REACH_M = 20.0  # m: no robot arm reaches farther from its base (the largest industrial arms: about 4.7 m)


@contextlib.contextmanager
def _numpy_path(model):
    """``model`` (and the models it wraps) on the numpy path for the block: a check made when a model is loaded
    never waits for the compiled kernels (on a cold cache they would compile in the caller)."""
    chain = []
    m = model
    while m is not None and m not in chain:
        chain.append(m)
        m = getattr(m, "inner", None)
    saved = [m.__dict__.get("_backend", _UNSET) for m in chain]
    for m in chain:
        m._backend = "numpy"
    try:
        yield
    finally:
        for m, b in zip(chain, saved):
            if b is _UNSET:
                del m._backend
            else:
                m._backend = b


_UNSET = object()


class ModelError(ValueError):
    """An invalid mechanism model or an invalid input to one; the message names the field."""


@dataclass(frozen=True)
class ErrorJacobian:
    """Parameter-error Jacobian with the names and units of its columns.

    J : (n, 6, p) array; rows 0-2 position (m per unit), rows 3-5 orientation (rad per unit).
    names : parameter names, one per column.
    units : 'm' or 'rad', the unit of each parameter.
    """

    J: np.ndarray
    names: tuple
    units: tuple

    @property
    def position(self) -> np.ndarray:
        """(n, 3, p) position rows."""
        return self.J[:, :3, :]

    @property
    def orientation(self) -> np.ndarray:
        """(n, 3, p) orientation rows."""
        return self.J[:, 3:, :]

    def select(self, rows: str = "position") -> np.ndarray:
        """Rows for an error criterion: 'position' (3), 'orientation' (3) or 'pose' (6)."""
        if rows == "position":
            return self.position
        if rows == "orientation":
            return self.orientation
        if rows == "pose":
            return self.J
        raise ValueError(f"rows: expected 'position', 'orientation' or 'pose', got {rows!r}")


class Mechanism(ABC):
    """A mechanism with named joints and named kinematic parameters.

    Subclasses set ``name``, ``joint_names``, ``joint_types``, ``joint_limits`` ((dof, 2), SI),
    ``param_names``, ``param_kinds`` ('length' or 'angle') and ``nominal`` ((p,), SI), and implement
    ``fk_and_jacobian``; ``continuous`` ((dof,) bool) marks the joints without limits (URDF ``continuous``),
    whose angles are compared with the limits modulo 2 pi (``within_turn``).
    """

    name: str
    joint_names: tuple
    joint_types: tuple
    joint_limits: np.ndarray
    param_names: tuple
    param_kinds: tuple
    nominal: np.ndarray
    compiled = False  # True where fk_and_jacobian has a compiled (numba) path
    _backend = None   # None: compiled when numba can be imported
    _units = (None, ())

    kernel_family = None  # the compiled kernel family of fk_and_jacobian (``kernels.FAMILIES``), where compiled
    continuous = None     # (dof,) bool: joints without limits; None: none

    def reach(self, samples: int = 512) -> float:
        """The largest distance (m) of the tool point from the base origin over ``samples`` seeded joint samples
        (the robot's size, against which lengths given for it are judged; the 512-sample figure is computed
        once)."""
        if samples == 512 and getattr(self, "_reach", None) is not None:
            return self._reach
        q = self.sample_joints(samples, 7)
        with np.errstate(over="ignore", invalid="ignore"):   # absurd lengths: infinite, refused by who asks
            reach = float(np.linalg.norm(self.fk(q)[:, :3, 3], axis=1).max())
        if samples == 512:
            self._reach = reach
        return reach

    def check_size(self, where: str = "") -> "Mechanism":
        """This model, or ModelError when it is larger than any robot arm (its tool reaching beyond ``MAX_REACH_M``
        from its base: lengths written in millimetres where metres were meant, as a URDF's are); judged on 16
        samples on the numpy path, so that loading a robot stays cheap and never waits for the compiled kernels
        (on a cold cache they would compile in the caller)."""
        with _numpy_path(self):
            try:
                reach = self.reach(16)
            except ModelError as exc:   # a workspace no posture of which assembles (a 3-PUPS box of 1e308 mm)
                raise ModelError(f"{where}{exc}") from None
        if not reach <= MAX_REACH_M:
            raise ModelError(f"{where}robot {self.name!r}: its tool reaches {reach:.4g} m from its base, more than any "
                             f"robot arm ({MAX_REACH_M:g} m): lengths in millimetres where metres were meant? (a URDF's "
                             f"lengths are metres)")
        return self

    def within_turn(self, q) -> np.ndarray:
        """``q`` (..., dof) with each continuous joint's angle taken modulo 2 pi into [-pi, pi) (the others as they
        are): what the limits are compared with. An unwrapped angle (4.79 rad) is the same pose as its wrap."""
        q = np.asarray(q, dtype=float)
        c = self.continuous
        if c is None or not np.any(c):
            return q
        return np.where(c, np.mod(q + np.pi, 2 * np.pi) - np.pi, q)

    @property
    def backend(self) -> str:
        """'numba' (compiled kernels) or 'numpy' (the reference implementation) for ``fk_and_jacobian``."""
        if self._backend is not None:
            return self._backend
        return "numba" if self.compiled and kernels.get(self.kernel_family) is not None else "numpy"

    @backend.setter
    def backend(self, name: str):
        if name not in BACKENDS:
            raise ModelError(f"backend: expected one of {list(BACKENDS)}, got {name!r}")
        if name == "numba" and not self.compiled:
            raise ModelError(f"backend: {type(self).__name__} has no compiled kernels")
        if name == "numba" and not kernels.pending() and kernels.get(self.kernel_family) is None:
            raise ModelError("backend: numba cannot be imported (pip install numba)")
        self._backend = name

    def _kernels(self):
        """The kernel family's module when fk_and_jacobian takes the compiled path, else None."""
        if self._backend == "numpy" or not self.compiled:
            return None
        return kernels.get(self.kernel_family)

    def warm_up(self) -> float:
        """Compile or load from the cache the kernels this model calls; returns the seconds it took."""
        t0 = time.perf_counter()
        if self._kernels() is not None:
            q = np.clip(np.zeros((1, self.dof)), self.joint_limits[:, 0], self.joint_limits[:, 1])
            self.fk_and_jacobian(q)
            self.fk_and_jacobian(q, np.zeros(self.n_params))
            self.fk_and_jacobian(q, jacobian=False)
        return time.perf_counter() - t0

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def param_units(self) -> tuple:
        kinds, units = self._units
        if kinds is not self.param_kinds:
            units = tuple(UNIT_OF_KIND[k] for k in self.param_kinds)
            self._units = (self.param_kinds, units)
        return units

    @property
    def orientation_observable(self) -> bool:
        """True when the end effector has an orientation that errors are judged on."""
        return True

    @abstractmethod
    def fk_and_jacobian(self, q, dx=None, jacobian: bool = True):
        """Forward kinematics and parameter-error Jacobian.

        q : (n, dof) or (dof,) joints, SI.  dx : (p,) or (n, p) parameter errors, SI, or None.
        Returns (T (n, 4, 4), ErrorJacobian or None).
        """

    def fk(self, q, dx=None) -> np.ndarray:
        """(n, 4, 4) end-effector poses in the base frame, metres; ``dx`` perturbs the parameters."""
        return self.fk_and_jacobian(q, dx, jacobian=False)[0]

    def error_jacobian(self, q, dx=None) -> ErrorJacobian:
        """(n, 6, p) parameter-error Jacobian at ``q`` (see the module docstring for its rows)."""
        return self.fk_and_jacobian(q, dx, jacobian=True)[1]

    def param_index(self, names) -> np.ndarray:
        """Column indices of the named parameters; unknown names raise ModelError."""
        lookup = {n: i for i, n in enumerate(self.param_names)}
        missing = [n for n in names if n not in lookup]
        if missing:
            raise ModelError(f"unknown parameter name(s) {missing} for robot {self.name!r}; "
                             f"known: {list(self.param_names)}")
        return np.array([lookup[n] for n in names], dtype=int)

    def check_joints(self, q, field: str = "joints", allow_out_of_limits: bool = True) -> np.ndarray:
        """Validate joints; return a float (n, dof) array. Raises ModelError naming the bad entry."""
        try:
            arr = np.asarray(q, dtype=float)
        except (TypeError, ValueError):
            raise ModelError(f"{field}: expected numbers") from None
        if arr.ndim == 1:
            arr = arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != self.dof:
            raise ModelError(f"{field}: expected shape (n, {self.dof}) for robot {self.name!r} "
                             f"(joints {list(self.joint_names)}), got {np.shape(q)}")
        bad = ~np.isfinite(arr)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise ModelError(f"{field}[{i}][{j}] ({self.joint_names[j]}): not a finite number")
        if not allow_out_of_limits:
            lo, hi = self.joint_limits[:, 0], self.joint_limits[:, 1]
            wrapped = self.within_turn(arr)
            out = (wrapped < lo - 1e-12) | (wrapped > hi + 1e-12)
            if out.any():
                i, j = np.argwhere(out)[0]
                raise ModelError(f"{field}[{i}][{j}] ({self.joint_names[j]}) = {arr[i, j]:.6g} is outside "
                                 f"the joint limits [{lo[j]:.6g}, {hi[j]:.6g}]")
        return arr

    def _joints_for_kernel(self, q) -> np.ndarray:
        """Joints as a writable C-contiguous float64 (n, dof) array, without a copy when ``q`` is one.

        Checks the shape only when ``q`` is such an array (or its (dof,) row): the kernels check that
        the values are finite and the caller then raises through ``check_joints``. Anything else goes
        through ``check_joints`` here.
        """
        if type(q) is np.ndarray and q.dtype is _FLOAT64:
            flags = q.flags
            if flags.c_contiguous and flags.writeable:
                shape = q.shape
                if len(shape) == 2 and shape[1] == self.dof:
                    return q
                if shape == (self.dof,):
                    return q[None]
        q = self.check_joints(q)
        return q if q.flags.c_contiguous and q.flags.writeable else np.array(q, order="C")

    def _dx_for_kernel(self, dx, n: int) -> np.ndarray | None:
        """Validated parameter errors as a C-contiguous (1, p) or (n, p) float64 array, or None."""
        if dx is None:
            return None
        dx = self.check_dx(dx, n)
        return np.array(dx.reshape(-1, self.n_params), order="C")

    @property
    def joint_direction(self) -> np.ndarray:
        """(dof,) +1 or -1: the sign of each joint as the caller gives it in the model's joint (a D-H
        robot's controller convention; +1 elsewhere)."""
        return np.ones(self.dof)

    def joint_columns(self) -> np.ndarray:
        """(dof,) column of each joint's zero offset in the parameter-error Jacobian: the derivative of the
        pose in that joint. ModelError for mechanisms whose joints are not such parameters."""
        raise ModelError(f"robot {self.name!r} is a {type(self).__name__}; its joints are not parameters of its "
                         f"error model (serial D-H and URDF chains only)")

    def out_of_limits(self, q) -> np.ndarray:
        """(n, dof) boolean mask of joints outside their limits."""
        q = self.within_turn(np.atleast_2d(np.asarray(q, dtype=float)))
        return (q < self.joint_limits[:, 0] - 1e-12) | (q > self.joint_limits[:, 1] + 1e-12)

    def sample_joints(self, m: int, seed=0) -> np.ndarray:
        """(m, dof) joints drawn uniformly within the joint limits (seeded)."""
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        lo, hi = self.joint_limits[:, 0], self.joint_limits[:, 1]
        return lo + (hi - lo) * rng.random((int(m), self.dof))

    def check_dx(self, dx, n: int) -> np.ndarray | None:
        """Validate parameter errors: (p,) or (n, p), finite."""
        if dx is None:
            return None
        arr = np.asarray(dx, dtype=float)
        if arr.shape not in ((self.n_params,), (n, self.n_params)):
            raise ModelError(f"dx: expected shape ({self.n_params},) or ({n}, {self.n_params}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ModelError("dx: parameter errors must be finite")
        return arr

    def search_space(self):
        """Coordinates for local searches of the workspace: (bounds (k, 2), to_joints, from_joints).

        Serial chains search their joints directly (``to_joints`` is None). A parallel mechanism, whose
        actuated joints are not free coordinates, searches its platform pose instead; its
        ``to_joints`` maps (m, k) coordinates to (m, dof) joints with NaN rows where out of reach.
        """
        return self.joint_limits, None, None

    def with_joint_limits(self, limits) -> "Mechanism":
        """A copy of the model with other joint limits ((dof, 2), SI)."""
        lim = np.asarray(limits, dtype=float)
        if lim.shape != (self.dof, 2) or not np.all(np.isfinite(lim)) or np.any(lim[:, 0] >= lim[:, 1]):
            raise ModelError(f"limits: expected finite (lower < upper) pairs of shape ({self.dof}, 2)")
        out = copy.copy(self)
        out.joint_limits = lim
        out._reach = None
        return out

    def describe(self) -> dict:
        """Plain summary for reports and JSON."""
        return {
            "name": self.name,
            "kind": type(self).__name__,
            "joints": [{"name": n, "type": t, "limits": [float(lo), float(hi)]}
                       for n, t, (lo, hi) in zip(self.joint_names, self.joint_types, self.joint_limits)],
            "parameters": [{"name": n, "unit": u, "nominal": float(v)}
                           for n, u, v in zip(self.param_names, self.param_units, self.nominal)],
        }


class CompiledChain(Mechanism):
    """A serial chain whose ``fk_and_jacobian`` runs a compiled kernel (numba) unless ``backend`` is
    'numpy', when its reference ``_fk_and_jacobian_numpy`` runs instead. Subclasses implement both."""

    compiled = True

    def fk_and_jacobian(self, q, dx=None, jacobian: bool = True):
        compiled = self._kernels()
        if compiled is None:
            return self._fk_and_jacobian_numpy(q, dx, jacobian)
        q = self._joints_for_kernel(q)
        n = q.shape[0]
        dx = self._dx_for_kernel(dx, n)
        T = np.empty((n, 4, 4))
        J = np.empty((n, 6, self.n_params)) if jacobian else compiled.NO_J
        if self._run_kernel(compiled, q, compiled.NO_DX if dx is None else dx, T, J, bool(jacobian)) >= 0:
            self.check_joints(q)  # a joint out of its limits or not finite: raises, naming it
        return T, (ErrorJacobian(J, self.param_names, self.param_units) if jacobian else None)

    @abstractmethod
    def _run_kernel(self, kernels, q, dx, T, J, jacobian: bool) -> int:
        """Fill ``T`` (n, 4, 4) and ``J`` (n, 6, p) from the compiled kernel; >= 0 names a bad pose, else -1."""

    @abstractmethod
    def _fk_and_jacobian_numpy(self, q, dx=None, jacobian: bool = True):
        """The numpy reference implementation of ``fk_and_jacobian``."""


class WrappedMechanism(Mechanism):
    """A mechanism built around another (``inner``: a tool moved to a target, a chain that deflects under its
    load): it takes the inner model's names, joints, limits and parameters, and answers the joint questions as
    the inner model does; a subclass gives ``fk_and_jacobian``."""

    COPIED = ("name", "joint_names", "joint_types", "joint_limits", "param_names", "param_kinds", "nominal",
              "continuous")
    IF_ANY = ("tip_link", "base_link", "source", "config_path")

    def __init__(self, inner: Mechanism):
        self.inner = inner
        for attr in self.COPIED:
            setattr(self, attr, getattr(inner, attr))
        for attr in self.IF_ANY:
            if hasattr(inner, attr):
                setattr(self, attr, getattr(inner, attr))

    def joint_columns(self) -> np.ndarray:
        return self.inner.joint_columns()

    @property
    def joint_direction(self) -> np.ndarray:
        return self.inner.joint_direction
