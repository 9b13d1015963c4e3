"""Closed-loop rollouts on the kernel: many controllers, one creature, K steps in one call.

Each step senses, runs the controller, observes and integrates, inside the compiled kernel
(:mod:`sanlab.sim.kernel`) that reads the creature as data: no creature is ever compiled, and a
batch of any size runs in tiles of SIMD lanes spread over the cores.

A controller is one of the kinds the kernel runs, named by its ``kind``:

- ``"san"``: a sensor-actuator network (``sanlab.san.San``; params a ``SanParams`` with weights
  [B, N, I] integers in [-2, 2], k1, k2 [B, N] in 1/s);
- ``"hold"``: :class:`ConstantController`, activations [B, A] held;
- ``"sine"``: :class:`SineController`, params [B, A + 1] (phases in rad, then f in Hz);
- ``"reflex"``: :class:`ReflexController`, params (W [B, A, S], b [B, A]);
- ``"pattern"``: :class:`PatternController`, params [B, 4 A + 1] (per actuator phase, duty, low
  and high level, then the period in s): an open-loop square wave per actuator.

An observer asks the kernel for accumulators and turns them into its own (``sanlab.metrics.Metric``
and ``sanlab.descriptors.Descriptors`` are observers):

    observe() -> kernel.Observe            # what to accumulate along the way
    collect(columns: dict) -> acc          # the accumulator from the kernel's named columns

A :class:`Result`'s arrays are NumPy float64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

import numpy as np

from sanlab.sim import kernel
from sanlab.sim.model import Model
from sanlab.sim.state import State, first_row, packed, row_tables


class Controller(Protocol):
    """What :func:`rollout` runs: a controller of one of the kernel's kinds (module docstring)."""

    kind: str


class Observer(Protocol):
    """What :func:`rollout` accumulates along the way (module docstring)."""

    def observe(self, /) -> kernel.Observe:
        """The kernel's accumulators this observer needs."""
        ...

    def collect(self, columns: dict, /) -> Any:
        """Its accumulator from the kernel's columns ({name of ``kernel.ACC``: [B]}, "duty"
        [B, touch sensors], "words", "times" [B, EVENTS])."""
        ...


class Frames(NamedTuple):
    """Recorded trajectory, one row per frame (batch axis first)."""

    t: Any  # [F] s, from the rollout's start
    q: Any  # [B, F, D] the state before the frame's step
    qd: Any  # [B, F, D] its velocity
    bits: Any  # [B, F, S] sensor values
    u: Any  # [B, F, A] actuator activations that step took
    cstate: Any  # the controller's state before the step: SanState of [B, F, N] for a SAN, else t [B, F]


class Result(NamedTuple):
    """Outcome of a rollout (batch axis first; NumPy float64)."""

    state: State  # final state
    acc: Any  # observer accumulator (None without observer)
    max_depth: Any  # [B] largest ground penetration over the run (m)
    finite: Any  # [B] bool: the state stayed finite and bounded
    frames: Frames | None
    cstate: Any = None  # final controller state (pass it back as ``cstate0`` to continue a run)


VELOCITY_LIMIT = 1e4  # |qd| beyond this (m/s, rad/s) counts as blown up


def stayed_finite(q: Any, qd: Any, p: Any, t: Any) -> np.ndarray:
    """[B] bool: each row's state q, qd, p [B, D] and time t [B] finite, and no speed past
    :data:`VELOCITY_LIMIT` (a run that blew up is flagged, never fatal)."""
    return (np.isfinite(q).all(1) & (np.abs(qd) < VELOCITY_LIMIT).all(1) & np.isfinite(p).all(1)
            & np.isfinite(t))


def devices() -> list[str]:
    """What a batch is spread over: the CPU's cores (one OpenMP thread per core)."""
    import os

    return ["cpu"] * (os.cpu_count() or 1)


