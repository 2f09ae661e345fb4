"""The declared floors: every requirement of setup.py has one, and .ci/floors.txt (what CI's floor run
installs) pins exactly those versions."""
import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FLOOR = re.compile(r"([A-Za-z0-9][A-Za-z0-9._-]*)>=([0-9][0-9.]*)")


def _norm(name):
    return re.sub(r"[-_.]+", "-", name).lower()


def _declared():
    """{name: floor} of install_requires and every extra of setup.py's ``setup()`` call."""
    call = next(n for n in ast.walk(ast.parse((ROOT / "setup.py").read_text()))
                if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "setup")
    kw = {k.arg: ast.literal_eval(k.value) for k in call.keywords if k.arg in ("install_requires", "extras_require")}
    reqs = kw["install_requires"] + [r for extra in kw["extras_require"].values() for r in extra]
    floors = {}
    for req in reqs:
        m = FLOOR.fullmatch(req)
        assert m, f"setup.py: {req!r} is not 'name>=version' (a floor that .ci/floors.txt can pin)"
        floors[_norm(m[1])] = m[2]
    return floors


def _pinned():
    pins = {}
    for line in (ROOT / ".ci" / "floors.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, sep, version = line.partition("==")
            assert sep and version, f".ci/floors.txt: {line!r} is not 'name==version'"
            pins[_norm(name)] = version
    return pins


def test_floors_txt_pins_the_declared_floors():
    assert _pinned() == _declared()


def test_ci_installs_the_floors():
    ci = (ROOT / ".ci" / "run").read_text()
    assert '-c .ci/floors.txt ".[test]"' in ci
