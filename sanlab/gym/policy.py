"""A sensor-actuator network as a policy for the environments: observation bits in, actuator
targets out, through the project's own SAN (``sanlab.san.San``, paper §4 and Figure 7).

    from sanlab.gait import Gait
    from sanlab.gym import SanPolicy, gait_env_kwargs
    gait = Gait.from_library(lib, "3fa1c2d0/1")
    env = gymnasium.make("sanlab/Creature-v0", **gait_env_kwargs(gait))
    policy = SanPolicy.from_gaits(env, [gait])
    obs, _ = env.reset(); policy.reset(); ret, done = 0.0, False
    while not done:
        obs, r, term, trunc, _ = env.step(policy(obs)); ret += r; done = term or trunc
    # ret == the gait's unperturbed evaluation (its ensemble's member 0), float for float

One call is one SAN step of the environment's step time (``env.unwrapped.dt``): with
``frame_skip=1`` exactly what a rollout does every simulator step, in the kernel's float64
arithmetic (``sanlab/sim/_kernel/step.h``, ``san``: the integer sums are exact, and the
integrator's update is the same two roundings), so bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sanlab.gym._core import Core
from sanlab.san import San, SanParams


def gait_env_kwargs(gait: Any) -> dict[str, Any]:
    """The environment keywords that reproduce a stored gait's evaluation (``sanlab.gait.Gait``):
    its creature as stored with its run, its run's evaluation time and metric, and a tuned
    gait's model overrides."""
    kw: dict[str, Any] = {"creature": gait.spec, "seconds": float(gait.seconds), "metric": gait.metric}
    if gait.params.model:
        kw["overrides"] = dict(gait.params.model)
    return kw


def _core_of(env: Any) -> Core:
    core = getattr(getattr(env, "unwrapped", env), "core", None)
    if not isinstance(core, Core):
        raise ValueError(f"env: expected a sanlab.gym environment (or a wrapper of one), got {type(env).__name__}")
    return core


class SanPolicy:
    """N SANs driving N environments (N = 1 for a single environment, ``num_envs`` for a vector
    one): ``policy(obs)`` -> actions [A] (one network) or [N, A], in the environment's action
    space.

    env: the environment (a wrapper is unwrapped). san: the networks' topology. params:
    ``SanParams`` with a leading axis of N (weights [N, H + A, S + H + A], rates k1, k2
    [N, H + A] in 1/s). Raises ValueError when the topology is not the creature's."""

    def __init__(self, env: Any, san: San, params: SanParams):
        core = _core_of(env)
        mine = San.for_creature(core.spec)
        if (san.n_sensors, san.n_hidden, san.n_actuators) != (mine.n_sensors, mine.n_hidden, mine.n_actuators):
            raise ValueError(f"san: sensors/hidden/actuators {(san.n_sensors, san.n_hidden, san.n_actuators)} do not match "
                             f"creature {core.spec.name!r}'s {(mine.n_sensors, mine.n_hidden, mine.n_actuators)}")
        w = np.asarray(params.weights)
        if w.ndim != 3:
            raise ValueError(f"params: expected weights [N, {san.n_nodes}, {san.n_inputs}], got shape {w.shape}")
        self.core, self.san, self.n = core, san, int(w.shape[0])
        self._w = w.astype(np.float64)
        self._k1, self._k2 = (np.asarray(x, np.float64) for x in (params.k1, params.k2))
        # the environment step's time: the simulator's step times frame_skip
        self._dt = float(np.asarray(core.model.params.dt, np.float64)) * core.settings.frame_skip
        self._istate = np.zeros((self.n, san.n_nodes))
        self._out = np.zeros((self.n, san.n_nodes))

    @classmethod
    def from_gaits(cls, env: Any, gaits: list) -> SanPolicy:
        """The SANs of stored gaits (``sanlab.gait.Gait``), one per environment: their weights
        and rates (a phase-1 gait's delays, or a tuned gait's per-node rates). Raises ValueError
        when a gait's creature is not the environment's (its links, sensors, actuators, world or
        dt differ)."""
        core = _core_of(env)
        body = lambda s: (s.links, s.sensors, s.actuators, s.springs, s.world, s.dt)
        for g in gaits:
            if body(g.spec) != body(core.spec):
                raise ValueError(f"gait {g.gait_id}: its creature {g.spec.name!r} is not the one this environment simulates "
                                 f"({core.spec.name!r}); make the environment with gait_env_kwargs(gait)")
        ps = [g.san_params() for g in gaits]
        params = SanParams(*(np.concatenate([np.asarray(getattr(p, f)) for p in ps]) for f in SanParams._fields))
        return cls(env, gaits[0].san, params)

    def reset(self, mask: Any = None) -> None:
        """Start the networks over (all, or those where ``mask`` [N] is true): istate and outputs
        0, as at the start of a rollout. Call it with the environment's reset."""
        m = np.ones(self.n, bool) if mask is None else np.asarray(mask, bool).reshape(self.n)
        self._istate[m] = 0.0
        self._out[m] = 0.0

    @property
    def outputs(self) -> np.ndarray:
        """The nodes' binary outputs [N, H + A] (hidden nodes first) after the last call."""
        return self._out.copy()

    def activations(self, obs: Any) -> np.ndarray:
        """One SAN step on the observation(s) ``obs`` (bits [S] or [N, S], or the ``state``
        observation's dict): activations u [N, A] in [0, 1]."""
        bits = obs["bits"] if isinstance(obs, dict) else obs
        b = np.asarray(bits).reshape(self.n, self.san.n_sensors).astype(np.float64)
        self._istate, self._out, u = self.san.step(SanParams(self._w, self._k1, self._k2), self._istate, self._out, b,
                                                   self._dt)
        return u

    def __call__(self, obs: Any) -> np.ndarray:
        """Actions for ``obs`` in the environment's action space: [A] for one network, else [N, A]."""
        a = self.core.targets(self.activations(obs))
        return a[0] if self.n == 1 and np.ndim(obs["bits"] if isinstance(obs, dict) else obs) == 1 else a
