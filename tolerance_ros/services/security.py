"""SROS2 for the suite, ROS-free: the shipped policy (``config/security/tolerance_ros.policy.xml``), its
specialisation for a namespace, the enclave of each node, and the ``ros2 security`` commands that make a
keystore of it (``tolerance-ros keystore``; docs/security.md).

Each node of the suite runs in an enclave of its own, ``/<namespace>/<node name>`` (``/tolerance_error_model``
in the root namespace), whose signed permissions grant exactly the node's own topics in that namespace; two
more enclaves serve the people and tools around it: ``tolerance_operator`` (service requests, reading
everything, parameters and lifecycle as a client) and ``tolerance_launch`` (the ``ros2 launch`` process that
drives managed nodes). Topic names in the policy follow sros2: relative ones resolve in the profile's
namespace, ``~/x`` under the node, absolute ones stay; ``*`` matches any characters (``measured_pose/*``).
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

from ..core.resources import config_dir

POLICY_FILE = "tolerance_ros.policy.xml"
SUITE_NODES = ("tolerance_joint_state_source", "tolerance_error_model", "tolerance_allocator",
               "tolerance_accuracy_monitor", "tolerance_simulated_tracker", "tolerance_trajectory_compensator")
OPERATOR, LAUNCH = "tolerance_operator", "tolerance_launch"
ENCLAVES = SUITE_NODES + (OPERATOR, LAUNCH)
_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_NAME = re.compile(r"^/?[A-Za-z_~*][A-Za-z0-9_/*~]*$")


class SecurityError(ValueError):
    """A namespace, remapping or policy that cannot be used; the message names it."""


def policy_path() -> Path:
    """The shipped policy file."""
    return config_dir() / "security" / POLICY_FILE


def namespace(ns) -> str:
    """A namespace as an absolute ROS name: '' and '/' -> '/', 'arm_left' -> '/arm_left'; SecurityError for one
    that is not a sequence of name tokens."""
    parts = [p for p in str(ns or "").strip().split("/") if p]
    bad = [p for p in parts if not _TOKEN.match(p)]
    if bad:
        raise SecurityError(f"namespace {ns!r}: {bad[0]!r} is not a ROS name token (a letter or _, then letters, "
                            f"digits, _)")
    return "/" + "/".join(parts)


def enclave(ns, node: str) -> str:
    """The enclave of a node in namespace ``ns``: ``/<ns>/<node>`` ('/tolerance_error_model' in the root)."""
    base = namespace(ns)
    return (base.rstrip("/") + "/" + node) if node else base


def remapping(text: str) -> tuple:
    """(from, to) of ``FROM:=TO``, both topic names as the nodes write them (relative or absolute)."""
    src, sep, dst = str(text).partition(":=")
    if not sep or not _NAME.match(src) or not _NAME.match(dst):
        raise SecurityError(f"remap {text!r}: expected FROM:=TO, two topic names (e.g. "
                            f"joint_trajectory:=/arm_controller/joint_trajectory)")
    return src, dst


def specialise(text: str, ns="/", remaps=()) -> str:
    """The policy of ``text`` for namespace ``ns``: enclave paths ``/<ns>/<name>``, every profile's ``ns`` set to
    it (relative topics then resolve in it), topics renamed by ``remaps`` ((from, to) pairs). Comments go."""
    ns = namespace(ns)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise SecurityError(f"policy: not well-formed XML: {exc}") from None
    if root.tag != "policy" or root.find("enclaves") is None:
        raise SecurityError("policy: expected <policy><enclaves>...</enclaves></policy> (sros2 format 0.2.0)")
    renamed = dict(remaps)
    for enc in root.iter("enclave"):
        enc.set("path", enclave(ns, enc.get("path", "").strip("/")))
        for profile in enc.iter("profile"):
            profile.set("ns", ns)
        for name in list(enc.iter("topic")):
            if name.text in renamed:
                name.text = renamed[name.text]
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def resolve(name: str, ns: str, node: str) -> str:
    """A policy name resolved as sros2 does: absolute stays, ``~/x`` -> ``<ns>/<node>/x``, relative -> ``<ns>/x``."""
    base = ns if ns.endswith("/") else ns + "/"
    if name.startswith("/"):
        return name
    if name.startswith("~"):
        return base + node + name[1:]
    return base + name


def grants(text: str, enclave_path: str) -> dict:
    """{"publish", "subscribe", "reply", "request"}: sets of resolved names granted to an enclave of a policy."""
    root = ET.fromstring(text)
    out = {k: set() for k in ("publish", "subscribe", "reply", "request")}
    found = False
    for enc in root.iter("enclave"):
        if enc.get("path") != enclave_path:
            continue
        found = True
        for profile in enc.iter("profile"):
            ns, node = profile.get("ns", "/"), profile.get("node", "")
            for group in profile:
                for kind in out:
                    if group.get(kind) == "ALLOW":
                        out[kind].update(resolve(e.text.strip(), ns, node) for e in group)
    if not found:
        raise SecurityError(f"policy: no enclave {enclave_path!r}")
    return out


def enclave_paths(text: str) -> list:
    """The enclave paths of a policy, in order."""
    return [e.get("path") for e in ET.fromstring(text).iter("enclave")]


def keystore_plan(keystore, policies: dict, new_keystore: bool) -> list:
    """The ``ros2 security`` commands (argv lists) that make the keystore: create it (when ``new_keystore``),
    then for every enclave of every policy file ({path: policy text}) create the enclave and its permissions."""
    ks = str(keystore)
    plan = [["ros2", "security", "create_keystore", ks]] if new_keystore else []
    for path, text in policies.items():
        for name in enclave_paths(text):
            plan += [["ros2", "security", "create_enclave", ks, name],
                     ["ros2", "security", "create_permission", ks, name, str(path)]]
    return plan
