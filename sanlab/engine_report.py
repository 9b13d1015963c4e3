"""Run random SANs on a creature and summarise the motion: the engine's end-to-end check, and
the CLI's ``simulate`` command. (The search with its gait library builds on the same calls.)"""

from __future__ import annotations

import math
import time

import numpy as np

from sanlab.creature.spec import Creature


def random_san_params(spec: Creature, n: int, seed: int, dtype="float32"):
    """n random networks for ``spec`` (controllers 0..n-1 of a search seeded ``seed``), with the
    creature's node delays: (San, SanParams with a leading batch axis)."""
    from sanlab.san import San

    san = San.for_creature(spec)
    weights = np.stack([san.random_weights(seed, i) for i in range(n)])
    return san, san.params(weights, spec.san.delay_on, spec.san.delay_off, dtype)


def simulate_random(spec: Creature, n: int, seconds: float, seed: int, dtype: str = "float32") -> dict:
    """Simulate n random SANs for ``seconds``; distances are of the first link's origin."""
    import jax

    from sanlab import sim

    model = sim.compile_creature(spec, dtype)
    san, params = random_san_params(spec, n, seed, dtype)
    t0 = time.perf_counter()
    r = sim.rollout(model, san, params, seconds)
    jax.block_until_ready(r.state.q)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    r = sim.rollout(model, san, params, seconds)
    jax.block_until_ready(r.state.q)
    wall = time.perf_counter() - t0
    steps = int(round(seconds / spec.dt))
    q0 = np.asarray(model.params.q0)
    q = np.asarray(r.state.q)
    dx = q[:, 0] - q0[0]
    root = model.structure.links[0]
    angle = q[:, root.dof_rot] if root.dof_rot >= 0 else np.zeros(n)
    finite = np.asarray(r.finite)
    dx = np.where(finite, dx, 0.0)
    order = np.argsort(-np.abs(dx), kind="stable")
    top = [
        {
            "controller": int(i),
            "distance_m": float(dx[i]),
            "speed_cm_s": float(abs(dx[i]) / seconds * 100),
            "final_angle_deg": float(math.degrees(math.remainder(angle[i], 2 * math.pi))) if finite[i] else float("nan"),
            "finite": bool(finite[i]),
        }
        for i in order
    ]
    devices = jax.devices()
    return {
        "creature": spec.name,
        "controllers": n,
        "seconds": seconds,
        "seed": seed,
        "dtype": dtype,
        "devices": f"{len(devices)} x {devices[0].platform}",
        "first_call_s": first,
        "wall_s": wall,
        "steps_per_s": n * steps / wall,
        "max_penetration_m": float(np.max(np.asarray(r.max_depth))),
        "non_finite": int(np.count_nonzero(~finite)),
        "top": top,
    }
