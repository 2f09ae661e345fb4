"""The result of a calibration: the identified errors of one robot, what they rest on, and the calibrated
model they make (``Calibration``). SI throughout."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..identification import BASE_NAMES, base_matrix
from ..targets import AtTarget, Targets
from ..models.base import Mechanism
from .elastic import DeflectedChain, Load
from .mechanism import calibrated_mechanism


NOMINAL_POSTURES = 8        # seeded postures whose nominal tool points identify the robot a calibration is for
NOMINAL_TOLERANCE = 1e-6    # m: the tool points of the same robot agree this well (any FK, any machine)


def nominal_fingerprint(model: Mechanism) -> dict:
    """The nominal robot a calibration is made for, as its tool points (m) at ``NOMINAL_POSTURES`` seeded
    postures: a robot of the same name whose geometry differs (a link 10 mm longer) puts them elsewhere."""
    q = model.sample_joints(NOMINAL_POSTURES, 1234)
    return {"joints": q.tolist(), "tool_points_m": model.fk(q)[:, :3, 3].tolist()}


@dataclass
class Calibration:
    """Identified parameter errors of one robot (SI) and what they rest on.

    dx, std : (p,) errors (identified - nominal) and standard uncertainties, m or rad; 0 where held.
    base : (6,) base correction [x y z (m), rotation vector (rad)], applied on the left of the model.
    T_tracker_base : 4x4 registration, nominal base frame -> tracker frame.  targets : the measured
    targets' frames in the tool frame (``targets_std`` their points' uncertainties, m).  compliance :
    (dof,) rad/(N m) or m/N per joint, or None (no elastostatic term).  held : parameters left at nominal
    (not identifiable from these poses).  aliases : what each estimated unknown absorbs of the held ones
    (see ``Identification``).  nominal_registration : tracker and targets of the registration-only fit
    (how the nominal robot is predicted, for ``before`` figures).  model : the identified set chosen and
    the cross-validation of the candidates.  rejected : measurements left out as outliers, with reasons.
    plausibility : {ok, problems}.  training : the training joints' ranges and postures (to group the
    postures of another campaign).  validation : see ``crossval.validate``.  convergence : how the final
    fit's loop ended (``identification.Convergence.to_dict``).  load : what loads the joints of the
    elastostatic term (``elastic.Load.to_dict``).  undetermined : {parameter: reason} of the estimated
    parameters the data cannot tell (set by the prior, or near-copies of another).  suspect : measurements
    beyond the rejection threshold that were kept because their removal would change what is identifiable.
    position_rms, position_max : the final fit's 3-D position residual RMS and max over the kept
    measurements, m (``residual_rms_before`` and ``residual_rms_after`` are per axis).  warnings : what the
    user should know that is not a refusal (a fit stopped by its iteration cap among them).  provenance : id,
    time, measurement log and its SHA-256, who made it, and (as read back) ``content_sha256``, the hash of the
    document (``provenance.py``).  signature : the Ed25519 signature block of a signed calibration, or None.
    """

    robot: str
    names: tuple
    kinds: tuple
    dx: np.ndarray
    std: np.ndarray
    base: np.ndarray
    T_tracker_base: np.ndarray
    tool_offset: np.ndarray | None
    held: list
    unidentifiable: list
    aliases: dict
    condition: float
    fit_condition: float
    rank: int
    unknowns: int
    sigma: float
    residual_rms_before: float
    residual_rms_after: float
    measurements: int
    poses: int
    rows: int
    registration: str = "base"
    validation: dict | None = None
    sources: dict = field(default_factory=dict)
    targets: Targets | None = None
    targets_std: np.ndarray | None = None
    compliance: np.ndarray | None = None
    compliance_std: np.ndarray | None = None
    nominal_registration: dict | None = None
    model: dict = field(default_factory=dict)
    rejected: list = field(default_factory=list)
    plausibility: dict = field(default_factory=lambda: {"ok": True, "problems": []})
    repeatability: dict | None = None
    training: dict | None = None
    has_orientation: bool = True
    convergence: dict | None = None
    load: dict | None = None
    undetermined: dict = field(default_factory=dict)
    suspect: list = field(default_factory=list)
    position_rms: float | None = None
    position_max: float | None = None
    warnings: list = field(default_factory=list)
    provenance: dict | None = None
    signature: dict | None = None
    nominal: dict | None = None

    def __post_init__(self):
        if self.targets is None:
            self.targets = (Targets.from_offsets([""], [self.tool_offset]) if self.tool_offset is not None
                            else Targets.at_tool(frames=self.has_orientation))

    @property
    def content_sha256(self) -> str | None:
        """The content hash of the document this calibration was read from (None before it is written)."""
        return (self.provenance or {}).get("content_sha256")

    @property
    def B(self) -> np.ndarray:
        """4x4 base correction."""
        return base_matrix(self.base)

    def fk(self, model: Mechanism, q, target_index=None) -> np.ndarray:
        """(n, 4, 4) calibrated target frames (the tool frame without targets) in the nominal base frame, m."""
        T = self.B @ self.mechanism_chain(model).fk(q, self.dx)
        return self.targets.poses(T, target_index if target_index is not None else [])

    def mechanism_chain(self, model: Mechanism) -> Mechanism:
        """The nominal model with the elastostatic term, when there is one (parameters not applied)."""
        if self.compliance is not None and np.any(self.compliance):
            return DeflectedChain(model, self.compliance, self.joint_load(model))
        return model

    def joint_load(self, model: Mechanism):
        """The ``elastic.Load`` of the elastostatic term (the model's own when the calibration names none)."""
        return Load.from_dict(self.load) if self.load else Load.for_model(model)

    def tool_point(self, target=None) -> tuple:
        """(name, 4x4 frame in the tool frame) of the target that is the tool point: ``target`` by name, or
        the first; ValueError for a name the calibration does not have."""
        names = self.targets.names
        if target is None:
            return names[0], self.targets.X[0]
        if str(target) not in names:
            raise ValueError(f"target: {target!r} is not one of the calibration's targets {list(names)}")
        return str(target), self.targets.X[names.index(str(target))]

    def mechanism(self, model: Mechanism, target=None) -> Mechanism:
        """The calibrated model: a Mechanism of the nominal model's kind (see ``calibrated_mechanism``), its
        joints deflected by the elastostatic term when there is one, its tool at the calibration's tool
        point (``tool_point``) when that is not the tool frame itself."""
        return self._at_tool_point(self.calibrated_chain(model), target)

    def calibrated_chain(self, model: Mechanism) -> Mechanism:
        """The calibrated chain, its tool frame the model's own (the targets are applied by who measures them)."""
        chain = calibrated_mechanism(model, self.dx, self.base)
        if self.compliance is not None and np.any(self.compliance):
            return DeflectedChain(chain, self.compliance, self.joint_load(model))
        return chain

    def nominal_at_tool_point(self, model: Mechanism, target=None) -> Mechanism:
        """The nominal model with its tool at the calibration's tool point (what the calibrated one is compared
        with)."""
        return self._at_tool_point(model, target)

    def _at_tool_point(self, chain, target):
        name, X = self.tool_point(target)
        return chain if np.array_equal(X, np.eye(4)) else AtTarget(chain, X, name)

    def to_dict(self) -> dict:
        """Plain dict, SI (m, rad)."""
        comp = None
        if self.compliance is not None:
            comp = {"unit": "rad/(N m) for revolute joints, m/N for prismatic ones", "load": self.load,
                    "joints": {n: {"compliance": float(c), "std": float(s)} for n, c, s in
                               zip(self._joint_names(), self.compliance, self.compliance_std)}}
        return {"robot": self.robot, "registration": self.registration, "model": self.model,
                "parameters": [{"name": n, "unit": "m" if k == "length" else "rad", "error": float(v),
                                "std": float(s), "held": n in self.held, "absorbs": self.aliases.get(n, {})}
                               for n, k, v, s in zip(self.names, self.kinds, self.dx, self.std)],
                "base_correction": dict(zip(BASE_NAMES, map(float, self.base))),
                "base_absorbs": {k: v for k, v in self.aliases.items() if k.startswith("base.")},
                "held": list(self.held), "unidentifiable": list(self.unidentifiable),
                "T_tracker_base": self.T_tracker_base, "tool_offset_m": self.tool_offset,
                "targets": [{"name": n, "xyz_m": X[:3, 3].tolist(), "rotation": X[:3, :3].tolist(),
                             "std_m": None if self.targets_std is None else self.targets_std[k].tolist()}
                            for k, (n, X) in enumerate(zip(self.targets.names, self.targets.X))],
                "orientation_measured": self.has_orientation, "compliance": comp,
                "fit": self.fit_dict(),
                "undetermined": dict(self.undetermined), "suspect": list(self.suspect), "warnings": list(self.warnings),
                "rejected": list(self.rejected), "plausibility": dict(self.plausibility),
                "repeatability": self.repeatability, "validation": self.validation, "sources": dict(self.sources)}

    def fit_dict(self) -> dict:
        """The ``fit`` block: counts, conditions, the noise (per axis, m), the 3-D position RMS and max of the
        final fit over its kept measurements, the per-axis RMS before and after, and the convergence."""
        return {"measurements": self.measurements, "poses": self.poses, "rows": self.rows, "unknowns": self.unknowns,
                "rank": self.rank, "condition": self.condition, "fit_condition": self.fit_condition,
                "noise_per_axis_m": self.sigma, "position_rms_m": self.position_rms,
                "position_max_m": self.position_max, "per_axis_rms_before_m": self.residual_rms_before,
                "per_axis_rms_after_m": self.residual_rms_after, "convergence": self.convergence}

    def _joint_names(self):
        return self.sources.get("joint_names") or [f"joint{i + 1}" for i in range(len(self.compliance))]
