"""The compensate command of the error-model service and its calibrated model: responses against the
schemas, the joints they return, and every error path."""
import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrate, calibrated_mechanism
from tolerance_ros.core.calibration.calibration_file import save_calibration
from tolerance_ros.core.geometry import matrices_to_quat, transform
from tolerance_ros.services.compensation import load_calibrations
from tolerance_ros.services.contracts import Limits
from tolerance_ros.services.error_model import ErrorModelService

SCHEMAS = Path(__file__).resolve().parents[2] / "schemas"
REQUEST = json.loads((SCHEMAS / "compute_error_jacobian.request.json").read_text())
RESPONSE = json.loads((SCHEMAS / "compute_error_jacobian.response.json").read_text())
BASE = np.array([2e-4, -1e-4, 3e-4, 1e-4, -2e-4, 5e-4])


@pytest.fixture(scope="module")
def calibrated(gao):
    return calibrated_mechanism(gao, as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 3), BASE)


@pytest.fixture(scope="module")
def service(gao, planar2r, calibrated):
    return ErrorModelService({"gao2023_7dof": gao, "planar2r": planar2r}, "gao2023_7dof",
                             Limits(max_bytes=200_000, max_poses=20), calibrations={"gao2023_7dof": calibrated})


def ask(service, req, valid_request=True):
    if valid_request:
        jsonschema.validate(req, REQUEST)
    out = json.loads(service.handle_text(json.dumps(req)))
    jsonschema.validate(out, RESPONSE)
    return out


def test_joint_targets_are_compensated_on_the_calibrated_model(service, gao, calibrated):
    q = gao.sample_joints(5, 1)
    r = ask(service, {"id": "c1", "command": "compensate", "joints": q.tolist()})
    assert r["ok"] and r["command"] == "compensate" and r["model"] == "calibrated" and r["n"] == 5
    assert r["out_of_reach"] == [] and max(r["residual_position_m"]) <= 1e-9
    np.testing.assert_allclose(calibrated.fk(np.array(r["joints"])), gao.fk(q), atol=1e-8)
    np.testing.assert_allclose(r["nominal_joints"], q)
    assert 0 < np.abs(r["correction"]).max() < 0.05
    same = ask(service, {"id": "c2", "command": "compensate", "joints": q.tolist(), "model": "nominal"})
    np.testing.assert_allclose(same["joints"], q, atol=1e-12)
    compact = ask(service, {"id": "c3", "command": "compensate", "joints": q.tolist(), "arrays": "base64"})
    assert compact["iterations"] == r["iterations"] and compact["joints"]["shape"] == [5, 7]  # flags stay lists


def test_pose_targets_as_matrices_or_quaternions(service, gao, calibrated):
    q = gao.sample_joints(4, 2)
    T = gao.fk(q)
    r1 = ask(service, {"id": 1, "command": "compensate", "poses": T.tolist(), "seed": q.tolist()})
    np.testing.assert_allclose(calibrated.fk(np.array(r1["joints"])), T, atol=1e-8)
    np.testing.assert_allclose(r1["nominal_joints"], q, atol=1e-7)
    seven = np.concatenate([T[:, :3, 3], matrices_to_quat(T[:, :3, :3])], axis=1)
    r2 = ask(service, {"id": 2, "command": "compensate", "poses": seven.tolist(), "seed": q[0].tolist()})
    np.testing.assert_allclose(calibrated.fk(np.array(r2["joints"])), T, atol=1e-8)
    r3 = ask(service, {"id": 3, "command": "compensate", "poses": [T[0].tolist()], "match": "position"})
    assert r3["match"] == "position" and r3["residual_position_m"][0] <= 1e-9


def test_jacobian_of_the_calibrated_model_on_request(service, gao, calibrated):
    q = gao.sample_joints(2, 3)
    nominal = ask(service, {"id": "j1", "joints": q.tolist()})
    cal = ask(service, {"id": "j2", "joints": q.tolist(), "model": "calibrated"})
    np.testing.assert_allclose(nominal["poses"], gao.fk(q), atol=1e-15)
    np.testing.assert_allclose(cal["poses"], calibrated.fk(q), atol=1e-15)
    np.testing.assert_allclose(cal["jacobian"], calibrated.error_jacobian(q).J, atol=1e-15)


Q = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
EYE = np.eye(4).tolist()


