"""Provenance, content hash and signature of a calibration: the ``provenance`` and ``signature`` blocks of the
calibration file (format in ``calibration_file``).

The content hash (``provenance.content_sha256``) is the SHA-256 of the calibration document as read back
(everything but ``provenance.content_sha256`` itself and the ``signature`` block), written as canonical JSON
(keys sorted, no spaces, UTF-8): it names one calibration's content, whatever the YAML layout, and a reader
refuses a document whose content no longer matches the hash it declares. It is not a defence against an
attacker (who recomputes it): that is the signature, Ed25519 (``cryptography``) over the content hash,
``signature: {algorithm: ed25519, key_id, value}``, verified against the public keys a node trusts.
``key_id`` is the first 16 hex digits of the SHA-256 of the raw 32-byte public key.
"""
from __future__ import annotations

import base64
import copy
import hashlib
import json
import math
import re
import time
import uuid
from pathlib import Path

SIGNED_PREFIX = b"tolerance_ros.calibration.content_sha256:"  # what is signed: this prefix, then the hex hash
ALGORITHM = "ed25519"
MAX_ID = 256  # characters of a calibration id or of made_by
_HEX64 = re.compile(r"^[0-9a-f]{64}$")
_KEY_ID = re.compile(r"^[0-9a-f]{16}$")
_PROVENANCE = {"id": str, "request_id": (str, int), "time": str, "unix_time_s": (int, float), "log": str,
               "log_sha256": str, "made_by": str, "content_sha256": str}


class ProvenanceError(ValueError):
    """A provenance or signature block that is malformed, a content that does not match its hash, a missing,
    foreign or false signature; the message says which."""


