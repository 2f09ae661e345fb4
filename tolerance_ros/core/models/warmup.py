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

One compiler per cache, whatever the processes and commands: the compiling child holds ``LOCK`` (an
exclusive ``flock`` beside the cache) for its whole life, handed to it by the process that took it, so
that the lock outlives a one-shot command that ends before its child. A process that finds the lock held
starts no child: it serves from the numpy path, loads each family as soon as the running child has it in
the cache, and leaves a note (``WANT``) of the families it waits for, which the child compiles next, at
its first families' priority; while such a one-shot command runs and needs none of the families left, the
child leaves them until it has ended. A child whose package has gone or changed under it (uninstalled,
reinstalled) ends quietly, with success: the package now installed compiles its own kernels when it runs.
"""
from __future__ import annotations

import errno
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

from ..threads import LOADING
from . import kernels

MARKER = "tolerance_ros-kernels.json"
LOCK = "tolerance_ros-kernels.lock"  # held by the child that fills the cache, for its whole life
WANT = "tolerance_ros-kernels-want"   # WANT.<pid>: the families a process waits for while another's child compiles
KERNEL_MODULES = ("jit.py", "chain_kernels.py", "jacobian_writers.py", "zonotope_kernel.py", "pups_kernels.py")
"""The modules whose compiled code (and writer choice) the marker vouches for."""
_HERE = Path(__file__).resolve().parent
_lock = threading.Lock()
status = {"state": "idle", "message": "", "seconds": None, "filled": False, "compiler": None}  # state: idle |
# loading | compiling | ready | failed; filled: this process's child filled the cache; compiler: whose child
# compiles ('this process', 'another process'; None with a warm cache)


@functools.lru_cache(maxsize=1)
def source_stamp() -> str:
    """Digest of what the cached code depends on: the kernel modules' text, numba's and Python's versions (read
    once: the code this process runs)."""
    return _digest()


def _digest() -> str:
    """``source_stamp`` of the kernel modules on disk now (OSError when one has gone)."""
    h = hashlib.sha256()
    for name in KERNEL_MODULES:
        h.update((_HERE / name).read_bytes())
    h.update(_numba_version().encode())
    h.update(sys.version.encode())
    return h.hexdigest()[:24]


@functools.lru_cache(maxsize=1)
def _numba_version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("numba")
    except PackageNotFoundError:
        return ""


def _package_intact() -> bool:
    """Whether the kernel modules on disk are still those this process started with (not uninstalled or
    replaced under it)."""
    try:
        return _digest() == source_stamp()
    except Exception:  # noqa: BLE001 - a file gone, or the metadata of a package half removed
        return False


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
    ``background``), 'loading' (in the background, from the cache, where every family of ``needs`` is),
    'compiling' (in the background: the numpy path answers until then; ``status['compiler']`` says whose
    child compiles: 'this process' or 'another process'), 'unavailable' (no numba: the numpy path always).
    In the background the kernel families ``needs`` (of ``kernels.FAMILIES``) come first, each ready for the
    callers as soon as it is compiled and loaded, then the families ``then`` and the others, at the lowest
    priority; ``nice`` lowers the compiling child's priority (``BACKGROUND_NICENESS``: for nodes, whose
    neighbours serve meanwhile; a one-shot command that waits for the answer passes False). At most one
    child compiles a cache (the module docstring). ``log(text)`` hears what happens in the background."""
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
        needs = [f for f in needs if f in kernels.FAMILIES]
        ahead = needs + [f for f in then if f in kernels.FAMILIES and f not in needs]
        order = ahead + [f for f in kernels.FAMILIES if f not in ahead]
        warm = cached()
        lock, held = (None, None) if warm else _take_lock()
        compiling = not warm and not all(cached(f) for f in (needs or order))
        compiler = None if warm else ("another process" if held is False else "this process")
        status.update(state="compiling" if compiling else "loading", message="", seconds=None, compiler=compiler)
        kernels.set_pending(True)
    threading.Thread(target=_prepare, args=(warm, order, log or (lambda text: None), nice, len(needs) or None,
                                            lock, held), kwargs={"ahead": len(ahead) if not nice else None},
                     name="tolerance_ros-kernels", daemon=True).start()
    return status["state"]


def _load(family):
    """Load a compiled family in this process (from the cache) and put it in force (under ``threads.LOADING``)."""
    with LOADING:
        kernels.warm_up((family,))


def _prime(families):
    """``kernels.prime`` (numba and the families' modules imported) under ``threads.LOADING``."""
    with LOADING:
        kernels.prime(families)


