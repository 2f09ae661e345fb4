"""The compiled kernels without a stall: serve from the numpy path while a child process fills the cache.

Compiling the kernels with an empty numba cache takes 30-40 s on a 2-core VM; loading them from the cache about 1 s
(most of it importing numba). A node, or a one-shot command, that waited for either would lose its first
requests. ``start(background=True)`` returns at once: the models answer from their numpy reference path
(equal to the compiled one to 1e-12) while a background thread prepares the kernels (a child process running
this module of the very package its parent runs, ``child_command``, compiles them into the cache when it is
cold, then this process loads them from there), and the models switch to them between two calls, without a
pause.
Without ``background`` (the library's default), the kernels compile or load on first use, in the caller.

Whether the cache is warm is known without importing numba: ``kernels.warm_up`` writes ``MARKER`` into
the kernel cache's directory (``cache_dir()``, numba's own choice of it) with the ``source_stamp`` of the
kernels it compiled; a changed kernels module, numba or Python makes the marker stale.
"""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

from . import kernels

MARKER = "tolerance_ros-kernels.json"
LOCK = "tolerance_ros-kernels.lock"  # held by the process whose child fills the cache
KERNEL_MODULES = ("jit.py", "chain_kernels.py", "jacobian_writers.py", "zonotope_kernel.py", "pups_kernels.py")
"""The modules whose compiled code (and writer choice) the marker vouches for."""
_HERE = Path(__file__).resolve().parent
_lock = threading.Lock()
status = {"state": "idle", "message": "", "seconds": None, "filled": False}  # state: idle | loading | compiling |
# ready | failed; filled: this process's child filled the cache


@functools.lru_cache(maxsize=1)
def source_stamp() -> str:
    """Digest of what the cached code depends on: the kernel modules' text, numba's and Python's versions (read
    once: the code this process runs)."""
    from importlib.metadata import PackageNotFoundError, version
    h = hashlib.sha256()
    for name in KERNEL_MODULES:
        h.update((_HERE / name).read_bytes())
    try:
        h.update(version("numba").encode())
    except PackageNotFoundError:
        pass
    h.update(sys.version.encode())
    return h.hexdigest()[:24]


def cache_dir() -> str | None:
    """The directory numba caches ``kernels.py`` in (its locators' order: ``NUMBA_CACHE_DIR``, the
    ``__pycache__`` beside the file, the user-wide cache), computed without importing numba; None when
    none is writable."""
    source = str(_HERE / "kernels.py")
    parent = os.path.dirname(os.path.abspath(source))
    subpath = "_".join([os.path.split(parent)[-1], hashlib.sha1(parent.encode()).hexdigest()])
    candidates = []
    if os.environ.get("NUMBA_CACHE_DIR"):
        candidates.append(os.path.join(os.environ["NUMBA_CACHE_DIR"], subpath))
    candidates.append(os.path.join(parent, "__pycache__"))
    candidates.append(os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "numba",
                                   subpath))
    for path in candidates:
        try:
            os.makedirs(path, exist_ok=True)
        except OSError:
            continue
        if os.access(path, os.W_OK):
            return path
    return None


def family_marker(family: str) -> str:
    """The file name that says ``family``'s kernels of this source are in the cache (written by the child)."""
    return f"tolerance_ros-kernels-{family}.json"


def cached(family: str | None = None) -> bool:
    """True when the kernel cache holds this source's compiled kernels: all of them (``MARKER`` is current), or
    the one ``family`` (its ``family_marker``)."""
    path = cache_dir()
    if path is None:
        return False
    try:
        with open(os.path.join(path, MARKER if family is None else family_marker(family)), encoding="utf-8") as f:
            return json.load(f).get("stamp") == source_stamp()
    except (OSError, ValueError, AttributeError):
        return False


