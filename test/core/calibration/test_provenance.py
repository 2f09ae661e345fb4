"""Provenance, content hash and Ed25519 signature of a calibration (core/calibration/provenance.py), through the
calibration file's writer and readers."""
import copy
import os
import re

import pytest
import yaml

from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.yamlio import dump_yaml
from tolerance_ros.core.calibration.calibrate import calibrate
from tolerance_ros.core.calibration.provenance import (ProvenanceError, content_sha256, file_sha256,
                                                      generate_key_pair, load_public_keys, load_signing_key,
                                                      new_provenance, verify_signature)
from tolerance_ros.core.calibration.calibration_file import (SI, CalibrationError, calibration_from_text,
                                                             calibration_text, load_calibration, save_calibration)


@pytest.fixture(scope="module")
def cal(gao):
    q = gao.sample_joints(30, 5)
    c = calibrate(gao, q, measure(gao, q, as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 1), 1e-5,
                                  0.0, None, seed=2), folds=3)
    c.provenance = new_provenance("/arm/tolerance_accuracy_monitor", request_id="k1", now=1_796_112_900.0)
    return c


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    d = tmp_path_factory.mktemp("keys")
    ids = [generate_key_pair(d / f"{n}.key", d / f"{n}.pub") for n in ("monitor", "other")]
    return d, ids


def test_the_provenance_names_the_maker_the_time_and_the_request(cal):
    p = cal.provenance
    assert re.fullmatch(r"[0-9a-f]{32}", p["id"]) and p["made_by"] == "/arm/tolerance_accuracy_monitor"
    assert p["time"] == "2026-12-01T08:15:00Z" and p["unix_time_s"] == 1_796_112_900.0 and p["request_id"] == "k1"
    assert new_provenance("x")["id"] != new_provenance("x")["id"]


def test_the_content_hash_is_the_same_for_the_writer_and_every_reader(gao, cal, tmp_path):
    text = calibration_text(cal, SI)
    doc = yaml.safe_load(text)
    declared = doc["provenance"]["content_sha256"]
    assert re.fullmatch(r"[0-9a-f]{64}", declared) and declared == content_sha256(doc)
    read = calibration_from_text(text, gao)
    assert read.content_sha256 == declared and read.provenance["made_by"] == cal.provenance["made_by"]
    (tmp_path / "c.yaml").write_text(text)                           # the service saves the text it publishes
    assert load_calibration(tmp_path / "c.yaml", gao).content_sha256 == declared
    again = calibration_text(read, SI)                               # written again from what was read
    assert yaml.safe_load(again)["provenance"]["content_sha256"] == declared
    mm = load_calibration(save_calibration(cal, tmp_path / "mm.yaml"), gao)   # another document (mm): another hash
    assert mm.content_sha256 != declared and mm.provenance["id"] == cal.provenance["id"]


def test_a_changed_content_is_refused_and_a_document_without_hash_gets_one(gao, cal):
    text = calibration_text(cal, SI)
    doc = yaml.safe_load(text)
    name = next(n for n in doc["parameters"] if doc["parameters"][n]["error"] != 0)
    changed = copy.deepcopy(doc)
    changed["parameters"][name]["error"] += 0.05                     # 50 mrad or 50 mm more, hash kept
    with pytest.raises(CalibrationError, match=r"provenance.content_sha256: the content does not match its hash"):
        calibration_from_text(yaml.safe_dump(changed), gao)
    del changed["provenance"]["content_sha256"]                      # an edit by hand, the hash line removed
    read = calibration_from_text(yaml.safe_dump(changed), gao)
    assert read.content_sha256 == content_sha256(changed) != doc["provenance"]["content_sha256"]
    del changed["provenance"]                                        # made before provenance existed
    assert calibration_from_text(yaml.safe_dump(changed), gao).content_sha256 == content_sha256(changed)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(provenance="x"), "provenance: expected a mapping"),
    (lambda d: d["provenance"].update(who="me"), "provenance.who: not a field"),
    (lambda d: d["provenance"].update(log_sha256="abc"), "provenance.log_sha256: expected 64 hex digits"),
    (lambda d: d["provenance"].update(made_by=3), "provenance.made_by: expected text"),
    (lambda d: d.update(signature={"algorithm": "rsa", "key_id": "0" * 16, "value": "AA=="}),
     "signature.algorithm: expected 'ed25519'"),
    (lambda d: d.update(signature={"key_id": "0" * 16}), "signature: expected {algorithm, key_id, value}"),
])
def test_malformed_provenance_and_signature_blocks_are_refused_naming_the_field(gao, cal, edit, message):
    doc = yaml.safe_load(calibration_text(cal, SI))
    edit(doc)
    with pytest.raises(CalibrationError, match=re.escape(message)):
        calibration_from_text(yaml.safe_dump(doc), gao)


def test_a_signed_calibration_verifies_only_with_its_key_and_unchanged(gao, cal, keys):
    d, (monitor_id, other_id) = keys
    assert oct(os.stat(d / "monitor.key").st_mode & 0o777) == "0o600"
    key = load_signing_key(d / "monitor.key")
    trusted = load_public_keys([d / "monitor.pub"])
    assert list(trusted) == [monitor_id] and monitor_id != other_id
    signed = calibration_from_text(calibration_text(cal, SI, key), gao)
    assert signed.signature["key_id"] == monitor_id
    assert verify_signature(signed.content_sha256, signed.signature, trusted) == monitor_id
    unsigned = calibration_from_text(calibration_text(cal, SI), gao)
    assert unsigned.content_sha256 == signed.content_sha256 and unsigned.signature is None
    with pytest.raises(ProvenanceError, match="unsigned"):
        verify_signature(unsigned.content_sha256, None, trusted)
    foreign = calibration_from_text(calibration_text(cal, SI, load_signing_key(d / "other.key")), gao)
    with pytest.raises(ProvenanceError, match=f"signed by key {other_id}, which this node does not trust"):
        verify_signature(foreign.content_sha256, foreign.signature, trusted)
    # changed and stamped again (the hash recomputed), the old signature kept: it no longer verifies
    doc = yaml.safe_load(calibration_text(cal, SI, key))
    doc["parameters"]["theta2"]["error"] += 0.05
    doc["provenance"]["content_sha256"] = content_sha256(doc)
    forged = calibration_from_text(dump_yaml(doc), gao)     # PyYAML would leave a key id such as 12e45 unquoted
    with pytest.raises(ProvenanceError, match="does not verify"):
        verify_signature(forged.content_sha256, forged.signature, trusted)


def test_keys_that_are_not_ed25519_pem_are_refused_naming_the_file(tmp_path):
    (tmp_path / "bad.pem").write_text("-----BEGIN PUBLIC KEY-----\nAAAA\n-----END PUBLIC KEY-----\n")
    with pytest.raises(ProvenanceError, match="trusted key .*bad.pem"):
        load_public_keys([tmp_path / "bad.pem"])
    with pytest.raises(ProvenanceError, match="signing key .*missing.key"):
        load_signing_key(tmp_path / "missing.key")


def test_the_log_hash_is_of_its_bytes_and_of_a_folder_its_files(tmp_path):
    import hashlib
    (tmp_path / "log.jsonl").write_bytes(b'{"event": "start"}\n')
    assert file_sha256(tmp_path / "log.jsonl") == hashlib.sha256(b'{"event": "start"}\n').hexdigest()
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("a")
    first = file_sha256(bag)
    (bag / "metadata.yaml").write_text("b")
    assert file_sha256(bag) != first and re.fullmatch(r"[0-9a-f]{64}", first)
