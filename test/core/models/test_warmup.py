"""The compiled kernels prepared in the background: a cold start serves at once from the numpy path and
switches to the compiled kernels without a pause (in child processes with an empty NUMBA_CACHE_DIR); one
compiler per cache, whatever the processes and commands."""
import contextlib
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from tolerance_ros.core.models import jacobian_writers, warmup

ROOT = Path(__file__).resolve().parents[3]

COLD_START = r"""
import json, sys, time
t0 = time.perf_counter()
from tolerance_ros.core.models import load_robot, warmup
model = load_robot(sys.argv[1], **json.loads(sys.argv[2]))
state = warmup.start(background=True, needs=(model.kernel_family,))
q = model.sample_joints(50, 0)
calls, first, numpy_answer = [], None, None
while True:
    t = time.perf_counter()
    backend = model.backend
    T, J = model.fk_and_jacobian(q)
    calls.append(time.perf_counter() - t)
    if first is None:
        first, numpy_answer = time.perf_counter() - t0, (T, J.J)
    if backend == "numba" or time.perf_counter() - t0 > 150:
        break
    time.sleep(0.02)
import numpy as np
from tolerance_ros.core.models import kernels
diff = max(np.abs(T - numpy_answer[0]).max(), np.abs(J.J - numpy_answer[1]).max())
switched_at, others_pending = time.perf_counter() - t0, kernels.pending()
warmup.wait(300)
print(json.dumps({"state": state, "first_s": first, "switched": backend == "numba", "after_s": switched_at,
                  "others_pending": others_pending, "calls": len(calls), "slowest_call_s": max(calls),
                  "diff": float(diff), "cached": warmup.cached(), "final": warmup.status}))
"""


def _env(cache):
    return dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))


