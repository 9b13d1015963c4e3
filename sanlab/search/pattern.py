"""The pattern ceiling: CMA-ES over open-loop square waves, a reference for what a body allows.

A *pattern* drives each actuator between the two ends of its range on a clock, as a SAN's
actuator nodes switch between targets on its sensors: per actuator a phase and a duty (the
fraction of the period spent at the range's upper end), and one period for all (2 A + 1
numbers, played by ``sanlab.sim.PatternController``). The controller could also hold each
actuator's two levels, but searching them too found slower gaits (the bounder, 1,280 patterns,
two seeds: 155 and 186 cm/s held out, against 245 and 246 for the full swing), so the search
keeps the ends. It senses nothing, so it is no SAN; the fastest pattern under the same robust
objective as every score (the ensemble's median, the lower of the dt and dt/2 groups) says how
fast the body can go with the SAN's own outputs, and a SAN gait's speed over it says how much of
that the search found (issue 56; on the paper's creatures patterns reach 2x a SAN on the bounder,
and less than a SAN where the closed loop holds a gait an open loop cannot).

The search is CMA-ES (``cmaes.CMA``, Hansen's algorithm as CyberAgent's package writes it: a
small, dependency-free, ask/tell implementation with box bounds) over a vector in [0, 1]^(2A+1),
phases wrapping round the cycle and the period on a log scale in :data:`PERIOD_RANGE`, restarted
from a new random mean every :data:`GENERATIONS` generations (or when it stops), so a budget of
many evaluations is several independent climbs, as a researcher would run it. Each evaluation has
its own ensemble draws (``ensemble.search_key``), so no pattern is scored twice on the same luck.

Generations, restarts and resuming are ``sanlab.search.generational``'s: an interrupted run
resumes by replaying its stored generations and ends exactly as an uninterrupted one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.records import GaitParams, ScoreBatch
from sanlab.library.records import EvaluationRow
from sanlab.search.base import Candidate, Problem
from sanlab.search.generational import Generational

PERIOD_RANGE = (0.1, 2.0)  # s: searched periods (the paper's node delays, 0.07-0.15 s, make cycles of 0.3-0.6 s)
GENERATIONS = 40  # per restart of CMA-ES
POPSIZE = 32  # candidates per generation (the default for this search; larger than CMA-ES's 4 + 3 ln n for the noise)
SIGMA0 = 0.3  # the first step size, in the unit cube


def decode(x: np.ndarray, actuators: int) -> np.ndarray:
    """Points of the search's unit cube [..., 2 A + 1] (per actuator a phase and a duty, then the
    period) -> patterns [..., 4 A + 1] (``sim.PatternController``: per actuator phase, duty, low,
    high, then the period): phases wrapped into [0, 1), duties clipped to [0, 1], every actuator
    switched between its range's ends (low 0, high 1), the period exp-mapped onto
    :data:`PERIOD_RANGE` (s)."""
    x = np.asarray(x, float)
    A = actuators
    out = np.zeros(x.shape[:-1] + (4 * A + 1,))
    out[..., 0:4 * A:4] = np.mod(x[..., 0:2 * A:2], 1.0)
    out[..., 1:4 * A:4] = np.clip(x[..., 1:2 * A:2], 0.0, 1.0)
    out[..., 3:4 * A:4] = 1.0
    lo, hi = PERIOD_RANGE
    out[..., 4 * A] = lo * (hi / lo) ** np.clip(x[..., 2 * A], 0.0, 1.0)
    return out


class PatternSearch(Generational):
    """``problem.budget`` evaluations of open-loop patterns by restarted CMA-ES (module
    docstring); ``problem.generation`` is the population (the CLI's default :data:`POPSIZE`).
    Every pattern is stored as a gait of its own kind (``GaitParams.pattern``, all-zero
    weights)."""

    generations = GENERATIONS

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self.actuators = problem.san.n_actuators
        self.dim = 2 * self.actuators + 1
        self.popsize = max(4, int(problem.generation))
        self._zero = np.zeros((problem.san.n_nodes, problem.san.n_inputs), np.int8)

    def optimiser(self, seed: int) -> Any:
        from cmaes import CMA

        rng = np.random.default_rng(seed)
        phases = [i < 2 * self.actuators and i % 2 == 0 for i in range(self.dim)]
        bounds = np.array([[-1e9, 1e9] if wrap else [0.0, 1.0] for wrap in phases])  # a phase wraps: unbounded
        return CMA(mean=rng.uniform(0.2, 0.8, self.dim), sigma=SIGMA0, bounds=bounds, seed=int(rng.integers(2**31 - 1)),
                   population_size=self.popsize)

    def candidate(self, idx: int, point) -> Candidate:
        p = self.problem
        return Candidate(idx, self._zero, None, search_key(p.seed, idx), pattern=decode(point, self.actuators))

    def row(self, candidate: Candidate, scores: ScoreBatch, k: int) -> EvaluationRow:
        assert candidate.pattern is not None
        p = self.problem
        return EvaluationRow(p.run_id, candidate.idx, p.san.encode(self._zero),
                             GaitParams(pattern=tuple(candidate.pattern.tolist())), scores.row(k))
