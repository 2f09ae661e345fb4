"""The robots a node serves, by name: shipped names or robot files loaded at start, and the robot whose
URDF arrives on the ``robot_description`` topic (as ``robot_state_publisher`` publishes it), which may
come late and may be replaced.

A node configured with ``robot_description`` (as its robot, or among its robots) serves that robot
under the URDF's ``<robot name>`` once the text has arrived; the chain runs from ``base_link`` to
``tip_link`` (default: the one leaf link the joints move; a branching URDF needs ``tip_link``). A new
description replaces the model; a malformed one raises ModelError and the previous model stays. The
message is URDF text: a path in it is not read. Each description is named by two SHA-256 hashes: of its
text, and of the chain the node takes from it (``chain_sha256``: joints, limits, nominal parameters and the
tool frame at fixed configurations), so that a new description whose chain differs from the one in force
is said (and logged) with both chains' hashes, and one that changes only what the chain does not use
(meshes, colours) is told apart.
"""
from __future__ import annotations

import hashlib

import numpy as np

from ..core.calibration.provenance import canonical
from ..core.models import ModelError, URDFChain, load_robot
from ..core.models.urdf import read_urdf
from .contracts import ContractError

DESCRIPTION = "robot_description"


def chain_sha256(model) -> str:
    """SHA-256 (hex) of a robot's chain: its description (joints, types, limits, parameters and their nominal
    values) and its tool frames (rounded to 1e-12) at the zero configuration and three seeded ones."""
    lim = np.where(np.isfinite(model.joint_limits), model.joint_limits, np.array([-np.pi, np.pi]))
    q = np.vstack([np.clip(np.zeros(model.dof), lim[:, 0], lim[:, 1]),
                   lim[:, 0] + (lim[:, 1] - lim[:, 0]) * np.random.default_rng(0).random((3, model.dof))])
    T = np.round(np.asarray(model.fk(q), float), 12) + 0.0  # + 0.0: no negative zeros
    return hashlib.sha256(canonical(model.describe()) + T.astype("<f8").tobytes()).hexdigest()


class RobotSet:
    """Models by robot name; ``specs`` are shipped names, robot files or ``robot_description``."""

    def __init__(self, specs, default, tip_link=None, base_link=None):
        self.models = {}
        self.tip_link, self.base_link = tip_link or None, base_link or None
        self.from_description = DESCRIPTION in list(specs) or default == DESCRIPTION
        self.description_name = None
        self.description_hashes = None  # (text sha256, chain sha256) of the description in force
        self.chain_changed = None       # (old chain sha256, new) when the last description changed the chain
        self.version = 0  # increases whenever a model is added or replaced
        names = {}
        for spec in dict.fromkeys([s for s in list(specs) + [default] if s != DESCRIPTION]):
            model = load_robot(spec)
            if (self.tip_link or self.base_link) and hasattr(model, "tip_link"):  # a URDF robot file: its chain
                model = load_robot(spec, self.tip_link, self.base_link)
            self.models[model.name] = model
            names[spec] = model.name
        if (self.tip_link or self.base_link) and not self.from_description and \
                not any(hasattr(m, "tip_link") for m in self.models.values()):
            raise ModelError(f"tip_link, base_link: only for URDF robots (a URDF file or robot_description), not "
                             f"{', '.join(sorted(self.models))}")
        self._default = DESCRIPTION if default == DESCRIPTION else names[default]

    @property
    def waiting(self) -> bool:
        """True while robot_description is expected and has not arrived."""
        return self.from_description and self.description_name is None

    @property
    def default_name(self):
        """Name of the default robot (None while it waits for robot_description)."""
        return self.description_name if self._default == DESCRIPTION else self._default

    def on_description(self, text, check=None) -> str:
        """Build (or replace) the robot of a ``robot_description`` message; returns what to log.

        Raises ModelError for a malformed or unusable URDF, and whatever ``check(model)`` raises for a
        robot the node cannot use (e.g. its budget file does not fit); the previous model is then kept.
        """
        if not self.from_description:
            raise ContractError("invalid_request", "this node does not take its robot from robot_description")
        if not isinstance(text, str) or not text.strip():
            raise ContractError("invalid_request", "robot_description: empty message")
        try:
            text, _ = read_urdf(text, text_only=True)  # the reader of URDF files: one answer for one content
        except ModelError as exc:
            raise ModelError(f"robot_description: {exc}") from None
        model = URDFChain(text, tip_link=self.tip_link, base_link=self.base_link).check_size("robot_description: ")
        if check is not None:
            check(model)
        hashes = (hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest(), chain_sha256(model))
        previous, old = self.description_name, self.description_hashes
        if previous is not None and previous != model.name:
            del self.models[previous]
        self.models[model.name] = model
        self.description_name = model.name
        self.description_hashes = hashes
        self.chain_changed = (old[1], hashes[1]) if old is not None and old[1] != hashes[1] else None
        self.version += 1
        tip = f"tip {model.tip_link!r}" + (" (the only moving leaf)" if model.tip_chosen else "")
        said = (f"robot_description: {'replaced the' if previous else 'loaded'} robot {model.name!r}: "
                f"{model.dof} joints from {model.base_link!r}, {tip}; chain sha256 {hashes[1][:12]}, text "
                f"sha256 {hashes[0][:12]}")
        if self.chain_changed is not None:
            said += f"; THE CHAIN CHANGED: {old[1][:12]} -> {hashes[1][:12]} (text {old[0][:12]} -> {hashes[0][:12]})"
        elif old is not None:
            said += " (the same chain as before)"
        return said

    def select(self, name=None):
        """(name, model) of the named robot, or of the default; ContractError 'unknown_robot' otherwise."""
        if name is None or name == DESCRIPTION:
            name = self.description_name if name == DESCRIPTION else self.default_name
            if name is None:
                raise ContractError("unknown_robot", "no robot yet: waiting for a URDF on robot_description")
        if name not in self.models:
            wait = " (and still waiting for robot_description)" if self.waiting else ""
            shown = name[:80] if isinstance(name, str) else type(name).__name__
            raise ContractError("unknown_robot", f"robot: {shown!r} is not served here; available: "
                                                 f"{sorted(self.models)}{wait}")
        return name, self.models[name]

    def single(self):
        """The default model, or None while it waits for robot_description (nodes that serve one robot)."""
        return self.models.get(self.default_name) if self.default_name is not None else None
