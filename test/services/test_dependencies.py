"""A node checks at start the packages it imports later, and names what is missing and how to install it."""
import sys

import pytest

from tolerance_ros.services.dependencies import MissingDependency, missing, require


def test_a_missing_package_is_named_with_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "scipy", None)                  # as if this Python had no scipy
    assert missing(["scipy", "numpy", "no_such_module_xyz"]) == ["scipy", "no_such_module_xyz"]
    with pytest.raises(MissingDependency) as exc:
        require(["numpy", "scipy"], "/arm/tolerance_accuracy_monitor")
    text = str(exc.value)
    assert text.startswith(f"/arm/tolerance_accuracy_monitor cannot start: this Python ({sys.executable}) lacks 'scipy'")
    assert "`pip install 'scipy>=1.11.2'`" in text and "apt install python3-scipy" in text and "rosdep install" in text


def test_present_packages_pass():
    require(["numpy", "scipy", "yaml", "cryptography"], "node")
