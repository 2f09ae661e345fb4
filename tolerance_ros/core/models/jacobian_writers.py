"""Which writer ``chain_kernels.urdf_chain`` fills a Jacobian with on this machine, measured once per CPU.

Three writers (see ``chain_kernels``): 0 columns in place, 1 rows in memory order, 2 rows with streaming
stores. Streaming saved a quarter of a 10,000-pose Panda Jacobian's time on a 2-core AMD EPYC VM and made the
same call 30x slower on an Intel Xeon, so none is assumed: each candidate is timed at warm-up on a J of
``SIZES`` bytes, the fastest chosen and remembered beside the kernel cache with the CPU it was made on.
"""
from __future__ import annotations

import math
import os
import time

import numba
import numpy as np

from .chain_kernels import urdf_chain
from .jit import NO_DX

WRITERS = ("columns", "rows", "stream")  # urdf_chain's writers, by code 0, 1, 2
MID_BYTES = 256 << 10    # a J below this many bytes is written in columns (it stays in the caches)
LARGE_BYTES = 8 << 20    # a J of this many bytes or more: the writer chosen for "large", else for "mid"
SIZES = {"mid": 2 << 20, "large": 16 << 20}  # bytes of the J that the candidates are timed on
CHOICE_FILE = "tolerance_ros-writers.json"   # beside the kernel cache: the choice and the CPU it was made on
WRITER_ENV = "TOLERANCE_ROS_JACOBIAN_WRITER"  # columns | rows | stream: no measurement, this writer
_choice = None           # the choice in force: {"writers": {size class: name}, "source", "times_us", "cpu"}


def writer_for(nbytes: int) -> int:
    """Code of the writer of a J of ``nbytes`` bytes (columns below MID_BYTES; else this machine's choice)."""
    if nbytes < MID_BYTES:
        return 0
    choice = _choice or choose_writers()
    return WRITERS.index(choice["writers"]["large" if nbytes >= LARGE_BYTES else "mid"])


def cpu_id() -> dict:
    """What the choice depends on: the CPU model, its feature flags (a digest), the architecture, numba."""
    import hashlib
    import platform
    model, flags = platform.processor() or platform.machine(), ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and model == (platform.processor() or platform.machine()):
                    model = value.strip()
                elif key.strip() in ("flags", "Features") and not flags:
                    flags = value.strip()
    except OSError:
        pass
    return {"cpu": model, "flags": hashlib.sha1(flags.encode()).hexdigest()[:12], "machine": platform.machine(),
            "numba": numba.__version__}


def _choice_path():
    """The file that remembers the choice (in the kernel cache's directory), or None without a cache."""
    cache = getattr(getattr(urdf_chain, "_cache", None), "_cache_path", None)
    return os.path.join(cache, CHOICE_FILE) if cache else None


def choose_writers(measure=None, path="auto", force=None) -> dict:
    """Put in force and return the writer of each size class: ``force`` (or the WRITER_ENV variable) when
    given; else the choice remembered in ``path`` (default beside the kernel cache) when it was made on
    this CPU; else each candidate timed by ``measure`` (default ``time_writers``), the fastest chosen and
    remembered."""
    import json
    global _choice
    force = force or os.environ.get(WRITER_ENV) or None
    if force is not None:
        if force not in WRITERS:
            raise ValueError(f"{WRITER_ENV}: expected one of {list(WRITERS)}, got {force!r}")
        _choice = {"writers": {c: force for c in SIZES}, "source": "forced", "times_us": None, "cpu": cpu_id()}
        return _choice
    path = _choice_path() if path == "auto" else path
    cpu = cpu_id()
    if path is not None:
        try:
            with open(path, encoding="utf-8") as f:
                doc = json.load(f)
            if doc.get("cpu") == cpu and set(doc["writers"]) == set(SIZES) and \
                    all(w in WRITERS for w in doc["writers"].values()):
                _choice = {**doc, "source": "remembered"}
                return _choice
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            pass
    times = (measure or time_writers)()
    doc = {"writers": {c: min(t, key=t.get) for c, t in times.items()},
           "times_us": {c: {w: round(v * 1e6, 1) for w, v in t.items()} for c, t in times.items()}, "cpu": cpu}
    if path is not None:
        try:
            tmp = f"{path}.{os.getpid()}.tmp"
            with open(tmp, "w", encoding="utf-8") as f:
                json.dump(doc, f)
            os.replace(tmp, path)
        except OSError:
            pass
    _choice = {**doc, "source": "measured"}
    return _choice


def time_writers(rounds: int = 3) -> dict:
    """{size class: {writer: best seconds}}: urdf_chain on a 7-joint chain (generic joint frames) for a J of
    SIZES bytes, each writer in turn, ``rounds`` times after one untimed round, each call with freshly
    allocated T and J as the models allocate them."""
    rng = np.random.default_rng(0)
    dof = 7
    fixed = np.repeat(np.eye(4)[None], dof, axis=0)
    for j in range(dof):
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        fixed[j, :3, :3] = R * np.sign(np.linalg.det(R))
        fixed[j, :3, 3] = rng.uniform(-0.2, 0.2, 3)
    axes = np.tile([0.0, 0.0, 1.0], (dof, 1))
    revolute = np.ones(dof, np.bool_)
    nominal, tool, origin_rpy = np.zeros(7 * dof), np.eye(4), np.zeros((dof, 3))
    out = {}
    for size_class, nbytes in SIZES.items():
        q = rng.uniform(-np.pi, np.pi, (max(1, nbytes // (6 * 7 * dof * 8)), dof))
        best = dict.fromkeys(WRITERS, math.inf)
        for r in range(rounds + 1):  # the first round untimed (first touch of the memory, first calls)
            for code, name in enumerate(WRITERS):
                T, J = np.empty((len(q), 4, 4)), np.empty((len(q), 6, 7 * dof))
                t0 = time.perf_counter()
                urdf_chain(q, nominal, NO_DX, revolute, fixed, origin_rpy, axes, tool, T, J, True, code)
                if r:
                    best[name] = min(best[name], time.perf_counter() - t0)
        out[size_class] = best
    return out

