"""The gate a calibration passes before a node puts it in force (services/guards.py): envelope, trusted
signatures, the swap old -> new, and what /diagnostics says."""
import copy

import pytest
import yaml

from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrate
from tolerance_ros.core.calibration.envelope import Envelope
from tolerance_ros.core.calibration.provenance import generate_key_pair, load_signing_key, new_provenance
from tolerance_ros.core.calibration.calibration_file import SI, calibration_from_text, calibration_text
from tolerance_ros.services.guards import CalibrationGate, CalibrationRefused, describe, summary


@pytest.fixture(scope="module")
def texts(gao):
    """(two calibrations of robots built within gao2023_delta2, one of them with 50 mrad more on joint 2), as the
    calibrate service publishes them (SI text)."""
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    out = []
    for seed in (1, 2):
        q = gao.sample_joints(30, 5 + seed)
        cal = calibrate(gao, q, measure(gao, q, as_built_errors(delta, seed), 1e-5, 0.0, None, seed=2), folds=3)
        cal.provenance = new_provenance("/arm/tolerance_accuracy_monitor", request_id=f"k{seed}")
        out.append(cal)
    bad = copy.deepcopy(out[0])
    bad.dx = bad.dx.copy()
    bad.dx[list(gao.param_names).index("theta2")] += 0.05
    bad.provenance = new_provenance("/rogue")
    return [calibration_text(c, SI) for c in out + [bad]]


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        self.t += 1.0
        return self.t


def test_the_gate_admits_real_calibrations_and_logs_each_swap_old_to_new(gao, texts):
    gate = CalibrationGate(Envelope(), clock=Clock())
    first, second = (calibration_from_text(t, gao) for t in texts[:2])
    check = gate.admit(first, gao, "tolerance_calibration")
    line = gate.swap(first, "tolerance_calibration", check)
    assert line.startswith(f"calibration in force: none -> sha256 {first.content_sha256[:12]} (id {first.provenance['id']}, "
                           f"by /arm/tolerance_accuracy_monitor")
    assert "from tolerance_calibration; correction up to " in line and " mm at the tool" in line
    line = gate.swap(second, "file.yaml", gate.admit(second, gao, "file.yaml"))
    assert line.startswith(f"calibration in force: sha256 {first.content_sha256[:12]} (")
    assert f"-> sha256 {second.content_sha256[:12]} (" in line
    values = gate.diagnostic_values()
    assert values["calibration_sha256"] == second.content_sha256 and values["calibration_id"] == second.provenance["id"]
    assert values["calibrations_refused"] == "0" and gate.refusal_message() is None
    assert gate.current == summary(second, "file.yaml") and gate.current["request_id"] == "k2"


def test_a_50_mrad_calibration_is_refused_the_one_in_force_stays_and_diagnostics_say_why(gao, texts):
    gate = CalibrationGate(Envelope(), clock=Clock())
    good, bad = calibration_from_text(texts[0], gao), calibration_from_text(texts[2], gao)
    gate.swap(good, "tolerance_calibration", gate.admit(good, gao))
    with pytest.raises(CalibrationRefused, match=r"correction outside the envelope: .*joint2 by up to 5\d\.\d mrad"):
        gate.admit(bad, gao, "tolerance_calibration")
    assert gate.current["sha256"] == good.content_sha256 and gate.refused == 1
    values = gate.diagnostic_values()
    assert values["last_refused_sha256"] == bad.content_sha256 and "max_joint_correction" in values["last_refusal"]
    message = gate.refusal_message()
    assert message.startswith(f"calibration {bad.content_sha256[:12]} refused, the one in force stays: correction")
    gate.swap(good, "again", gate.admit(good, gao))                  # a calibration put in force since
    assert gate.refusal_message() is None and gate.diagnostic_values()["calibrations_refused"] == "1"


def test_with_trusted_keys_only_their_signatures_pass(gao, texts, tmp_path):
    generate_key_pair(tmp_path / "monitor.key", tmp_path / "monitor.pub")
    generate_key_pair(tmp_path / "other.key", tmp_path / "other.pub")
    cal = calibration_from_text(texts[0], gao)
    gate = CalibrationGate(Envelope(), trusted_keys=[tmp_path / "monitor.pub"])
    with pytest.raises(CalibrationRefused, match="unsigned, and this node trusts only calibrations signed by"):
        gate.admit(cal, gao)
    foreign = calibration_from_text(calibration_text(cal, SI, load_signing_key(tmp_path / "other.key")), gao)
    with pytest.raises(CalibrationRefused, match="which this node does not trust"):
        gate.admit(foreign, gao)
    signed = calibration_from_text(calibration_text(cal, SI, load_signing_key(tmp_path / "monitor.key")), gao)
    check = gate.admit(signed, gao)
    assert check["ok"] and gate.refused == 2
    assert gate.swap(signed, "", check).endswith("mm at the tool") and gate.diagnostic_values()["calibration_signed_by"] == \
        signed.signature["key_id"]
    rogue = yaml.safe_load(texts[2])                                 # signed by the monitor's key, yet 50 mrad off
    signed_rogue = calibration_from_text(calibration_text(calibration_from_text(yaml.safe_dump(rogue), gao), SI,
                                                          load_signing_key(tmp_path / "monitor.key")), gao)
    with pytest.raises(CalibrationRefused, match="outside the envelope"):
        gate.admit(signed_rogue, gao)


def test_without_an_envelope_or_keys_the_gate_lets_everything_in(gao, texts):
    gate = CalibrationGate()
    assert gate.admit(calibration_from_text(texts[2], gao), gao) is None
    assert describe(None) == "none"


def test_a_calibration_refused_before_the_gate_is_recorded_for_the_diagnostics():
    gate = CalibrationGate(Envelope(), clock=Clock())
    gate.record("tolerance_calibration: robot 'ur5' is not served (['gao2023_7dof'])", None, "tolerance_calibration")
    assert gate.refused == 1 and gate.diagnostic_values()["last_refused_sha256"] == "none"
    assert gate.refusal_message() == ("calibration none refused, the one in force stays: tolerance_calibration: robot "
                                      "'ur5' is not served (['gao2023_7dof'])")
