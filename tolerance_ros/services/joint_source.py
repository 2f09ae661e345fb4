"""Joint configurations over time for the joint-state publisher (ROS-free).

Modes: 'campaign' (the test poses of a campaign, each held ``dwell`` seconds, for its cycles in its
visiting order; a pose's pre-pose ``via``, where it has one, is held ``dwell`` seconds before it), 'random'
(seeded uniform samples within the joint limits), 'selected' (the
configurations of highest pose-selection index F, eq. 25) and 'trajectory' (a joint trajectory, e.g. an
ISO 9283 test path of ``plan-campaign --path``, interpolated between its knots, for its cycles: the robot
moves). With ``loop`` the sequence repeats; otherwise the last configuration is held once it has run out.
"""
from __future__ import annotations

import math

import numpy as np

MODES = ("campaign", "random", "selected", "trajectory")


class JointStateSequence:
    """``at(t)`` gives (step, label, joints (dof,), finished) for t seconds after the start."""

    def __init__(self, model, mode="random", campaign=None, count=100, seed=0, dwell=None, loop=False,
                 trajectory=None):
        if mode not in MODES:
            raise ValueError(f"mode: expected one of {MODES}, got {mode!r}")
        self.model = model
        self.mode = mode
        self.trajectory = None
        if mode == "trajectory":
            if trajectory is None:
                raise ValueError("mode 'trajectory' needs a trajectory (a JointPath)")
            self.trajectory = trajectory
            self.q = trajectory.q
            self.labels = [f"knot{k}" for k in range(len(self.q))]
            self.cycles = [None] * len(self.q)
            self.dwell = trajectory.duration  # the whole run: ``at`` interpolates within it
        elif mode == "campaign":
            if campaign is None:
                raise ValueError("mode 'campaign' needs a campaign")
            self.q, pose, cycle, via = campaign.steps(model)   # a pre-pose (``via``): a step of its own
            self.labels = [campaign.names[i] + (" via" if v else "") for i, v in zip(pose, via)]
            self.cycles = [int(c) for c in cycle]
            self.dwell = float(dwell if dwell is not None else campaign.dwell_s)
        else:
            if count < 1:
                raise ValueError("count: must be >= 1")
            if mode == "random":
                self.q = model.sample_joints(count, seed)
            else:
                from ..core.synthesis.search import select_poses
                self.q = select_poses(model, count, seed=seed)
            self.labels = [f"{mode}{k}" for k in range(len(self.q))]
            self.cycles = [None] * len(self.q)
            self.dwell = float(dwell if dwell is not None else 2.0)
        if not self.dwell > 0:
            raise ValueError("dwell: must be > 0 s")
        self.loop = loop

    def __len__(self):
        return len(self.q)

    def at(self, t: float):
        if not math.isfinite(t):
            raise ValueError(f"t: expected a finite time in s, got {t!r}")
        if self.trajectory is not None:
            return self._along(max(t, 0.0))
        t, n = max(t, 0.0), len(self.q)
        if t >= n * self.dwell:
            if not self.loop:
                return n - 1, self.labels[-1], self.q[-1], True
            t %= n * self.dwell  # a time of any size: its steps need not fit an integer
        k = min(int(t // self.dwell), n - 1)
        return k, self.labels[k], self.q[k], False

    def _along(self, t: float):
        """Trajectory mode: (step, label, joints, finished) at ``t`` s; the step is the cycle's knot interval, so
        that a compensated source sends each interval's end once."""
        traj = self.trajectory
        duration = traj.duration
        finished = t >= duration
        if finished and self.loop:
            t, finished = t % duration, False
        t = min(t, duration)
        cycle = min(int(t // traj.period), traj.cycles - 1)
        knot = int(np.searchsorted(traj.t, t - cycle * traj.period, side="right")) - 1
        knot = min(max(knot, 0), len(traj.t) - 1)
        q = traj.at(np.array([t]))[0]
        return cycle * len(traj.t) + knot, f"cycle{cycle + 1} knot{knot}", q, finished