def write_marker(path: str | None, name: str = MARKER) -> None:
    """Record in ``path`` (the kernel cache's directory) that it holds this source's compiled kernels: all of
    them (``MARKER``), or one family (``family_marker``)."""
    if path is None:
        return
    try:
        tmp = os.path.join(path, f"{name}.{os.getpid()}.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"stamp": source_stamp(), "written": time.time()}, f)
        os.replace(tmp, os.path.join(path, name))
    except OSError:
        pass


def start(background: bool = True, log=None, needs=(), nice: bool = True, then=()) -> str:
    """Make the compiled kernels available; returns the state: 'ready' (already, or loaded now without
    ``background``), 'loading' / 'compiling' (in the background: the numpy path answers until then),
    'unavailable' (no numba: the numpy path always). In the background the kernel families ``needs`` (of
    ``kernels.FAMILIES``) come first, each ready for the callers as soon as it is compiled and loaded, then
    the families ``then`` and the others, at the lowest priority; ``nice`` lowers the compiling child's
    priority (``BACKGROUND_NICENESS``: for nodes, whose neighbours serve meanwhile; a one-shot command that
    waits for the answer passes False). ``log(text)`` hears what happens in the background."""
    with _lock:
        if status["state"] in ("ready", "loading", "compiling", "unavailable"):
            return status["state"]
        if importlib.util.find_spec("numba") is None:
            kernels.mark_unavailable()
            status.update(state="unavailable", message="numba is not installed: the numpy path serves")
            return "unavailable"
        if not background:
            try:
                kernels.warm_up()
            except ImportError as exc:
                kernels.mark_unavailable()
                status.update(state="unavailable", message=f"numba cannot be imported ({exc})")
                return "unavailable"
            write_marker(cache_dir())
            status.update(state="ready", message="loaded in the caller")
            return "ready"
        warm = cached()
        status.update(state="loading" if warm else "compiling", message="", seconds=None)
        kernels.set_pending(True)
    needs = [f for f in needs if f in kernels.FAMILIES]
    ahead = needs + [f for f in then if f in kernels.FAMILIES and f not in needs]
    order = ahead + [f for f in kernels.FAMILIES if f not in ahead]
    first = len(needs) or None
    threading.Thread(target=_prepare, args=(warm, order, log or (lambda text: None), nice, first),
                     name="tolerance_ros-kernels", daemon=True).start()
    return status["state"]


def _load(family):
    """Load a compiled family in this process (from the cache) and put it in force."""
    kernels.warm_up((family,))


def _prepare(warm: bool, order, log, nice=True, first=None):
    """Background thread of ``start``: fill the cache in a child process when it is cold, each family loaded
    here and put in force as soon as the child has compiled it (in ``order``); a warm cache loads family by
    family. One process at a time fills a cache (a lock beside it): the nodes of a launch started together on
    a cold cache compile once, the others wait for it, loading each family as soon as it is in the cache."""
    t0 = time.perf_counter()
    lock = None if warm else _lock_cache(order)
    try:
        if not warm and not cached():
            status["filled"] = True
            failed = _fill_in_child(order, nice, first)
            if failed:
                _give_up(f"compiling the kernels failed ({failed}); the numpy path serves", log)
                return
    finally:
        if lock is not None:
            lock.close()
    try:
        for family in order:
            _load(family)
    except Exception as exc:  # numba broken in this environment: stay on the numpy path
        _give_up(f"loading the compiled kernels failed ({type(exc).__name__}: {exc}); the numpy path serves", log)
        return
    seconds = time.perf_counter() - t0
    with _lock:
        kernels.set_pending(False)
        status.update(state="ready", seconds=seconds,
                      message=f"compiled kernels {'loaded' if warm else 'compiled and loaded'} in {seconds:.1f} s")
    log(status["message"])


def _lock_cache(order=()):
    """An exclusive lock on ``LOCK`` in the cache's directory, or None where there is no cache directory or no
    flock. While another process holds it (its child fills the cache), each family of ``order`` is loaded
    here as soon as that child has it in the cache (``cached(family)``)."""
    path = cache_dir()
    if path is None:
        return None
    try:
        import fcntl
        f = open(os.path.join(path, LOCK), "a")
    except (ImportError, OSError):
        return None
    waiting = list(order)
    while True:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return f
        except BlockingIOError:  # another process fills the cache: take each family it has finished
            for family in [fam for fam in waiting if cached(fam)]:
                try:
                    _load(family)
                except Exception:  # noqa: BLE001 - loaded again, or given up on, after the lock
                    pass
                waiting.remove(family)
            time.sleep(0.2)
        except OSError:
            f.close()
            return None


_CHILD = ("import sys; sys.path[0] = sys.argv.pop(1); import runpy; "
          "runpy.run_module('tolerance_ros.core.models.warmup', run_name='__main__', alter_sys=True)")


def child_command(args) -> list:
    """The command line of the child that fills the cache: this very package first on its import path (the
    folder that holds this ``tolerance_ros``), in place of the working directory. ``python -m`` would put the
    working directory first: run from a checkout's root after ``pip install .``, the child would compile the
    checkout's kernels into the checkout's cache, where the installed package never looks."""
    return [sys.executable, "-c", _CHILD, str(_HERE.parents[2])] + list(args)


def _fill_in_child(order, nice=True, first=None):
    """Run ``fill_cache`` in a child process; meanwhile import numba here (``kernels.prime``: the families
    waited for then load in milliseconds, not a second); each family it reports ready is loaded here at once.
    None on success, else the reason."""
    args = child_command((["--nice"] if nice else []) + list(order) + ([f"--first={first}"] if first is not None
                                                                         else []))
    try:
        child = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, start_new_session=True)
    except OSError as exc:
        return str(exc)
    kernels.prime(order[:first or len(order)])
    for line in child.stdout:
        word, _, family = line.strip().partition(" ")
        if word == "ready" and family in kernels.FAMILIES:
            try:
                _load(family)
            except Exception:  # the family stays on the numpy path; the end of the child says why
                pass
    err = child.stderr.read()
    child.wait()
    return None if child.returncode == 0 else (err.strip().splitlines() or ["no message"])[-1]