def rollout(
    model: Model,
    controller: Controller,
    cparams: Any,
    seconds: float | None = None,
    *,
    steps: int | None = None,
    record_fps: float | None = None,
    observer: Observer | None = None,
    state0: State | None = None,
    cstate0: Any = None,
    params_batched: bool = False,
) -> Result:
    """Roll out a batch of controllers on ``model`` on the kernel.

    cparams: controller parameters with a leading batch axis [B, ...] (see the module docstring).
    seconds / steps: duration (one of them). record_fps: record frames at this rate (None: no
    recording); a frame every round(1 / (record_fps dt)) steps from the first, whole frames only.
    state0: initial state (default: the creature's pose at rest), unbatched or [B, ...]; its
    time must be one for the batch. cstate0: the controller's state to go on from (a SAN's
    ``SanState``; default: at rest). params_batched: model.params leaves carry the batch axis
    too (tuning, ensembles, designs: each row its own numbers).

    Returns a :class:`Result` of NumPy arrays. A controller's result is bit for bit the same
    alone or anywhere in any batch, on any number of threads. Raises ValueError for a duration
    that is negative, not finite or not a whole number of steps in [0, 2**63 - 1], a record_fps that is negative or not finite, neither seconds nor steps, a
    controller of no kind the kernel runs, or parameters of the wrong shape.
    """
    one = first_row(model) if params_batched else model
    dt = float(model.structure.dt)
    if steps is None:
        if seconds is None:
            raise ValueError("give seconds or steps")
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(seconds) and 0 <= seconds / dt <= kernel.COUNT_MAX):
            raise ValueError(f"seconds: expected a duration >= 0 of at most 2**63 - 1 steps of dt = {dt:g} s, "
                             f"got {seconds!r}")
        steps = int(round(seconds / dt))
    steps = kernel.check_count("steps", steps)
    if record_fps is not None and not (math.isfinite(record_fps) and record_fps >= 0):
        raise ValueError(f"record_fps: expected a finite rate >= 0 (frames per second), got {record_fps}")
    every = 0
    if record_fps:
        spacing = 1.0 / (record_fps * dt) if record_fps * dt > 0 else math.inf
        every = steps + 1 if spacing >= steps + 1 else max(1, int(round(spacing)))
    kind = getattr(controller, "kind", None)
    if kind not in kernel.KINDS:
        raise ValueError(f"controller: expected one of the kernel's kinds ({', '.join(kernel.KINDS)}), got {controller!r}")
    hidden = int(controller.n_hidden) if kind == "san" else 0  # type: ignore[attr-defined]
    pk = packed(one, hidden)
    B = _batch(kind, cparams)
    if B < 1:
        raise ValueError("cparams: expected at least one controller (a leading batch axis of B >= 1)")
    rows = row_tables(model, B) if params_batched else None
    if state0 is None:
        q0 = np.broadcast_to(np.asarray(model.params.q0, np.float64), (B, pk.ndof))
        q, anchor = kernel.start(pk, q0, seat=False, rows=rows)
        p, t0 = np.zeros_like(q), 0.0
    else:
        def given(name: str, x: Any, shape: tuple) -> np.ndarray:
            a = np.asarray(x, np.float64)
            if a.shape not in (shape, (B, *shape)):
                raise ValueError(f"state0.{name}: expected shape {shape} or {(B, *shape)}, got {a.shape}")
            return np.broadcast_to(a, (B, *shape))

        q, p = given("q", state0.q, (pk.ndof,)), given("p", state0.p, (pk.ndof,))
        anchor = given("anchor", state0.anchor, (pk.ci.shape[0], 2))
        times = np.unique(np.asarray(state0.t, np.float64))
        if len(times) > 1:
            raise ValueError(f"state0: expected one time for the whole batch, got {len(times)} different times")
        t0 = float(times[0]) if len(times) else 0.0
    ob = observer.observe() if observer is not None else None
    if kind == "san":
        N = controller.n_hidden + pk.ai.shape[0]  # type: ignore[attr-defined]
        if cstate0 is None:
            istate = out = np.zeros((B, N))
        else:
            istate = np.broadcast_to(np.asarray(cstate0.istate, np.float64), (B, N))
            out = np.broadcast_to(np.asarray(cstate0.out, np.float64), (B, N))
        r = kernel.run_san(pk, np.asarray(cparams.weights), np.asarray(cparams.k1, np.float64),
                           np.asarray(cparams.k2, np.float64), q, p, anchor, istate, out, steps, t0=t0, rows=rows,
                           observe=ob, every=every)
    else:
        params = cparams if kind == "reflex" else np.asarray(cparams, np.float64)
        r = kernel.run_open(pk, kind, params, q, p, anchor, steps, t0=t0, rows=rows, observe=ob, every=every)
    state = State(q=r["q"], qd=r["qd"], t=r["t"], p=r["p"], anchor=r["anchor"])
    finite = stayed_finite(r["q"], r["qd"], r["p"], r["t"])
    acc = observer.collect(columns(r["acc"], ob)) if observer is not None and ob is not None else None
    cstate = _san_state(r["istate"], r["out"]) if kind == "san" else r["t"]
    frames = None
    if every:
        n = r["frames_q"].shape[1]
        ft = np.arange(n) * every * dt
        if kind == "san":
            fc = _san_state(r["frames_istate"], r["frames_out"])
        else:
            fc = t0 + np.broadcast_to(ft, (B, n))
        frames = Frames(ft, r["frames_q"], r["frames_qd"], r["frames_bits"], r["frames_u"], fc)
    return Result(state, acc, np.maximum(r["dmax"], 0.0), finite, frames, cstate)


