"""Accept/reject chains over a parameter vector, run speculatively in batches.

Stochastic gradient ascent and simulated annealing (paper §5.3) are sequential: each trial
perturbs the current vector and is accepted or rejected before the next. A chain here draws every
trial's random choices (which parameter, which sign, and the acceptance uniform) in advance, so
``ask(n)`` can propose trials t .. t+n-1 against the current vector at once; ``tell`` walks them
in order and stops at the first accepted one, discarding the speculation after it (those trials
are asked again, against the new vector). The accepted and rejected trials, their order and their
outcomes are exactly those of the one-at-a-time algorithm; the batch only saves wall time.
"""

from __future__ import annotations

import numpy as np

from sanlab.search.base import Candidate
from sanlab.search.space import Space


class Chain:
    """Base: hill-climbing on ``space`` from ``theta0`` (with known score ``score0``)."""

    def __init__(self, space: Space, weights: np.ndarray, theta0: np.ndarray, score0: float, trials: int, seed: int):
        self.space, self.weights, self.trials = space, weights, trials
        rng = np.random.default_rng(seed)
        self.which = rng.integers(0, len(space), trials)
        self.sign = rng.choice([-1.0, 1.0], trials)
        self.uniform = rng.random(trials)
        self.theta, self.score = np.array(theta0, float), float(score0)
        self.best_theta, self.best = self.theta.copy(), self.score
        self.t = 0  # trials decided so far
        self.trace: list[tuple[int, float, bool]] = []  # (trial, score, accepted)
        self.accepted = 0
        self.wasted = 0  # speculative evaluations discarded

    @property
    def done(self) -> bool:
        """Every trial has been decided."""
        return self.t >= self.trials

    def ask(self, n: int) -> list[Candidate]:
        end = min(self.trials, self.t + n)
        return [
            Candidate(t, self.weights, {"theta": self.space.perturb(self.theta, self.which[t], self.sign[t])})
            for t in range(self.t, end)
        ]

    def accept(self, trial: int, new: float) -> bool:
        raise NotImplementedError

    def tell(self, candidates: list[Candidate], results: dict[str, np.ndarray]) -> None:
        for k, c in enumerate(candidates):
            new = float(results["score"][k])
            ok = bool(np.isfinite(new)) and not bool(results["nonfinite"][k]) and self.accept(c.idx, new)
            self.trace.append((c.idx, new, ok))
            self.t = c.idx + 1
            if ok:
                self.theta, self.score = c.params["theta"], new
                self.accepted += 1
                if new > self.best:
                    self.best_theta, self.best = self.theta.copy(), new
                self.wasted += len(candidates) - k - 1
                return