def _run(code, cache, *args, timeout=240):
    out = subprocess.run([sys.executable, "-c", code, *args], env=_env(cache), capture_output=True, text=True,
                         timeout=timeout, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_marker_lives_where_numba_caches_the_kernels(tmp_path):
    """cache_dir() (without numba) is the directory numba itself chose, here and with NUMBA_CACHE_DIR."""
    assert warmup.cache_dir() == os.path.dirname(jacobian_writers._choice_path())
    code = ("import json, os; from tolerance_ros.core.models import jacobian_writers, kernels, warmup; "
            "kernels.warm_up(('dh',)); "
            "print(json.dumps([warmup.cache_dir(), os.path.dirname(jacobian_writers._choice_path())]))")
    ours, numbas = _run(code, tmp_path)
    assert ours == numbas and ours.startswith(str(tmp_path))


def test_a_cold_start_serves_at_once_and_switches_to_the_compiled_kernels_without_a_pause(tmp_path):
    """Empty cache, two processes started together: ``start`` returns while the kernels compile (each process
    answers meanwhile, from the numpy path until its family is ready); one child process compiles the kernels
    while the other process waits for it; both load them and switch between two calls; the compiled answer
    equals the numpy one to 1e-12; the next start finds the cache warm and loads. (How long each step takes:
    bench/bench_first_run.py.)"""
    with _compilers_seen(tmp_path) as seen:
        starts = [subprocess.Popen([sys.executable, "-c", COLD_START, "gao2023_7dof", "{}"], env=_env(tmp_path),
                                   stdout=subprocess.PIPE, text=True) for _ in range(2)]  # two nodes of one launch
        both = [json.loads(p.communicate(timeout=300)[0].strip().splitlines()[-1]) for p in starts]
    assert len(seen) == 1, f"compiling children {sorted(seen)}: one was expected"
    for cold in both:
        assert cold["state"] == "compiling" and cold["switched"], cold
        assert cold["diff"] < 1e-12 and cold["cached"] and cold["final"]["state"] == "ready", cold
    assert any(c["others_pending"] for c in both), "the family asked for first switched before the others were ready"
    assert sorted(c["final"]["filled"] for c in both) == [False, True], "one of them compiles, the other waits"
    warm = _run(COLD_START, tmp_path, "gao2023_7dof", "{}")
    assert warm["state"] == "loading" and warm["switched"] and not warm["final"]["filled"], warm
    out = subprocess.run([sys.executable, "-m", "tolerance_ros.cli", "jacobian", "--robot", "gao2023_7dof", "--random",
                          "2"], env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "compil" not in out.stderr, out.stderr  # the compiler has finished: no word of it


def test_a_stale_marker_is_not_trusted(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    path = warmup.cache_dir()
    assert path.startswith(str(tmp_path)) and not warmup.cached()
    warmup.write_marker(path)
    assert warmup.cached()
    doc = json.loads(Path(path, warmup.MARKER).read_text())
    Path(path, warmup.MARKER).write_text(json.dumps({**doc, "stamp": "another source"}))
    assert not warmup.cached()


def _children_compiling_into(cache) -> list:
    """The pids of the processes that fill the kernel cache ``cache`` (``warmup``'s child), from /proc; not a
    fork of one of them (numba's library look-ups run a program: its fork has the child's command line until
    it runs it)."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes()
            env = (entry / "environ").read_bytes()
            ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if warmup._CHILD.encode() in cmd and f"NUMBA_CACHE_DIR={cache}\0".encode() in env:
            found[int(entry.name)] = ppid
    return [pid for pid, ppid in found.items() if ppid not in found]


@contextlib.contextmanager
def _compilers_seen(cache):
    """The set of the pids of every process seen compiling into ``cache`` (every 50 ms) while the block runs."""
    seen, stop = set(), threading.Event()

    def watch():
        while not stop.is_set():
            seen.update(_children_compiling_into(cache))
            time.sleep(0.05)
    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        yield seen
    finally:
        stop.set()
        watcher.join()


def _stop(pids):
    for pid in pids:
        try:
            os.kill(pid, 9)
        except ProcessLookupError:
            pass
    deadline = time.monotonic() + 10
    while any(Path(f"/proc/{pid}").exists() for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.05)


JACOBIAN = [sys.executable, "-m", "tolerance_ros.cli", "jacobian", "--robot", "gao2023_7dof", "--joints",
            "0rad,0.1rad,0.2rad,0.3rad,0.4rad,0.5rad,0.6rad"]


def test_commands_one_after_another_on_a_cold_cache_start_one_compiler_which_holds_the_cache_lock(tmp_path,
                                                                                                  monkeypatch):
    """A user's rhythm on an empty cache: quick commands one after another, each ending before the kernels
    are compiled. The first starts the compiling child, and the child, not the command, holds the cache's
    lock: the next commands find it held after the first has ended, start none, say that an earlier command
    compiles (nothing, where it has compiled what they use by then), and answer. When the child ends (stopped here), the lock goes with it."""
    import fcntl
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    lock = open(os.path.join(warmup.cache_dir(), warmup.LOCK), "a")
    with _compilers_seen(tmp_path) as seen:
        outs = [subprocess.run(JACOBIAN, env=_env(tmp_path), capture_output=True, text=True, timeout=120)
                for _ in range(3)]
        alive = _children_compiling_into(tmp_path)
    try:
        assert [o.returncode for o in outs] == [0, 0, 0], [o.stderr for o in outs]
        assert len(seen) == 1 and set(alive) == seen, (seen, alive)
        with pytest.raises(BlockingIOError):  # the child holds the lock after its command has ended
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert "compiling the kernels in the background" in outs[0].stderr
        for out in outs[1:]:   # an earlier command's child compiles, or has compiled what this one uses by now
            assert ("the kernels are being compiled by an earlier command" in out.stderr
                    or "compil" not in out.stderr), out.stderr
    finally:
        _stop(list(seen))
    fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    lock.close()


def test_a_compiling_child_whose_package_has_gone_ends_quietly(tmp_path):
    """The package uninstalled before its child starts (the folder it was to import from holds none): the
    child ends with 0 and says nothing. Uninstalled or reinstalled while the child compiles (here by the
    first compilation itself, in a copy of the package): it ends after that family, with 0, saying nothing,
    and vouches for nothing in the cache (no marker: the package now installed compiles its own)."""
    gone = tmp_path / "gone"
    gone.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-S", "-c", warmup._CHILD, str(gone), "dh", "--first=1"], env=env,
                         capture_output=True, text=True, timeout=60)
    assert (out.returncode, out.stdout, out.stderr) == (0, "", "")
    import shutil
    for change in ("uninstall", "reinstall"):
        site = tmp_path / change
        shutil.copytree(ROOT / "tolerance_ros", site / "tolerance_ros", ignore=shutil.ignore_patterns("__pycache__"))
        driver = (f"import shutil, sys; sys.path.insert(0, {str(site)!r}); from pathlib import Path; "
                  "from tolerance_ros.core.models import kernels, warmup\n"
                  "def compile_and_change(which):\n"
                  "    print('compiled', *which, flush=True)\n"
                  "    kernel = Path(warmup.__file__).parent / 'zonotope_kernel.py'\n"
                  f"    if {change!r} == 'uninstall': shutil.rmtree(Path(warmup.__file__).parents[2])\n"
                  "    else: kernel.write_text(kernel.read_text() + '# a new version')\n"
                  "kernels.warm_up = compile_and_change\n"
                  "sys.exit(warmup.fill_cache(['dh', 'zonotope'], False, 1))")
        cache = tmp_path / f"cache-{change}"
        out = subprocess.run([sys.executable, "-c", driver], env=dict(env, NUMBA_CACHE_DIR=str(cache)),
                             capture_output=True, text=True, timeout=60)
        assert (out.returncode, out.stdout, out.stderr) == (0, "compiled dh\n", ""), (change, out)
        assert not [f.name for f in cache.rglob("*.json")], change


@pytest.mark.skipif(not os.path.exists("/proc/self/autogroup"), reason="no Linux autogroups on this machine")
def test_a_running_compiler_takes_next_the_families_another_process_waits_for_at_its_first_priority(tmp_path,
                                                                                                   monkeypatch):
    """A command's compiling child, past the families its own command waited for (at the lowest priority),
    finds a WANT note of a live process waiting for 'pups': it compiles pups next, its autogroup back at its
    first niceness, then the rest at 19 again. The note of a process that has ended is removed unread."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    path = warmup.cache_dir()
    ended = subprocess.Popen(["true"])
    ended.wait()
    for pid, families in ((os.getpid(), ["pups"]), (ended.pid, ["urdf"])):
        Path(path, f"{warmup.WANT}.{pid}").write_text(json.dumps({"families": families}))
    code = ("from tolerance_ros.core.models import kernels, warmup; "
            "kernels.warm_up = lambda which: print(*which, open('/proc/self/autogroup').read().split()[-1], "
            "flush=True); warmup.fill_cache(['dh', 'zonotope', 'urdf', 'pups'], False, 1)")
    out = subprocess.run([sys.executable, "-c", code], env=_env(tmp_path), capture_output=True, text=True,
                         check=True, start_new_session=True, timeout=60)
    compiled = [line.split() for line in out.stdout.splitlines() if not line.startswith("ready")]
    assert compiled == [["dh", "0"], ["pups", "0"], ["zonotope", "19"], ["urdf", "19"]], out.stdout
    assert not Path(path, f"{warmup.WANT}.{ended.pid}").exists()
    assert Path(path, f"{warmup.WANT}.{os.getpid()}").exists()  # a live process's note is its own to remove


def test_the_families_nobody_waits_for_wait_for_a_running_command_to_end(tmp_path, monkeypatch):
    """While a one-shot command runs that needs none of the families left (its WANT note: it runs on what is
    compiled), the compiling child leaves them until the command has ended; a node's note (not one-shot)
    does not hold them back."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    path = warmup.cache_dir()
    command = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(2)"])
    node = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        for pid, one_shot in ((command.pid, True), (node.pid, False)):
            Path(path, f"{warmup.WANT}.{pid}").write_text(json.dumps({"families": ["dh"], "one_shot": one_shot}))
        code = ("import time; from tolerance_ros.core.models import kernels, warmup; "
                "kernels.warm_up = lambda which: print(*which, time.time(), flush=True); "
                "warmup.fill_cache(['dh', 'zonotope', 'urdf', 'pups'], False, 1)")
        child = subprocess.Popen([sys.executable, "-c", code], env=_env(tmp_path), stdout=subprocess.PIPE, text=True)
        command.wait()
        ended = time.time()
        out = child.communicate(timeout=60)[0]
    finally:
        node.kill()
        node.wait()
    compiled = {line.split()[0]: float(line.split()[1]) for line in out.splitlines() if not line.startswith("ready")}
    assert list(compiled) == ["dh", "zonotope", "urdf", "pups"]
    assert compiled["dh"] < ended <= compiled["zonotope"], (compiled, ended)


def test_the_families_a_command_does_not_use_wait_for_it_to_end(tmp_path):
    """A one-shot command's child (``ahead``: the command uses the first two families) compiles those, then
    leaves the others until the command has ended: beside it they would only slow it down."""
    code = ("import time; from tolerance_ros.core.models import kernels, warmup; "
            "kernels.warm_up = lambda which: print(*which, time.time(), flush=True); "
            "warmup.fill_cache(['zonotope', 'dh', 'urdf', 'pups'], False, 1, None, 2)")
    log = tmp_path / "compiled.txt"
    command = (f"import subprocess, sys, time; child = subprocess.Popen([sys.executable, '-c', {code!r}], "
               f"stdout=open({str(log)!r}, 'w')); time.sleep(2); print(time.time())")
    ended = float(subprocess.run([sys.executable, "-c", command], env=_env(tmp_path / "cache"), capture_output=True,
                                 text=True, check=True, timeout=60).stdout)
    deadline = time.monotonic() + 60
    while log.read_text().count("ready") < 4 and time.monotonic() < deadline:
        time.sleep(0.1)
    compiled = {line.split()[0]: float(line.split()[1]) for line in log.read_text().splitlines()
                if not line.startswith("ready")}
    assert list(compiled) == ["zonotope", "dh", "urdf", "pups"]
    assert compiled["dh"] < ended <= compiled["urdf"], (compiled, ended)


def test_a_child_whose_command_ended_before_it_started_compiles_everything(tmp_path):
    """A quick command ends before its child has even started (the child then has another parent from its
    first moment): the child knows its command by pid, not as whatever parent it finds, and goes on with
    the families the command did not use."""
    code = ("import os, sys, time; time.sleep(0.5); from tolerance_ros.core.models import kernels, warmup; "
            "kernels.warm_up = lambda which: print(*which, flush=True); "
            "warmup.fill_cache(['dh', 'zonotope', 'urdf', 'pups'], False, 1, None, 1, int(sys.argv[1]))")
    log = tmp_path / "compiled.txt"
    command = (f"import os, subprocess, sys; subprocess.Popen([sys.executable, '-c', {code!r}, str(os.getpid())], "
               f"stdout=open({str(log)!r}, 'w'))")
    subprocess.run([sys.executable, "-c", command], env=_env(tmp_path / "cache"), check=True, timeout=60)
    deadline = time.monotonic() + 30
    while log.read_text().count("ready") < 4 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert [line for line in log.read_text().split() if line != "ready"][:8:2] == ["dh", "zonotope", "urdf", "pups"]


def test_the_command_line_answers_at_once_on_a_cold_cache_and_says_it_compiles(tmp_path):
    """The one-shot command answers from the numpy path and leaves the cache to its child, which this test
    stops (nothing of it outlives the test)."""
    out = subprocess.run([sys.executable, "-m", "tolerance_ros.cli", "jacobian", "--robot", "gao2023_7dof",
                          "--random", "5", "--json"], env=_env(tmp_path), capture_output=True, text=True, timeout=60)
    still = _children_compiling_into(tmp_path)       # the answer came while its child still compiled
    for pid in still:
        os.kill(pid, 9)
    deadline = time.monotonic() + 10
    while _children_compiling_into(tmp_path) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _children_compiling_into(tmp_path)
    assert out.returncode == 0, out.stderr
    assert "compiling the kernels in the background" in out.stderr
    doc = json.loads(out.stdout)
    assert doc["ok"] and np.asarray(doc["jacobian"]).shape[0] == 5
    assert still, "the command waited for the compilation"


def test_the_compiling_child_runs_at_a_lower_priority(tmp_path):
    """fill_cache lowers its own priority by BACKGROUND_NICENESS before it compiles (the serving processes keep
    the CPU meanwhile); a process already niced ends at 19, the lowest priority."""
    code = ("import os; from tolerance_ros.core.models import kernels, warmup; before = os.nice(0); "
            "kernels.warm_up = lambda *a, **k: None; warmup.fill_cache(); print(os.nice(0) - before)")
    out = subprocess.run([sys.executable, "-c", code], env=_env(tmp_path), capture_output=True, text=True,
                         check=True)
    assert int(out.stdout.split()[-1]) == min(warmup.BACKGROUND_NICENESS, 19 - os.nice(0))


@pytest.mark.skipif(not os.path.exists("/proc/self/autogroup"), reason="no Linux autogroups on this machine")
@pytest.mark.parametrize("nice", [False, True])
def test_the_compiling_child_of_a_command_lowers_its_autogroup_after_the_families_waited_for(tmp_path, nice):
    """With autogroups a niceness only orders one session's processes. The child, a session of its own, keeps
    its autogroup's share while it compiles the families its callers wait for; for a one-shot command
    (``nice`` False) it then sets its autogroup's niceness to its own, 19, for the rest (the next run's); for
    nodes (``nice``) the rest keeps the share, so that every family comes on a loaded machine too. A process
    in its caller's session leaves that session's autogroup alone, the init session's too (which is no
    autogroup: its file reads empty, as in a CI container whose processes never left PID 1's session). (Each run
    compiles into a cache of its own: a family in the cache is not compiled again.)"""
    code = ("import os, sys; from tolerance_ros.core.models import kernels, warmup; "
            "kernels.warm_up = lambda *a, **k: print((open('/proc/self/autogroup').read().split() or ['-'])[-1], "
            f"os.nice(0)); warmup.fill_cache(['dh', 'zonotope'], {nice}, 1)")
    out = subprocess.run([sys.executable, "-c", code], env=_env(tmp_path), capture_output=True, text=True,
                         check=True, start_new_session=True)
    lines = [[int(v) for v in line.split()] for line in out.stdout.splitlines() if not line.startswith("ready")]
    own = min(19, os.nice(0) + warmup.BACKGROUND_NICENESS) if nice else os.nice(0)
    assert lines[0] == [0, own] and lines[1] == [0 if nice else 19, 19], lines  # a session's autogroup starts at 0
    before = open("/proc/self/autogroup").read()
    out = subprocess.run([sys.executable, "-c", code], env=_env(tmp_path / "again"), capture_output=True, text=True,
                         check=True)
    assert open("/proc/self/autogroup").read() == before
    nices = [int(line.split()[-1]) for line in out.stdout.splitlines() if not line.startswith("ready")]
    assert nices == [own] + [19] * (len(nices) - 1) and len(nices) == len(lines), nices


def test_a_process_waiting_for_another_to_fill_the_cache_loads_each_family_as_it_comes(tmp_path, monkeypatch):
    """While another process holds the cache's lock (its child compiling), a family whose marker the child has
    written is loaded at once, and the families waited for are in a WANT note of this process; the lock is
    taken when the other process lets it go, and the note removed."""
    import fcntl
    import threading
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    loaded = []
    monkeypatch.setattr(warmup, "_load", loaded.append)
    holder = open(os.path.join(warmup.cache_dir(), warmup.LOCK), "a")
    fcntl.flock(holder, fcntl.LOCK_EX)
    lock, held = warmup._take_lock()
    assert held is False
    note = Path(warmup.cache_dir(), f"{warmup.WANT}.{os.getpid()}")
    waiter = threading.Thread(target=warmup._wait_for_compiler, args=(lock, ["zonotope", "dh"], 1))
    waiter.start()
    time.sleep(0.5)
    assert loaded == [] and waiter.is_alive()
    assert json.loads(note.read_text()) == {"families": ["zonotope"], "one_shot": False}
    assert warmup._wanted(["dh", "zonotope", "urdf"]) == ["zonotope"]
    warmup.write_marker(warmup.cache_dir(), warmup.family_marker("dh"))
    deadline = time.monotonic() + 10
    while not loaded and time.monotonic() < deadline:
        time.sleep(0.05)
    assert loaded == ["dh"] and waiter.is_alive()
    holder.close()  # the compiling child ends
    waiter.join(10)
    assert not waiter.is_alive() and loaded == ["dh"] and not note.exists()
    assert warmup._try_lock(lock)  # held by this process now
    lock.close()


def test_the_families_a_command_waits_for_compile_first_then_the_next_then_the_rest(monkeypatch):
    """start(needs, then): the child compiles ``needs`` at the caller's priority (``--first``), then ``then``
    and the other families at the lowest."""
    from tolerance_ros.core.models import kernels
    seen = []
    monkeypatch.setattr(warmup, "status", dict(warmup.status, state="idle"))
    monkeypatch.setattr(warmup, "cached", lambda family=None: False)
    monkeypatch.setattr(warmup, "_take_lock", lambda: (None, None))
    monkeypatch.setattr(warmup, "_prepare", lambda warm, order, log, nice, first, lock, held, ahead:
                        seen.append((order, first, ahead)))
    try:
        assert warmup.start(background=True, needs=("zonotope",), then=("urdf", "zonotope"), nice=False) == "compiling"
    finally:
        kernels.set_pending(False)
    deadline = time.monotonic() + 10
    while not seen and time.monotonic() < deadline:  # _prepare runs in the background thread start() made
        time.sleep(0.01)
    assert seen == [(["zonotope", "urdf", "dh", "pups"], 1, 2)]


LAUNCHER = r"""
import subprocess, sys
from tolerance_ros.core.models import warmup
print(warmup.__file__)
print(subprocess.run(warmup.child_command(["--where"]), capture_output=True, text=True, check=True).stdout.strip())
"""


def test_the_compiling_child_imports_the_package_its_parent_runs_whatever_the_working_directory(tmp_path):
    """The README's path: the package installed (``pip install .`` copies it into site-packages; a copy here),
    the command run from a checkout's root, which holds another ``tolerance_ros``. A console script's parent
    imports the installed one; its child must too (``python -m`` would import the checkout's and compile into
    its cache, where the installed package never looks)."""
    import shutil
    skip = shutil.ignore_patterns("__pycache__")
    site, checkout, scripts = tmp_path / "site", tmp_path / "checkout", tmp_path / "bin"
    shutil.copytree(ROOT / "tolerance_ros", site / "tolerance_ros", ignore=skip)
    shutil.copytree(ROOT / "tolerance_ros", checkout / "tolerance_ros", ignore=skip)
    scripts.mkdir()
    (scripts / "tolerance-ros").write_text(LAUNCHER)
    env = dict(os.environ, PYTHONPATH=str(site))
    out = subprocess.run([sys.executable, str(scripts / "tolerance-ros")], cwd=checkout, env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    parent, child = out.stdout.split()
    assert Path(parent).is_relative_to(site) and Path(child) == site / "tolerance_ros"
    old = subprocess.run([sys.executable, "-m", "tolerance_ros.core.models.warmup", "--where"], cwd=checkout, env=env,
                         capture_output=True, text=True, timeout=120)
    assert Path(old.stdout.strip()) == checkout / "tolerance_ros"    # what ``python -m`` imported: the checkout's