def _batch(kind: str, cparams: Any) -> int:
    if kind == "san":
        return int(np.shape(cparams.weights)[0])
    if kind == "reflex":
        return int(np.shape(cparams[1])[0])
    return int(np.shape(cparams)[0])


def _san_state(istate: np.ndarray, out: np.ndarray):
    from sanlab.sim.state import SanState

    return SanState(istate, out)


def columns(acc: np.ndarray, ob: kernel.Observe) -> dict[str, np.ndarray]:
    """The kernel's accumulators acc [B, ob.size] by name: each of ``kernel.ACC`` [B], "duty"
    [B, touch sensors], "words" and "times" [B, EVENTS]."""
    n = len(kernel.ACC)
    out = {name: acc[:, i] for i, name in enumerate(kernel.ACC)}
    k = len(ob.touch)
    out["duty"] = acc[:, n:n + k]
    out["words"] = acc[:, n + k:n + k + kernel.EVENTS]
    out["times"] = acc[:, n + k + kernel.EVENTS:n + k + 2 * kernel.EVENTS]
    return out


# ------------------------------------------------------------- simple controllers (tests, demos)


@dataclass(frozen=True)
class ConstantController:
    """Holds every actuator at activations ``params`` [B, A] in [0, 1] (open loop)."""

    kind = "hold"


@dataclass(frozen=True)
class SineController:
    """Open-loop oscillation: u_a = 0.5 + 0.5 sin(2 pi f t + phase_a); params [B, A + 1] =
    (phases..., f)."""

    kind = "sine"


@dataclass(frozen=True)
class ReflexController:
    """Closed loop through the sensors: u = clip(W @ bits + b, 0, 1); params (W [B, A, S], b [B, A])."""

    kind = "reflex"


@dataclass(frozen=True)
class PatternController:
    """Open loop, a square wave per actuator: u_a = high_a while frac(t / T - phase_a) < duty_a,
    else low_a; params [B, 4 A + 1] = per actuator (phase, duty, low, high), then the period T
    (s). Phase and duty are fractions of the period, the levels activations in [0, 1]. The
    actuators switch between set targets as a SAN's actuator nodes do, but on a clock instead
    of the sensors (the pattern ceiling, ``sanlab.search.pattern``)."""

    kind = "pattern"
