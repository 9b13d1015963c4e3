"""Simulated annealing (paper §5.3, after Kirkpatrick et al. and Fiume & Ouellette)."""

from __future__ import annotations

import math

from sanlab.search.base import Problem
from sanlab.search.chain import Chain


class Anneal(Chain):
    """Simulated annealing: 65 trials at each temperature, the next 0.75 x the previous; a worse
    score is accepted with probability exp((new - current) / T).

    Starting temperature: ``t0_fraction`` (5 %) of the starting score's magnitude, so that at first
    a change costing 5 % of the score is accepted with probability 1/e; after the paper's 1000
    trials (16 temperatures) T has fallen to 1.3 % of that and the chain is nearly greedy. (A
    chain starting from a score of 0 uses T0 = 1e-3.)
    """

    PER_TEMPERATURE = 65
    COOLING = 0.75

    def __init__(self, problem: Problem, t0_fraction: float = 0.05):
        self.t0_fraction = t0_fraction
        self.t0 = float("nan")
        super().__init__(problem)

    def started(self) -> None:
        self.t0 = max(self.t0_fraction * abs(self.score), 1e-3)

    def temperature(self, trial: int) -> float:
        return self.t0 * self.COOLING ** (trial // self.PER_TEMPERATURE)

    def accept(self, trial: int, new: float) -> bool:
        if new > self.score:
            return True
        return self.uniform[trial] < math.exp((new - self.score) / self.temperature(trial))
