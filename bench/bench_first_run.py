"""Benchmark: a user's first run against the second, for the README's main job and an allocation.

Each job runs as a user runs it (a fresh process): first on an empty kernel cache (the kernels compile in a
background child while the job starts on the numpy path and switches to each kernel family as it is ready),
then, once that child has filled the cache, again on the warm cache. Two setups:

- ``--readme``: the README's own path. A fresh clone of this checkout's HEAD, ``python3 -m venv
  --system-site-packages .venv && .venv/bin/pip install -q .`` in it (not editable), each job run as
  ``.venv/bin/tolerance-ros ...`` from the clone's root with the environment as it is (no
  ``NUMBA_CACHE_DIR``): the cache is the installed package's own, and an empty cache is its numba files and
  marker removed. After each first run the clone's own ``tolerance_ros`` must hold no kernel cache: the
  child compiled for the package its parent runs, not for the checkout in the working directory.
- default: this checkout (``python -m tolerance_ros.cli ...``, the checkout first on ``PYTHONPATH``), each
  empty cache a new ``NUMBA_CACHE_DIR``.

Printed side by side: the seconds of each, the ratio of the first run to the mean of the second runs just
before and just after it (``measure``), and the longest time the progress on stderr stood still in each run.
Target: the first run within 1.3x of the second, and the progress never still for more than 2 s; exits 1
when a job misses either. ``--busy N`` runs N busy loops beside the jobs, each a session of its own (a loaded
machine, reproducibly); ``--repeat N`` measures each job N times, each from an empty cache, and prints the
medians (a VM's speed drifts by 10-20 % between runs).

``--rhythm``: a user's rhythm on the README's path (implies ``--readme``): on an empty cache, six quick
``jacobian`` calls one after another, then ``paper gao2023`` twice; the processes compiling into the
installed package's cache are counted all along (every 50 ms: the most alive at once, and how many in all),
and once none is left and the cache is complete, one more ``jacobian`` must say nothing of compiling and
``paper gao2023`` runs twice more, warm. Printed: the compilers, the seconds of each call, the first
(cold) paper run against the mean of the warm ones. Target: one compiler in all, the cold run within 1.3x
of the warm, and no word of compiling once the compiler has finished. ``--rev REV`` installs that
revision of the clone instead of HEAD (the same rhythm before a change).

    python bench/bench_first_run.py [--readme] [--jobs paper,allocate,rong2018] [--busy 1] [--repeat 3]
    python bench/bench_first_run.py --rhythm [--repeat 3] [--rev REV]
"""
import argparse
import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import load_average, machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
JOBS = {"paper": ["paper", "gao2023"],
        "allocate": ["allocate", "--robot", "gao2023_7dof", "--limit", "2mm"],
        "rong2018": ["paper", "rong2018"]}
DEFAULT_JOBS = ("paper", "allocate")
RATIO, STILL_S = 1.3, 2.0


def child_env(cache):
    """This environment with ``cache`` as the kernel cache and this checkout first on the import path."""
    return dict(os.environ, NUMBA_CACHE_DIR=str(cache),
                PYTHONPATH=os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))


def _is_cache_file(f) -> bool:
    """A numba cache file or the kernels' marker or lock."""
    return f.suffix in (".nbi", ".nbc") or f.name.startswith("tolerance_ros-kernels")


class Checkout:
    """The jobs run from this checkout, each empty cache a new ``NUMBA_CACHE_DIR``."""

    cwd = None

    def __init__(self):
        self.cache = None

    def command(self, argv):
        return [sys.executable, "-m", "tolerance_ros.cli", *argv]

    def env(self):
        return child_env(self.cache)

    @contextlib.contextmanager
    def empty_cache(self):
        with tempfile.TemporaryDirectory() as cache:
            self.cache = cache
            yield

    def python(self, code):
        return subprocess.run([sys.executable, "-c", code], env=self.env()).returncode

    def fill(self):
        from tolerance_ros.core.models import warmup
        subprocess.run(warmup.child_command([]), env=self.env(), stdout=subprocess.DEVNULL, check=True)

    def check(self):
        return None


