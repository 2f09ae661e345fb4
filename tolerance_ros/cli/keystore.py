"""`tolerance-ros keystore`: an SROS2 keystore for the suite, made with `ros2 security` from the shipped policy:
an enclave per node of each namespace, with signed permissions that grant the node exactly its own topics."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from .common import CLIError

NAME = "keystore"
HELP = "SROS2 keystore: an enclave per node with signed permissions from the shipped policy (needs ros2 security)"
ROBOT = False


def add_arguments(p):
    p.add_argument("--out", required=True, metavar="DIR", help="the keystore (made if missing; an existing one gets "
                                                               "the enclaves added or their permissions renewed)")
    p.add_argument("--namespace", action="append", metavar="NS",
                   help="namespace of a suite (repeat for several, e.g. /arm_left and /arm_right; default: the root)")
    p.add_argument("--domain-id", type=int, metavar="ID",
                   help="ROS_DOMAIN_ID the permissions are for (default: $ROS_DOMAIN_ID, or 0)")
    p.add_argument("--remap", action="append", default=[], metavar="FROM:=TO",
                   help="a topic the launch remaps, granted under its new name, e.g. "
                        "joint_trajectory:=/arm_controller/joint_trajectory")
    p.add_argument("--policy", metavar="XML", help="policy to start from (default: the shipped "
                                                   "config/security/tolerance_ros.policy.xml)")


def run(args):
    from ..services.security import SecurityError, keystore_plan, namespace, policy_path, remapping, specialise
    if shutil.which("ros2") is None:
        raise CLIError("keystore: `ros2` is not on PATH; source ROS 2 Jazzy with sros2 first "
                       "(source /opt/ros/jazzy/setup.bash; apt install ros-jazzy-sros2)")
    domain = args.domain_id if args.domain_id is not None else int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
    if not 0 <= domain <= 232:
        raise CLIError(f"--domain-id: {domain} is not a DDS domain id (0-232)")
    try:
        spaces = list(dict.fromkeys(namespace(ns) for ns in (args.namespace or ["/"])))
        remaps = [remapping(r) for r in args.remap]
        template = Path(args.policy or policy_path()).read_text()
        ks = Path(args.out).resolve()
        policies = {}
        for ns in spaces:
            path = ks / "policies" / f"tolerance_ros{ns.replace('/', '.') if ns != '/' else ''}.policy.xml"
            policies[path] = specialise(template, ns, remaps)
    except (SecurityError, OSError) as exc:
        raise CLIError(f"keystore: {exc}") from None
    new = not (ks / "public" / "permissions_ca.cert.pem").is_file()
    for path, text in policies.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    for argv in keystore_plan(ks, policies, new):
        if not args.quiet:
            print("+ " + " ".join(argv), file=sys.stderr)
        done = subprocess.run(argv, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            if argv[2] == "create_permission":   # never leave create_enclave's allow-all permissions behind
                for name in ("permissions.xml", "permissions.p7s"):
                    (ks / "enclaves" / argv[4].lstrip("/") / name).unlink(missing_ok=True)
            raise CLIError(f"keystore: `{' '.join(argv)}` failed: {(done.stderr or done.stdout).strip()[-500:]}")
    enclaves = [name for text in policies.values() for name in _paths(text)]
    out = {"keystore": str(ks), "domain_id": domain, "namespaces": spaces, "enclaves": enclaves,
           "policies": [str(p) for p in policies]}
    if args.json:
        return out
    print(f"keystore {ks} (domain {domain}): {len(enclaves)} enclaves with permissions from "
          f"{', '.join(str(p) for p in policies)}")
    for ns in spaces:
        arg = "" if ns == "/" else f" namespace:={ns.lstrip('/')}"
        print(f"  ros2 launch tolerance_ros accuracy_suite.launch.py{arg} keystore:={ks}")
    return None


def _paths(text):
    from ..services.security import enclave_paths
    return enclave_paths(text)
