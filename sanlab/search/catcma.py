"""Phase 1 by mixed-integer CMA-ES: random SANs first, then the weights learnt from the best of them.

The paper draws 200 SANs at random and keeps the weights of the best fixed, because "small changes
in the weights often result in either no change at all or a very large change" (§5.3). A
mixed-integer evolution strategy learns which weights matter from whole generations instead of
single changes: CatCMAwM (Hamano et al., GECCO 2025, arXiv 2504.07884; ``cmaes.CatCMAwM``) keeps
a Gaussian over the weights, rounds it onto the SAN's alphabet {-2, ..., 2} (§4) and holds a
margin of probability on each integer so that no weight freezes.

A run first spends a sixth of its budget (:data:`WARMUP`) on random SANs, exactly the controllers
a random search of the same seed draws (so it finds the paper's modes too), then runs CatCMAwM
from the best of them (each weight spread by :data:`SPREAD`), with its default population
4 + floor(3 ln n) (20 for the bounder's 240 weights), until it converges; each restart starts
from the best SAN so far with a new seed (``sanlab.search.generational``). Started from the
alphabet's centre instead, it lost the luxo (49 cm/s held out, against random search and
annealing's 117 at the same 3,000 evaluations) where the warm start reached 133.

Each controller is evaluated with the creature file's node delays, actuator and sensor
parameters, exactly as a random SAN (its gaits are phase-1 gaits: tuned, audited and shown as
any); phase 2 (``sanlab tune``) then tunes those. Every evaluation has its own perturbed starts,
so an optimiser is never told an old score twice. What it finds against random search and the
pattern ceiling: ``benchmarks/search_strength.py`` and docs/search-strength.md.
"""

from __future__ import annotations

import numpy as np

from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.records import ScoreBatch
from sanlab.library.records import EvaluationRow
from sanlab.san import WEIGHT_MAX, WEIGHT_MIN
from sanlab.search.base import Candidate, Problem
from sanlab.search.generational import Generational

WARMUP = 1 / 6  # of the budget on random SANs first: the paper's proportions (200 random SANs, 1000 tuning trials)
SPREAD = 0.8  # a weight's standard deviation about the elite a restart starts from (the alphabet's step is 1)


def around(weights, spread: float, population_size: int, seed: int):
    """CatCMAwM over the weights' alphabet {-2, ..., 2}, started from ``weights`` (any shape),
    each with a standard deviation of ``spread`` (a weight at the alphabet's edge sits a little
    inside it: the package needs room on both sides)."""
    from cmaes import CatCMAwM

    mean = np.clip(np.asarray(weights, float).reshape(-1), WEIGHT_MIN + 0.5, WEIGHT_MAX - 0.5)
    n = mean.size
    return CatCMAwM(z_space=[list(range(WEIGHT_MIN, WEIGHT_MAX + 1))] * n, population_size=population_size,
                    seed=seed, mean=mean, cov=np.eye(n) * spread**2, sigma=1.0)


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
        self.warmup = int(problem.budget * WARMUP)

    def warm(self, idx: int) -> Candidate:
        """Random SAN ``idx``: the one a random search of this seed evaluates as its ``idx``."""
        p = self.problem
        return Candidate(idx, p.san.random_weights(p.seed, idx), None, search_key(p.seed, idx))

    def optimiser(self, seed: int):
        from cmaes import CatCMAwM

        n = self.shape[0] * self.shape[1]
        alphabet = list(range(WEIGHT_MIN, WEIGHT_MAX + 1))
        if self.elite is None:  # no warm-up: the alphabet's centre, the package's own spread
            return CatCMAwM(z_space=[alphabet] * n, population_size=self.popsize, seed=seed)
        return around(self.elite[2].weights, SPREAD, self.popsize, seed)  # from the best SAN so far

    def candidate(self, idx: int, point) -> Candidate:
        w = np.rint(np.asarray(point.z)).astype(np.int8).reshape(self.shape)
        return Candidate(idx, w, None, search_key(self.problem.seed, idx))

    def row(self, candidate: Candidate, scores: ScoreBatch, k: int) -> EvaluationRow:
        p = self.problem
        return EvaluationRow(p.run_id, candidate.idx, p.san.encode(candidate.weights), p.gait_params, scores.row(k))
