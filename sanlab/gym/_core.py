"""What both environments share: one creature, a batch of rows stepped by the simulator
(``sanlab.sim.Rows``, on the rollouts' own kernel), and the metric scored on the host by
``sanlab.metrics.scores``, the function an evaluation is scored with.

A row is one copy of the creature. An environment step is one call of the kernel: ``frame_skip``
steps of every row with its activations held, the metric's accumulators carried along, then the
sensors of the new state. The kernel steps a row bit for bit the same alone or in any batch, and
continuing a run over several calls is the run in one call, so a controller driven through an
environment reproduces its evaluation's unperturbed member (``sanlab.evaluate.ensemble``: member
0) exactly (checked by ``tests/gym``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sanlab.creature import Creature, load
from sanlab.creature.spec import LinearActuator
from sanlab.evaluate.ensemble import Ensemble
from sanlab.evaluate.resolution import Servos
from sanlab.gait import check_params
from sanlab.metrics import Metric, MetricAcc, scores
from sanlab.sim.model import Model

OBSERVATIONS = ("bits", "state")
ACTIONS = ("target", "activation")


def check_width(width: Any) -> int:
    """A picture's ``width`` (px), an integer in render.film.WIDTH_RANGE ([64, 4096], as
    ``sanlab render --width``); raises ValueError naming it. Checked whether or not the
    environment renders, so that a wrong width never passes silently (0 and -5 once gave 64 px,
    100,000 grew the process to 18 GB)."""
    from sanlab.render.film import WIDTH_RANGE

    lo, hi = WIDTH_RANGE
    if isinstance(width, bool) or not isinstance(width, (int, np.integer)) or not lo <= width <= hi:
        raise ValueError(f"width: expected an integer in [{lo}, {hi}] (px), got {width!r}")
    return int(width)


def _floats(action: Any) -> np.ndarray:
    """``action`` as float64, an integer too large for a float (``10**400``) as +-inf (then
    refused as outside its range, naming its actuator). TypeError/ValueError as np.asarray."""
    try:
        return np.asarray(action, dtype=np.float64)
    except OverflowError:
        obj = np.asarray(action, dtype=object)

        def one(x: Any) -> float:
            try:
                return float(x)
            except OverflowError:
                return math.inf if x > 0 else -math.inf

        return np.vectorize(one, otypes=[np.float64])(obj) if obj.size else obj.astype(np.float64)


def _shown(action: Any, a: np.ndarray, r: int, k: int) -> str:
    """Value [r, k] of an action as given: an integer too large for a float by its magnitude."""
    if np.isinf(a[r, k]):
        x = np.asarray(action, dtype=object).reshape(a.shape)[r, k]
        if isinstance(x, (int, np.integer)) and not isinstance(x, bool):  # not a float: beyond one
            return f"an integer of about {'-' if x < 0 else ''}1e{int(abs(int(x)).bit_length() * math.log10(2))}"
    return repr(a[r, k])


def resolve(creature: str | Creature | None, path: str | None) -> Creature:
    """The creature an environment simulates: ``creature`` (a built-in name, a file path or a
    ``Creature``) or ``path`` (a creature file), exactly one of them. Raises ValueError when
    both or neither are given, ``sanlab.creature.CreatureError`` (a ValueError, one line
    naming the file) for an unknown name or a bad file."""
    if (creature is None) == (path is None):
        raise ValueError("give a creature (a built-in name, a .toml path or a Creature) or path= (a creature file), not both"
                         if creature is not None else "give path= (a creature file) or creature= (a built-in name)")
    if isinstance(creature, Creature):
        return creature
    src = path if path is not None else creature
    if not isinstance(src, str):
        raise ValueError(f"creature: expected a built-in name, a .toml path or a Creature, got {type(src).__name__}")
    return load(src)


@dataclass(frozen=True)
class Settings:
    """An environment's options (see ``sanlab.gym.env.SanlabEnv``), checked."""

    observation: str = "bits"
    action: str = "target"
    frame_skip: int = 1
    terminate_on_fall: bool = True
    reset_noise_scale: float = 0.0

    def __post_init__(self):
        if self.observation not in OBSERVATIONS:
            raise ValueError(f"observation: expected one of {list(OBSERVATIONS)}, got {self.observation!r}")
        if self.action not in ACTIONS:
            raise ValueError(f"action: expected one of {list(ACTIONS)}, got {self.action!r}")
        if isinstance(self.frame_skip, bool) or not isinstance(self.frame_skip, (int, np.integer)) or self.frame_skip < 1:
            raise ValueError(f"frame_skip: expected an integer >= 1, got {self.frame_skip!r}")
        if not (isinstance(self.reset_noise_scale, (int, float)) and not isinstance(self.reset_noise_scale, bool) and math.isfinite(self.reset_noise_scale)
                and self.reset_noise_scale >= 0):
            raise ValueError(f"reset_noise_scale: expected a number >= 0, got {self.reset_noise_scale!r}")
        object.__setattr__(self, "frame_skip", int(self.frame_skip))
        object.__setattr__(self, "reset_noise_scale", float(self.reset_noise_scale))