def _prepare(warm: bool, order, log, nice=True, first=None, lock=None, held=None, ahead=None):
    """Background thread of ``start``: with a cold cache, fill it in a child process (``_fill``), each family
    loaded here and put in force as soon as it is in the cache (in ``order``); a warm cache loads family by
    family. ``lock``: the cache's lock file (None without one), ``held`` whether this process holds it;
    ``ahead``: how many families of ``order`` a one-shot command uses (``fill_cache``)."""
    t0 = time.perf_counter()
    try:
        if not warm:
            failed = _fill(order, nice, first, lock, held, ahead)
            if failed:
                _give_up(f"compiling the kernels failed ({failed}); the numpy path serves", log)
                return
    finally:
        if lock is not None:
            lock.close()  # a child it was handed to keeps the lock until it ends
    path = cache_dir()
    missing = [family for family in order if path is not None and not cached(family)]
    if missing:  # the child ended without them: its package changed under it (this process's too)
        _give_up(f"the kernels of {', '.join(missing)} were not compiled (the compiling child ended before them); "
                 "the numpy path serves", log)
        return
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


def _fill(order, nice, first, lock, held, ahead=None):
    """Fill a cold cache: by a child of this process, which ``lock`` goes to (held here, or taken once the
    running compiler of another process has ended), unless the cache is complete by then; meanwhile each
    family that other compiler finishes is loaded here. None on success, else the reason."""
    if lock is None:  # no lock to be had here (no cache directory, no flock): a child of this process
        status["filled"] = True
        return _fill_in_child(order, nice, first, ahead=ahead)
    if not held:
        _wait_for_compiler(lock, order, first, one_shot=not nice)
    if cached():
        return None
    status.update(filled=True, compiler="this process")
    return _fill_in_child(order, nice, first, lock, ahead)


def _take_lock():
    """(the open ``LOCK`` file, whether this process now holds it); (None, None) where there is no cache
    directory or no flock."""
    path = cache_dir()
    if path is None:
        return None, None
    try:
        import fcntl  # noqa: F401 - not on every platform
        f = open(os.path.join(path, LOCK), "a")
    except (ImportError, OSError):
        return None, None
    held = _try_lock(f)
    if held is None:
        f.close()
        return None, None
    return f, held


def _try_lock(f):
    """Take ``f``'s exclusive flock without waiting: True, False while another process holds it, None where
    the file system refuses locks."""
    import fcntl
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        return False
    except OSError:
        return None


def _wait_for_compiler(lock, order=(), first=None, one_shot=False):
    """While another process's child holds ``lock`` (it compiles), load each family of ``order`` as soon as
    it is in the cache (``cached(family)``), and leave a note (``WANT``) of the families waited for (the
    first ``first``; all without it), which that child compiles next, and, for a ``one_shot`` command,
    of the command itself: the child leaves the families nobody waits for until it has ended. Returns once
    this process holds the lock (the child has ended)."""
    waiting = list(order)
    needs = waiting[:first or len(waiting)]
    note = _write_want(needs, one_shot)
    _prime([f for f in needs if not cached(f)])
    try:
        while True:
            for family in [fam for fam in waiting if cached(fam)]:
                try:
                    _load(family)
                except Exception:  # noqa: BLE001 - loaded again, or given up on, after the lock
                    pass
                waiting.remove(family)
            if _try_lock(lock) is not False:
                return
            time.sleep(0.2)
    finally:
        if note is not None:
            try:
                os.unlink(note)
            except OSError:
                pass


def _write_want(families, one_shot=False):
    """Write this process's ``WANT`` note beside the cache (the families it waits for, whether it is a
    one-shot command); its path, or None."""
    path = cache_dir()
    if path is None:
        return None
    name = os.path.join(path, f"{WANT}.{os.getpid()}")
    try:
        with open(f"{name}.tmp", "w", encoding="utf-8") as f:
            json.dump({"families": list(families), "one_shot": bool(one_shot)}, f)
        os.replace(f"{name}.tmp", name)
    except OSError:
        return None
    return name


def _notes(path=None) -> list:
    """[(families, one_shot)] of the ``WANT`` notes of live processes, oldest first; the notes of processes
    that have ended are removed."""
    path = path or cache_dir()
    if path is None:
        return []
    notes = []
    try:
        names = [n for n in os.listdir(path) if n.startswith(WANT + ".") and n[len(WANT) + 1:].isdigit()]
    except OSError:
        return []
    for name in names:
        full = os.path.join(path, name)
        try:
            os.kill(int(name[len(WANT) + 1:]), 0)
        except ProcessLookupError:
            try:
                os.unlink(full)
            except OSError:
                pass
            continue
        except OSError:  # alive, another user's
            pass
        try:
            with open(full, encoding="utf-8") as f:
                doc = json.load(f)
            notes.append((os.stat(full).st_mtime, list(doc.get("families", [])), bool(doc.get("one_shot"))))
        except (OSError, ValueError, AttributeError, TypeError):
            continue
    return [(families, one_shot) for _, families, one_shot in sorted(notes, key=lambda n: n[0])]


