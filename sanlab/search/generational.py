"""What the CMA-ES strategies share: whole generations asked and told, restarts, and resuming by
replaying the stored generations.

A generational strategy draws a population from its optimiser, asks for it (in pieces of any size;
the driver may evaluate them anywhere, in any order), and tells the optimiser once the whole
generation is scored. Evaluation ``idx`` belongs to generation ``idx // popsize``. An optimiser is
replaced by a fresh one (a *restart*, seeded from the run's seed and the restart's number) every
``generations`` generations, or sooner when it has converged (``should_stop``).

A strategy may first spend ``warmup`` evaluations (indices 0 .. warmup - 1) on candidates of its
own choosing, one at a time in any order (:meth:`Generational.warm`: e.g. random SANs, the
paper's phase 1), and start its first optimiser from what they scored; generation ``g`` then
holds the indices ``warmup + g * popsize`` onwards.

Everything an optimiser draws follows from its seed and the scores it was told, and the library
stores every score exactly, so an interrupted run resumes by replaying its stored generations
through fresh optimisers with the same seeds: it asks the same candidates again and ends exactly
as an uninterrupted run (tests/search/test_strategies.py). Each evaluation has its own ensemble
draws (``ensemble.search_key``): no candidate is scored twice on the same luck, and an elite is
never carried over on an old, lucky score.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from sanlab.evaluate.records import ScoreBatch
from sanlab.library.records import Evaluation, EvaluationRow, TracePoint
from sanlab.search.base import Candidate, Problem, Told


class Generational:
    """Base of the ask/tell strategies that run an optimiser generation by generation (module
    docstring). A subclass sets ``popsize`` and ``generations`` (None: restart only when the
    optimiser stops) and writes :meth:`optimiser`, :meth:`candidate` and :meth:`row`; the
    optimiser has ``ask()`` (one point) and ``tell([(point, value)])`` (minimising), as
    ``cmaes.CMA`` and ``cmaes.CatCMAwM`` do, and ``should_stop()``."""

    phase: ClassVar[int] = 1
    popsize: int
    generations: int | None = None
    warmup: int = 0  # evaluations asked (by :meth:`warm`) before the first optimiser

    def __init__(self, problem: Problem):
        self.problem = problem
        self._restart, self._again = -1, 0  # the optimiser in use: its restart and its re-seeds within it
        self._opt: Any = None
        self._gen: list[tuple[int, Any]] = []  # the generation in flight: (idx, point)
        self._full: list[Any] = []  # all of its points (a last generation cut by the budget asks fewer)
        self._asked: set[int] = set()
        self._scores: dict[int, float] = {}  # scores of the generation in flight, told or stored
        self._next = 0  # the first evaluation index of the next generation (after the warm-up)
        self._stored = 0
        self._best = 0.0
        self._warm_todo: list[int] | None = None  # warm-up indices not yet asked (None: not begun)
        self.warm_scores: dict[int, float] = {}  # the warm-up's scores, by index
        # the best candidate so far (score, idx, candidate), updated as the warm-up and each
        # generation close (in index order, so a resumed run has the same): a restart starts there
        self.elite: tuple[float, int, Candidate] | None = None

    # -- what a subclass writes

    def optimiser(self, seed: int) -> Any:
        """A fresh optimiser drawing from ``seed``."""
        raise NotImplementedError

    def candidate(self, idx: int, point: Any) -> Candidate:
        """The candidate that evaluates ``point`` as evaluation ``idx``."""
        raise NotImplementedError

    def row(self, candidate: Candidate, scores: ScoreBatch, k: int) -> EvaluationRow:
        """What to store of ``candidate``, scored as row ``k`` of ``scores``."""
        raise NotImplementedError

    def warm(self, idx: int) -> Candidate:
        """The warm-up's candidate ``idx`` (only with ``warmup`` > 0); the optimisers then read
        ``warm_scores``."""
        raise NotImplementedError

    # -- the strategy

    @property
    def done(self) -> bool:
        return self._warmed and max(self._next, self._n_warm) >= self.problem.budget and not self._gen

    @property
    def _n_warm(self) -> int:
        return min(self.warmup, self.problem.budget)

    @property
    def _warmed(self) -> bool:
        """Every warm-up evaluation is scored (then the optimisers begin)."""
        return len(self.warm_scores) >= self._n_warm

    @property
    def run_ids(self) -> tuple[str, ...]:
        return (self.problem.run_id,)

    def _seed(self, restart: int, again: int) -> int:
        rng = np.random.default_rng([self.problem.seed, 56, restart, again])
        return int(rng.integers(2**31 - 1))

    def _end_warmup(self) -> None:
        """The warm-up is scored: its best is the first elite, and generations begin after it."""
        self._next = self._n_warm
        if self.warm_scores:
            i = max(sorted(self.warm_scores), key=lambda j: self.warm_scores[j])  # the first of the best
            self.elite = (self.warm_scores[i], i, self.warm(i))

    def restart_of(self, g: int) -> int:
        """The restart that generation ``g`` belongs to: a new one starts a fresh optimiser."""
        return g // self.generations if self.generations else 0

    def _new_generation(self) -> None:
        g = (self._next - self._n_warm) // self.popsize
        restart = self.restart_of(g)
        if restart != self._restart:
            self._restart, self._again = restart, 0
            self._opt = self.optimiser(self._seed(restart, 0))
        elif self._opt.should_stop():
            self._again += 1
            self._opt = self.optimiser(self._seed(restart, self._again))
        with _one_blas_thread():
            xs = [self._opt.ask() for _ in range(self.popsize)]
        n = min(self.popsize, self.problem.budget - self._next)
        self._gen = [(self._next + k, xs[k]) for k in range(n)]
        self._full = xs
        self._asked = set()
        self._scores = {}

    def ask(self, n: int) -> list[Candidate]:
        if not self._warmed:
            if self._warm_todo is None:
                self._warm_todo = [i for i in range(self._n_warm) if i not in self.warm_scores]
            take, self._warm_todo = self._warm_todo[:n], self._warm_todo[n:]
            return [self.warm(i) for i in take]  # [] while the last of them are being scored
        if self._next < self._n_warm:
            self._end_warmup()
        if not self._gen:
            if self._next >= self.problem.budget:
                return []
            self._new_generation()
        take = [(i, x) for i, x in self._gen if i not in self._asked and i not in self._scores][:n]
        self._asked.update(i for i, _ in take)
        return [self.candidate(i, x) for i, x in take]

    def _close_generation(self) -> None:
        """Tell the optimiser the whole generation (a last one cut short by the budget is not told:
        the run ends with it). It minimises; a candidate that blew up or fell scored 0 already
        (the evaluator's rule), one whose score is not a number counts as 0."""
        if len(self._gen) == self.popsize:
            with _one_blas_thread():
                self._opt.tell([(x, -self._scores[i]) for (i, _), x in zip(self._gen, self._full)])
        for i, x in self._gen:
            if self.elite is None or self._scores[i] > self.elite[0]:
                self.elite = (self._scores[i], i, self.candidate(i, x))
        self._next = self._gen[-1][0] + 1
        self._gen = []

    def tell(self, candidates: Sequence[Candidate], scores: ScoreBatch) -> Told:
        rows = []
        for k, c in enumerate(candidates):
            s = float(scores.score[k])
            s = s if math.isfinite(s) else 0.0
            if c.idx < self._n_warm:
                self.warm_scores[c.idx] = s
            else:
                self._scores[c.idx] = s
            rows.append(self.row(c, scores, k))
        self._stored += len(candidates)
        if len(scores):
            self._best = max(self._best, float(np.nan_to_num(scores.score).max()))
        if self._gen and len(self._scores) == len(self._gen):
            self._close_generation()
        return Told(rows, [], [self.problem.run_id] if self.done else [])

    def resume(self, evaluations: Sequence[Evaluation], trace: Sequence[TracePoint]) -> None:
        """Replay the stored generations through fresh optimisers (the same seeds ask the same
        candidates); a generation cut short keeps its stored scores and asks only for the rest."""
        stored = {e.idx: (e.score if e.score == e.score else 0.0) for e in evaluations}
        self._stored = len(stored)
        self._best = max(stored.values(), default=0.0)
        self.warm_scores = {i: s for i, s in stored.items() if i < self._n_warm}
        if not self._warmed:
            return  # the warm-up asks what it lacks; no generation was drawn before it ended
        self._end_warmup()
        while self._next < self.problem.budget:
            self._new_generation()
            self._scores = {i: stored[i] for i, _ in self._gen if i in stored}
            if len(self._scores) < len(self._gen):
                return
            self._close_generation()

    def progress(self) -> tuple[int, int, float]:
        return self._stored, self.problem.budget, self._best


def _one_blas_thread():
    """The optimisers' linear algebra on one BLAS thread: its matrices are small (at most a few
    hundred rows), and BLAS threads beside the kernel's OpenMP threads made CatCMAwM 12x slower on
    2 busy cores (the cart's 72 weights: 0.59 s a generation, 0.05 s on one thread)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, user_api="blas")
