"""Where the shipped configuration lives: a source checkout, a pip install or a colcon install."""
from __future__ import annotations

import os
import sys
import sysconfig
from pathlib import Path

PACKAGE = "tolerance_ros"


class ConfigNotFound(FileNotFoundError):
    """No such file and no shipped config of that name; ``kind`` is the config folder ('robots', ...)."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


def share_dirs() -> list[Path]:
    """Candidate ``share/tolerance_ros`` roots, most specific first."""
    here = Path(__file__).resolve()
    dirs = [here.parents[2]]  # source checkout: <repo>/tolerance_ros/core/resources.py
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share" / PACKAGE)
    for prefix in {sysconfig.get_path("data"), sys.prefix, getattr(sys, "base_prefix", sys.prefix)}:
        dirs.append(Path(prefix) / "share" / PACKAGE)
    try:
        import site
        dirs.append(Path(site.getuserbase()) / "share" / PACKAGE)
    except Exception:  # pragma: no cover - site may be stripped in embedded interpreters
        pass
    # colcon/ament installs: <prefix>/lib/python3.x/site-packages/tolerance_ros -> <prefix>/share/...
    for parent in here.parents:
        if parent.name == "lib":
            dirs.append(parent.parent / "share" / PACKAGE)
            break
    return [d for d in dirs]


def config_dir() -> Path:
    """The ``config`` directory shipped with the package."""
    for d in share_dirs():
        if (d / "config" / "robots").is_dir():
            return d / "config"
    raise FileNotFoundError("cannot find the tolerance_ros config directory; searched: "
                            + ", ".join(str(d / "config") for d in share_dirs()))


def resolve(kind: str, spec: str | os.PathLike, suffixes=(".yaml", ".yml")) -> Path:
    """A file path for ``spec``: an existing path, or the name of a shipped config under ``config/<kind>``."""
    path = Path(spec).expanduser()
    what = kind[:-1] if kind.endswith("s") else kind
    if path.is_file():
        return path
    if path.is_dir():
        raise ConfigNotFound(kind, f"{what} {str(spec)!r}: is a directory; expected a file "
                                   f"({', '.join(suffixes)}) or a shipped name")
    try:
        root = config_dir() / kind
    except FileNotFoundError:
        root = None
    if root is not None:
        for suffix in ("",) + tuple(suffixes):
            cand = root / f"{spec}{suffix}"
            if cand.is_file():
                return cand
    known = sorted(p.stem for p in root.glob("*") if p.suffix in suffixes) if root and root.is_dir() else []
    raise ConfigNotFound(kind, f"{what} {str(spec)!r}: no such file, and not a shipped name"
                               f"{did_you_mean(str(spec), known)} (known: {', '.join(known) or 'none'})")


def did_you_mean(name: str, known) -> str:
    """'; did you mean 'x'?' for the closest of ``known`` to a mistyped ``name``, or ''."""
    import difflib
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def shipped(kind: str, suffixes=(".yaml", ".yml")) -> list[str]:
    """Names of the shipped configs of a kind (e.g. 'robots')."""
    try:
        root = config_dir() / kind
    except FileNotFoundError:
        return []
    return sorted(p.stem for p in root.glob("*") if p.suffix in suffixes)


def not_a_file(path) -> str:
    """Why ``path`` cannot be read as a file, in words: 'is a folder, not a file' or 'file not found'."""
    return "is a folder, not a file" if Path(path).is_dir() else "file not found"