def _wanted(remaining, path=None, notes=None) -> list:
    """The families of ``remaining`` that live processes wait for (their ``WANT`` notes, oldest first)."""
    out = []
    for families, _ in _notes(path) if notes is None else notes:
        out += [f for f in families if f in remaining and f not in out]
    return out


_CHILD = """import sys
sys.path[0] = sys.argv.pop(1)
try:
    from tolerance_ros.core.models import warmup
except Exception:  # its package has gone (uninstalled, or replaced under it): nothing left to compile for
    sys.exit(0)
sys.exit(warmup.main(sys.argv[1:]))
"""


def child_command(args) -> list:
    """The command line of the child that fills the cache: this very package first on its import path (the
    folder that holds this ``tolerance_ros``), in place of the working directory. ``python -m`` would put the
    working directory first: run from a checkout's root after ``pip install .``, the child would compile the
    checkout's kernels into the checkout's cache, where the installed package never looks."""
    return [sys.executable, "-c", _CHILD, str(_HERE.parents[2])] + list(args)


def _fill_in_child(order, nice=True, first=None, lock=None, ahead=None):
    """Run ``fill_cache`` in a child process, ``lock`` (the cache's lock file, held) handed to it: the child
    holds the lock until it ends, whether this process has ended or not. Meanwhile import numba here
    (``kernels.prime``: the families waited for then load in milliseconds, not a second); each family it
    reports ready is loaded here at once. None on success, else the reason."""
    args = child_command((["--nice"] if nice else []) + list(order) + ([f"--first={first}"] if first is not None
                                                                         else [])
                         + ([f"--lock-fd={lock.fileno()}"] if lock is not None else [])
                         + ([f"--ahead={ahead}", f"--parent={os.getpid()}"] if ahead is not None else []))
    try:
        child = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True, start_new_session=True,
                                 pass_fds=(lock.fileno(),) if lock is not None else ())
    except OSError as exc:
        return str(exc)
    finally:
        if lock is not None:
            lock.close()  # the child holds it now
    _prime(order[:first or len(order)])
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
    if group:
        _set_autogroup(niceness)


def _own_autogroup():
    """This process's autogroup niceness when it leads a session of its own and has an autogroup, else None
    (another session's autogroup is not ours to change; the init session's file reads empty)."""
    try:
        if os.getsid(0) != os.getpid():
            return None
        with open("/proc/self/autogroup", encoding="ascii") as f:
            return int(f.read().split()[-1])
    except (AttributeError, OSError, ValueError, IndexError):
        return None


def _set_autogroup(niceness) -> bool:
    """Set this process's autogroup niceness where ``_own_autogroup`` allows (back up to 0 needs no privilege;
    the kernel refuses a second change within 0.1 s to the unprivileged: tried again); whether it was set."""
    if _own_autogroup() is None:
        return False
    for _ in range(3):
        try:
            with open("/proc/self/autogroup", "w", encoding="ascii") as f:
                f.write(str(niceness))
            return True
        except OSError as exc:  # no autogroups here: the niceness alone orders the processes
            if exc.errno != errno.EAGAIN:
                return False
            time.sleep(0.11)
    return False


def _hold_lock(fd=None):
    """The cache's lock, held by this child until it ends: the descriptor its parent handed over (locked
    already: taking it again is immediate), or, run on its own, ``LOCK`` taken here, after the compiler
    running now if there is one. None where there is no lock to take."""
    try:
        import fcntl
    except ImportError:
        return None
    try:
        if fd is not None:
            f = os.fdopen(fd, "a")
            os.set_inheritable(fd, False)
        else:
            path = cache_dir()
            if path is None:
                return None
            f = open(os.path.join(path, LOCK), "a")
        fcntl.flock(f, fcntl.LOCK_EX)
        return f
    except OSError:
        return None


_held = None  # the child's lock, kept open for its whole life
GAP = 1.0
"""Seconds the compiling child still leaves the families nobody waits for after a one-shot command has ended
(the next command of a user's rhythm starts within it)."""