class Core:
    """``rows`` copies of ``spec`` stepped together by the simulator, scored by ``metric``
    (default: the creature file's) over ``seconds`` (default: the file's evaluation time).

    overrides: {``sanlab.sim.Params`` field: array}, e.g. a tuned gait's ``params.model``
    (``sanlab.gait.Gait.model``). Raises ValueError for a bad metric, duration, dtype or
    override (``sanlab.gait.check_params``), a creature without sensors or actuators, a
    duration shorter than one environment step."""

    def __init__(self, spec: Creature, settings: Settings, rows: int, *, metric: str | None = None,
                 seconds: float | None = None, dtype: str = "float64", overrides: dict | None = None):
        from sanlab import sim

        if dtype not in ("float32", "float64"):
            raise ValueError(f"dtype: expected float32 or float64, got {dtype!r}")
        if not spec.actuators:
            raise ValueError(f"creature {spec.name!r} has no actuators: nothing to act on")
        if not spec.sensors and settings.observation == "bits":
            raise ValueError(f"creature {spec.name!r} has no sensors: use observation='state'")
        self.spec = spec
        self.settings = settings
        self.metric = Metric.for_creature(spec, metric)
        if seconds is not None and (isinstance(seconds, bool) or not isinstance(seconds, (int, float))
                                    or not math.isfinite(seconds) or seconds <= 0):
            raise ValueError(f"seconds: expected a duration > 0 (s), got {seconds!r}")
        self.seconds = float(spec.evaluation.seconds if seconds is None else seconds)
        if overrides:
            check_params(spec, {"model": overrides})  # one line naming a bad field, as for a stored gait
        model = sim.compile_creature(spec, dtype)
        if overrides:
            # as Gait.model applies a stored gait's overrides
            model = model.with_params(**{k: np.asarray(v, model.dtype) for k, v in overrides.items()})
        self.model: Model = model
        self.dtype = np.dtype(np.float64)  # the kernel's arithmetic, whatever the model's numbers
        self.dt = float(model.structure.dt)  # s, the simulator's step
        self.sim_steps = int(round(self.seconds / self.dt))  # what a rollout of this duration runs (sanlab.sim.rollout)
        self.max_steps = self.sim_steps // settings.frame_skip
        if self.max_steps < 1:
            raise ValueError(f"seconds: {self.seconds:g} s is shorter than one environment step "
                             f"({settings.frame_skip} x {self.dt:g} s)")
        st = model.structure
        self.n_sensors, self.n_actuators, self.ndof = len(spec.sensors), len(spec.actuators), st.ndof
        self.act_min = np.asarray(model.params.act_min, np.float64)
        self.act_max = np.asarray(model.params.act_max, np.float64)
        self.act_names = [a.name for a in spec.actuators]
        self.act_units = ["m" if isinstance(a, LinearActuator) else "rad" for a in spec.actuators]
        self.unresolved = bool(Servos.of(spec).unresolved(np.asarray(model.params.act_ks), np.asarray(model.params.act_kd), self.dt))
        self.q0 = np.asarray(model.params.q0, np.float64)
        self.rows = int(rows)
        if self.rows < 1:
            raise ValueError(f"rows: expected >= 1, got {rows}")
        self._seat = st.plane == "vertical" and bool(st.contacts)
        # each row's state and the metric's accumulators, carried between calls
        self._rows = sim.Rows(model, self.rows, observe=self.metric.observe())

    # ---- spaces' numbers, and actions -----------------------------------------------------

    def activations(self, action: Any, n: int) -> np.ndarray:
        """Actions [n, A] (targets in the actuators' units, or activations in [0, 1]) ->
        activations [rows, A] in the model's dtype, the padding rows copying the last real one.
        Raises ValueError naming the first actuator whose value is outside its range (or not a
        number), or a wrong shape."""
        A = self.n_actuators
        try:
            a = _floats(action)
        except (TypeError, ValueError):
            raise ValueError(f"action: expected {A} numbers per environment, got {type(action).__name__}") from None
        if n == 1 and a.shape == (A,):
            a = a[None]
        if a.shape != (n, A):
            raise ValueError(f"action: expected shape {(A,) if n == 1 else (n, A)} ({A} actuators), got {a.shape}")
        lo, hi = (self.act_min, self.act_max) if self.settings.action == "target" else (np.zeros(A), np.ones(A))
        # a bound rounded to float32 (a float32 policy clipped to the Box) may lie a rounding past it
        tol = np.maximum(np.abs(lo), np.abs(hi)) * 2.0**-23
        bad = ~(np.isfinite(a) & (a >= lo - tol) & (a <= hi + tol))
        if bad.any():
            r, k = np.argwhere(bad)[0]
            unit = self.act_units[k] if self.settings.action == "target" else "activation"
            where = f"action[{r}, {k}]" if n > 1 else f"action[{k}]"
            got = _shown(action, a, r, k)
            raise ValueError(f"{where} (actuator {self.act_names[k]!r}): {got} is outside its range "
                             f"[{lo[k]:.9g}, {hi[k]:.9g}] {unit}")
        a = np.clip(a, lo, hi)
        if self.settings.action == "target":
            # float64 throughout, so that any float32 activation (a SAN's) survives the trip to a
            # target and back exactly, and the step sees the activation the controller gave
            a = (a - self.act_min) / (self.act_max - self.act_min)
        u = np.clip(a, 0.0, 1.0).astype(self.dtype)
        if n < self.rows:
            u = np.concatenate([u, np.repeat(u[-1:], self.rows - n, axis=0)])
        return u

    def targets(self, u: Any) -> np.ndarray:
        """Activations u [..., A] in [0, 1] -> the actions of this environment's action space
        (targets in the actuators' units, float64; or u itself)."""
        u = np.asarray(u, np.float64)
        if self.settings.action == "activation":
            return u
        return self.act_min + u * (self.act_max - self.act_min)

    # ---- starts ---------------------------------------------------------------------------

    def start_q(self, rng: np.random.Generator | None) -> tuple[np.ndarray, bool]:
        """(start coordinates [D], re-seat on the ground): the creature file's start, or with
        ``reset_noise_scale`` s > 0 a start drawn as one perturbed member of the robust ensemble
        (``sanlab.evaluate.ensemble``: each free tree's COM moved by N(0, s mm), every angle by
        N(0, 0.5 s deg), clipped at 3 sigma), its key drawn from ``rng``."""
        s = self.settings.reset_noise_scale
        if s == 0 or rng is None:
            return self.q0.copy(), False
        key = tuple(int(k) for k in rng.integers(0, 2**62, 2))
        dq, _ = Ensemble(members=2, pose=1e-3 * s, angle=0.5 * s).draws(self.model.structure, key, len(self.spec.links))
        return (self.q0.astype(np.float64) + dq[1]).astype(self.dtype), self._seat

    # ---- the simulator's calls ------------------------------------------------------------

    def restart(self, mask: np.ndarray, q: np.ndarray, seat: np.ndarray) -> np.ndarray:
        """Start the rows where ``mask`` [rows] from coordinates q [rows, D] (re-seated on the
        ground where ``seat``), at rest, their metric restarted; every row's packed
        observation [rows, K] comes back."""
        self._rows.restart(mask, q, np.asarray(seat, bool) & self._seat)
        return self._pack()

    def step(self, u: np.ndarray) -> np.ndarray:
        """Every row ``frame_skip`` simulator steps on with activations u [rows, A]; their packed
        observations [rows, K] come back."""
        self._rows.step(u, self.settings.frame_skip)
        return self._pack()

    def _pack(self) -> np.ndarray:
        """Every row's packed observation: bits [S], q [D], qd [D] (M^-1 p of this state), then
        the metric's numbers and whether the state is finite (as a rollout's end judges it)."""
        r = self._rows
        finite = r.finite()
        a = r.columns()
        tail = np.stack([a["p0x"], a["p0y"], a["y0"], a["hop"], a["pursuit"], a["fell"], a["px"], a["py"],
                         np.maximum(a["deepest"], 0.0), finite.astype(np.float64),
                         a["gap"] / np.maximum(a["steps"], 1.0), a["gap0"]], 1)
        return np.concatenate([r.bits(), r.q, r.qd, tail], 1)

    # ---- unpacking on the host ------------------------------------------------------------

    def bits(self, out: np.ndarray) -> np.ndarray:
        return out[:, : self.n_sensors].astype(np.int8)

    def q(self, out: np.ndarray) -> np.ndarray:
        return out[:, self.n_sensors : self.n_sensors + self.ndof]

    def qd(self, out: np.ndarray) -> np.ndarray:
        return out[:, self.n_sensors + self.ndof : self.n_sensors + 2 * self.ndof]

    def com(self, out: np.ndarray) -> np.ndarray:
        """The centre of mass (x, y) [rows, 2] of each row's current state (m)."""
        k = self.n_sensors + 2 * self.ndof
        return out[:, k + 6 : k + 8].astype(np.float64)

    def score(self, out: np.ndarray) -> dict[str, np.ndarray]:
        """``sanlab.metrics.scores`` of each row's episode so far: what an evaluation ending at
        this state would score (the same float32 arithmetic on the same numbers)."""
        a = out[:, self.n_sensors + 2 * self.ndof :]
        acc = MetricAcc._make([(a[:, 0], a[:, 1]), a[:, 2], a[:, 3], a[:, 4], a[:, 5] > 0, (a[:, 6], a[:, 7]), a[:, 8],
                               a[:, 10], a[:, 11]])
        return scores(self.metric, acc, a[:, 9] > 0, self.seconds, self.spec.world.plane)
