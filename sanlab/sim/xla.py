"""The XLA engine's closed-loop rollout, kept as the reference the kernel is tested against (issue 46):
no command runs it. Many controllers, one creature, batched with vmap, time with lax.scan.

Each step runs sensors -> controller -> actuator activations -> physics inside one compiled
program. The batch is sharded over every XLA device (one per CPU core, or the GPU), padded to a
fixed size so that a search never recompiles.

A controller (:class:`Controller`) is any hashable object with

    init(params, model) -> cstate                       (one controller, pure)
    apply(params, cstate, bits [S], dt) -> (cstate, u [A] in [0, 1])

and its ``params`` pytree carries a leading batch axis when many are rolled out at once.
An observer (:class:`Observer`; optional, hashable) accumulates quantities along the way
(metrics):

    init(model, state) -> acc
    update(model, acc, state, frame, bits, u) -> acc     (called before every step)
    finish(model, acc, final_state) -> acc               (optional)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, NamedTuple, Protocol

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import PartitionSpec as P

from sanlab.sim import executables
from sanlab.sim.dynamics import Frame, State, _barrier, advance, make_state, prepare, sense, velocity
from sanlab.sim.model import Model


class Controller(Protocol):
    """What :func:`rollout` calls on a controller (``sanlab.san.San`` is one); it must be hashable
    (it is a static argument of the compiled program)."""

    def init(self, params: Any, model: Model, /) -> Any:
        """The controller state at t = 0 for one controller's ``params``."""
        ...

    def apply(self, params: Any, cstate: Any, bits: Any, dt: Any, /) -> tuple[Any, Any]:
        """One step: sensor values ``bits`` [S] (0/1) -> (next state, activations u [A] in [0, 1])."""
        ...


class Observer(Protocol):
    """What :func:`rollout` calls on an observer (``sanlab.metrics.Metric`` is one); hashable.
    It may also define ``finish(model, acc, final_state) -> acc``, called once after the last
    step when present."""

    def init(self, model: Model, state: State, /) -> Any:
        """The accumulator before the first step."""
        ...

    def update(self, model: Model, acc: Any, state: State, fr: Frame, bits: Any, u: Any, /) -> Any:
        """The accumulator after seeing ``state`` (and its prepared frame ``fr``, sensor values
        ``bits``, activations ``u``), before the step from it."""
        ...


class Frames(NamedTuple):
    """Recorded trajectory, one row per frame (batch axis first when batched)."""

    t: Any  # [F] s
    q: Any  # [..., F, D]
    qd: Any  # [..., F, D]
    bits: Any  # [..., F, S] sensor values
    u: Any  # [..., F, A] actuator activations
    cstate: Any  # controller state pytree, [..., F, ...]


class Result(NamedTuple):
    """Outcome of a rollout (batch axis first when batched)."""

    state: State  # final state
    acc: Any  # observer accumulator (None without observer)
    max_depth: Any  # [...] largest ground penetration over the run (m)
    finite: Any  # [...] bool: the state stayed finite and bounded
    frames: Frames | None
    cstate: Any = None  # final controller state (pass it back as ``cstate0`` to continue a run)


