"""Where the shipped configuration and schemas live: package data of ``tolerance_ros`` when installed (pip, or
colcon, which also copies them to ``share/tolerance_ros`` for ``ros2 launch``), else the source checkout."""
from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

PACKAGE = "tolerance_ros"
DATA = ("config", "schemas")
"""The shipped folders: at the top of the source tree, package data ``tolerance_ros/<folder>`` once installed."""


class ConfigNotFound(FileNotFoundError):
    """No such file and no shipped config of that name; ``kind`` is the config folder ('robots', ...)."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


def data_dir(name: str) -> Path:
    """The shipped folder ``name`` (one of ``DATA``): the installed package's data (``importlib.resources``),
    else the source checkout's (``<repo>/<name>`` beside the package); FileNotFoundError names both."""
    if name not in DATA:
        raise ValueError(f"data_dir: expected one of {DATA}, got {name!r}")
    packaged = Path(str(resources.files(PACKAGE) / name))
    checkout = Path(__file__).resolve().parents[2] / name
    for path in (packaged, checkout):
        if path.is_dir():
            return path
    raise FileNotFoundError(f"cannot find the shipped {name!r} folder of {PACKAGE}: neither the package data "
                            f"{packaged} nor the source checkout's {checkout} (reinstall the package)")


def config_dir() -> Path:
    """The ``config`` directory shipped with the package."""
    return data_dir("config")


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
