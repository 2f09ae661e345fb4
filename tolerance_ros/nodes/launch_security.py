"""SROS2 in the launch files (``launch`` imports: the ROS side of the package). The ``keystore`` argument (a
keystore from ``tolerance-ros keystore``) switches security on: ``ROS_SECURITY_KEYSTORE`` set to it,
``ROS_SECURITY_ENABLE=true``, ``ROS_SECURITY_STRATEGY=Enforce``, and each node started in its own enclave,
``/<namespace>/<node name>`` (``ROS_SECURITY_ENCLAVE_OVERRIDE`` in the node's environment, which rcl prefers to
``--enclave``); the launch process itself, which drives managed nodes, runs in ``/<namespace>/tolerance_launch``.
Empty (the default), the environment decides as for any ROS node."""
from __future__ import annotations

import os

from launch.actions import DeclareLaunchArgument, SetEnvironmentVariable
from launch.conditions import IfCondition
from launch.substitution import Substitution
from launch.substitutions import LaunchConfiguration, NotEqualsSubstitution
from launch.utilities import normalize_to_list_of_substitutions, perform_substitutions

from ..services.security import LAUNCH, enclave

KEYSTORE = LaunchConfiguration("keystore")
OVERRIDE = "ROS_SECURITY_ENCLAVE_OVERRIDE"


def keystore_argument() -> DeclareLaunchArgument:
    """The ``keystore`` launch argument."""
    return DeclareLaunchArgument("keystore", default_value="",
                                 description="SROS2 keystore made by `tolerance-ros keystore` for this namespace: every "
                                             "node runs in its own enclave with security enforced (empty: as the "
                                             "environment says)")


class Enclave(Substitution):
    """The enclave of ``node`` in the launch's namespace when a keystore is given; otherwise the environment's
    ``ROS_SECURITY_ENCLAVE_OVERRIDE`` (usually empty: unset)."""

    def __init__(self, namespace, node: str):
        super().__init__()
        self.namespace = normalize_to_list_of_substitutions(namespace)
        self.node = node

    def describe(self) -> str:
        return f"Enclave(<namespace>, {self.node})"

    def perform(self, context) -> str:
        if not KEYSTORE.perform(context):
            return os.environ.get(OVERRIDE, "")
        return enclave(perform_substitutions(context, self.namespace), self.node)


def security_actions(namespace) -> list:
    """Actions that switch security on for the launch (its own process included) when ``keystore`` is set."""
    on = IfCondition(NotEqualsSubstitution(KEYSTORE, ""))
    return [SetEnvironmentVariable("ROS_SECURITY_KEYSTORE", KEYSTORE, condition=on),
            SetEnvironmentVariable("ROS_SECURITY_ENABLE", "true", condition=on),
            SetEnvironmentVariable("ROS_SECURITY_STRATEGY", "Enforce", condition=on),
            SetEnvironmentVariable(OVERRIDE, Enclave(namespace, LAUNCH), condition=on)]


def enclave_env(namespace, node: str) -> dict:
    """``additional_env`` of a node: its own enclave."""
    return {OVERRIDE: Enclave(namespace, node)}
