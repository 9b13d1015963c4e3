"""Random SANs on a creature, scored and summarised: the CLI's ``simulate`` command.

Controllers 0..n-1 of a search seeded ``seed`` are scored by the same evaluator, with the same
ensemble draws, as ``sanlab search`` scores them (distance is the centre of mass's, as in every
metric), so the same controller shows the same score and speed in both commands; nothing is
stored.
"""

from __future__ import annotations

import time

import numpy as np

from sanlab.creature.spec import Creature
from sanlab.evaluate.ensemble import Ensemble, search_key
from sanlab.evaluate.evaluator import Evaluator, describe_devices


def random_san_params(spec: Creature, n: int, seed: int, dtype="float64"):
    """n random networks for ``spec`` (controllers 0..n-1 of a search seeded ``seed``), with the
    creature's node delays: (San, SanParams with a leading batch axis)."""
    from sanlab.san import San

    san = San.for_creature(spec)
    weights = np.stack([san.random_weights(seed, i) for i in range(n)])
    return san, san.params(weights, spec.san.delay_on, spec.san.delay_off, dtype)


def simulate_random(spec: Creature, n: int, seconds: float, seed: int, dtype: str = "float64",
                    ensemble: Ensemble | None = None, metric: str | None = None) -> dict:
    """Score controllers 0..n-1 of a search seeded ``seed`` for ``seconds`` (see the module
    docstring); the report's ``top`` lists every controller, best score first."""
    ens = ensemble if ensemble is not None else Ensemble()
    ev = Evaluator(spec, metric=metric, seconds=seconds, dtype=dtype, batch=n, ensemble=ens)
    weights = np.stack([ev.san.random_weights(seed, i) for i in range(n)])
    t0 = time.perf_counter()
    s = ev(weights, keys=[search_key(seed, i) for i in range(n)])
    wall = time.perf_counter() - t0
    steps = int(round(seconds / spec.dt))
    order = np.argsort(-s.score, kind="stable")
    top = [
        {
            "controller": int(i),
            "score": float(s.score[i]),
            "distance_m": float(s.distance_m[i]),
            "dx_m": float(s.dx_m[i]) if np.isfinite(s.dx_m[i]) else None,  # m, signed, along x
            "speed_cm_s": float(s.speed_cm_s[i]),
            "fell": bool(s.fell[i]),
            "finite": not bool(s.nonfinite[i]),
        }
        for i in order
    ]
    return {
        "creature": spec.name,
        "controllers": n,
        "seconds": seconds,
        "seed": seed,
        "dtype": dtype,
        "metric": ev.metric.kind,
        "ensemble": ens.members,
        "devices": describe_devices(),
        "wall_s": wall,  # compile included on a cold cache
        "steps_per_s": n * ens.members * steps / wall,
        "non_finite": int(np.count_nonzero(s.nonfinite)),
        "top": top,
    }
