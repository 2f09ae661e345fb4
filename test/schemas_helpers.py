"""The shipped JSON Schemas of the services, for tests."""
import json
from pathlib import Path

SCHEMAS = Path(__file__).resolve().parents[1] / "schemas"


def schema(name: str) -> dict:
    """The schema ``schemas/<name>.json`` (e.g. 'compute_error_jacobian.response')."""
    return json.loads((SCHEMAS / f"{name}.json").read_text())