class Readme:
    """The README's path: a fresh clone, ``pip install .`` (not editable), the jobs run from the clone's root."""

    INSTALL = "python3 -m venv --system-site-packages .venv && .venv/bin/pip install -q ."

    def __init__(self, where, rev=None):
        self.outside = Path(where)        # a folder without a checkout, to ask the installed package from
        self.clone = self.outside / "tolerance_ros"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(self.clone)], check=True)
        if rev:
            subprocess.run(["git", "checkout", "-q", rev], cwd=self.clone, check=True)
        print(f"installing as the README does in a fresh clone of {ROOT}: {self.INSTALL}", flush=True)
        subprocess.run(["bash", "-c", self.INSTALL], cwd=self.clone, check=True)
        self.bin = self.clone / ".venv" / "bin"
        self.cache_dir = Path(subprocess.run(
            [str(self.bin / "python"), "-c", "from tolerance_ros.core.models.warmup import cache_dir; print(cache_dir())"],
            cwd=self.outside, capture_output=True, text=True, check=True).stdout.strip())

    @property
    def cwd(self):
        return self.clone

    def command(self, argv):
        return [str(self.bin / "tolerance-ros"), *argv]

    def env(self):
        return {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}

    @contextlib.contextmanager
    def empty_cache(self):
        for f in self.cache_dir.glob("*"):
            if _is_cache_file(f):
                f.unlink()
        yield

    def python(self, code):
        return subprocess.run([str(self.bin / "python"), "-c", code], env=self.env(), cwd=self.outside).returncode

    def fill(self):
        code = ("import subprocess, sys; from tolerance_ros.core.models import warmup; "
                "sys.exit(subprocess.run(warmup.child_command([]), stdout=subprocess.DEVNULL).returncode)")
        if subprocess.run([str(self.bin / "python"), "-c", code], env=self.env(), cwd=self.outside).returncode:
            raise SystemExit("filling the installed package's kernel cache failed")

    def check(self):
        """What is wrong with where the first run compiled to, or None: the clone's own package holds no cache."""
        stray = [f for f in (self.clone / "tolerance_ros" / "core" / "models" / "__pycache__").glob("*")
                 if _is_cache_file(f)]
        if stray:
            return f"the first run compiled into the checkout's cache ({len(stray)} files), not the installed package's"
        return None


