"""Robust scores: every evaluation runs its controller on K slightly perturbed copies of the
creature and scores a statistic over them (issue 10, "Robust scores").

The closed loop of a SAN (binary thresholds, contacts) is chaotic: one rollout's distance is one
sample, and a search over single samples breeds gaits that only work on one exact float32
trajectory. An :class:`Ensemble` of K members is evaluated instead, all K in the same batched
rollout:

- member 0 is the unperturbed start (so ``members=1`` is single-sample scoring);
- members 1 .. K-1: each free tree's centre of mass x and y moved by N(0, ``pose``) (m), every
  angle coordinate (root angles and joint angles) by N(0, ``angle``) (degrees), each draw clipped
  at 3 standard deviations; with ``friction`` > 0 every link's friction coefficients scaled by
  1 + U(-friction, friction); with ``dt`` > 0 the member's time step scaled by 1 + U(-dt, dt)
  (it runs the same number of steps, and its score, speed and distance are divided by the same
  factor, so members compare over the nominal time); then, in the vertical plane, the start is
  re-seated on the ground (``sanlab.sim.dynamics.seat_on_ground``) so that no contact starts
  inside it.

The step jitter is off by default. It nudges the integrator inside the ensemble, as the audit
nudges it afterwards (``sanlab.audit``): a gait that only works at one exact step, which tuning
otherwise breeds, then loses its median.

The perturbations of an evaluation come from its own random stream, ``default_rng(key)``, where
the key names the evaluation within its run (see the ``*_key`` functions): any subset of a run
re-evaluates alone, in any batch, on any backend, and a resumed run ends exactly as an
uninterrupted one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sanlab.sim.model import Structure

Key = tuple[int, ...]

# The last element of every key says what kind of evaluation it names, so that no two kinds
# ever share a stream.
_SEARCH, _TRIAL, _START, _HELDOUT, _CHAIN = 1, 2, 3, 4, 5


def search_key(seed: int, idx: int) -> Key:
    """Controller ``idx`` of a phase-1 run seeded ``seed``."""
    return (seed, idx, _SEARCH)


def trial_key(seed: int, chain: int, trial: int) -> Key:
    """Trial ``trial`` of tuning chain ``chain`` (its index among the chains started together)."""
    return (seed, chain, trial, _TRIAL)


def start_key(seed: int, chain: int) -> Key:
    """A tuning chain's starting point, scored under the tuning conditions."""
    return (seed, chain, _START)


def heldout_key(seed: int, chain: int) -> Key:
    """The held-out re-evaluation of a chain's best vector: its stored score."""
    return (seed, chain, _HELDOUT)


def chain_key(seed: int, chain: int) -> Key:
    """A tuning chain's own random choices (which parameter, which sign, acceptance draws)."""
    return (seed, chain, _CHAIN)


@dataclass(frozen=True)
class Ensemble:
    """K perturbed copies per evaluation (see the module docstring).

    members: K >= 1. pose: standard deviation of each free tree's centre of mass x and y (m).
    angle: standard deviation of every angle coordinate (degrees). friction: half-width of the
    uniform relative change of every link's friction coefficients (0: unchanged). dt: half-width
    of the uniform relative change of each member's time step (0: unchanged; below 0.5).
    """

    members: int = 8
    pose: float = 1e-3
    angle: float = 0.5
    friction: float = 0.0
    dt: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.members, int) and self.members >= 1):
            raise ValueError(f"ensemble: members must be an integer >= 1, got {self.members!r}")
        for name in ("pose", "angle", "friction", "dt"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"ensemble: {name} must be >= 0, got {v!r}")
        if self.friction >= 1:
            raise ValueError(f"ensemble: friction must be < 1, got {self.friction!r}")
        if self.dt >= 0.5:
            raise ValueError(f"ensemble: dt must be < 0.5, got {self.dt!r}")

    def to_json(self) -> dict[str, Any]:
        out = {"members": self.members, "pose": self.pose, "angle": self.angle, "friction": self.friction}
        if self.dt:  # written only when used, so that the settings of every other run read as before
            out["dt"] = self.dt
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any] | None) -> Ensemble:
        """The ensemble of a stored run; runs stored before ensembles existed were scored on one
        sample (``members=1``)."""
        if not d:
            return cls(members=1)
        return cls(int(d.get("members", 1)), float(d.get("pose", 1e-3)), float(d.get("angle", 0.5)),
                   float(d.get("friction", 0.0)), float(d.get("dt", 0.0)))

    def step_scales(self, key: Key) -> np.ndarray:
        """Each member's factor on the time step [K] for the evaluation named ``key`` (member 0:
        1, the unperturbed step; all 1 when ``dt`` is 0). Drawn from a stream of its own, so that
        turning the step jitter on leaves every other draw as it was."""
        scale = np.ones(self.members)
        if self.members > 1 and self.dt > 0:
            rng = np.random.default_rng([*key, 0])  # a longer key: no other kind of evaluation draws from it
            scale[1:] = 1.0 + self.dt * rng.uniform(-1.0, 1.0, self.members - 1)
        return scale

    def draws(self, st: Structure, key: Key, n_links: int) -> tuple[np.ndarray, np.ndarray]:
        """The perturbations of the evaluation named ``key``: (dq [K, D] to add to the start
        coordinates, mu_scale [K, L] friction factors); row 0 is (0, 1), the unperturbed start."""
        K = self.members
        dq = np.zeros((K, st.ndof))
        mu = np.ones((K, n_links))
        if K == 1:
            return dq, mu
        rng = np.random.default_rng(list(key))
        roots = [st.links[t.root] for t in st.trees if t.free]
        angles = [ls.dof_rot for ls in st.links if ls.dof_rot >= 0]
        # Every draw happens whatever the settings, in a fixed order, so that changing one
        # setting never changes the draws of another.
        z_pose = np.clip(rng.standard_normal((K - 1, len(roots), 2)), -3.0, 3.0)
        z_angle = np.clip(rng.standard_normal((K - 1, len(angles))), -3.0, 3.0)
        u = rng.uniform(-1.0, 1.0, (K - 1, n_links))
        for r, ls in enumerate(roots):
            dq[1:, ls.dof_x] = self.pose * z_pose[:, r, 0]
            dq[1:, ls.dof_y] = self.pose * z_pose[:, r, 1]
        for a, dof in enumerate(angles):
            dq[1:, dof] = math.radians(self.angle) * z_angle[:, a]
        mu[1:] = 1.0 + self.friction * u
        return dq, mu
