"""Generated requests for the services, valid ones mixed with mutations (wrong types, NaN/Infinity, huge
numbers, odd ids, deep nesting, unknown fields, duplicate keys, non-UTF-8 text, oversized strings);
shared by the fuzz tests and bench/bench_fuzz.py. ``jacobian_request`` is valid about half of the
time, ``allocate_request`` about a quarter (the rest is hostile)."""
import json

from hypothesis import strategies as st

Q = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
HOSTILE_NUMBERS = [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 5e-324, 2 ** 64, -(2 ** 63) - 1,
                   10 ** 400, True, None, "1", [], {}]
ODD_IDS = [None, True, 1.5, "", "x" * 300, "\ud800", 2 ** 64, -(2 ** 63), [1], {"a": 1}, "ü"]


def scalars():
    return st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(2 ** 70), 2 ** 70),
                     st.booleans(), st.none(), st.text(max_size=8), st.sampled_from(HOSTILE_NUMBERS))


def json_values(depth=3):
    return st.recursive(scalars(), lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                           st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                        max_leaves=depth * 4)


def ids():
    return st.one_of(st.text(max_size=12), st.integers(-(2 ** 63), 2 ** 63 - 1))


CONFIGURATION = st.lists(st.floats(-3.14, 3.14), min_size=7, max_size=7)


def valid_jacobian_request():
    """Requests the service serves for gao2023_7dof: Jacobians of one to five configurations, with or
    without bounds, and compensate requests on the nominal model (joint or pose targets)."""
    poses = st.lists(CONFIGURATION, min_size=1, max_size=3).map(
        lambda qs: [[[0.0, 0.0, 1.0, 0.05 * k], [0.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.6], [0, 0, 0, 1]]
                    for k in range(len(qs))])
    jacobian = st.fixed_dictionaries(
        {"id": ids(), "joints": st.one_of(CONFIGURATION, st.lists(CONFIGURATION, min_size=1, max_size=5))},
        optional={"robot": st.just("gao2023_7dof"), "outputs": st.sampled_from(["pose", "position"]),
                  "tolerances": st.fixed_dictionaries({"default": st.just(0), "a1": st.floats(0, 1e-3),
                                                       "theta2": st.floats(0, 1e-3)}),
                  "criteria": st.lists(st.sampled_from(["paper", "worst-case", "per-axis", "rss"]), min_size=1,
                                       max_size=4),
                  "include_jacobian": st.booleans(), "arrays": st.sampled_from(["json", "base64"])})
    compensate = st.fixed_dictionaries(
        {"id": ids(), "command": st.just("compensate"), "model": st.just("nominal")},
        optional={"match": st.sampled_from(["pose", "position"]), "arrays": st.sampled_from(["json", "base64"])}
    ).flatmap(lambda req: st.one_of(st.lists(CONFIGURATION, min_size=1, max_size=3).map(
        lambda qs: {**req, "joints": qs}), poses.map(lambda ps: {**req, "poses": ps})))
    return st.one_of(jacobian, compensate)


def valid_allocate_request():
    """Requests the allocator accepts: an allocation with a feasible limit and small options, status, or a
    cancel of some id."""
    allocation = st.fixed_dictionaries(
        {"id": ids(), "limit": st.floats(0.0008, 0.005)},
        optional={"model": st.sampled_from(["min-cost", "optimal-precision"]),
                  "criterion": st.sampled_from(["paper", "rss"]), "seed": st.integers(0, 100),
                  "mc_poses": st.integers(100, 500), "time_limit": st.floats(0.5, 2.0)})
    return st.one_of(allocation, st.fixed_dictionaries({"id": ids(), "command": st.just("status")}),
                     st.fixed_dictionaries({"id": ids(), "command": st.just("cancel"), "target": ids()}))


def jacobian_request():
    return st.one_of(valid_jacobian_request(), hostile_jacobian_request())


def allocate_request():
    return st.one_of(valid_allocate_request(), hostile_allocate_request(), hostile_allocate_request(),
                     hostile_allocate_request())


