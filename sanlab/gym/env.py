"""One sanlab creature as a Gymnasium environment (``gymnasium.Env``, Gymnasium 1.x API).

    import gymnasium, sanlab.gym
    env = gymnasium.make("sanlab/Bounder-v0")                     # a built-in creature
    env = gymnasium.make("sanlab/Creature-v0", path="my.toml")    # any creature file
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

One environment step is ``frame_skip`` (default 1) steps of the simulator, each of the
creature's ``dt`` (1 ms for every built-in): ``env.unwrapped.dt`` seconds. The paper's SANs run
every simulator step (§4), so ``frame_skip=1`` is the environment a SAN is evaluated in.

- observation: the binary sensor values, ``MultiBinary(S)`` (int8, in the creature file's
  order; paper §3 "sensors"); with ``observation="state"`` a ``Dict`` of ``bits`` (the same),
  ``q`` and ``qd`` (``Box`` [D] of the generalised coordinates, m and rad, and velocities, m/s
  and rad/s, of ``sanlab.sim``'s state: per free tree its centre of mass and root angle, then
  one relative angle per joint; non-finite values of a blown-up state are reported as 0).
- action: each actuator's target, ``Box(min, max)`` in the actuator's units (rad for a joint's
  servo angle, m for a linear actuator's length; float64, so that any float32 activation, such
  as a SAN's, goes to a target and back exactly); with ``action="activation"`` the
  activation u in [0, 1] the simulator takes (target = min + u (max - min)). An action outside
  its range raises ValueError naming the actuator.
- reward: the increment of the creature's metric (``sanlab.metrics``, paper §5.1) over the
  step, so that an episode's return is the score an evaluation of the same length gives: the
  running score is ``sanlab.metrics.scores`` of the metric's accumulator on the host (the
  function an evaluation is scored with) and the rewards are its float64 differences, whose
  sums telescope exactly. ``info["score"]`` is that running score.
- terminated: the creature's fall test (``[evaluation]`` fell_link / fell_com_height in its
  file) judged as the metric judges it, on the states the steps start from (so the last state of
  an episode, like a rollout's, is never judged), when ``terminate_on_fall``; and always a
  simulation that blew up or sank into the ground (``info["nonfinite"]``), which scores 0.
  Under ``distance_upright`` and ``hopping`` a fall scores 0, so that step's reward takes back
  everything earned.
- truncated: after the creature's evaluation time (``seconds``, default the file's ``[evaluation]
  seconds``): ``round(seconds / dt) // frame_skip`` environment steps.
- reset: the creature at rest in its start pose (the robust ensemble's unperturbed member 0,
  docs/robust-objective.md); with ``reset_noise_scale`` s > 0 a start perturbed like one of the
  ensemble's other members (COM by N(0, s mm), angles by N(0, 0.5 s deg)), drawn from the
  environment's ``np_random``.
- render: ``render_mode="rgb_array"`` draws the current state with sanlab's renderer
  (``sanlab.render``): an [H, W, 3] uint8 picture, ``width`` x ``width * 9 / 16`` pixels.

Source: Gymnasium's ``Env`` API (https://gymnasium.farama.org/api/env/); the spaces follow its
MuJoCo environments' conventions (``frame_skip``, ``reset_noise_scale``, ``width``).
"""

from __future__ import annotations

import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sanlab.creature import Creature
from sanlab.gym._core import Core, Settings, check_width, resolve


def observation_space(core: Core) -> spaces.Space:
    """The single environment's observation space (see the module docstring)."""
    bits = spaces.MultiBinary(core.n_sensors) if core.n_sensors else None
    if core.settings.observation == "bits":
        assert bits is not None
        return bits
    D = core.ndof
    box = lambda: spaces.Box(-np.inf, np.inf, (D,), core.dtype)
    parts: dict[str, spaces.Space] = {"q": box(), "qd": box()}
    if bits is not None:
        parts["bits"] = bits
    return spaces.Dict(parts)


def action_space(core: Core) -> spaces.Box:
    """The single environment's action space (see the module docstring)."""
    if core.settings.action == "activation":
        return spaces.Box(0.0, 1.0, (core.n_actuators,), core.dtype)
    return spaces.Box(core.act_min.copy(), core.act_max.copy(), (core.n_actuators,), np.float64)


def observations(core: Core, out: np.ndarray) -> Any:
    """Observations of packed rows ``out`` [n, K] (each row's, batched as the vector
    environment's space batches them)."""
    bits = core.bits(out)
    if core.settings.observation == "bits":
        return bits
    q, qd = core.q(out), core.qd(out)
    if not (np.isfinite(q).all() and np.isfinite(qd).all()):
        q, qd = np.nan_to_num(q, nan=0.0, posinf=0.0, neginf=0.0), np.nan_to_num(qd, nan=0.0, posinf=0.0, neginf=0.0)
    obs = {"q": q.copy(), "qd": qd.copy()}
    if core.n_sensors:
        obs["bits"] = bits
    return obs


