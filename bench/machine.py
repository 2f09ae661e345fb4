"""What every benchmark prints beside its figures: the machine (CPU model, cores) and its load average."""
import os
from pathlib import Path


def machine() -> str:
    """CPU model and core counts, e.g. 'AMD EPYC, 2 cores (2 usable)'."""
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return f"{cpu}, {os.cpu_count()} cores ({usable} usable)"


def load_average() -> str:
    return "load average {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def verdicts(results) -> int:
    """Print one line per (met, text) and a count; 1 when a target is missed, else 0."""
    print("verdict:")
    for ok, text in results:
        print(f"  {'ok    ' if ok else 'MISSED'} {text}")
    missed = [text for ok, text in results if not ok]
    print(f"{len(results) - len(missed)} met, {len(missed)} missed" + (": " + "; ".join(missed) if missed else ""))
    return 1 if missed else 0
