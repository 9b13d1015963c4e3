"""Phase 2 (paper §5.3): fine-tune gaits by SGA or simulated annealing, many chains at once.

Each gait is one chain (``sga.SGA`` or ``anneal.Anneal``) over the parameters of ``space.Space``;
the weights are never tuned. Every round asks each unfinished chain for a speculative window of
trials, evaluates all of them in one batched rollout (the creature's numbers are batched arrays,
so nothing recompiles), and tells each chain its results. Each tuned gait is stored as a "tune"
run linked to its parent gait, with the score-per-trial trace.

With ``terrain`` ("rough" or "hill") every proposal is scored as the mean over several terrains
(§6.2), so the tuned gait stays robust: rough = three rough grounds (RMS height 1.5 cm, shortest
wavelength 0.25 m, seeds 1-3); hill = four smooth hills 8 cm high and 1 m wide, centred 0.7 m and
1.2 m ahead and behind (creatures may go either way).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sanlab import __version__
from sanlab.creature.spec import Creature, Terrain
from sanlab.gait import Gait
from sanlab.metrics import Metric, scores
from sanlab.search.anneal import Anneal
from sanlab.search.sga import SGA
from sanlab.search.space import Space

METHODS = {"sga": SGA, "sa": Anneal}
TERRAINS = {
    "flat": [Terrain()],
    "rough": [Terrain(kind="rough", height=0.015, wavelength=0.25, seed=s) for s in (1, 2, 3)],
    "hill": [Terrain(kind="hill", height=0.08, width=1.0, center=c) for c in (0.7, -0.7, 1.2, -1.2)],
}


class TuneEvaluator:
    """Score (weights, parameter vector) pairs, averaged over a set of terrains."""

    def __init__(self, spec: Creature, space: Space, *, metric: str, seconds: float, terrain: str = "flat",
                 dtype: str = "float32", batch: int = 128):
        from sanlab import sim

        if terrain not in TERRAINS:
            raise ValueError(f"terrain: expected one of {list(TERRAINS)}, got {terrain!r}")
        if terrain != "flat" and spec.world.plane != "vertical":
            raise ValueError("terrain: only creatures in the vertical plane walk on terrain")
        grounds = TERRAINS[terrain]
        kind = grounds[0].kind
        self.spec = dataclasses.replace(spec, world=dataclasses.replace(spec.world, terrain=grounds[0])) if terrain != "flat" else spec
        self.space, self.seconds, self.dtype, self.batch = space, seconds, dtype, batch
        self.metric = Metric.for_creature(self.spec, metric)
        self.model = sim.compile_creature(self.spec, dtype)
        self.variants = [sim.compile_creature(dataclasses.replace(
            self.spec, world=dataclasses.replace(self.spec.world, terrain=g)), dtype).params for g in grounds]
        self.terrain, self.kind = terrain, kind

    def __call__(self, weights: np.ndarray, thetas: np.ndarray) -> dict[str, np.ndarray]:
        """weights [B, N, I], thetas [B, P] -> per-row score, speed_cm_s, ... (terrain means;
        nonfinite and fell if on any terrain)."""
        import jax.numpy as jnp

        from sanlab import sim
        from sanlab.san import SanParams

        T = len(self.variants)
        B = len(thetas)
        k1, k2, m = self.space.batch(np.repeat(thetas, T, axis=0), self.model)
        if T > 1:
            tp = np.tile(np.stack([np.asarray(v.terrain) for v in self.variants]), (B, 1))
            rp = np.tile(np.stack([np.asarray(v.rough) for v in self.variants]), (B, 1, 1))
            m = m.with_params(terrain=jnp.asarray(tp, m.dtype), rough=jnp.asarray(rp, m.dtype))
        params = SanParams(*(jnp.asarray(x, self.dtype) for x in (np.repeat(weights, T, axis=0), k1, k2)))
        r = sim.rollout(m, self.space.san, params, self.seconds, observer=self.metric, params_batched=True,
                        pad_to=self.batch * T)
        out = scores(self.metric, r.acc, r.finite, self.seconds, self.spec.world.plane)
        res = {k: v.reshape(B, T) for k, v in out.items()}
        return {
            "score": res["score"].mean(1),
            "speed_cm_s": res["speed_cm_s"].mean(1),
            "distance_m": res["distance_m"].mean(1),
            "fell": np.asarray(res["fell"].any(1)),
            "nonfinite": np.asarray(res["nonfinite"].any(1)),
        }


@dataclass(frozen=True)
class TuneProgress:
    trials: int  # decided so far, all chains
    total: int
    best: float  # best score over chains
    rate: float  # evaluations per second (speculative ones included)
    done: bool = False


@dataclass(frozen=True)
class TuneResult:
    gait: str  # the parent gait, as given
    tuned_gait: str  # "RUN/1" of the stored tuned gait
    run_id: str
    before: dict  # score, speed_cm_s of the parent under the tuning conditions
    after: dict
    trials: int
    accepted: int
    evaluations: int  # including discarded speculative ones
    seconds: float  # wall time


def tune(
    library,
    gait_ids: list[str],
    *,
    method: str = "sa",
    trials: int = 1000,
    seed: int = 0,
    morphology: bool = False,
    terrain: str = "flat",
    batch: int = 128,
    dtype: str = "float32",
    reporter: Callable[[TuneProgress], None] | None = None,
) -> list[TuneResult]:
    """Tune each gait as its own chain (all on the same creature), store the tuned gaits."""
    if method not in METHODS:
        raise ValueError(f"method: expected one of {list(METHODS)}, got {method!r}")
    t_start = time.perf_counter()
    gaits = [Gait.from_library(library, g) for g in gait_ids]
    spec = gaits[0].spec
    if any(g.spec != spec for g in gaits):
        raise ValueError("all gaits tuned together must be of the same creature")
    space = Space(spec, morphology=morphology)
    ev = TuneEvaluator(spec, space, metric=gaits[0].metric, seconds=gaits[0].seconds, terrain=terrain,
                       dtype=dtype, batch=batch)
    starts = np.stack([space.nominal(g.params) for g in gaits])
    weights = np.stack([g.weights for g in gaits])
    before = ev(weights, starts)
    chains = [
        METHODS[method](space, g.weights, starts[i], before["score"][i], trials, seed=seed * 1_000_003 + i)
        for i, g in enumerate(gaits)
    ]
    report = reporter or (lambda p: None)
    evaluations = 0
    report(TuneProgress(0, trials * len(chains), float(max(c.best for c in chains)), 0.0))
    window = max(1, batch // len(chains))
    while not all(c.done for c in chains):
        asked = [c.ask(window) if not c.done else [] for c in chains]
        flat = [cand for a in asked for cand in a]
        res = ev(np.stack([c.weights for c in flat]), np.stack([c.params["theta"] for c in flat]))
        evaluations += len(flat)
        k = 0
        for c, a in zip(chains, asked):
            c.tell(a, {key: v[k : k + len(a)] for key, v in res.items()})
            k += len(a)
        rate = evaluations / (time.perf_counter() - t_start)
        report(TuneProgress(sum(c.t for c in chains), trials * len(chains), float(max(c.best for c in chains)), rate))
    after = ev(weights, np.stack([c.best_theta for c in chains]))
    wall = time.perf_counter() - t_start
    results = []
    for i, (g, c) in enumerate(zip(gaits, chains)):
        params = {
            "method": method, "trials": trials, "seed": seed, "morphology": morphology, "terrain": terrain,
            "seconds": ev.seconds, "metric": ev.metric.kind, "batch": batch, "source": g.run_params.get("source"),
            "parameters": space.names,
        }
        run = library.create_run(
            kind="tune", creature=spec.name, creature_text=g.creature_text, params=params, seed=seed,
            total=1, dtype=dtype, device=_device(), sanlab_version=__version__, parent_gait=g.gait_id,
        )
        library.add_batch(run.run_id, [{
            "idx": 0,
            "encoding": space.san.encode(g.weights),
            "params": space.gait_params(c.best_theta, ev.model),
            "score": float(after["score"][i]),
            "speed_cm_s": float(after["speed_cm_s"][i]),
            "fell": bool(after["fell"][i]),
            "nonfinite": bool(after["nonfinite"][i]),
            "extra": {"distance_m": float(after["distance_m"][i]), "accepted": c.accepted, "theta": c.best_theta.tolist()},
            "parent": g.gait_id,
        }])
        library.add_trace(run.run_id, [{"trial": t, "score": s, "accepted": a} for t, s, a in c.trace])
        library.set_status(run.run_id, "done")
        results.append(TuneResult(
            gait_ids[i], f"{run.run_id}/1", run.run_id,
            {"score": float(before["score"][i]), "speed_cm_s": float(before["speed_cm_s"][i])},
            {"score": float(after["score"][i]), "speed_cm_s": float(after["speed_cm_s"][i])},
            trials, c.accepted, evaluations, wall,
        ))
    report(TuneProgress(sum(c.t for c in chains), trials * len(chains), float(max(c.best for c in chains)),
                        evaluations / wall, True))
    return results


def _device() -> str:
    import jax

    d = jax.devices()
    return f"{len(d)} x {d[0].platform}"


__all__ = ["tune", "TuneEvaluator", "TuneResult", "TuneProgress", "METHODS", "TERRAINS"]
