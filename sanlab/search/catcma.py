"""Phase 1 by mixed-integer CMA-ES: the SAN's weights searched as one distribution, not drawn at random.

The paper draws 200 SANs at random and keeps the weights of the best fixed, because "small changes
in the weights often result in either no change at all or a very large change" (§5.3). A
mixed-integer evolution strategy learns which weights matter from whole generations instead of
single changes: CatCMAwM (Hamano et al., GECCO 2025, arXiv 2504.07884; ``cmaes.CatCMAwM``) keeps a
Gaussian over the weights, rounds it onto the SAN's alphabet {-2, ..., 2} (§4) and holds a
margin of probability on each integer so that no weight freezes. Its default population,
4 + floor(3 ln n) (20 for the bounder's 240 weights), runs until it converges, then restarts
with a new seed (``sanlab.search.generational``).

Each controller is evaluated with the creature file's node delays, actuator and sensor
parameters, exactly as a random SAN (so its gaits are phase-1 gaits: tuned, audited and shown
as any); phase 2 (``sanlab tune``) then tunes those. Every evaluation has its own perturbed
starts, so an optimiser is never told an old score twice.

Measured on the bounder (robust median, held-out starts), 3,000 evaluations: 148 cm/s against
random search's 56 at the same number (``benchmarks/search_strength.py``; docs/search.md).
"""

from __future__ import annotations

import numpy as np

from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.records import ScoreBatch
from sanlab.library.records import EvaluationRow
from sanlab.san import WEIGHT_MAX, WEIGHT_MIN
from sanlab.search.base import Candidate, Problem
from sanlab.search.generational import Generational


def population(n_weights: int) -> int:
    """CatCMAwM's default population for ``n_weights`` integer variables: 4 + floor(3 ln n)."""
    return 4 + int(3 * np.log(n_weights))


class CatCma(Generational):
    """``problem.budget`` SANs drawn by CatCMAwM over the weights (module docstring), stored as
    phase-1 controllers with ``problem.gait_params``."""

    def __init__(self, problem: Problem):
        super().__init__(problem)
        san = problem.san
        self.shape = (san.n_nodes, san.n_inputs)
        self.popsize = population(san.n_nodes * san.n_inputs)

    def optimiser(self, seed: int):
        from cmaes import CatCMAwM

        alphabet = list(range(WEIGHT_MIN, WEIGHT_MAX + 1))
        return CatCMAwM(z_space=[alphabet] * (self.shape[0] * self.shape[1]), population_size=self.popsize, seed=seed)

    def candidate(self, idx: int, point) -> Candidate:
        w = np.rint(np.asarray(point.z)).astype(np.int8).reshape(self.shape)
        return Candidate(idx, w, None, search_key(self.problem.seed, idx))

    def row(self, candidate: Candidate, scores: ScoreBatch, k: int) -> EvaluationRow:
        p = self.problem
        return EvaluationRow(p.run_id, candidate.idx, p.san.encode(candidate.weights), p.gait_params, scores.row(k))