class SanlabEnv(gym.Env):
    """A sanlab creature as a Gymnasium environment (see the module docstring for the spaces,
    reward and episode).

    creature: a built-in name ("bounder"), a creature file's path, or a ``Creature``; or
    path: a creature file (exactly one of the two). metric: the score (a name of
    ``sanlab.creature.spec.METRICS``; default the file's). seconds: the episode's simulated time
    (default the file's evaluation time). observation: "bits" or "state". action: "target" or
    "activation". frame_skip: simulator steps per environment step. terminate_on_fall: end the
    episode when the fall test says so. reset_noise_scale: the start's perturbation (0: exact).
    dtype: the simulation's arithmetic, "float32" or "float64" (sim.compile_creature). overrides: {``sanlab.sim.Params`` field:
    array}, e.g. a tuned gait's ``params.model``. render_mode: None or "rgb_array"; width: its
    picture's width (px), an integer in [64, 4096] (checked even when nothing is rendered).

    Raises ``sanlab.creature.CreatureError`` (a ValueError) for an unknown creature or a bad
    file, ValueError for any other bad option (each one line naming it). Warns when the
    creature's servos are too fast for its time step (an evaluation then scores 0:
    ``sanlab.evaluate.resolution``).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1000}  # noqa: RUF012 (gymnasium.Env declares it a plain class attribute; __init__ copies it)

    def __init__(self, creature: str | Creature | None = None, *, path: str | None = None, metric: str | None = None,
                 seconds: float | None = None, observation: str = "bits", action: str = "target", frame_skip: int = 1,
                 terminate_on_fall: bool = True, reset_noise_scale: float = 0.0, dtype: str = "float64",
                 overrides: dict | None = None, render_mode: str | None = None, width: int = 640):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        width = check_width(width)
        spec = resolve(creature, path)
        settings = Settings(observation, action, frame_skip, bool(terminate_on_fall), reset_noise_scale)
        self.core = Core(spec, settings, 1, metric=metric, seconds=seconds, dtype=dtype, overrides=overrides)
        if self.core.unresolved:
            warnings.warn(f"creature {spec.name!r}: a servo is faster than dt = {self.core.dt:g} s resolves; "
                          "an evaluation scores it 0 (sanlab.evaluate.resolution)", stacklevel=2)
        self.observation_space = observation_space(self.core)
        self.action_space = action_space(self.core)
        self.dt = self.core.dt * settings.frame_skip
        self.max_episode_steps = self.core.max_steps
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.dt}
        self.render_mode = render_mode
        self._renderer = None
        if render_mode == "rgb_array":
            from sanlab.gym._render import Renderer

            self._renderer = Renderer(self.core.model, width)
        self._out: np.ndarray | None = None
        self._score = 0.0
        self._steps = 0
        self._done = False
        self._u: np.ndarray | None = None
        self._trail: list[np.ndarray] = []

    @property
    def creature(self) -> Creature:
        """The creature this environment simulates."""
        return self.core.spec

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Start an episode (Gymnasium ``Env.reset``): the observation of the start and an info
        dict (``score`` 0, ``t`` 0 s). ``options`` is accepted and unused."""
        super().reset(seed=seed, options=options)
        q, seat = self.core.start_q(self.np_random)
        rows = self.core.rows
        out = self.core.restart(np.ones(rows, bool), np.repeat(q[None], rows, 0), np.full(rows, seat))
        self._out = out
        self._score = float(self.core.score(out[:1])["score"][0])
        self._steps = 0
        self._done = False
        self._u = None
        self._trail = [self.core.com(out[:1])[0]] if self._renderer is not None else []
        return self._obs(out), {"score": self._score, "t": 0.0}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """One environment step (Gymnasium ``Env.step``): ``frame_skip`` simulator steps with the
        actuators driven towards ``action``. Returns (observation, reward, terminated, truncated,
        info); info: ``score`` (the metric so far), ``t`` (s), ``fell``, ``nonfinite``. Raises
        RuntimeError before ``reset`` or after the episode ended, ValueError for an action
        outside the action space."""
        if self._out is None:
            raise RuntimeError("step() before reset(): call reset() first")
        if self._done:
            raise RuntimeError("step() after the episode ended (terminated or truncated): call reset()")
        u = self.core.activations(action, 1)
        out = self.core.step(u)
        self._out = out
        self._u = u[0]
        s = self.core.score(out[:1])
        score = float(s["score"][0])
        reward = score - self._score
        self._score = score
        self._steps += 1
        nonfinite = bool(s["nonfinite"][0])
        fell = bool(s["fell"][0])
        terminated = nonfinite or (fell and self.core.settings.terminate_on_fall and self.core.metric.can_fall)
        truncated = not terminated and self._steps >= self.core.max_steps
        self._done = terminated or truncated
        if self._renderer is not None:
            self._trail.append(self.core.com(out[:1])[0])
        info = {"score": score, "t": self._steps * self.dt, "fell": fell, "nonfinite": nonfinite}
        return self._obs(out), reward, terminated, truncated, info

    def _obs(self, out: np.ndarray) -> Any:
        obs = observations(self.core, out[:1])
        return obs[0] if isinstance(obs, np.ndarray) else {k: v[0] for k, v in obs.items()}

    def render(self) -> np.ndarray | None:
        """The current state's picture [H, W, 3] uint8 with ``render_mode="rgb_array"`` (None
        without a render mode, as Gymnasium asks). Raises RuntimeError before ``reset``."""
        if self._renderer is None:
            return None
        if self._out is None:
            raise RuntimeError("render() before reset(): call reset() first")
        q = self.core.q(self._out[:1])[0]
        return self._renderer.frame(q, self._steps * self.dt, self._u, np.asarray(self._trail))
