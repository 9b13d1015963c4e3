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
  re-seated on the ground (``sanlab.sim.state.start_states``) so that no contact starts
  inside it.

Members at several steps (``dt_factors``, issue 28: an objective the step cannot win). With
``dt_factors = (1, 0.5)`` the members take the factors on the time step in turn (member 0 at dt,
member 1 at dt/2, member 2 at dt, ...), each simulating the same time (a member at dt/2 runs
twice the steps), and the evaluation scores the *lower* of the two groups' medians, so a gait
that only moves at one step size cannot raise its score: tuning at dt alone learns the 1 ms step
(the walker of ``docs/table1-seed0-before-issue-28.md``, 114 cm/s at dt and 23 at dt/4). The group with the lower median
score gives the evaluation's speed and distance too. One step factor (``(1.0,)``) is plain
scoring, and what every run stored before this option existed reads as.

The step jitter (``dt``) is off by default. It too nudges the integrator inside the ensemble,
but only within [1 - dt, 1 + dt] of the step, where a tuned gait can still find a rate that
works at all of them (measured: ``docs/robust-objective.md``).

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
_SEARCH, _TRIAL, _START, _HELDOUT, _CHAIN, _AUDIT, _CONFIRM = 1, 2, 3, 4, 5, 6, 7


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


def audit_key(key: Key) -> Key:
    """The audit's draws for the evaluation named ``key`` (``sanlab.audit``): its own stream, so
    an audit's members are never the members its score was taken on."""
    return (*key, _AUDIT)


def confirm_key(seed: int, chain: int) -> Key:
    """Fresh draws confirming the rung a tuning chain's audited selection chose."""
    return (seed, chain, _CONFIRM)


# The searches' default step groups (issue 28): members at dt and at dt/2, the lower group median
# scored. Chosen by measurement: docs/robust-objective.md.
DEFAULT_DT_FACTORS: tuple[float, ...] = (1.0, 0.5)


def default_ensemble(members: int = 8, dt_factors: tuple[float, ...] | None = None, dt: float = 0.0) -> Ensemble:
    """The ensemble a search or tuning run scores with when given ``members`` (and optionally
    its step factors and jitter): :data:`DEFAULT_DT_FACTORS` from two members on, plain scoring
    for one member (a single unperturbed rollout, as before ensembles existed). Raises
    ValueError as :class:`Ensemble`."""
    if dt_factors is None:
        dt_factors = DEFAULT_DT_FACTORS if members >= len(DEFAULT_DT_FACTORS) else (1.0,)
    return Ensemble(members=int(members), dt=dt, dt_factors=tuple(dt_factors))


@dataclass(frozen=True)
class Ensemble:
    """K perturbed copies per evaluation (see the module docstring).

    members: K >= 1. pose: standard deviation of each free tree's centre of mass x and y (m).
    angle: standard deviation of every angle coordinate (degrees). friction: half-width of the
    uniform relative change of every link's friction coefficients (0: unchanged). dt: half-width
    of the uniform relative change of each member's time step (0: unchanged; below 0.5). dt_factors:
    the members' factors on the time step, taken in turn, the first 1 (the unperturbed member
    0's), each in (0, 1]; with several, the score is the lowest group median (module docstring).
    Raises ValueError for values outside these ranges, or fewer members than step factors.
    """

    members: int = 8
    pose: float = 1e-3
    angle: float = 0.5
    friction: float = 0.0
    dt: float = 0.0
    dt_factors: tuple[float, ...] = (1.0,)

    def __post_init__(self):
        if not (isinstance(self.members, int) and self.members >= 1):
            raise ValueError(f"ensemble: members must be an integer >= 1, got {self.members!r}")
        fs = tuple(float(f) for f in self.dt_factors)
        object.__setattr__(self, "dt_factors", fs)
        if not fs or fs[0] != 1.0 or not all(0 < f <= 1 and math.isfinite(f) for f in fs):
            raise ValueError(f"ensemble: dt_factors must start with 1 and lie in (0, 1], got {list(fs)}")
        if len(set(fs)) != len(fs):
            raise ValueError(f"ensemble: dt_factors must differ from each other, got {list(fs)}")
        if self.members < len(fs):
            raise ValueError(f"ensemble: {len(fs)} step factors need at least as many members, got {self.members}")
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
        if len(self.dt_factors) > 1:
            out["dt_factors"] = list(self.dt_factors)
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any] | None) -> Ensemble:
        """The ensemble of a stored run; runs stored before ensembles existed were scored on one
        sample (``members=1``)."""
        if not d:
            return cls(members=1)
        return cls(int(d.get("members", 1)), float(d.get("pose", 1e-3)), float(d.get("angle", 0.5)),
                   float(d.get("friction", 0.0)), float(d.get("dt", 0.0)), tuple(d.get("dt_factors", (1.0,))))

    def groups(self) -> list[np.ndarray]:
        """The members of each step factor, in the order of ``dt_factors``: [array of member indices]."""
        G = len(self.dt_factors)
        return [np.arange(j, self.members, G) for j in range(G)]

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
