"""Logic of the simulated laser tracker node: an as-built robot drawn within a tolerance budget (seeded),
measurement noise and a base-frame offset; a joint state in, the tracker's reading out (SI). Streaming
(``stream``): the tracker ticks at its own rate while the robot moves, each reading taken at the joints of
its tick (linear between the joint states around it) and stamped ``latency`` s late."""
from __future__ import annotations

import numpy as np

from ..core.accuracy.simulate import as_built_errors, measure
from ..core.geometry import matrices_to_quat
from ..core.ingest import JointOrder, stamp_seconds
from ..core.models.base import Mechanism


class SimulatedTracker:
    """A stand-in laser tracker: an as-built robot drawn within ``delta`` (seeded), measurement noise
    and a base-frame offset. ``measure_at(q)`` gives the reading (4x4, tracker frame) at joints q."""

    def __init__(self, model: Mechanism, delta, seed=0, noise_position=1e-5, noise_orientation=1e-5,
                 T_tracker_base=None, distribution="uniform"):
        self.model = model
        self.dx = as_built_errors(delta, seed, distribution)
        self.noise_position, self.noise_orientation = noise_position, noise_orientation
        self.T_tracker_base = None if T_tracker_base is None else np.asarray(T_tracker_base, float)
        self.rng = np.random.default_rng(seed + 1)
        self.joint_order = JointOrder(model.joint_names)
        self._prev = None

    def measure_at(self, q) -> np.ndarray:
        return measure(self.model, np.atleast_2d(q), self.dx, self.noise_position, self.noise_orientation,
                       self.T_tracker_base, self.rng)[0]

    def on_joint_state(self, names, positions) -> np.ndarray:
        """Reading for a joint state (names in any order); raises IngestError if it cannot be used."""
        return self.measure_at(self.joint_order(names, positions))

    def on_joint_state_msg(self, msg):
        """(stamp s, position (3,) m, quaternion x y z w) of the reading for a duck-typed JointState,
        stamped like it; raises IngestError if the state cannot be used."""
        t = stamp_seconds(msg.header.stamp)
        T = self.on_joint_state(msg.name, msg.position)
        return t, T[:3, 3].copy(), matrices_to_quat(T[None, :3, :3])[0]


    def stream(self, t: float, q, rate: float, latency: float = 0.0) -> list:
        """[(stamp s, reading 4x4)] of the ticks of a tracker at ``rate`` Hz (ticks at whole multiples of
        1/rate) after the previous joint state up to this one (``t`` s, joints q (dof,)), each at the joints
        interpolated linearly to its tick and stamped ``latency`` s late. The first joint state only starts."""
        q = np.asarray(q, float)
        prev, self._prev = self._prev, (float(t), q)
        if prev is None or t <= prev[0]:
            return []
        k = np.arange(np.floor(prev[0] * rate) + 1, np.floor(t * rate) + 1)
        if not len(k):
            return []
        ticks = k / rate
        w = ((ticks - prev[0]) / (t - prev[0]))[:, None]
        T = measure(self.model, prev[1] + w * (q - prev[1]), self.dx, self.noise_position, self.noise_orientation,
                    self.T_tracker_base, self.rng)
        return list(zip(ticks + latency, T))


def stamp_fields(stamp: float):
    """(sec, nanosec) of a time in seconds, for a builtin_interfaces/Time."""
    ns = int(round(stamp * 1e9))
    return ns // 1_000_000_000, ns % 1_000_000_000
