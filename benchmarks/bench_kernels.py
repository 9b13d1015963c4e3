"""Helpers of benchmarks/engine.py: one rollout of random SANs on the kernel."""

from __future__ import annotations

import time

import numpy as np


def best(calls: list, repeats: int) -> list[float]:
    """The best seconds of each of ``calls`` over ``repeats`` rounds that call each in turn, after
    a round of untimed calls (compiles, first-time costs): a change in the machine's load falls on
    all of them."""
    out = [float("inf")] * len(calls)
    for r in range(repeats + 1):
        for i, f in enumerate(calls):
            t = time.perf_counter()
            f()
            if r:
                out[i] = min(out[i], time.perf_counter() - t)
    return out


def _start(spec, B: int, seed: int, rows=None, dtype: str = "float64"):
    """The kernel's inputs for controllers 0..B-1 of seed ``seed``, with nothing compiled for the
    creature: its tables from the file (``model.assemble``, NumPy arrays), seated and anchored by
    the kernel, the SANs' weights and rates in NumPy (``San.random_weights``, as a search draws
    them): (model, san, params, packed tables, start state, per-row tables). rows: a function of
    the packed tables giving ``kernel.run_san``'s per-row tables (a mixed batch), or None (one
    shared table). dtype: the arithmetic, "float64" or "float32" (the model's dtype)."""
    from sanlab.san import San, SanParams
    from sanlab.sim import kernel
    from sanlab.sim.model import assemble

    m = assemble(spec, dtype)
    san = San.for_creature(spec)
    N = san.n_nodes
    weights = np.stack([san.random_weights(seed, i) for i in range(B)]).astype(np.float64)
    sp = SanParams(weights, np.full((B, N), 1.0 / spec.san.delay_on), np.full((B, N), -1.0 / spec.san.delay_off))
    pk = kernel.pack(m, san.n_hidden)
    seat = spec.world.plane == "vertical" and bool(m.structure.contacts)
    per_row = rows(pk) if rows is not None else None
    q, anchor = kernel.start(pk, np.repeat(np.asarray(m.params.q0)[None], B, 0), seat=seat, rows=per_row)
    return m, san, sp, pk, (q, np.zeros_like(q), anchor, np.zeros((B, N)), np.zeros((B, N))), per_row


def new_creature(spec, B: int = 8, steps: int = 1000) -> float:
    """Seconds from a creature file's spec to the final states of B random SANs after ``steps``
    steps on the kernel: what a never-seen creature's first search waits for its simulation."""
    from sanlab.sim import kernel

    t0 = time.perf_counter()
    _, _, sp, pk, (q, p, anchor, istate, out), _ = _start(spec, B, 0)
    kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, p, anchor, istate, out, steps)
    return time.perf_counter() - t0


def prepared(spec, B: int, steps: int, seed: int, rows=None, dtype: str = "float64"):
    """A rollout of B random SANs (controllers 0..B-1 of seed ``seed``) for ``steps`` steps on the
    kernel as a callable with its inputs made (calling it times the rollout alone; it returns the
    final coordinates q [B, D]). rows, dtype: see :func:`_start`."""
    from sanlab.sim import kernel

    _, _, sp, pk, (q, p, anchor, istate, out), per_row = _start(spec, B, seed, rows, dtype)
    w = np.asarray(sp.weights, np.float64)
    k1, k2 = np.asarray(sp.k1, np.float64), np.asarray(sp.k2, np.float64)
    return lambda: kernel.run_san(pk, w, k1, k2, q, p, anchor, istate, out, steps, rows=per_row)["q"]


def prepared_open(spec, B: int, steps: int, seed: int):
    """As :func:`prepared`, but the B rows hold random activations (the kernel's "hold"
    controller): the physics alone, no network in the loop."""
    from sanlab.sim import kernel

    _, _, _, pk, (q, p, anchor, _, _), _ = _start(spec, B, seed)
    u = np.random.default_rng(seed).uniform(0.0, 1.0, (B, pk.ai.shape[0]))
    return lambda: kernel.run_open(pk, "hold", u, q, p, anchor, steps)["q"]