def run(argv, setup):
    """(seconds, longest gap between progress lines on stderr, exit code) of one command in a fresh process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(setup.command(argv), env=setup.env(), cwd=setup.cwd, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    stamps = []

    def read():
        for line in proc.stderr:
            if "%" in line:
                stamps.append(time.perf_counter())
    reader = threading.Thread(target=read)
    reader.start()
    code = proc.wait()
    reader.join()
    end = time.perf_counter()
    marks = [t0] + stamps + [end]
    return end - t0, max(b - a for a, b in zip(marks, marks[1:])), code


@contextlib.contextmanager
def paused(busy):
    """The ``busy`` loops stopped meanwhile: a cache fills between two runs (the child, at the lowest priority,
    would barely run beside them)."""
    for proc in busy:
        proc.send_signal(signal.SIGSTOP)
    try:
        yield
    finally:
        for proc in busy:
            proc.send_signal(signal.SIGCONT)


def wait_filled(setup, busy=(), timeout=600):
    """Wait until the background child of the first run has filled the cache (its marker is current), the
    ``busy`` loops ``paused``."""
    code = "from tolerance_ros.core.models import warmup; import sys; sys.exit(0 if warmup.cached() else 1)"
    with paused(busy):
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < timeout:
            if setup.python(code) == 0:
                return True
            time.sleep(2.0)
        return False


JACOBIAN = ["jacobian", "--robot", "gao2023_7dof", "--joints", "0rad,0.1rad,0.2rad,0.3rad,0.4rad,0.5rad,0.6rad"]


CHILD_CODE = (b"warmup.main(sys.argv", b"run_module('tolerance_ros.core.models.warmup'",
              b"-m tolerance_ros.core.models.warmup")
"""What a compiling child's command line holds: ``warmup._CHILD``'s call (and the revisions' before it), or the
module run on its own."""


def describe(pid) -> str:
    """A process in a few words: its pid, its parent's pid and command line, its age."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        ppid, start = int(stat[1]), int(stat[19]) / os.sysconf("SC_CLK_TCK")
        parent = Path(f"/proc/{ppid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")[:100]
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return f"{pid} (parent {ppid}: {parent or '?'}; started {uptime - start:.1f} s ago)"
    except (OSError, ValueError, IndexError):
        return f"{pid} (gone)"


def compilers(setup) -> set:
    """The pids of the processes compiling into ``setup``'s cache: the installed package's compiling child
    (its python is the clone's venv's, its code the warmup module's: ``CHILD_CODE``), read from /proc."""
    prefix = str(setup.clone).encode()
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")
            ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if argv[0].startswith(prefix) and any(a in b" ".join(argv[1:3]) for a in CHILD_CODE):
            found[int(entry.name)] = ppid
    return {pid for pid, ppid in found.items() if ppid not in found}  # not a compiler's fork before it runs a
    # program (numba's library look-ups): it has the compiler's command line until then


def timed(argv, setup):
    """(seconds, stderr, exit code) of one command in a fresh process."""
    t0 = time.perf_counter()
    out = subprocess.run(setup.command(argv), env=setup.env(), cwd=setup.cwd, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    return time.perf_counter() - t0, out.stderr, out.returncode


def rhythm(setup, repeat):
    """The user's rhythm (module docstring), ``repeat`` times from an empty cache; prints each and returns
    the targets missed."""
    code = "from tolerance_ros.core.models import warmup; import sys; sys.exit(0 if warmup.cached() else 1)"
    missed, ratios, most, total = [], [], 0, 0
    for k in range(repeat):
        with setup.empty_cache():
            seen, alive, stop = set(), [0], threading.Event()

            def watch():
                while not stop.is_set():
                    now = compilers(setup)
                    if len(now) > 1 and len(now) > alive[0]:
                        print("  compilers at once: " + "; ".join(describe(pid) for pid in sorted(now)), flush=True)
                    seen.update(now)
                    alive[0] = max(alive[0], len(now))
                    time.sleep(0.05)
            watcher = threading.Thread(target=watch)
            watcher.start()
            try:
                jac = [timed(JACOBIAN, setup) for _ in range(6)]
                papers = [timed(JOBS["paper"], setup) for _ in range(2)]
                t0 = time.perf_counter()
                while (compilers(setup) or setup.python(code) != 0) and time.perf_counter() - t0 < 900:
                    time.sleep(1.0)
                filled = time.perf_counter() - t0
            finally:
                stop.set()
                watcher.join()
            left = compilers(setup)
            if left:  # never two rhythms' compilers at once: the next rhythm empties the cache
                missed.append(f"rhythm {k + 1}: the compiler had not finished {filled:.0f} s after the last call "
                              f"({'; '.join(describe(pid) for pid in sorted(left))}); stopped")
                for pid in left:
                    os.kill(pid, signal.SIGKILL)
            after = timed(JACOBIAN, setup)
            warm = [timed(JOBS["paper"], setup) for _ in range(2)]
        codes = [r[2] for r in jac + papers + [after] + warm]
        said = [r[1] for r in jac + papers]
        cold, second = papers[0][0], papers[1][0]
        reference = float(np.mean([w[0] for w in warm]))
        ratio = cold / reference
        ratios.append(ratio)
        most, total = max(most, alive[0]), max(total, len(seen))
        print(f"  rhythm {k + 1}: jacobian x6 {', '.join(f'{r[0]:.1f}' for r in jac)} s; paper gao2023 cold "
              f"{cold:.1f} s, then {second:.1f} s; the cache complete {filled:.0f} s after; warm "
              f"{', '.join(f'{w[0]:.1f}' for w in warm)} s; cold / warm {ratio:.2f}; compilers: {alive[0]} at once, "
              f"{len(seen)} in all; {sum('compil' in text for text in said)} of the 8 calls spoke of compiling",
              flush=True)
        if "compil" in after[1]:
            missed.append(f"rhythm {k + 1}: a command spoke of compiling once the compiler had finished: "
                          f"{after[1].strip().splitlines()[0]}")
        if any(codes):
            missed.append(f"rhythm {k + 1}: exit codes {codes}")
        wrong = setup.check()
        if wrong:
            missed.append(f"rhythm {k + 1}: {wrong}")
    median = float(np.median(ratios))
    print(f"\n| rhythm (six `jacobian`, two `paper gao2023`) | compilers at once (most) | compilers in all (most) | "
          f"paper cold / warm (median; the runs) |")
    print("|---|---|---|---|")
    print(f"| {repeat} run(s) | {most} | {total} | **{median:.2f}** ({', '.join(f'{r:.2f}' for r in ratios)}) |")
    if total > 1:
        missed.append(f"{total} compilers in one rhythm (target: one)")
    if median > RATIO:
        missed.append(f"the cold paper run {median:.2f}x the warm one (target {RATIO}x)")
    return missed


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", default=",".join(DEFAULT_JOBS), help=f"comma-separated, of {list(JOBS)}")
    ap.add_argument("--busy", type=int, default=0, help="busy loops beside the jobs, each a session of its own")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each job (each from an empty cache); medians")
    ap.add_argument("--readme", action="store_true",
                    help="the README's path: a fresh clone, pip install . (not editable), run from its root")
    ap.add_argument("--rhythm", action="store_true",
                    help="a user's rhythm on the README's path: six jacobian calls, then paper gao2023 twice")
    ap.add_argument("--rev", help="with --readme or --rhythm: install this revision of the clone (default HEAD)")
    args = ap.parse_args()
    args.readme = args.readme or args.rhythm
    names = args.jobs.split(",")
    unknown = [n for n in names if n not in JOBS]
    if unknown:
        ap.error(f"--jobs: unknown {unknown}; expected some of {list(JOBS)}")
    if args.busy < 0 or args.repeat < 1:
        ap.error("--busy: expected 0 or more; --repeat: expected 1 or more")
    print(f"machine: {machine()}, {load_average()}, {args.busy} busy loop(s) beside")
    if args.rhythm:
        with tempfile.TemporaryDirectory() as where:
            setup = Readme(where, args.rev)
            print(f"setup: the README's (a fresh clone at {args.rev or 'HEAD'}, pip install ., run from its root)",
                  flush=True)
            missed = rhythm(setup, args.repeat)
        print(f"\nafter: {load_average()}")
        for m in missed:
            print(f"MISSED: {m}")
        print("verdict: " + ("MISSED" if missed else "ok"))
        return 1 if missed else 0
    with tempfile.TemporaryDirectory() as where:
        setup = Readme(where, args.rev) if args.readme else Checkout()
        print("setup: " + ("the README's (a fresh clone, pip install ., run from its root)" if args.readme else
                           "this checkout, NUMBA_CACHE_DIR a new folder for each empty cache"), flush=True)
        busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True)
                for _ in range(args.busy)]
        try:
            rows, missed = measure(names, setup, args.repeat, busy)
        finally:
            for proc in busy:
                proc.kill()
                proc.wait()
    print(f"medians of {args.repeat} run(s) each" if args.repeat > 1 else "one run each")
    print("| job | first run s (empty cache) | second run s | ratio | progress still, first / second s | exit |")
    print("|---|---|---|---|---|---|")
    for job, cold, warm, ratio, cs, ws, c1, c2 in rows:
        print(f"| tolerance-ros {job} | {cold:.1f} | {warm:.1f} | {ratio:.2f} | {cs:.1f} / {ws:.1f} | {c1} / {c2} |")
    print(f"\nafter: {load_average()}")
    for m in missed:
        print(f"MISSED: {m}")
    print("verdict: " + ("MISSED" if missed else "ok"))
    return 1 if missed else 0