def hostile_jacobian_request():
    joints = st.one_of(st.just(Q), st.lists(st.just(Q), min_size=1, max_size=5),
                       st.lists(st.floats(-4, 4), min_size=0, max_size=9), json_values())
    tolerances = st.one_of(st.just("current"), st.fixed_dictionaries({"default": st.just(0), "a1": st.floats(0, 1e-3)}),
                           st.dictionaries(st.sampled_from(["a1", "theta2", "tolerances", "free", "default", "zz"]),
                                           json_values(), max_size=3), json_values())
    poses = st.one_of(st.lists(st.lists(st.one_of(st.floats(-1, 1), scalars()), min_size=7, max_size=7), max_size=4),
                      st.just([[0.5, 0.1, 0.6, 0.0, 0.0, 0.0, 1.0]]), st.just([[0.4, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0]]),
                      st.just([[[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0.6], [0, 0, 0, 1]]]),
                      st.just([[[2, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0.6], [0, 0, 0, 1]]]), json_values())
    criteria = st.one_of(st.lists(st.sampled_from(["paper", "worst-case", "per-axis", "rss", "max"]), max_size=6),
                         st.lists(st.just("worst-case"), min_size=50, max_size=2000), json_values())
    return st.fixed_dictionaries({"id": st.one_of(st.text(max_size=12), st.integers(), st.sampled_from(ODD_IDS))},
                                 optional={"joints": joints, "robot": st.sampled_from(["gao2023_7dof", "ur5", 1]),
                                           "outputs": st.sampled_from(["pose", "position", "all", 3]),
                                           "tolerances": tolerances, "criteria": criteria,
                                           "allow_out_of_limits": st.one_of(st.booleans(), json_values()),
                                           "include_jacobian": st.booleans(),
                                           "arrays": st.sampled_from(["json", "base64", "xml"]),
                                           "command": st.sampled_from(["compute_error_jacobian", "compensate",
                                                                       "compensate", "x"]),
                                           "model": st.sampled_from(["nominal", "calibrated", "x"]),
                                           "poses": poses, "seed": joints,
                                           "match": st.sampled_from(["pose", "position", "x"]),
                                           "colour": json_values()})


def hostile_allocate_request():
    return st.fixed_dictionaries({"id": st.one_of(st.text(max_size=12), st.integers(), st.sampled_from(ODD_IDS))},
                                 optional={"limit": st.one_of(st.floats(0, 0.01), scalars()),
                                           "command": st.sampled_from(["allocate", "status", "cancel", "nope"]),
                                           "target": json_values(), "orientation_limit": scalars(),
                                           "model": st.sampled_from(["min-cost", "optimal-precision", "x"]),
                                           "solver": st.sampled_from(["active-set", "ga", "x"]),
                                           "criterion": st.sampled_from(["paper", "rss", "worst-case", "per-axis"]),
                                           "floors": st.one_of(st.dictionaries(st.sampled_from(["length", "angle",
                                                                                                "a1", "zz"]),
                                                                               scalars(), max_size=3), json_values()),
                                           "seed": scalars(), "mc_poses": scalars(), "ga_tol": scalars(),
                                           "ga_rounds": scalars(), "confidence": scalars(), "time_limit": scalars()})


def encode(request, how):
    """A request as the text a node might receive: strict JSON, JSON with NaN, duplicate keys, deep nesting,
    bytes that are not UTF-8, a truncated text, or an oversized one."""
    text = json.dumps(request, allow_nan=True, default=str, ensure_ascii=False) if how != "strict" else \
        json.dumps(request, default=str)
    if how == "duplicate":
        return text[:-1] + ', "id": "again"}' if text.endswith("}") else text
    if how == "deep":
        return '{"id": 1, "joints": ' + "[" * 5000 + "]" * 5000 + "}"
    if how == "bytes":
        return text.encode("utf-8", "surrogatepass")[:-1] + b"\xff"
    if how == "truncated":
        return text[: max(1, len(text) // 2)]
    if how == "huge":
        return text[:-1] + ', "pad": "' + "x" * 1_000_100 + '"}'
    return text


ENCODINGS = ["strict", "loose", "loose", "loose", "duplicate", "deep", "bytes", "truncated", "huge"]
