"""Phase 1 (paper §5.2): random generation and evaluation.

Controller ``idx`` of a run seeded ``seed`` always has the same weights (its own random stream,
``San.random_weights``) and the same ensemble draws (``ensemble.search_key``), so a search
interrupted at any point resumes by asking only for the indices not yet stored, and ends exactly
as an uninterrupted one; batches may be evaluated anywhere and come back in any order.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.records import ScoreBatch
from sanlab.library.records import Evaluation, EvaluationRow, TracePoint
from sanlab.search.base import Candidate, Problem, Told


class RandomSearch:
    """``problem.budget`` random SANs, weights uniform integers in [-2, 2], each evaluated with
    the creature file's parameters and stored with ``problem.gait_params``."""

    phase: ClassVar[int] = 1

    def __init__(self, problem: Problem):
        self.problem = problem
        self._todo = list(range(problem.budget))
        self._pending = 0
        self._stored = 0
        self._best = 0.0

    @property
    def done(self) -> bool:
        """Every controller not stored before has been asked for and told."""
        return not self._todo and not self._pending

    @property
    def run_ids(self) -> tuple[str, ...]:
        return (self.problem.run_id,)

    def resume(self, evaluations: Sequence[Evaluation], trace: Sequence[TracePoint]) -> None:
        stored = {e.idx for e in evaluations}
        self._todo = [i for i in self._todo if i not in stored]
        self._stored = len(stored)
        self._best = max((e.score for e in evaluations if e.score == e.score), default=0.0)

    def ask(self, n: int) -> list[Candidate]:
        take, self._todo = self._todo[:n], self._todo[n:]
        self._pending += len(take)
        p = self.problem
        return [Candidate(i, p.san.random_weights(p.seed, i), None, search_key(p.seed, i)) for i in take]

    def tell(self, candidates: Sequence[Candidate], scores: ScoreBatch) -> Told:
        p = self.problem
        rows = [EvaluationRow(p.run_id, c.idx, p.san.encode(c.weights), p.gait_params, scores.row(k))
                for k, c in enumerate(candidates)]
        self._pending -= len(candidates)
        self._stored += len(candidates)
        if len(scores):
            self._best = max(self._best, float(scores.score.max()))
        return Told(rows, [], [p.run_id] if self.done else [])

    def progress(self) -> tuple[int, int, float]:
        return self._stored, self.problem.budget, self._best
