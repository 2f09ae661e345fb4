"""`tolerance-ros signing-key`: an Ed25519 key pair for signed calibrations (the monitor's ``signing_key``, the
nodes' ``trusted_calibration_keys``, ``calibrate --signing-key``)."""
from __future__ import annotations

from pathlib import Path

from .common import CLIError

NAME = "signing-key"
HELP = "Ed25519 key pair that signs calibrations (private NAME.key readable by its owner only, public NAME.pub)"
ROBOT = False


def add_arguments(p):
    p.add_argument("--out", required=True, metavar="DIR", help="folder of the two PEM files (made if missing)")
    p.add_argument("--name", default="calibration_signing", help="file name of the pair (default calibration_signing)")


def run(args):
    from ..core.calibration.provenance import generate_key_pair
    out = Path(args.out)
    if not args.name or "/" in args.name or args.name in (".", ".."):
        raise CLIError(f"--name: {args.name!r} is not a file name")
    private, public = out / f"{args.name}.key", out / f"{args.name}.pub"
    for path in (private, public):
        if path.exists():
            raise CLIError(f"--out: {path} exists; a key is never overwritten (remove it, or choose another --name)")
    key_id = generate_key_pair(private, public)
    doc = {"private_key": str(private), "public_key": str(public), "key_id": key_id}
    if args.json:
        return doc
    print(f"key {key_id}: private {private} (give it to the monitor: -p signing_key:={private.resolve()}), public "
          f"{public} (give it to the nodes: -p trusted_calibration_keys:=\"['{public.resolve()}']\")")
    return None