def _plain(value):
    """Canonical JSON cannot hold NaN or infinities: they are written as the strings YAML uses for them."""
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if math.isnan(value) else (".inf" if value > 0 else "-.inf")
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def canonical(doc) -> bytes:
    """Canonical JSON bytes of a document (keys sorted, no spaces, UTF-8, floats by their shortest repr)."""
    return json.dumps(_plain(doc), sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def content_sha256(doc: dict) -> str:
    """SHA-256 (hex) of the document without ``provenance.content_sha256`` and ``signature``."""
    body = {k: v for k, v in doc.items() if k != "signature"}
    prov = body.get("provenance")
    if isinstance(prov, dict):
        body["provenance"] = {k: v for k, v in prov.items() if k != "content_sha256"}
    return hashlib.sha256(canonical(body)).hexdigest()


def new_provenance(made_by: str, log=None, log_sha256=None, request_id=None, calibration_id=None,
                   now=None) -> dict:
    """A provenance block for a calibration made now: ``id`` (a uuid4, or ``calibration_id``), ``time`` (ISO
    8601, UTC) and ``unix_time_s``, ``made_by`` (the node's full name, or the command), the measurement log and
    its SHA-256, the request's id when it came from a request."""
    now = time.time() if now is None else float(now)
    out = {"id": str(calibration_id or uuid.uuid4().hex), "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(now)),
           "unix_time_s": round(now, 3), "made_by": str(made_by)[:MAX_ID]}
    if request_id is not None:
        out["request_id"] = request_id
    if log is not None:
        out["log"] = str(log)
        out["log_sha256"] = log_sha256 if log_sha256 is not None else file_sha256(log)
    return out


def file_sha256(path) -> str:
    """SHA-256 (hex) of a file's bytes; of a folder (a rosbag2), of each file's relative path and bytes in order."""
    path = Path(path)
    h = hashlib.sha256()
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    for f in files:
        if path.is_dir():
            h.update(str(f.relative_to(path)).encode("utf-8") + b"\0")
        with f.open("rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def check_blocks(doc: dict, where=None) -> None:
    """The types of the ``provenance`` and ``signature`` blocks; ProvenanceError naming the field."""
    where = where or "calibration"
    prov = doc.get("provenance")
    if prov is not None:
        if not isinstance(prov, dict):
            raise ProvenanceError(f"{where}: provenance: expected a mapping")
        for key, value in prov.items():
            kind = _PROVENANCE.get(key)
            if kind is None:
                raise ProvenanceError(f"{where}: provenance.{str(key)[:40]}: not a field of provenance "
                                      f"({', '.join(_PROVENANCE)})")
            if value is not None and (not isinstance(value, kind) or isinstance(value, bool)):
                raise ProvenanceError(f"{where}: provenance.{key}: expected {'text' if kind is str else 'a number'}")
            if isinstance(value, str) and len(value) > MAX_ID * 4:
                raise ProvenanceError(f"{where}: provenance.{key}: longer than {MAX_ID * 4} characters")
        for key in ("content_sha256", "log_sha256"):
            if prov.get(key) is not None and not _HEX64.match(prov[key]):
                raise ProvenanceError(f"{where}: provenance.{key}: expected 64 hex digits (SHA-256)")
    sig = doc.get("signature")
    if sig is not None:
        if not isinstance(sig, dict) or set(sig) != {"algorithm", "key_id", "value"}:
            raise ProvenanceError(f"{where}: signature: expected {{algorithm, key_id, value}}")
        if sig["algorithm"] != ALGORITHM:
            raise ProvenanceError(f"{where}: signature.algorithm: expected {ALGORITHM!r}, got {str(sig['algorithm'])[:40]!r}")
        if not isinstance(sig["key_id"], str) or not _KEY_ID.match(sig["key_id"]):
            raise ProvenanceError(f"{where}: signature.key_id: expected 16 hex digits")
        if not isinstance(sig["value"], str) or len(sig["value"]) > 200:
            raise ProvenanceError(f"{where}: signature.value: expected the base64 signature")


def verified_provenance(doc: dict, where=None) -> dict:
    """The provenance block with ``content_sha256`` the hash of this content; ProvenanceError when the document
    declares another (its content was changed after it was made). A document without provenance gets
    ``{"content_sha256": ...}`` alone."""
    check_blocks(doc, where)
    computed = content_sha256(doc)
    prov = dict(doc.get("provenance") or {})
    declared = prov.get("content_sha256")
    if declared is not None and declared != computed:
        raise ProvenanceError(f"{where + ': ' if where else ''}provenance.content_sha256: the content does not match "
                              f"its hash (declared "
                              f"{declared[:16]}..., computed {computed[:16]}...): it was changed after it was made")
    prov["content_sha256"] = computed
    return prov


def stamped(doc: dict, reload) -> dict:
    """``doc`` with ``provenance.content_sha256`` set to the hash of the document as ``reload(doc)`` reads it
    back (the text it becomes, parsed by the reader every node uses), so that writer and reader agree."""
    out = copy.deepcopy(doc)
    out.setdefault("provenance", {})
    out["provenance"].pop("content_sha256", None)
    out.pop("signature", None)
    out["provenance"]["content_sha256"] = content_sha256(reload(out))
    return out


# ------------------------------------------------------------------ signing (Ed25519)


def _crypto():
    try:
        from cryptography.hazmat.primitives import serialization
        from cryptography.hazmat.primitives.asymmetric import ed25519
    except ImportError as exc:  # a declared dependency; named so that a broken install says what is missing
        raise ProvenanceError(f"signing needs the Python package 'cryptography' ({exc}); install it with "
                              f"`pip install cryptography` or `apt install python3-cryptography`") from None
    return serialization, ed25519


def key_id(public_key) -> str:
    """First 16 hex digits of the SHA-256 of the raw 32-byte Ed25519 public key."""
    serialization, _ = _crypto()
    raw = public_key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return hashlib.sha256(raw).hexdigest()[:16]


def load_signing_key(path):
    """The Ed25519 private key of a PEM file (PKCS#8, unencrypted); ProvenanceError naming the file."""
    serialization, ed25519 = _crypto()
    try:
        key = serialization.load_pem_private_key(Path(path).read_bytes(), password=None)
    except (OSError, ValueError, TypeError) as exc:
        raise ProvenanceError(f"signing key {path}: {exc}") from None
    if not isinstance(key, ed25519.Ed25519PrivateKey):
        raise ProvenanceError(f"signing key {path}: not an Ed25519 private key ({type(key).__name__})")
    return key


def load_public_keys(paths) -> dict:
    """{key_id: Ed25519 public key} of PEM files (SubjectPublicKeyInfo); ProvenanceError naming the file."""
    serialization, ed25519 = _crypto()
    out = {}
    for path in paths:
        try:
            key = serialization.load_pem_public_key(Path(path).read_bytes())
        except (OSError, ValueError, TypeError) as exc:
            raise ProvenanceError(f"trusted key {path}: {exc}") from None
        if not isinstance(key, ed25519.Ed25519PublicKey):
            raise ProvenanceError(f"trusted key {path}: not an Ed25519 public key ({type(key).__name__})")
        out[key_id(key)] = key
    return out


def generate_key_pair(private_path, public_path) -> str:
    """Write a new Ed25519 key pair (private PEM readable by its owner only, public PEM); returns its key id."""
    serialization, ed25519 = _crypto()
    key = ed25519.Ed25519PrivateKey.generate()
    private_path, public_path = Path(private_path), Path(public_path)
    private_path.parent.mkdir(parents=True, exist_ok=True)
    public_path.parent.mkdir(parents=True, exist_ok=True)
    pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                            serialization.NoEncryption())
    private_path.touch(mode=0o600, exist_ok=False)
    private_path.write_bytes(pem)
    public_path.write_bytes(key.public_key().public_bytes(serialization.Encoding.PEM,
                                                          serialization.PublicFormat.SubjectPublicKeyInfo))
    return key_id(key.public_key())


def signature(content_hash: str, private_key) -> dict:
    """The ``signature`` block of a content hash."""
    value = private_key.sign(SIGNED_PREFIX + content_hash.encode("ascii"))
    return {"algorithm": ALGORITHM, "key_id": key_id(private_key.public_key()),
            "value": base64.b64encode(value).decode("ascii")}


def verify_signature(content_hash: str, block, trusted: dict, where="calibration") -> str:
    """The key id of the trusted key whose signature ``block`` is over ``content_hash``; ProvenanceError for an
    unsigned calibration, a key that is not trusted, or a signature that does not verify."""
    from cryptography.exceptions import InvalidSignature
    if block is None:
        raise ProvenanceError(f"{where}: unsigned, and this node trusts only calibrations signed by "
                              f"{sorted(trusted)} (parameter trusted_calibration_keys)")
    key = trusted.get(block.get("key_id"))
    if key is None:
        raise ProvenanceError(f"{where}: signed by key {str(block.get('key_id'))[:16]}, which this node does not "
                              f"trust ({sorted(trusted)})")
    try:
        key.verify(base64.b64decode(block["value"], validate=True), SIGNED_PREFIX + content_hash.encode("ascii"))
    except (InvalidSignature, ValueError):
        raise ProvenanceError(f"{where}: the signature of key {block['key_id']} does not verify: the content was "
                              f"changed after it was signed, or the signature is false") from None
    return block["key_id"]
