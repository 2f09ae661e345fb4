"""A request's way through ``services/`` runs downwards: error model and trajectory compensator -> compensation
-> requests -> contracts; no module imports one above it."""
import ast
from pathlib import Path

SERVICES = Path(__file__).resolve().parents[2] / "tolerance_ros" / "services"
ORDER = ["contracts", "requests", "compensation", "error_model", "trajectory"]


def imports(name):
    tree = ast.parse((SERVICES / f"{name}.py").read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            out.add((node.module or "").split(".")[0])
    return out


def test_each_layer_imports_only_the_layers_below_it():
    for k, name in enumerate(ORDER):
        above = set(ORDER[k + 1:]) | {name}
        assert not (imports(name) & above), (name, imports(name) & above)
    assert "requests" in imports("compensation") and "compensation" in imports("error_model")
    assert "compensation" in imports("trajectory")
