"""The shipped JSON Schemas of the services, for the tests and the benchmarks (jsonschema, a test dependency)."""
import functools
import json
import jsonschema

from ..core.resources import data_dir

SCHEMAS = data_dir("schemas")


def schema(name: str) -> dict:
    """The schema ``schemas/<name>.json`` (e.g. 'compute_error_jacobian.response')."""
    return json.loads((SCHEMAS / f"{name}.json").read_text())


@functools.lru_cache(maxsize=None)
def validator(name: str):
    """A validator of the schema ``schemas/<name>.json``, the schema itself checked once (``jsonschema.validate``
    checks it on every call, which costs more than validating a document)."""
    s = schema(name)
    cls = jsonschema.validators.validator_for(s)
    cls.check_schema(s)
    return cls(s)