def fill_cache(order=kernels.FAMILIES, nice=True, first=None, lock_fd=None, ahead=None, parent=None) -> int:
    """The child process: compile every kernel family into the cache, ``order`` first, saying "ready <family>"
    on stdout after each (and choose the Jacobian writer), at a lower priority with ``nice``
    (``BACKGROUND_NICENESS``, within its session: the families its callers wait for still get their share of
    a loaded machine, for the numpy path meanwhile costs more CPU); after the ``first`` families, at the lowest
    priority; without ``nice`` (a one-shot command, which waits for its own families only) its autogroup's
    too, so that the rest, for the next run, never slows the command down, except while another process
    waits for one of the families left (its ``WANT`` note): those come next (before the ``first`` ones too
    once the parent has ended: nothing waits for them then), at the first families' priority; and while a
    one-shot command that waits for none of them runs (its note; ``GAP`` s more), or, with ``ahead``, while
    the parent runs (a one-shot command that uses the first ``ahead`` families of ``order``), the families
    nobody waits for wait for it to end (two processes on a 2-core VM slow each other down, whatever their
    priorities). The cache's lock is held throughout (``lock_fd``: handed over by the parent; else taken here).
    ``parent``: the pid of the process that started this one (it may have ended before this one asks).
    A family already in the cache is not compiled again. Ends at once, with 0 and nothing said, when the
    package's kernel modules have gone or changed on disk; 0 on success."""
    global _held
    source_stamp()  # the code this child runs, before anything can change under it
    _held = _hold_lock(lock_fd)
    if nice:
        _lower_priority(BACKGROUND_NICENESS)
    order = list(order) + [f for f in kernels.FAMILIES if f not in order]
    path = cache_dir()
    group = None if nice else _own_autogroup()
    parent = os.getppid() if parent is None else parent  # may have ended already: then never the parent again
    progress = {"left": list(order), "low": False, "group": group, "busy": -GAP}

    def prioritise():
        """The autogroup back at its first niceness while a process waits for a family left, else 19."""
        if progress["low"] and group is not None and path is not None:
            target = group if _wanted(progress["left"], path) else 19
            if target != progress["group"] and _set_autogroup(target):
                progress["group"] = target

    if group is not None and path is not None:
        def watch():
            while progress["left"]:
                prioritise()
                time.sleep(0.25)
        threading.Thread(target=watch, name="tolerance_ros-wants", daemon=True).start()
    listening = True
    while progress["left"]:
        alive = os.getppid() == parent  # a command that has ended waits for nothing
        firsts = [f for f in order[:first] if f in progress["left"]] if first is not None and alive else []
        if first is not None and not firsts and not progress["low"]:
            _lower_priority(19, group=not nice)
            progress.update(low=True, group=19 if group is not None else None)
        prioritise()
        notes = _notes(path) if path is not None else []
        wanted = _wanted(progress["left"], notes=notes)
        if any(one_shot for _, one_shot in notes):
            progress["busy"] = time.monotonic()
        used = [f for f in order[:ahead] if f in progress["left"]] if ahead is not None and alive else None
        if not firsts and not wanted and (time.monotonic() - progress["busy"] < GAP or used == []):
            time.sleep(0.25)  # a command runs that needs none of the families left: they come after it
            continue
        family = (firsts or wanted or progress["left"])[0]
        if not _package_intact():
            return 0
        if not cached(family):
            try:
                kernels.warm_up((family,))
            except Exception:
                if not _package_intact():
                    return 0
                raise
            if not _package_intact():
                return 0
            write_marker(path, family_marker(family))
        progress["left"].remove(family)
        if listening:
            try:
                print(f"ready {family}", flush=True)
            except OSError:  # the parent has ended (a one-shot command): finish the cache for the next run
                listening = False
                sys.stdout = open(os.devnull, "w")
    write_marker(path)
    return 0


def main(args) -> int:
    """The child's command line: the families in order, ``--nice``, ``--first=N``, ``--lock-fd=FD``,
    ``--ahead=N``, ``--parent=PID``; or
    ``--where`` (which package it imports: ``child_command``'s test)."""
    if "--where" in args:
        print(Path(sys.modules["tolerance_ros"].__file__).resolve().parent)
        return 0
    first = next((int(a.split("=", 1)[1]) for a in args if a.startswith("--first=")), None)
    fd = next((int(a.split("=", 1)[1]) for a in args if a.startswith("--lock-fd=")), None)
    ahead = next((int(a.split("=", 1)[1]) for a in args if a.startswith("--ahead=")), None)
    parent = next((int(a.split("=", 1)[1]) for a in args if a.startswith("--parent=")), None)
    return fill_cache([a for a in args if a in kernels.FAMILIES], "--nice" in args, first, fd, ahead, parent)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
