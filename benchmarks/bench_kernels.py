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
    from sanlab.engine_report import random_san_params
    from sanlab.sim import dynamics, kernel

    m = _model(spec, "float64")
    san, sp = random_san_params(spec, B, seed, dtype="float64")
    s0 = dynamics.make_state(m)
    pk = kernel.pack(m, san.n_hidden)
    N = san.n_nodes
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    return m, san, sp, pk, (tile(s0.q), tile(s0.p), tile(s0.anchor), np.zeros((B, N)), np.zeros((B, N)))


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