def fill(setup, busy=()):
    """Fill the cache with every kernel family (the background child's work, in the foreground), the ``busy``
    loops ``paused``."""
    with paused(busy):
        setup.fill()


def measure(names, setup, repeat=1, busy=()):
    """Rows (job, cold s, warm s, ratio, still cold, still warm, exit codes) and the targets missed; with
    ``repeat`` the median seconds and ratio, the longest stillness and the worst exit codes. Each first run
    is bracketed by two second runs, the one before it and its own after it (on the cache its child
    filled), and its ratio is to their mean: a VM whose speed drifts between runs moves both sides alike.
    The ``busy`` loops are stopped while a cache fills."""
    rows, missed = [], []
    for name in names:
        runs = []
        with setup.empty_cache():
            fill(setup, busy)
            before, before_still, c0 = run(JOBS[name], setup)
        for _ in range(repeat):
            with setup.empty_cache():
                cold, cold_still, c1 = run(JOBS[name], setup)
                if not wait_filled(setup, busy):
                    raise SystemExit("the background child did not fill the cache")
                wrong = setup.check()
                if wrong:
                    missed.append(f"{name}: {wrong}")
                warm, warm_still, c2 = run(JOBS[name], setup)
            ratio = cold / (0.5 * (before + warm))
            runs.append((cold, warm, ratio, cold_still, max(warm_still, before_still), c1, max(c0, c2)))
            print(f"  {name} run {len(runs)}: first {cold:.1f} s, second runs {before:.1f} s before and {warm:.1f} s "
                  f"after, ratio {ratio:.2f}", flush=True)
            before, before_still, c0 = warm, warm_still, c2
        cold, warm, ratio = (float(np.median([r[k] for r in runs])) for k in range(3))
        cold_still, warm_still = max(r[3] for r in runs), max(r[4] for r in runs)
        c1, c2 = max(r[5] for r in runs), max(r[6] for r in runs)
        rows.append((" ".join(JOBS[name]), cold, warm, ratio, cold_still, warm_still, c1, c2))
        if ratio > RATIO:
            missed.append(f"{name}: first run {ratio:.2f}x the second (target {RATIO}x)")
        if max(cold_still, warm_still) > STILL_S:
            missed.append(f"{name}: the progress stood still for {max(cold_still, warm_still):.1f} s (target {STILL_S} s)")
    return rows, missed

if __name__ == "__main__":
    sys.exit(main())
