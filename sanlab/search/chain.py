"""Accept/reject chains over a parameter vector, run speculatively in batches.

Stochastic gradient ascent and simulated annealing (paper §5.3) are sequential: each trial
perturbs the current vector and is accepted or rejected before the next. A chain here draws every
trial's random choices (which parameter, which sign, and the acceptance uniform) in advance, so
``ask(n)`` can propose trials t .. t+n-1 against the current vector at once; ``tell`` walks them
in order and stops at the first accepted one, discarding the speculation after it (those trials
are asked again, against the new vector). The accepted and rejected trials, their order and their
outcomes are exactly those of the one-at-a-time algorithm; the batch only saves wall time.

A chain's life, each step one batch: its start scored under the tuning conditions (unless the
:class:`~sanlab.search.base.Start` brings its scores), the trials, then the held-out evaluation of
the best vector on fresh ensemble draws (``ensemble.heldout_key``), which is what the tuned gait
stores as its score: the chain's luckiest sample is not reported as its result (its own best is
kept in the row's ``extra`` as ``chain_best``). Every decided trial is committed with its batch,
so an interrupted chain resumes by re-scoring its start and replaying its stored trials
(acceptances and scores), and ends exactly as an uninterrupted one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from sanlab.evaluate.ensemble import chain_key, heldout_key, start_key, trial_key
from sanlab.evaluate.records import ScoreBatch, Scores
from sanlab.library.records import Evaluation, EvaluationRow, TracePoint, TraceRow
from sanlab.search.base import Candidate, Problem, Told


class Chain:
    """Base: hill-climbing on ``problem.space`` from ``problem.start``; subclasses say what is
    accepted (:meth:`accept`) and may set up on the start's score (:meth:`started`)."""

    phase: ClassVar[int] = 2

    def __init__(self, problem: Problem):
        if problem.space is None or problem.start is None:
            raise ValueError(f"{type(self).__name__} tunes a start's parameters: give a space and a start")
        self.problem = problem
        self.space, self.weights, self.trials = problem.space, problem.start.weights, problem.budget
        rng = np.random.default_rng(list(chain_key(problem.seed, problem.stream)))
        self.which = rng.integers(0, len(self.space), self.trials)
        self.sign = rng.choice([-1.0, 1.0], self.trials)
        self.uniform = rng.random(self.trials)
        self.theta = np.array(problem.start.theta, float)
        self.best_theta = self.theta.copy()
        self.before: Scores | None = None  # the start's scores
        self.score = self.best = float("nan")
        self.t = 0  # trials decided so far
        self.trace: list[tuple[int, float, bool]] = []  # (trial, score, accepted)
        self.accepted = 0
        self.wasted = 0  # speculative evaluations discarded
        self.result: Scores | None = None  # the held-out scores of the best vector
        self._pending = False
        self._replay: list[TracePoint] = []
        self._finished = False
        self._model: Any = None
        if problem.start.scores is not None:
            self._started(problem.start.scores)

    # -- what subclasses define ------------------------------------------------------------------

    def accept(self, trial: int, new: float) -> bool:
        raise NotImplementedError

    def started(self) -> None:
        """Called once the start's score (``self.score``) is known."""

    # -- the Strategy protocol -------------------------------------------------------------------

    @property
    def done(self) -> bool:
        return self._finished

    @property
    def run_ids(self) -> tuple[str, ...]:
        return (self.problem.run_id,)

    def progress(self) -> tuple[int, int, float]:
        return self.t, self.trials, 0.0 if self.best != self.best else self.best

    def resume(self, evaluations: Sequence[Evaluation], trace: Sequence[TracePoint]) -> None:
        final = [e for e in evaluations if e.idx == 0]
        if final:  # finished before: nothing left to evaluate
            e = final[0]
            extra = e.extra or {}
            self._finished = True
            self.t = self.trials
            self.trace = [(p.trial, p.score, p.accepted) for p in trace]
            self.accepted = int(extra.get("accepted", sum(p.accepted for p in trace)))
            self.result = e.scores
            if "before" in extra:
                self.before = Scores.from_json(extra["before"])
            self.best = float(extra.get("chain_best", e.score))
            return
        self._replay = sorted(trace, key=lambda p: p.trial)
        if self.before is not None:
            self._apply_replay()

    def ask(self, n: int) -> list[Candidate]:
        if self._pending or self._finished:
            return []
        p = self.problem
        self._pending = True
        if self.before is None:
            return [Candidate(0, self.weights, self.theta.copy(), start_key(p.seed, p.stream), "start")]
        if self.t >= self.trials:
            return [Candidate(0, self.weights, self.best_theta.copy(), heldout_key(p.seed, p.stream), "final")]
        end = min(self.trials, self.t + max(1, n))
        return [Candidate(t, self.weights, self.space.perturb(self.theta, self.which[t], self.sign[t]),
                          trial_key(p.seed, p.stream, t), "trial") for t in range(self.t, end)]

    def tell(self, candidates: Sequence[Candidate], scores: ScoreBatch) -> Told:
        self._pending = False
        if not candidates:
            return Told()
        role = candidates[0].role
        if role == "start":
            self._started(scores.row(0))
            self._apply_replay()
            return Told()
        if role == "final":
            return self._final(scores.row(0))
        told = Told()
        run_id = self.problem.run_id
        for k, c in enumerate(candidates):
            new = float(scores.score[k])
            ok = bool(np.isfinite(new)) and not bool(scores.nonfinite[k]) and self.accept(c.idx, new)
            self._decide(c.idx, new, ok, c.theta)
            told.trace.append(TraceRow(run_id, c.idx, new, ok))
            if ok:
                self.wasted += len(candidates) - k - 1
                break
        return told

    # -- internals ------------------------------------------------------------------------------

    def _started(self, scores: Scores) -> None:
        self.before = scores
        self.score = self.best = scores.score
        self.started()

    def _decide(self, trial: int, new: float, ok: bool, theta: np.ndarray | None) -> None:
        self.trace.append((trial, new, ok))
        self.t = trial + 1
        if ok:
            assert theta is not None
            self.theta, self.score = np.array(theta, float), new
            self.accepted += 1
            if new > self.best:
                self.best_theta, self.best = self.theta.copy(), new

    def _apply_replay(self) -> None:
        """Re-decide the stored trials as they were decided (their acceptances and scores)."""
        for p in self._replay:
            if p.trial != self.t:
                raise ValueError(f"run {self.problem.run_id}: stored trials are not consecutive at {p.trial}")
            theta = self.space.perturb(self.theta, self.which[p.trial], self.sign[p.trial]) if p.accepted else None
            self._decide(p.trial, p.score, p.accepted, theta)
        self._replay = []

    def _final(self, result: Scores) -> Told:
        p = self.problem
        assert p.start is not None and self.before is not None
        self.result = result
        self._finished = True
        if self._model is None:
            from sanlab import sim

            self._model = sim.compile_creature(self.space.spec, p.dtype)
        extra = {"accepted": self.accepted, "theta": self.best_theta.tolist(), "chain_best": self.best,
                 "before": self.before.to_json()}
        row = EvaluationRow(p.run_id, 0, p.san.encode(self.weights), self.space.gait_params(self.best_theta, self._model),
                            result, extra, p.start.parent)
        return Told([row], [], [p.run_id])
