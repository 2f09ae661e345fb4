"""The URDFs of the PyPI package example-robot-data (a test extra), found by file name, for tests and benchmarks."""
from __future__ import annotations

import importlib.metadata
from pathlib import Path


def example_urdf(name: str) -> Path:
    """Path of a file shipped by example-robot-data (e.g. 'ur5_robot.urdf'); FileNotFoundError if it has none."""
    for f in importlib.metadata.files("example-robot-data") or []:
        if str(f).endswith("/" + name):
            return Path(f.locate())
    raise FileNotFoundError(f"{name}: not shipped by the installed example-robot-data")