def _batched(model: Model, controller: Controller, observer: Observer | None, n_steps, every, capacity: int,
             cparams, state0, cstate0, gate, in_model):
    """Roll a batch of controllers out for n_steps, recording a frame every ``every`` steps into
    ``capacity`` frame buffers (0: no recording); every argument but ``gate``, ``n_steps``,
    ``every`` and ``capacity`` carries the batch axis first (``model`` only where ``in_model`` says
    so). n_steps and every: traced scalars, so that one compiled program serves every duration
    and frame rate whose ``n_steps // every`` frames fit the buffers (the frames past them are
    the caller's to cut off).

    Time is one ``fori_loop`` (recording or not) over a ``vmap``-ed step, not a
    ``vmap`` over a looped one: the step is then traced once, already batched, where batching a
    loop traces the step and then batches its trace again (about twice the tracing time, the
    largest part of a cold start). The compiled program is the same.

    cstate0: the controller's state to start from (None: ``controller.init``).
    gate: an unbatched boolean that is true at run time (see dynamics._barrier)."""

    def each(f, *axes):
        return jax.vmap(f, in_axes=(in_model, *axes))

    if cstate0 is None:
        cstate0 = each(lambda m, c: controller.init(c, m), 0)(model, cparams)
    acc0 = each(lambda m, s: observer.init(m, s), 0)(model, state0) if observer is not None else None
    deepest0 = jnp.zeros(state0.q.shape[:1], state0.q.dtype)

    def one(m, c, carry):
        state, cstate, acc, deepest = carry
        fr = prepare(m, state, gate)
        bits = sense(m, fr, state.t)
        cstate2, u = controller.apply(c, cstate, bits, m.params.dt)
        if observer is not None:
            acc = observer.update(m, acc, state, fr, bits, u)
        nxt, depth = advance(m, fr, state, u)
        qd_n = jnp.stack([x + jnp.zeros((), state.q.dtype) for x in fr.qd]) if fr.qd else state.qd
        out = (state.q, qd_n, bits, u, cstate) if capacity else None
        return (nxt, cstate2, acc, jnp.maximum(deepest, depth)), out

    step = each(one, 0, 0)

    def body(carry, _):
        return step(model, cparams, carry)

    carry = (state0, cstate0, acc0, deepest0)
    if not capacity:
        carry = jax.lax.fori_loop(0, n_steps, lambda _, c: body(c, None)[0], carry)
        frames = None
    else:
        # One loop over every step, so the step is traced and compiled once; a frame is written
        # on every ``every``-th step. A scan over frames with an inner loop held two or three
        # copies of the step (a block's first step, the rest of the block, the leftover steps)
        # and compiled 1.5-1.7x slower (bounder, 2 cores) for the same arithmetic.
        n_frames = n_steps // every

        def record(i, cf):
            carry, buf = cf
            carry, out = body(carry, None)
            return carry, write_frame(buf, out, i, every, n_frames)

        buf = _empty_frames(model, controller, cparams, carry, capacity)
        carry, rec = jax.lax.fori_loop(0, n_steps, record, (carry, buf))
        frames = _frames_first(rec)
    state, cstate, acc, deepest = carry

    def last(m, state, acc):
        finish = getattr(observer, "finish", None)  # optional (see Observer)
        if finish is not None:
            acc = finish(m, acc, state)
        state = state._replace(qd=velocity(m, state, gate))
        finite = jnp.all(jnp.isfinite(state.q)) & jnp.all(jnp.abs(state.qd) < 1e4) & jnp.all(jnp.isfinite(state.p))
        return state, acc, finite

    state, acc, finite = each(last, 0, 0)(model, state, acc)
    return state, acc, deepest, finite, frames, cstate


