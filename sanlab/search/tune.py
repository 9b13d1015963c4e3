"""Phase 2 (paper §5.3) set up for the driver: fine-tune gaits by SGA or simulated annealing,
many chains at once (``sanlab tune``).

Each gait is one chain (a phase-2 strategy of ``registry``: ``sga.SGA`` or ``anneal.Anneal``)
over the parameters of ``space.Space``; the weights are never tuned. Each chain is its own
"tune" run linked to its parent gait, created before the first trial: every decided trial is
committed with its batch (the run's trace), and the tuned gait (its best vector, scored on a
held-out ensemble) is stored as the run's evaluation #0 when the chain ends. An interrupted
tuning (Ctrl-C, SIGKILL) resumes with ``resume=[RUN_ID, ...]`` and ends exactly as an
uninterrupted one.

With ``terrain`` ("rough" or "hill", ``sanlab.evaluate.TERRAINS``) every proposal is scored as
the mean over several terrains (§6.2), so the tuned gait stays robust.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

from sanlab import __version__
from sanlab.creature import loads
from sanlab.evaluate.backends import Backend, Local
from sanlab.evaluate.ensemble import Ensemble, default_ensemble
from sanlab.evaluate.evaluator import TERRAINS, Evaluator
from sanlab.evaluate.records import Scores
from sanlab.gait import Gait
from sanlab.library import Library, LibraryError, TuneSettings
from sanlab.search import driver, registry
from sanlab.search.base import Problem, Start, Strategy, Together
from sanlab.search.space import Space

TuneProgress = driver.Progress  # the name reporters of phase 2 have used
METHODS = {name: registry.STRATEGIES[name] for name in registry.names(2)}

# The default batch, by platform. A round keeps each chain's trials up to its first accepted
# one and is padded to the whole batch, so proposing ahead only pays where a larger batch costs
# little more wall time than a small one: on an accelerator, not on a few CPU cores. On 2 cores,
# benchmarks/tune_batch.py timed the same trials 2.2-3.2 x longer at --batch 128 than at 8, and
# 8 in all beat 8 per chain with 4 and 8 chains (figures in docs/tuning.md).
CPU_BATCH = 8  # in all, and at least one trial per chain per round
ACCELERATOR_BATCH = 128  # not measured against smaller ones on a GPU yet: the earlier default
MAX_DEFAULT_BATCH = 128


def default_batch(chains: int, platform: str | None = None) -> int:
    """The default ``batch`` of ``chains`` chains tuned together on ``platform`` ("cpu", "gpu",
    "tpu"; default: "cpu", where the kernel runs): on the CPU :data:`CPU_BATCH`, or one trial per chain
    where there are more chains (at most :data:`MAX_DEFAULT_BATCH`); elsewhere
    :data:`ACCELERATOR_BATCH`. Raises ValueError for ``chains`` < 1."""
    if chains < 1:
        raise ValueError(f"chains: expected >= 1, got {chains}")
    if platform is None:
        platform = "cpu"  # the kernel runs on the CPU's cores
    if platform != "cpu":
        return ACCELERATOR_BATCH
    return min(MAX_DEFAULT_BATCH, max(CPU_BATCH, chains))


@dataclass(frozen=True)
class TuneResult:
    gait: str  # the parent gait
    tuned_gait: str  # "RUN#0": the stored tuned gait (the chain's best; an audited selection is RUN#1)
    run_id: str
    before: dict  # score, speed_cm_s of the parent under the tuning conditions
    after: dict  # score, speed_cm_s of the tuned gait (held-out ensemble)
    trials: int
    accepted: int
    evaluations: int  # this session's, all chains, including discarded speculative ones
    seconds: float  # this session's wall time


def tune(
    library: Library,
    gait_ids: Sequence[str] = (),
    *,
    method: str = "sa",
    trials: int = 1000,
    seed: int = 0,
    morphology: bool = False,
    terrain: str = "flat",
    batch: int | None = None,
    dtype: str = "float64",
    ensemble: int | Ensemble = 8,
    reporter: driver.Reporter | None = None,
    resume: Sequence[str] = (),
    backend: Backend | None = None,
    chains: Sequence[int] | None = None,
) -> list[TuneResult]:
    """Tune each gait of ``gait_ids`` as its own chain (all of one creature), storing every
    trial as it is decided; or, with ``resume``, finish the given tune runs (their own settings).
    Each trial is scored as its ensemble's median (``ensemble`` members, drawn per chain and
    trial); returns one result per chain. Raises ValueError on bad settings, LibraryError on
    unknown gaits or runs. ``batch``: controllers simulated together per round (default:
    :func:`default_batch` of the chains; a resumed run keeps its own). ``chains``: each gait's
    chain number (default 0, 1, ...), on which its random stream depends: chain 2 tuned alone is
    chain 2 of a run that tuned 0 to 3 together, trial for trial (``sanlab.search.chain``: a
    chain's trials do not depend on the batch), so a caller may add chains to stored ones."""
    t_start = time.perf_counter()
    if batch is None:
        batch = default_batch(max(1, len(gait_ids)))
    backend = backend if backend is not None else Local()
    if bool(gait_ids) == bool(resume):
        raise ValueError("give gaits to tune, or runs to resume (not both)")
    if resume:
        ev, made = _resumed(library, resume)
    else:
        numbers = list(range(len(gait_ids))) if chains is None else [int(c) for c in chains]
        if len(numbers) != len(gait_ids) or len(set(numbers)) != len(numbers) or min(numbers, default=0) < 0:
            raise ValueError(f"chains: expected {len(gait_ids)} distinct numbers >= 0 (one per gait), got {list(numbers)}")
        ev, made = _fresh(library, list(gait_ids), method, trials, seed, morphology, terrain, batch, dtype,
                          ensemble if isinstance(ensemble, Ensemble) else default_ensemble(int(ensemble)),
                          backend.describe(), numbers)
    summary = driver.run(Together([c for _, c in made]), ev, library, reporter, backend)
    results = []
    for parent, chain in made:
        run_id = chain.run_ids[0]
        final = library.gait(f"{run_id}#0")
        extra = final.extra or {}
        before, after = final.scores, final.scores
        if "before" in extra:
            before = Scores.from_json(extra["before"])
        s = library.get_run(run_id).settings
        results.append(TuneResult(
            parent, f"{run_id}#0", run_id, {"score": before.score, "speed_cm_s": before.speed_cm_s},
            {"score": after.score, "speed_cm_s": after.speed_cm_s}, s.trials if isinstance(s, TuneSettings) else 0,
            int(extra.get("accepted", 0)), summary.evaluations, time.perf_counter() - t_start))
    return results


def _fresh(library: Library, gait_ids: list[str], method: str, trials: int, seed: int, morphology: bool,
           terrain: str, batch: int, dtype: str, ens: Ensemble, device: str,
           numbers: list[int]) -> tuple[Evaluator, list[tuple[str, Strategy]]]:
    if method not in METHODS:
        raise ValueError(f"method: expected one of {list(METHODS)}, got {method!r}")
    if terrain not in TERRAINS:
        raise ValueError(f"terrain: expected one of {list(TERRAINS)}, got {terrain!r}")
    if trials < 1:
        raise ValueError(f"trials: expected >= 1, got {trials}")
    gaits = [Gait.from_library(library, g) for g in gait_ids]
    for g in gaits:
        g.require_san("tuned (phase 2 tunes a SAN's parameters)")
    spec = gaits[0].spec
    if any(g.spec != spec for g in gaits):
        raise ValueError("all gaits tuned together must be of the same creature")
    space = Space(spec, morphology=morphology)
    ev = Evaluator(spec, metric=gaits[0].metric, seconds=gaits[0].seconds, dtype=dtype, batch=batch, terrain=terrain,
                   ensemble=ens, space=space)
    chains = []
    for i, g in zip(numbers, gaits, strict=True):
        settings = TuneSettings(method, trials, seed, i, morphology, terrain, ev.seconds, ev.metric.kind, batch,
                                g.source, ens, tuple(space.names))
        run = library.create_run(
            kind="tune", creature=spec.name, creature_text=g.creature_text, params=settings.to_json(), seed=seed,
            total=1, dtype=dtype, device=device, sanlab_version=__version__, parent_gait=g.gait_id)
        start = Start(g.weights, space.nominal(g.params), g.gait_id)
        chains.append((g.gait_id, registry.make(method, Problem(run.run_id, space.san, trials, seed, i, space, start,
                                                                 dtype=dtype))))
    return ev, chains


def _resumed(library: Library, run_refs: Sequence[str]) -> tuple[Evaluator, list[tuple[str, Strategy]]]:
    runs = list({r.run_id: r for r in (library.get_run(ref) for ref in run_refs)}.values())  # each chain once
    first = None
    chains = []
    ev = None
    for run in runs:
        s = run.settings
        if run.kind != "tune" or not isinstance(s, TuneSettings) or run.parent_gait is None:
            raise LibraryError(f"run {run.run_id} is a {run.kind} run, not a tuning run to resume")
        shared = (run.creature_text, s.seconds, s.metric, s.terrain, s.ensemble, s.morphology, s.batch, run.dtype)
        if first is None:
            first = shared
            spec = loads(run.creature_text, source=s.source or run.creature)
            space = Space(spec, morphology=s.morphology)
            ev = Evaluator(spec, metric=s.metric, seconds=s.seconds, dtype=run.dtype or "float32", batch=s.batch,
                           terrain=s.terrain, ensemble=s.ensemble, space=space)
        elif shared != first:
            raise ValueError(f"run {run.run_id}: runs resumed together must share creature and evaluation settings")
        assert ev is not None and ev.space is not None
        space = ev.space
        assert isinstance(space, Space)
        g = Gait.from_library(library, run.parent_gait)
        start = Start(g.weights, space.nominal(g.params), g.gait_id)
        chain = registry.make(s.method, Problem(run.run_id, space.san, s.trials, s.seed, s.chain, space, start,
                                                dtype=run.dtype or "float32"))
        chain.resume(library.top(run.run_id, None), library.trace(run.run_id))
        chains.append((run.parent_gait, chain))
    assert ev is not None
    return ev, chains


__all__ = ["tune", "TuneResult", "TuneProgress", "METHODS", "TERRAINS", "default_batch"]
