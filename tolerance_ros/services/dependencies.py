"""The Python packages a node imports only when it first needs them (scipy for a fit, pinocchio for a URDF,
rosbags for a bag, cryptography for a signature), checked when the node starts (or is configured): a node
that lacks one refuses to start and says which package is missing and how to install it, instead of
starting and answering every request that needs it with ``internal: ModuleNotFoundError``. ROS-free."""
from __future__ import annotations

import importlib.util
import sys

# module: (what it is for, pip requirement, rosdep key / Debian package)
PACKAGES = {
    "scipy": ("fits and statistics (calibration, registration, allocation, bounds)", "scipy>=1.11.2", "python3-scipy"),
    "pinocchio": ("URDF robots and robot_description", "pin>=2.7.0", "pinocchio (ros-jazzy-pinocchio)"),
    "rosbags": ("rosbag2 measurement logs", "rosbags>=0.10.10", "python3-rosbags-pip"),
    "cryptography": ("signed calibrations (Ed25519)", "cryptography>=41.0.7", "python3-cryptography"),
}


class MissingDependency(RuntimeError):
    """A package a node needs is not importable; the message names it and how to install it."""


def missing(modules) -> list:
    """The modules of ``modules`` that this Python cannot import (found by their spec; nothing is imported)."""
    out = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a parent that fails, or a module set to None in sys.modules
            found = False
        if not found:
            out.append(name)
    return out


def require(modules, who: str) -> None:
    """MissingDependency naming every missing module of ``modules``, what it is for and how to install it."""
    lacking = missing(modules)
    if not lacking:
        return
    lines = []
    for name in lacking:
        what, pip, apt = PACKAGES.get(name, ("", name, f"python3-{name}"))
        lines.append(f"'{name}' ({what}): `pip install '{pip}'`, or `apt install {apt}` / rosdep (`rosdep install "
                     f"--from-paths src --ignore-src -y` installs every key package.xml declares)")
    raise MissingDependency(f"{who} cannot start: this Python ({sys.executable}) lacks " + "; ".join(lines))