def _give_up(message, log):
    with _lock:
        kernels.mark_unavailable()
        kernels.set_pending(False)
        status.update(state="failed", message=message)
    log(message)


def wait(timeout: float | None = None) -> str:
    """Block until a background ``start`` has finished (or ``timeout`` s); returns the state."""
    deadline = None if timeout is None else time.monotonic() + timeout
    while kernels.pending() and (deadline is None or time.monotonic() < deadline):
        time.sleep(0.05)
    return status["state"]


BACKGROUND_NICENESS = 10
"""How much lower the compiling child's CPU priority is than its parent's: the processes that serve from
the numpy path meanwhile (the nodes of a launch, a robot's own stack) keep the CPU."""


def _lower_priority(by, group=False):
    """Raise this process's niceness by ``by``; with ``group``, when it leads a session of its own (the child
    ``start`` spawns), its Linux autogroup's too. With autogroups (``kernel.sched_autogroup_enabled``) a
    niceness only orders the processes of one session: the child's own niceness leaves it an equal share of
    the CPU beside the command or node it serves; its autogroup's takes it back."""
    try:
        niceness = os.nice(by)
    except (AttributeError, OSError):  # no nice on this platform: compile at the parent's priority
        return
    try:
        if group and os.getsid(0) == os.getpid():
            with open("/proc/self/autogroup", "w", encoding="ascii") as f:
                f.write(str(niceness))
    except (AttributeError, OSError):  # no autogroups here: the niceness alone orders the processes
        pass


def fill_cache(order=kernels.FAMILIES, nice=True, first=None) -> int:
    """The child process: compile every kernel family into the cache, ``order`` first, saying "ready <family>"
    on stdout after each (and choose the Jacobian writer), at a lower priority with ``nice``
    (``BACKGROUND_NICENESS``, within its session: the families its callers wait for still get their share of
    a loaded machine, for the numpy path meanwhile costs more CPU); after the ``first`` families, at the lowest
    priority; without ``nice`` (a one-shot command, which waits for its own families only) its autogroup's
    too, so that the rest, for the next run, never slows the command down; 0 on success."""
    if nice:
        _lower_priority(BACKGROUND_NICENESS)
    order = list(order) + [f for f in kernels.FAMILIES if f not in order]
    listening = True
    for k, family in enumerate(order):
        if first is not None and k == first:
            _lower_priority(19, group=not nice)
        kernels.warm_up((family,))
        write_marker(cache_dir(), family_marker(family))
        if listening:
            try:
                print(f"ready {family}", flush=True)
            except OSError:  # the parent has ended (a one-shot command): finish the cache for the next run
                listening = False
                sys.stdout = open(os.devnull, "w")
    write_marker(cache_dir())
    return 0


if __name__ == "__main__":
    _args = sys.argv[1:]
    if "--where" in _args:              # which package this child imports (``child_command``'s test)
        print(Path(sys.modules["tolerance_ros"].__file__).resolve().parent)
        sys.exit(0)
    _first = next((int(a.split("=", 1)[1]) for a in _args if a.startswith("--first=")), None)
    sys.exit(fill_cache([a for a in _args if a in kernels.FAMILIES], "--nice" in _args, _first))
