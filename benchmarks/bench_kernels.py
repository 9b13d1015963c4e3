"""Helpers of benchmarks/kernel_spike.py: one rollout of random SANs on each form of the step."""

from __future__ import annotations

import time

import numpy as np


def best(f, n: int) -> float:
    """The best of n timed calls of f, after one untimed call."""
    f()
    out = float("inf")
    for _ in range(n):
        t0 = time.perf_counter()
        f()
        out = min(out, time.perf_counter() - t0)
    return out


_MODELS: dict = {}


def _model(spec, dtype):
    from sanlab import sim

    key = (spec.name, dtype)
    if key not in _MODELS:
        _MODELS[key] = sim.compile_creature(spec, dtype=dtype)
    return _MODELS[key]


def _start(spec, B: int, seed: int):
    """The kernel's inputs for controllers 0..B-1 of seed ``seed``, with nothing compiled for the
    creature: its tables from the file (``model.assemble``, NumPy arrays), seated and anchored by
    the kernel, the SANs' weights and rates in NumPy (``San.random_weights``, as a search draws
    them)."""
    from sanlab.san import San, SanParams
    from sanlab.sim import kernel
    from sanlab.sim.model import assemble

    m = assemble(spec, "float64", host=True)
    san = San.for_creature(spec)
    N = san.n_nodes
    weights = np.stack([san.random_weights(seed, i) for i in range(B)]).astype(np.float64)
    sp = SanParams(weights, np.full((B, N), 1.0 / spec.san.delay_on), np.full((B, N), -1.0 / spec.san.delay_off))
    pk = kernel.pack(m, san.n_hidden)
    seat = spec.world.plane == "vertical" and bool(m.structure.contacts)
    q, anchor = kernel.start(pk, np.repeat(np.asarray(m.params.q0)[None], B, 0), seat=seat)
    return m, san, sp, pk, (q, np.zeros_like(q), anchor, np.zeros((B, N)), np.zeros((B, N)))


def new_creature(spec, B: int = 8, steps: int = 1000) -> float:
    """Seconds from a creature file's spec to the final states of B random SANs after ``steps``
    steps on the kernel: what a never-seen creature's first search waits for its simulation."""
    from sanlab.sim import kernel

    t0 = time.perf_counter()
    _, _, sp, pk, (q, p, anchor, istate, out) = _start(spec, B, 0)
    kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, p, anchor, istate, out, steps)
    return time.perf_counter() - t0


def run(form: str, spec, B: int, steps: int, seed: int):
    """Final coordinates q [B, D] of B random SANs (controllers 0..B-1 of seed ``seed``) after
    ``steps`` steps on ``form``: "engine" (sim.rollout, float32), "engine64" or "c++" (the kernel)."""
    return prepared(form, spec, B, steps, seed)()


def prepared(form: str, spec, B: int, steps: int, seed: int):
    """:func:`run` as a callable with its inputs made: calling it times the rollout alone."""
    if form in ("engine", "engine64"):
        import jax

        from sanlab import sim
        from sanlab.engine_report import random_san_params

        dtype = "float32" if form == "engine" else "float64"
        san, sp = random_san_params(spec, B, seed, dtype=dtype)
        m = _model(spec, dtype)
        return lambda: np.asarray(jax.block_until_ready(sim.rollout(m, san, sp, steps=steps).state.q))
    from sanlab.sim import kernel

    m, san, sp, pk, (q, p, anchor, istate, out) = _start(spec, B, seed)
    w = np.asarray(sp.weights, np.float64)
    k1, k2 = np.asarray(sp.k1, np.float64), np.asarray(sp.k2, np.float64)
    return lambda: kernel.run_san(pk, w, k1, k2, q, p, anchor, istate, out, steps)["q"]



def agreement(spec, B: int, steps: int) -> np.ndarray:
    """Per controller, max |q_kernel - q_engine| / (1 + max |q_engine|) after ``steps`` steps in
    float64."""
    a = run("engine64", spec, B, steps, 0)
    b = run("c++", spec, B, steps, 0)
    return np.abs(a - b).max(1) / (1 + np.abs(a).max(1))