@pytest.mark.parametrize("req, code, needle", [
    ({"command": "compensate", "robot": "planar2r", "joints": [[0.1, 0.2]]}, "invalid_request", "no calibration"),
    ({"robot": "planar2r", "joints": [[0.1, 0.2]], "model": "calibrated"}, "invalid_request", "no calibration"),
    ({"command": "compensate", "joints": [Q], "poses": [EYE]}, "invalid_request", "give exactly one"),
    ({"command": "compensate"}, "invalid_request", "give exactly one"),
    ({"command": "compensate", "joints": [Q], "tolerances": "current"}, "invalid_request", "tolerances: not a field"),
    ({"joints": [Q], "poses": [EYE]}, "invalid_request", "poses: only with command 'compensate'"),
    ({"command": "calibrate", "joints": [Q]}, "invalid_request", "command: expected"),
    ({"command": "compensate", "model": "as-built", "joints": [Q]}, "invalid_request", "model: expected"),
    ({"command": "compensate", "poses": [[[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]]},
     "invalid_request", "poses[0]: not a rigid transform"),
    ({"command": "compensate", "poses": [[1, 2, 3]]}, "invalid_request", "poses: expected (n, 4, 4)"),
    ({"command": "compensate", "poses": [[]]}, "invalid_request", "poses: expected (n, 4, 4)"),
    ({"command": "compensate", "poses": [[[]]]}, "invalid_request", "poses: expected (n, 4, 4)"),
    ({"command": "compensate", "poses": [[0, 0, 0, 0, 0, 0, 0]]}, "invalid_request", "zero norm"),
    ({"command": "compensate", "poses": [EYE] * 21}, "too_large", "cap of 20"),
    ({"command": "compensate", "joints": [[4.0] + Q[1:]]}, "out_of_limits", "joints[0][0]"),
    ({"command": "compensate", "joints": [Q], "seed": [Q]}, "invalid_request", "seed: only with poses"),
    ({"command": "compensate", "poses": [EYE, EYE], "seed": [Q, Q, Q]}, "invalid_request", "seed: expected one"),
    ({"command": "compensate", "match": "orientation", "joints": [Q]}, "invalid_request", "match: expected"),
    ({"command": "compensate", "robot": "nope", "joints": [Q]}, "unknown_robot", "nope"),
])
def test_errors_have_their_code_and_name_the_field(service, req, code, needle):
    r = ask(service, {"id": "e", **req}, valid_request=False)
    assert r["ok"] is False and r["error"]["code"] == code and needle in r["error"]["message"], r


def test_targets_a_kilometre_away_are_flagged_with_finite_residuals(service):
    far = [[1000.0, 0.0, 0.5, 0.0, 0.0, 0.0, 1.0], [0.0, -1000.0, 0.5, 0.0, 0.0, 0.0, 1.0]]
    r = ask(service, {"id": "far", "command": "compensate", "poses": far})
    assert r["ok"] and r["out_of_reach"] == [0, 1]
    assert all(np.isfinite(r[k]).all() for k in ("joints", "residual_position_m", "residual_orientation_rad"))
    assert 990 < min(r["residual_position_m"]) and max(r["residual_position_m"]) < 1010
    r = ask(service, {"id": "farther", "command": "compensate", "poses": [[1e200, 0, 0, 0, 0, 0, 1]]})
    assert r["error"]["code"] == "invalid_request" and "poses[0]: a target 1e+200 m from the base is beyond 1e+06 m" \
        in r["error"]["message"]


def test_joint_targets_whose_tool_is_beyond_a_thousand_km_are_refused_not_solved_into_overflow():
    from tolerance_ros.core.models import DHChain
    slide = DHChain("slide", a=[0.0, 0.3], alpha=[0.5, 0.0], d=[0.0, 0.0], theta=[0.0, 0.0],
                    joint_types=["revolute", "prismatic"], joint_limits=[[-3, 3], [0, 1]])
    svc = ErrorModelService({"slide": slide}, "slide",
                            calibrations={"slide": calibrated_mechanism(slide, np.full(8, 1e-3), np.zeros(6))})
    r = ask(svc, {"id": 1, "command": "compensate", "joints": [[0.1, 1e300]], "allow_out_of_limits": True})
    assert r["error"]["code"] == "invalid_request" and "joints[0]: the target's tool point is 8.78e+299 m from the " \
        "base, beyond 1e+06 m" in r["error"]["message"]
    assert ask(svc, {"id": 2, "command": "compensate", "joints": [[0.1, 1e5]], "allow_out_of_limits": True})["ok"]


def test_the_work_of_a_compensate_request_is_capped(gao):
    svc = ErrorModelService({"gao2023_7dof": gao}, "gao2023_7dof", Limits(max_compensate_joints=30,
                                                                        max_compensate_poses=3))
    many = gao.sample_joints(31, 0).tolist()
    r = ask(svc, {"id": 1, "command": "compensate", "model": "nominal", "joints": many})
    assert r["error"]["code"] == "too_large" and "joints: 31 targets exceed the cap of 30" in r["error"]["message"]
    assert ask(svc, {"id": 2, "command": "compensate", "model": "nominal", "joints": many[:30]})["ok"]
    r = ask(svc, {"id": 3, "command": "compensate", "model": "nominal", "poses": [EYE] * 4})
    assert r["error"]["code"] == "too_large" and "poses: 4 targets exceed the cap of 3" in r["error"]["message"]
    assert Limits().max_compensate_joints == 1000 and Limits().max_compensate_poses == 100


@pytest.mark.parametrize("req", [
    {"id": 1, "command": "compensate", "joints": [Q], "poses": [EYE]},
    {"id": 1, "command": "compensate", "joints": [Q], "tolerances": "current"},
    {"id": 1, "joints": [Q], "seed": [Q]},
    {"id": 1, "command": "compensate"},
    {"id": 1},
])
def test_the_request_schema_refuses_what_the_service_refuses(req):
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(req, REQUEST)


def test_calibrations_load_from_files_for_the_served_robots(gao, planar2r, tmp_path):
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    T_tb = transform([1.2, 0.1, 0.0], [0.0, 0.0, 0.4])
    q = np.tile(gao.sample_joints(20, 5), (2, 1))
    cal = calibrate(gao, q, measure(gao, q, as_built_errors(delta, 1), 1e-5, 0.0, T_tb, seed=2), folds=3)
    path = save_calibration(cal, tmp_path / "calibration.yaml")
    loaded = load_calibrations([path], {"gao2023_7dof": gao})
    qq = gao.sample_joints(5, 6)
    np.testing.assert_allclose(loaded["gao2023_7dof"].fk(qq), cal.fk(gao, qq), atol=1e-12)
    with pytest.raises(ValueError, match="not served"):
        load_calibrations([path], {"planar2r": planar2r})
