"""The numba decorator every kernel module compiles with, and the empty arrays its kernels take for "none".

``njit`` is ``numba.njit(cache=True)`` with every helper inlined where it is called. Compiled code is cached on
disk: in ``NUMBA_CACHE_DIR`` when set, else beside the kernel module when its directory is writable, else in
numba's per-user cache directory (``~/.cache/numba``). When none of these is writable (numba then refuses
to cache), a private directory ``<tmp>/tolerance_ros-numba-<uid>`` is used, and without one the kernels
compile in every process. numba invalidates a cached function only when its own module's file changes: no
jitted function lives here, so that no kernel module inlines code from another file.
"""
from __future__ import annotations

import os
import stat
import tempfile

import numba
import numpy as np


def _private_cache_dir():
    """``<tmp>/tolerance_ros-numba-<uid>``, created 0700; None unless it is a directory only we can write."""
    path = os.path.join(tempfile.gettempdir(), f"tolerance_ros-numba-{os.getuid()}")
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
        st = os.lstat(path)
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or stat.S_IMODE(st.st_mode) & 0o022:
        return None
    return path


def njit(fn=None, **options):
    """``numba.njit(cache=True)``, with the fallbacks of the module docstring when no cache directory is writable.
    Every helper is inlined where it is called (numba IR inlining: the small tuple-returning helpers are
    otherwise real calls, about 10 % of a chain's time). ``njit(**options)`` passes more options to numba
    (``fastmath`` for zonotope_max; ``pups_kernels``: ``error_model='numpy'``)."""
    if fn is None:
        return lambda f: njit(f, **options)
    options = {"inline": "always", **options}
    try:
        return numba.njit(cache=True, **options)(fn)
    except RuntimeError:  # "cannot cache function ...: no locator available"
        path = _private_cache_dir()
        if path is None:
            return numba.njit(**options)(fn)
        numba.config.CACHE_DIR = path
        return numba.njit(cache=True, **options)(fn)


NO_DX = np.empty((0, 0))  # dx argument when there are no parameter errors
NO_J = np.empty((0, 0, 0))  # J argument when only the poses are wanted