def write_frame(buf, out, i, every, n=None):
    """Frame buffers ``buf`` (leaves [F, ...]) with step ``i``'s outputs ``out`` (leaves [...])
    written as frame ``i // every`` when ``i`` is a multiple of ``every`` and that frame is one of
    the first ``n`` (default: F), and unchanged otherwise (also for the steps after the last whole
    frame). For a loop that runs the step once and records every ``every``-th step (the rollout,
    the studio's live chunks); ``every`` and ``n`` may be traced."""
    cap = jax.tree_util.tree_leaves(buf)[0].shape[0]
    n = cap if n is None else n
    k = jnp.minimum(i // every, cap - 1)
    keep = (i % every == 0) & (i < n * every)
    put = lambda b, x: jax.lax.dynamic_update_index_in_dim(
        b, jnp.where(keep, x, jax.lax.dynamic_index_in_dim(b, k, 0, keepdims=False)), k, 0)
    return jax.tree_util.tree_map(put, buf, out)


def _frames_first(rec):
    """Recorded buffers [F, B, ...] -> [B, F, ...]."""
    return jax.tree_util.tree_map(lambda x: jnp.moveaxis(x, 0, 1), rec)


def _empty_frames(model: Model, controller: Controller, cparams, carry, n: int):
    """Zeroed buffers for ``n`` recorded frames [n, B, ...] of (q, qd, bits, u, cstate), shaped
    without tracing the step: only the controller's ``apply`` is traced, for its output's shape."""
    state, cstate = carry[0], carry[1]
    B, dtype = state.q.shape[0], state.q.dtype
    one = lambda x: jax.ShapeDtypeStruct(x.shape[1:], x.dtype)
    bits = jax.ShapeDtypeStruct((model.structure.n_sensors,), dtype)
    _, u = jax.eval_shape(lambda c, s, b, h: controller.apply(c, s, b, h), jax.tree_util.tree_map(one, cparams),
                          jax.tree_util.tree_map(one, cstate), bits, jax.ShapeDtypeStruct((), dtype))
    zeros = lambda s: jnp.zeros((n, B, *s.shape), s.dtype)
    return jax.tree_util.tree_map(zeros, (one(state.q), one(state.q), bits, u, jax.tree_util.tree_map(one, cstate)))


def devices():
    """The devices a batch is spread over: the GPU if JAX has one, else every CPU core."""
    return jax.devices()


def batch_quantum() -> int:
    """Batch sizes are padded to a multiple of this (lanes per device x devices)."""
    return 8 * len(devices())


MIN_FRAMES = 256  # 8.4 s at 30 fps (a frame every 33 ms): a creature's films, replays and checks share one program


def frame_capacity(n_frames: int) -> int:
    """Frame buffers for ``n_frames`` recorded frames: at least :data:`MIN_FRAMES`, else the next
    power of two, so that recordings of nearby lengths and rates share a compiled program at no
    more than twice the frames' memory (a 6 s replay at 30 fps: 181 frames in 256)."""
    return max(MIN_FRAMES, 1 << max(0, int(n_frames) - 1).bit_length())


@lru_cache(maxsize=64)
def _program(controller: Controller, observer: Observer | None, capacity: int, params_batched: bool,
             fence: bool, with_cstate: bool, with_state0: bool, devs: tuple):
    """The compiled rollout of one configuration over the devices ``devs``: each device rolls out
    its own contiguous share of the batch, and nothing in the program crosses devices. The number
    of steps and the steps between recorded frames are arguments of the program, not part of it;
    only the frame buffers' size ``capacity`` (0: no recording) is: evaluations of any duration
    share one compilation, and so do recordings whose frames fit the same buffers.

    Why shard_map and host-side results: under ``jit`` with sharded inputs the program itself is
    collective-free, but slicing its sharded output (the padding cut) is a second multi-device
    program with a collective-permute; XLA's CPU collectives wait for every device at a
    rendezvous and abort the process (SIGABRT) when one device, slowed by other work on a busy
    machine, arrives past the deadline. Here each device's share is a manual shard (no collective
    can be inserted), inputs are placed per device from the host and results are fetched per
    device to the host and cut in NumPy, so no device ever waits for another. It stays one
    compiled program for all devices (compiling per device would multiply the compile time).
    """
    mesh = jax.sharding.Mesh(np.array(devs), ("b",))
    B, R = P("b"), P()

    def local(model, cparams, state0, cstate0, one, steps, every):
        in_model = jax.tree_util.tree_map(lambda _: 0 if params_batched else None, model)
        gate = (one > 0) if fence else None
        if state0 is None:  # at rest in the start pose, built here: op by op on the host it cost 30-50 ms a call
            if params_batched:
                state0 = jax.vmap(make_state, in_axes=(in_model,))(model)
            else:
                b = jax.tree_util.tree_leaves(cparams)[0].shape[0]
                # the fence keeps XLA from fusing the whole start state into the broadcast, which
                # then re-derives it for every element of the batch (20 ms a call at batch 1024)
                one0 = _barrier(make_state(model), gate)
                state0 = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (b, *x.shape)), one0)
        return _batched(model, controller, observer, steps, every, capacity, cparams, state0, cstate0, gate, in_model)

    specs = (B if params_batched else R, B, B if with_state0 else R, B if with_cstate else R, R, R, R)
    return mesh, jax.jit(jax.shard_map(local, mesh=mesh, in_specs=specs, out_specs=B, check_vma=False))


def _pad(x: np.ndarray, n: int) -> np.ndarray:
    pad = n - x.shape[0]
    if pad == 0:
        return x
    return np.concatenate([x, np.repeat(x[-1:], pad, axis=0)], axis=0)


