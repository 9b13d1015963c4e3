"""Run a search: ask a strategy, evaluate in batches, commit each batch, report progress.

The gait library is the search's memory: each finished batch is committed in one transaction,
so an interrupted search (Ctrl-C, or SIGKILL) loses at most the batch in flight and resumes from
what is stored.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sanlab import __version__
from sanlab.creature import loads
from sanlab.evaluate import Evaluator
from sanlab.library import Library
from sanlab.search.base import Strategy
from sanlab.search.random_search import RandomSearch


@dataclass(frozen=True)
class SearchProgress:
    """What a reporter is told after every committed batch (and once at the start)."""

    run_id: str
    evaluated: int  # stored so far, including earlier sessions of a resumed run
    total: int
    best: float  # best score so far (0 before any)
    rate: float  # evaluations per second in this session
    done: bool = False


Reporter = Callable[[SearchProgress], None]


def _device() -> str:
    import jax

    devs = jax.devices()
    return f"{len(devs)} x {devs[0].platform} ({devs[0].device_kind})"


def run_search(
    library: Library,
    creature_text: str,
    creature_source: str,
    *,
    controllers: int = 200,
    seconds: float | None = None,
    seed: int = 0,
    metric: str | None = None,
    batch: int = 256,
    dtype: str = "float32",
    reporter: Reporter | None = None,
    resume: str | None = None,
) -> str:
    """Phase 1: evaluate ``controllers`` random SANs; returns the run id.

    With ``resume=RUN_ID`` everything (creature text, parameters) comes from the stored run and
    only the controllers not yet stored are evaluated.
    """
    if resume is not None:
        run = library.get_run(resume)
        params = run.params
        creature_text = run.creature_text
        spec = loads(creature_text, source=params.get("source", run.creature))
        controllers, seconds = params["controllers"], params["seconds"]
        seed = run.seed if run.seed is not None else seed  # a search run always stores both
        dtype = run.dtype or dtype
        metric, batch = params["metric"], params["batch"]
        run_id = run.run_id
    else:
        spec = loads(creature_text, source=creature_source)
        run_id = None
    ev = Evaluator(spec, metric=metric, seconds=seconds, dtype=dtype, batch=batch)
    if run_id is None:
        params = {
            "controllers": controllers,
            "seconds": ev.seconds,
            "metric": ev.metric.kind,
            "batch": batch,
            "source": creature_source,
            "san": {"sensors": ev.san.n_sensors, "hidden": ev.san.n_hidden, "actuators": ev.san.n_actuators},
            **ev.delays(),
        }
        run = library.create_run(
            kind="search", creature=spec.name, creature_text=creature_text, params=params, seed=seed,
            total=controllers, dtype=dtype, device=_device(), sanlab_version=__version__,
        )
        run_id = run.run_id
    library.set_status(run_id, "running")
    done = library.done_indices(run_id)
    strategy: Strategy = RandomSearch(ev.san, controllers, seed, ev.delays(), done)
    best = max(library.scores(run_id), default=0.0)
    evaluated, t0, fresh = len(done), time.perf_counter(), 0
    report = reporter or (lambda p: None)
    report(SearchProgress(run_id, evaluated, controllers, best, 0.0))
    try:
        while not strategy.done:
            cands = strategy.ask(batch)
            res = ev(np.stack([c.weights for c in cands]))
            rows = [
                {
                    "idx": c.idx,
                    "encoding": ev.san.encode(c.weights),
                    "params": c.params,
                    "score": float(res["score"][k]),
                    "speed_cm_s": float(res["speed_cm_s"][k]),
                    "fell": bool(res["fell"][k]),
                    "nonfinite": bool(res["nonfinite"][k]),
                    "extra": {"distance_m": float(res["distance_m"][k])},
                }
                for k, c in enumerate(cands)
            ]
            library.add_batch(run_id, rows)
            strategy.tell(cands, res)
            evaluated += len(cands)
            fresh += len(cands)
            best = max(best, float(np.max(res["score"])))
            report(SearchProgress(run_id, evaluated, controllers, best, fresh / (time.perf_counter() - t0)))
    except BaseException:
        library.set_status(run_id, "interrupted")
        raise
    library.set_status(run_id, "done")
    report(SearchProgress(run_id, evaluated, controllers, best, fresh / max(time.perf_counter() - t0, 1e-9), True))
    return run_id
