"""The shipped configs and schemas: found in the source checkout, and as package data in an installed copy."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tolerance_ros.core import resources

ROOT = Path(__file__).resolve().parents[2]


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts)


def test_a_source_checkout_reads_its_own_folders():
    assert resources.config_dir() == ROOT / "config"
    assert resources.data_dir("schemas") == ROOT / "schemas"
    with pytest.raises(ValueError, match="expected one of"):
        resources.data_dir("launch")


def test_an_installed_copy_carries_every_shipped_file_as_package_data(tmp_path):
    """pip installs config/ and schemas/ into the package (setup.py's package data misses no shipped file), and
    the installed copy, run away from the checkout, finds them there with importlib.resources."""
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target), str(ROOT)],
                   check=True, capture_output=True, text=True, timeout=600)
    for name in resources.DATA:
        assert _files(target / "tolerance_ros" / name) == _files(ROOT / name), name
    code = ("from tolerance_ros.core import resources; from tolerance_ros.core.models import load_robot; "
            "print(resources.config_dir()); print(resources.data_dir('schemas')); "
            "print(load_robot('gao2023_7dof').name)")
    env = dict(os.environ, PYTHONPATH=str(target))
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, check=True, capture_output=True,
                         text=True, timeout=120).stdout.split()
    assert out == [str(target / "tolerance_ros" / "config"), str(target / "tolerance_ros" / "schemas"), "gao2023_7dof"]