def _host(x, dtype) -> np.ndarray:
    x = np.asarray(x)
    if np.issubdtype(x.dtype, np.floating):
        x = x.astype(dtype)  # float64 inputs would otherwise promote a float32 model
    return x


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
    pad_to: int | None = None,
    fence: bool | None = None,
) -> Result:
    """Roll out a batch of controllers on ``model``.

    cparams: controller parameters with a leading batch axis [B, ...].
    seconds / steps: duration (one of them); an input of the compiled program, so runs of any
    duration share one compilation. record_fps: record frames at this rate (None: no recording,
    and none of its cost); an input of the program too, whose frame buffers hold
    :func:`frame_capacity` frames: recordings whose frames fit the same buffers share one
    compilation.
    state0: initial state (default: the creature's pose at rest), unbatched or [B, ...]. params_batched: model.params leaves carry the batch axis too
    (tuning several parameter sets at once). pad_to: pad the batch to this size (default: the
    next multiple of :func:`batch_quantum`) so that varying batch sizes reuse one compilation.
    fence: keep XLA from re-deriving shared intermediates in every kernel (see
    dynamics._barrier) with conditionals on a runtime-true flag; measured faster at every batch
    size from 16 to 2048 on CPU (2 to 14 x). None (default): on for CPUs, off for GPUs (a
    conditional there waits for its predicate on the host every step). Results then differ in
    the last bits.

    Returns a :class:`Result` of NumPy arrays (fetched from the devices, padding cut off). The
    batch is split into one contiguous share per device, each rolled out on its own (see
    ``_program``); a controller's result is bit-identical alone or anywhere in any batch, and
    whatever the number of devices. Raises ValueError for a negative duration, a record_fps
    that is negative or not finite, or neither seconds nor steps.
    """
    dt = float(model.structure.dt)
    if steps is None:
        if seconds is None:
            raise ValueError("give seconds or steps")
        steps = int(round(seconds / dt))
    if steps < 0:
        raise ValueError(f"steps: expected >= 0, got {steps} (seconds={seconds})")
    if record_fps is not None and not (math.isfinite(record_fps) and record_fps >= 0):
        raise ValueError(f"record_fps: expected a finite rate >= 0 (frames per second), got {record_fps}")
    every = 0
    if record_fps:
        # a rate too low for one frame in the run records none (every is then an int32 input)
        spacing = 1.0 / (record_fps * dt) if record_fps * dt > 0 else math.inf
        every = steps + 1 if spacing >= steps + 1 else max(1, int(round(spacing)))
    leaves = jax.tree_util.tree_leaves(cparams)
    B = leaves[0].shape[0]
    q = batch_quantum()
    n = max(pad_to or 0, B)
    n = int(math.ceil(n / q) * q)
    if state0 is not None and np.ndim(state0.q) == 1:
        state0 = jax.tree_util.tree_map(lambda x: np.broadcast_to(np.asarray(x), (B, *np.shape(x))), state0)
    dtype = model.dtype
    if fence is None:
        fence = devices()[0].platform == "cpu"
    n_frames = steps // every if every else 0
    config = (controller, observer, frame_capacity(n_frames) if every else 0, params_batched, fence,
              cstate0 is not None, state0 is not None, tuple(devices()))
    mesh, program = _program(*config)
    shard = jax.sharding.NamedSharding(mesh, P("b"))
    whole = jax.sharding.NamedSharding(mesh, P())
    batched = lambda x: _pad(_host(x, dtype), n)
    host = lambda x: _host(x, dtype)
    # one transfer call per placement, not one per leaf (a call costs ~0.2 ms, a model has ~40 leaves)
    cp, s0, cs0 = jax.device_put(jax.tree_util.tree_map(batched, (cparams, state0, cstate0)), shard)
    m = jax.device_put(jax.tree_util.tree_map(batched if params_batched else host, model),
                       shard if params_batched else whole)
    one, n_run, n_every = jax.device_put((np.ones((), dtype), np.asarray(steps, np.int32),
                                          np.asarray(max(every, 1), np.int32)), whole)
    # a warm start loads the stored executable and skips the trace (see sim.executables)
    out = jax.device_get(executables.call(config[:-1], program, (m, cp, s0, cs0, one, n_run, n_every)))  # each device's share, to the host
    state, acc, deepest, finite, frames, cstate = jax.tree_util.tree_map(lambda x: x[:B], out)
    if frames is not None:
        qf, qdf, bits, u, cs = jax.tree_util.tree_map(lambda x: x[:, :n_frames], frames)  # the buffers' unused tail
        t = np.arange(qf.shape[1]) * every * dt
        frames = Frames(t, qf, qdf, bits, u, cs)
    return Result(state, acc, deepest, finite, frames, cstate)


# ------------------------------------------------------------- simple controllers (tests, demos)


@dataclass(frozen=True)
class ConstantController:
    """Holds every actuator at activations ``params`` [A] (open loop)."""

    def init(self, params, model):
        return jnp.zeros((), params.dtype)

    def apply(self, params, cstate, bits, dt):
        return cstate, params


@dataclass(frozen=True)
class SineController:
    """Open-loop oscillation: u_a = 0.5 + 0.5 sin(2 pi f t + phase_a); params [A + 1] = (phases..., f)."""

    def init(self, params, model):
        return jnp.zeros((), params.dtype)

    def apply(self, params, t, bits, dt):
        u = 0.5 + 0.5 * jnp.sin(2 * math.pi * params[-1] * t + params[:-1])
        return t + dt, u


@dataclass(frozen=True)
class ReflexController:
    """Closed loop through the sensors: u = clip(W @ bits + b, 0, 1); params (W [A, S], b [A])."""

    def init(self, params, model):
        return jnp.zeros((), params[1].dtype)

    def apply(self, params, cstate, bits, dt):
        W, b = params
        return cstate, jnp.clip(jnp.sum(W * bits[None, :], axis=1) + b, 0.0, 1.0)
