"""Many copies of one creature as a Gymnasium vector environment (``gymnasium.vector.VectorEnv``,
Gymnasium 1.x API), backed by the batched simulator.

    import gymnasium, sanlab.gym
    envs = gymnasium.make_vec("sanlab/Bounder-v0", num_envs=256, vectorization_mode="vector_entry_point")
    obs, info = envs.reset(seed=0)                                  # obs [256, S] int8
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())

Every sub-environment is exactly the single environment (``sanlab.gym.env``: the same spaces,
reward, termination and episode length; the same numbers bit for bit, sub-environment i
seeded ``seed + i`` as Gymnasium's ``SyncVectorEnv`` seeds it), but all of them advance in one
call of the simulator's kernel per step, in tiles of SIMD lanes spread over the cores (as a
rollout runs its batch, ``sanlab.sim.rollout``). A sub-environment's numbers depend neither on
the others, nor on ``num_envs``, nor on the number of threads.

Autoreset (``autoreset_mode``, https://farama.org/Vector-Autoreset-Mode): ``NEXT_STEP`` (the
default, Gymnasium's): the step after a sub-environment's episode ended resets it instead of
stepping it (its action is ignored; reward 0, not terminated, not truncated); ``SAME_STEP``: it
is reset in the step that ended it, that step's observation and info going to
``info["final_obs"]`` (an object array) and ``info["final_info"]``; ``DISABLED``: reset it
yourself with ``reset(options={"reset_mask": mask})`` (stepping it before raises RuntimeError).
``reset_mask`` works in every mode.

info (each key with its ``_key`` mask, as Gymnasium batches infos): ``score`` (the metric so
far), ``t`` (s since the episode's start), ``fell``, ``nonfinite``.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from sanlab.creature import Creature
from sanlab.gym._core import Core, Settings, check_width, resolve
from sanlab.gym.env import action_space, observation_space, observations


class SanlabVectorEnv(VectorEnv):
    """``num_envs`` copies of a sanlab creature (see the module docstring; every other keyword
    is the single environment's, ``sanlab.gym.env.SanlabEnv``).

    max_episode_steps: truncate after this many environment steps (default, and at most: the
    creature's evaluation time). autoreset_mode: an ``AutoresetMode`` or its value ("NextStep",
    "SameStep", "Disabled").

    Observations are batched as Gymnasium batches the single space (``batch_space``): [N, S]
    int8 bits, or a dict of [N, D] arrays; actions [N, A]. Raises ValueError as the single
    environment does, and for a bad ``num_envs``, ``max_episode_steps`` or ``autoreset_mode``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1000, "autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012 (gymnasium.Env declares it a plain class attribute; __init__ copies it)

    def __init__(self, num_envs: int = 1, creature: str | Creature | None = None, *, path: str | None = None,
                 metric: str | None = None, seconds: float | None = None, observation: str = "bits",
                 action: str = "target", frame_skip: int = 1, terminate_on_fall: bool = True,
                 reset_noise_scale: float = 0.0, dtype: str = "float64", overrides: dict | None = None,
                 max_episode_steps: int | None = None, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 render_mode: str | None = None, width: int = 640):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs: expected an integer >= 1, got {num_envs!r}")
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(f"autoreset_mode: expected one of {[m.value for m in AutoresetMode]}, got {autoreset_mode!r}") from None
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        width = check_width(width)
        spec = resolve(creature, path)
        settings = Settings(observation, action, frame_skip, bool(terminate_on_fall), reset_noise_scale)
        n = int(num_envs)
        self.core = Core(spec, settings, n, metric=metric, seconds=seconds, dtype=dtype, overrides=overrides)
        if self.core.unresolved:
            warnings.warn(f"creature {spec.name!r}: a servo is faster than dt = {self.core.dt:g} s resolves; "
                          "an evaluation scores it 0 (sanlab.evaluate.resolution)", stacklevel=2)
        self.max_episode_steps = self.core.max_steps
        if max_episode_steps is not None:
            if isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, (int, np.integer)) or max_episode_steps < 1:
                raise ValueError(f"max_episode_steps: expected an integer >= 1, got {max_episode_steps!r}")
            self.max_episode_steps = min(int(max_episode_steps), self.core.max_steps)
        self.num_envs = n
        self.autoreset_mode = mode
        self.single_observation_space = observation_space(self.core)
        self.single_action_space = action_space(self.core)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self.dt = self.core.dt * settings.frame_skip
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.dt, "autoreset_mode": mode}
        self.render_mode = render_mode
        self._renderer = None
        if render_mode == "rgb_array":
            from sanlab.gym._render import Renderer

            self._renderer = Renderer(self.core.model, width)
        self._out: np.ndarray | None = None
        self._score = np.zeros(n)
        self._steps = np.zeros(n, np.int64)
        self._ended = np.zeros(n, bool)
        self._rngs: list[np.random.Generator] | None = None
        self._u: np.ndarray | None = None
        self._trails: list[list[np.ndarray]] = [[] for _ in range(n)]

    # ---- reset ----------------------------------------------------------------------------

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every sub-environment, or those of ``options["reset_mask"]`` (a bool array
        [N]; the first reset resets all); sub-environment i is seeded ``seed + i`` (or
        ``seed[i]`` for a list). Returns the batched observations and info (``score``, ``t``,
        ``fell``, ``nonfinite``, masked to the reset ones). Raises ValueError for a bad seed or
        mask."""
        n = self.num_envs
        if isinstance(seed, (list, tuple)):
            if len(seed) != n:
                raise ValueError(f"seed: expected {n} seeds (one per sub-environment), got {len(seed)}")
            seeds = list(seed)
        elif seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(n)]
        else:
            raise ValueError(f"seed: expected an integer, a list of {n} or None, got {type(seed).__name__}")
        super().reset(seed=seeds[0])
        mask = np.ones(n, bool)
        if options and "reset_mask" in options and self._out is not None:  # the first reset starts them all
            mask = np.asarray(options["reset_mask"])
            if mask.shape != (n,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(f"options['reset_mask']: expected a bool array of shape ({n},) with a True, got "
                                 f"{mask.dtype} {mask.shape}")
        if self._rngs is None:
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        else:
            for i in np.flatnonzero(mask):
                if seeds[i] is not None:
                    self._rngs[i] = seeding.np_random(seeds[i])[0]
        out = self._restart(mask)
        self._u = None
        return self._obs(out), self._info(out, mask)

    def _restart(self, mask: np.ndarray) -> np.ndarray:
        """Restart the sub-environments where ``mask`` [N]; every row's packed observation. The
        padding rows (see ``sanlab.gym._core``) copy the last sub-environment: its start, its
        actions, so they never wander off into numbers of their own."""
        core = self.core
        n, rows = self.num_envs, core.rows
        assert self._rngs is not None
        q = np.repeat(core.q0[None], rows, 0).astype(core.dtype)
        seat = np.zeros(rows, bool)
        for i in np.flatnonzero(mask):
            q[i], seat[i] = core.start_q(self._rngs[i])
        q[n:], seat[n:] = q[n - 1], seat[n - 1]
        out = core.restart(np.concatenate([mask, np.full(rows - n, mask[-1])]), q, seat)
        self._out = out
        self._score[mask] = core.score(out[:n][mask])["score"]
        self._steps[mask] = 0
        self._ended[mask] = False
        if self._renderer is not None:
            com = core.com(out[:n])
            for i in np.flatnonzero(mask):
                self._trails[i] = [com[i]]
        return out

    # ---- step -----------------------------------------------------------------------------

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every sub-environment (``frame_skip`` simulator steps each) with ``actions``
        [N, A]; returns batched (observations, rewards [N] float64, terminated [N], truncated
        [N], info). Raises RuntimeError before ``reset`` (or, with ``DISABLED``, stepping an
        ended sub-environment), ValueError for an action outside the action space."""
        if self._out is None:
            raise RuntimeError("step() before reset(): call reset() first")
        core, n = self.core, self.num_envs
        u = core.activations(actions, n)
        renew = self._ended.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP else np.zeros(n, bool)
        if self.autoreset_mode == AutoresetMode.DISABLED and self._ended.any():
            i = int(np.flatnonzero(self._ended)[0])
            raise RuntimeError(f"sub-environment {i} ended and autoreset is disabled: reset it with "
                               "reset(options={'reset_mask': mask}) before stepping it")
        out = core.step(u)
        self._out = out
        if renew.any():
            out = self._restart(renew)
        self._u = u[:n]
        s = core.score(out[:n])
        score = s["score"]
        reward = np.where(renew, 0.0, score - self._score)
        self._score = score
        self._steps = np.where(renew, 0, self._steps + 1)
        fell, nonfinite = np.asarray(s["fell"]), np.asarray(s["nonfinite"])
        falls = fell if (core.settings.terminate_on_fall and core.metric.can_fall) else np.zeros(n, bool)
        terminated = ~renew & (nonfinite | falls)
        truncated = ~renew & ~terminated & (self._steps >= self.max_episode_steps)
        ended = terminated | truncated
        if self._renderer is not None:
            com = core.com(out[:n])
            for i in range(n):
                if not renew[i]:
                    self._trails[i].append(com[i])
        obs = self._obs(out)
        info = self._info(out, np.ones(n, bool), s)
        if self.autoreset_mode == AutoresetMode.SAME_STEP and ended.any():
            final = np.full(n, None, dtype=object)
            for i in np.flatnonzero(ended):
                final[i] = obs[i] if isinstance(obs, np.ndarray) else {k: v[i] for k, v in obs.items()}
            final_info = {k: (ended.copy() if k.startswith("_") else v.copy()) for k, v in info.items()}
            out = self._restart(ended)
            obs = self._obs(out)
            info = self._info(out, np.ones(n, bool))  # the restarted ones' from their reset, as SyncVectorEnv has it
            info.update(final_obs=final, _final_obs=ended.copy(), final_info=final_info, _final_info=ended.copy())
            self._ended[:] = False
        else:
            self._ended = ended
        return obs, reward, terminated, truncated, info

    # ---- outputs --------------------------------------------------------------------------

    def _obs(self, out: np.ndarray) -> Any:
        return observations(self.core, out[: self.num_envs])

    def _info(self, out: np.ndarray, mask: np.ndarray, s: dict | None = None) -> dict[str, Any]:
        """The batched info of the sub-environments where ``mask`` (``s``: their scores, if known)."""
        n = self.num_envs
        s = self.core.score(out[:n]) if s is None else s
        info: dict[str, Any] = {"score": np.where(mask, s["score"], 0.0), "t": np.where(mask, self._steps * self.dt, 0.0),
                                "fell": np.asarray(s["fell"]) & mask, "nonfinite": np.asarray(s["nonfinite"]) & mask}
        for k in list(info):
            info["_" + k] = mask.copy()
        return info

    def render(self) -> tuple[np.ndarray, ...] | None:
        """Every sub-environment's picture ([H, W, 3] uint8 each) with ``render_mode="rgb_array"``;
        None without a render mode. Raises RuntimeError before ``reset``."""
        if self._renderer is None:
            return None
        if self._out is None:
            raise RuntimeError("render() before reset(): call reset() first")
        q = self.core.q(self._out[: self.num_envs])
        u = self._u
        return tuple(self._renderer.frame(q[i], float(self._steps[i] * self.dt), None if u is None else u[i],
                                          np.asarray(self._trails[i])) for i in range(self.num_envs))

