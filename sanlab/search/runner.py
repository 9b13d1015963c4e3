"""Phase 1 set up for the driver: a search run (random SANs, or MAP-Elites), new or resumed
(``sanlab search``)."""

from __future__ import annotations

from sanlab import __version__
from sanlab.creature import loads
from sanlab.evaluate.backends import Backend, Local
from sanlab.evaluate.ensemble import Ensemble, default_ensemble
from sanlab.evaluate.evaluator import Evaluator
from sanlab.evaluate.records import GaitParams
from sanlab.library import Library, LibraryError, SearchSettings
from sanlab.search import driver, registry
from sanlab.search.base import Grid, Problem
from sanlab.search.map_elites import parse_grid
from sanlab.search.space import Space

SearchProgress = driver.Progress  # the name reporters of phase 1 have used


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
    dtype: str = "float64",
    ensemble: int | Ensemble = 8,
    reporter: driver.Reporter | None = None,
    resume: str | None = None,
    backend: Backend | None = None,
    strategy: str = "random",
    grid: Grid | None = None,
) -> str:
    """Phase 1: evaluate ``controllers`` random SANs, each scored over an ensemble of
    ``ensemble`` perturbed copies (a number of members, or an :class:`Ensemble`; 1: a single
    unperturbed rollout); returns the run id.

    With ``resume=RUN_ID`` everything (creature text, settings, seed, dtype) comes from the
    stored run and only the controllers not yet stored are evaluated; the run then ends exactly
    as an uninterrupted one. ``backend``: where evaluations run (default: this machine).
    ``strategy``: a phase-1 strategy of ``sanlab.search.registry`` ("random", "map-elites": then
    ``grid`` is its archive, and ``batch`` its generation). ``batch``: controllers simulated
    together; a random search of fewer controllers than that simulates (and stores as its batch)
    only those. ValueError for an unknown strategy.
    """
    backend = backend if backend is not None else Local()
    if resume is not None:
        run = library.get_run(resume)
        s = run.settings
        if run.kind != "search" or not isinstance(s, SearchSettings):
            raise LibraryError(f"run {run.run_id} is a {run.kind} run, not a search to resume")
        creature_text = run.creature_text
        spec = loads(creature_text, source=s.source or run.creature)
        controllers, seconds, metric, batch, ens = s.controllers, s.seconds, s.metric, s.batch, s.ensemble
        strategy, grid = s.strategy, None if s.grid is None else Grid.from_json(s.grid)
        seed = run.seed if run.seed is not None else seed  # a search run always stores both
        dtype = run.dtype or dtype
        run_id = run.run_id
    else:
        spec = loads(creature_text, source=creature_source)
        ens = ensemble if isinstance(ensemble, Ensemble) else default_ensemble(int(ensemble))
        run_id = None
    if strategy not in registry.names(1):
        raise ValueError(f"strategy: expected one of {registry.names(1)}, got {strategy!r}")
    if strategy == "map-elites" and grid is None:
        grid = parse_grid(None)
    if run_id is None and strategy == "random":
        # the evaluator pads every call to its batch: 64 controllers in a batch of 256 simulated
        # 256; a controller's score does not depend on its batch, so this changes no result
        batch = min(batch, controllers)
    space = Space(spec) if getattr(registry.STRATEGIES[strategy], "needs_space", False) else None
    ev = Evaluator(spec, metric=metric, seconds=seconds, dtype=dtype, batch=batch, ensemble=ens, space=space)
    on, off = ev.delays()
    if run_id is None:
        settings = SearchSettings(
            controllers, ev.seconds, ev.metric.kind, batch, creature_source, ens, on, off,
            {"sensors": ev.san.n_sensors, "hidden": ev.san.n_hidden, "actuators": ev.san.n_actuators},
            strategy=strategy, grid=None if grid is None or strategy == "random" else grid.to_json())
        run_id = library.create_run(
            kind="search", creature=spec.name, creature_text=creature_text, params=settings.to_json(), seed=seed,
            total=controllers, dtype=dtype, device=backend.describe(), sanlab_version=__version__,
        ).run_id
    problem = Problem(run_id, ev.san, controllers, seed, gait_params=GaitParams(on, off), dtype=dtype,
                      grid=grid if strategy != "random" else None, generation=batch, space=space)
    searcher = registry.make(strategy, problem)
    searcher.resume(library.top(run_id, None), [])
    driver.run(searcher, ev, library, reporter, backend)
    return run_id
