"""The outer search of ``sanlab design``: ask/tell strategies over a creature file's free numbers
(paper §6.3, "Evolution"; issue 47).

A body is a vector of free values [D] within a box ``lo``..``hi`` (the file's ranges, its units).
A strategy proposes bodies (``ask``) and learns each one's score (``tell``: the robust tuned
speed, cm/s, that ``sanlab.design`` measures with phase 1, a short phase 2 and the audited
selection); it never simulates and never stores. Both are deterministic given the problem's seed
and the scores told, so a design run that is made again on the same library asks the same
bodies, finds their runs stored, and continues where it stopped.

- ``cma-es`` (the default): pyribs' CMA-ES (``ribs.emitters.opt.CMAEvolutionStrategy``) on the
  box scaled to [0, 1]^D, started at the file's defaults with a step of 0.3 of each range. A
  body costs a phase 1, a phase 2 and an audit (minutes), so a design affords tens of bodies, not
  the thousands a MAP-Elites archive needs to fill its cells; CMA-ES is the method that makes the
  most of a few evaluations in a few continuous dimensions, and it needs no descriptor chosen.
- ``random``: bodies drawn uniformly from the box, the baseline (``benchmarks/design.py``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np

SIGMA0 = 0.3  # CMA-ES's first step, as a fraction of each range


@dataclass(frozen=True)
class BodyProblem:
    """What a body strategy is built from: the box ``lo``, ``hi`` [D] and the start ``x0`` [D]
    (the file's defaults), ``budget`` bodies in all, ``generation`` bodies per ask/tell round,
    ``seed``."""

    lo: np.ndarray
    hi: np.ndarray
    x0: np.ndarray
    budget: int
    generation: int
    seed: int


class BodyStrategy(Protocol):
    """Asked for a generation of bodies [n, D] (within the box) while not ``done``; told their
    scores [n] (higher is better) in the order asked."""

    name: ClassVar[str]

    @property
    def done(self) -> bool: ...

    def ask(self) -> np.ndarray: ...

    def tell(self, bodies: np.ndarray, scores: np.ndarray) -> None: ...


class RandomBodies:
    """``budget`` bodies uniform in the box, ``generation`` at a time (the last round smaller)."""

    name: ClassVar[str] = "random"

    def __init__(self, problem: BodyProblem):
        self.p = problem
        self.rng = np.random.default_rng([problem.seed, 47])
        self.asked = 0

    @property
    def done(self) -> bool:
        return self.asked >= self.p.budget

    def ask(self) -> np.ndarray:
        n = min(self.p.generation, self.p.budget - self.asked)
        self.asked += n
        return self.p.lo + (self.p.hi - self.p.lo) * self.rng.random((n, len(self.p.lo)))

    def tell(self, bodies: np.ndarray, scores: np.ndarray) -> None:
        pass


class CmaBodies:
    """pyribs' CMA-ES on the box scaled to [0, 1]^D (see the module docstring); ``generation``
    bodies per round, the best half its parents. A last round smaller than a generation is
    asked as a whole one and cut (CMA-ES's update needs its population)."""

    name: ClassVar[str] = "cma-es"

    def __init__(self, problem: BodyProblem):
        from sanlab.search.map_elites import ribs  # the optional qd extra: one line naming it when absent

        CMAEvolutionStrategy = ribs("emitters.opt", "design --strategy cma-es").CMAEvolutionStrategy

        self.p = problem
        d = len(problem.lo)
        self.es = CMAEvolutionStrategy(SIGMA0, d, batch_size=problem.generation, seed=problem.seed,
                                       lower_bounds=np.zeros(d), upper_bounds=np.ones(d))
        self.es.reset(self._unit(problem.x0))
        self.asked = 0

    def _unit(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, float) - self.p.lo) / (self.p.hi - self.p.lo)

    @property
    def done(self) -> bool:
        return self.asked >= self.p.budget

    def ask(self) -> np.ndarray:
        with warnings.catch_warnings():
            # pyribs resamples each body until it lies in the box and, past 100 rounds, warns that
            # it "may resample forever". It cannot: the mean is a weighted mean of bodies in the
            # box. Many rounds only mean that the start (the file's defaults) sits at the ends of
            # several ranges, where half of each draw falls outside: no news for a user.
            warnings.filterwarnings("ignore", message="During bounds handling")
            u = np.clip(self.es.ask(), 0.0, 1.0)
        n = min(len(u), self.p.budget - self.asked)
        self.asked += n
        return self.p.lo + (self.p.hi - self.p.lo) * u[:n]

    def tell(self, bodies: np.ndarray, scores: np.ndarray) -> None:
        if len(bodies) < self.p.generation:
            return  # the last, cut round: nothing follows it
        order = np.argsort(-np.asarray(scores, float), kind="stable")
        self.es.tell(order, np.asarray(scores, float)[order], max(1, len(bodies) // 2))


BODIES: dict[str, type] = {"cma-es": CmaBodies, "random": RandomBodies}


def make_bodies(name: str, problem: BodyProblem) -> BodyStrategy:
    """The body strategy called ``name``; ValueError for an unknown name."""
    if name not in BODIES:
        raise ValueError(f"strategy: expected one of {list(BODIES)}, got {name!r}")
    return BODIES[name](problem)


__all__ = ["BODIES", "BodyProblem", "BodyStrategy", "CmaBodies", "RandomBodies", "make_bodies"]
