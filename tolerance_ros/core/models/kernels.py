"""The compiled (numba) kernels and which of them this process calls: one registry, no numba imported here.

Kernel families, each in a module of its own concern (all compiled with ``jit.njit``):

- ``dh`` and ``urdf``: ``chain_kernels.dh_chain`` and ``urdf_chain``, the batched forward kinematics and
  parameter-error Jacobians of serial chains (the numpy code of ``dh.py`` and ``urdf.py`` is the reference);
  ``urdf`` also chooses its Jacobian writer for this machine (``jacobian_writers``);
- ``zonotope``: ``zonotope_kernel.zonotope_max``, the exact worst case of ``errors.worst_case_bound``;
- ``pups``: ``pups_kernels``, the 3-PUPS platform (``pups.py`` is the reference).

``get(family)`` gives a family's module, or None: without numba, or while ``warmup`` prepares the kernels in
the background and that family is not ready yet (its callers then take their numpy path). A family becomes
ready on its own (``mark_ready``) as soon as the background has it, so that a running job switches to it
between two calls. Outside a background preparation, the first call of a family imports numba and compiles
it in the caller, or loads it from the on-disk cache (about 1 s, most of it importing numba).
"""
from __future__ import annotations

import importlib
import time

FAMILIES = ("dh", "zonotope", "urdf", "pups")  # in the order the background compiles what no job asked first
_MODULES = {"dh": "chain_kernels", "urdf": "chain_kernels", "zonotope": "zonotope_kernel", "pups": "pups_kernels"}
_ready = {}             # family -> its module, callable in this process
_pending = False        # a background preparation runs: only the families in _ready are served
_unavailable = False    # numba cannot be imported (or is built for another numpy): the numpy paths always


def get(family: str):
    """The module of ``family`` when its compiled kernels may be called now, else None (see the docstring)."""
    if _unavailable:
        return None
    module = _ready.get(family)
    if module is not None or _pending:
        return module
    try:
        module = importlib.import_module(f".{_MODULES[family]}", __package__)
    except ImportError:  # numba missing, or built for another numpy
        return mark_unavailable()
    _ready[family] = module
    return module


def available() -> bool:
    """Whether numba can be used at all (False once an import of it failed)."""
    return not _unavailable


def mark_unavailable():
    """numba cannot be used: every family takes its numpy path from now on (returns None)."""
    global _unavailable
    _unavailable = True
    _ready.clear()
    return None


def mark_ready(family: str, module) -> None:
    """The background has ``family`` compiled and loaded: callers switch to it from their next call."""
    _ready[family] = module


def set_pending(pending: bool) -> None:
    """A background preparation starts (only ready families are served) or ends (the others load on use)."""
    global _pending
    _pending = bool(pending)


def pending() -> bool:
    return _pending


def prime(which=FAMILIES) -> None:
    """Import numba and the modules of the families ``which`` and load numba's own registries (about 1 s, most
    of it imports: its array maths imports scipy.linalg for BLAS), without compiling or loading a kernel: what
    every first compile or load pays, paid ahead while a child compiles, so that each family then loads from
    the cache in milliseconds. Only a head start: any failure is left for ``warm_up`` to meet and report."""
    modules = [_MODULES[family] for family in which]
    try:
        for name in modules:
            importlib.import_module(f".{name}", __package__)
        from numba.core.registry import cpu_target
        cpu_target.target_context.refresh()
    except Exception:  # noqa: BLE001 - warm_up meets the same failure and says it
        pass


def warm_up(which=FAMILIES) -> float:
    """Compile, or load from the on-disk cache, the kernel families in ``which`` in every signature the models
    call (for ``urdf`` also choose its writer); returns seconds. Each family is ready when it returns."""
    t0 = time.perf_counter()
    for family in which:
        module = importlib.import_module(f".{_MODULES[family]}", __package__)
        if family in ("dh", "urdf"):
            module.warm_up((family,))
            if family == "urdf":
                from .jacobian_writers import choose_writers
                choose_writers()
        else:
            module.warm_up()
        mark_ready(family, module)
    return time.perf_counter() - t0
