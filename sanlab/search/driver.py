"""The one search driver: ask a strategy, evaluate on a backend, tell, commit, report.

    run(strategy, evaluator, library, reporter, backend)

keeps up to ``backend.slots`` batches in flight; as each comes back (in any order) it tells the
strategy its scores and commits what the strategy returns — evaluated controllers, decided
tuning trials, finished runs — in one transaction, then reports progress. The gait library is
the search's memory: an interrupted run (Ctrl-C, or SIGKILL) loses at most the batches in
flight and resumes from what is stored (each strategy's ``resume``). The driver is the only
writer of the library, whatever the backend.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sanlab.evaluate.backends import Backend, Local
from sanlab.evaluate.evaluator import Evaluator, Request
from sanlab.library import Library, LibraryError
from sanlab.search.base import Candidate, Strategy


@dataclass(frozen=True)
class Progress:
    """What a reporter is told once at the start, after every committed batch and at the end."""

    run_id: str  # the (first) run being written
    evaluated: int  # units finished so far, earlier sessions of a resumed run included:
    #                 controllers stored (search) or trials decided (tuning, all chains)
    total: int
    best: float  # best score so far (0 before any; a tuning chain's own in-sample best)
    rate: float  # evaluations per second in this session (speculative ones included)
    done: bool = False
    run_ids: tuple[str, ...] = ()  # every run being written
    stats: dict | None = None  # what the strategy says of itself (map-elites: coverage, qd_score, elites)
    workers: int | None = None  # workers alive on the backend (a Ray cluster's); None: this machine

    @property
    def trials(self) -> int:
        """``evaluated``, under the name tuning reporters use."""
        return self.evaluated


Reporter = Callable[[Progress], None]


@dataclass(frozen=True)
class Summary:
    """What a finished driver run did in this session."""

    evaluations: int  # controllers evaluated (speculative tuning trials included)
    seconds: float  # wall time


def run(strategy: Strategy, evaluator: Evaluator, library: Library, reporter: Reporter | None = None,
        backend: Backend | None = None) -> Summary:
    """Drive ``strategy`` to the end (see the module docstring); returns what this session did.

    The strategy's runs must exist; they are marked "running" now, each "done" in the transaction
    that stores its last rows, and "interrupted" (those not done) if anything (Ctrl-C included)
    stops the driver, which re-raises it. ``backend``: default :class:`~sanlab.evaluate.backends.Local`
    (started and closed here either way).
    """
    backend = backend if backend is not None else Local()
    report = reporter or (lambda p: None)
    run_ids = strategy.run_ids
    finished: set[str] = set()
    for r in run_ids:
        library.set_status(r, "running")
    t0 = time.perf_counter()
    evaluated = 0

    def progress(done: bool = False) -> Progress:
        units, total, best = strategy.progress()
        rate = evaluated / max(time.perf_counter() - t0, 1e-9)
        stats = getattr(strategy, "stats", None)
        said = stats() if callable(stats) else None
        alive = getattr(backend, "alive", None)  # a cluster's backend says how many of its workers are up
        workers = alive() if callable(alive) else None
        return Progress(run_ids[0], units, total, best, rate, done, run_ids, said if isinstance(said, dict) else None,
                        workers if isinstance(workers, int) else None)

    pending: dict[int, list[Candidate]] = {}
    try:
        backend.start(evaluator)
        report(progress())
        while not strategy.done:
            while len(pending) < backend.slots:
                cands = strategy.ask(evaluator.batch)
                if not cands:
                    break
                pending[backend.submit(_request(cands))] = cands
            if not pending:
                raise RuntimeError(f"{type(strategy).__name__} asked for nothing but is not done")
            ticket, scores = backend.next()
            cands = pending.pop(ticket)
            told = strategy.tell(cands, scores)
            library.commit(told.evaluations, told.trace, told.finished)
            finished.update(told.finished)
            evaluated += len(cands)
            report(progress())
        for r in run_ids:  # a resumed run that had nothing left to do
            if r not in finished:
                library.set_status(r, "done")
        finished.update(run_ids)
    except BaseException:
        for r in run_ids:
            if r not in finished:
                try:
                    library.set_status(r, "interrupted")
                except LibraryError:  # the disk that stopped the run may refuse this too: the cause is
                    pass  # what to report; the run reads "interrupted" once this process is gone
        raise
    finally:
        backend.close()
    report(progress(done=True))
    return Summary(evaluated, time.perf_counter() - t0)


def _request(cands: list[Candidate]) -> Request:
    thetas = [c.theta for c in cands]
    if any(t is None for t in thetas) and not all(t is None for t in thetas):
        raise ValueError("a batch mixes controllers with and without parameter vectors")
    stacked = None if thetas[0] is None else np.stack([np.asarray(t) for t in thetas])
    patterns = [c.pattern for c in cands]
    if any(x is None for x in patterns) and not all(x is None for x in patterns):
        raise ValueError("a batch mixes patterns and SANs")
    rows = None if patterns[0] is None else np.stack([np.asarray(x) for x in patterns])
    return Request(np.stack([c.weights for c in cands]), stacked, tuple(c.key for c in cands), rows)
