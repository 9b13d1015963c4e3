"""Every search strategy by name: the one list the command line, ``reproduce`` and the tests use.

A new optimiser is one module implementing ``sanlab.search.base.Strategy`` (constructed from a
``Problem``; ``phase`` 1 searches weights from scratch, phase 2 tunes a start's parameters) plus
its line here; ``tests/search/test_strategies.py`` then runs the shared API checks on it.

``BODIES`` are the strategies of the outer search of ``sanlab design`` (``sanlab.search.bodies``):
ask/tell over a creature file's free numbers, each body scored by a whole phase 1, phase 2 and
audited selection (``sanlab.design``), whose searches and tunings run on the driver.
"""

from __future__ import annotations

from sanlab.search.anneal import Anneal
from sanlab.search.base import Problem, Strategy, StrategyClass
from sanlab.search.bodies import BODIES, make_bodies
from sanlab.search.catcma import CatCma
from sanlab.search.map_elites import MapElites
from sanlab.search.pattern import PatternSearch
from sanlab.search.random_search import RandomSearch
from sanlab.search.rhythm import ReflexSearch, RhythmSearch
from sanlab.search.sga import SGA

STRATEGIES: dict[str, StrategyClass] = {
    "random": RandomSearch,  # phase 1 (§5.2)
    "catcma": CatCma,  # phase 1: mixed-integer CMA-ES over the weights
    "map-elites": MapElites,  # phase 1: a repertoire over two behaviour descriptors
    "rhythm": RhythmSearch,  # phase 1: SANs built as clocks, CMA-ES over their rhythm
    "reflex": ReflexSearch,  # phase 1: the rhythm search, then reflexes (sensors to actuators) on its best
    "pattern": PatternSearch,  # phase 1: open-loop patterns by CMA-ES, the pattern ceiling (no SAN)
    "sga": SGA,  # phase 2: stochastic gradient ascent (Figure 9)
    "sa": Anneal,  # phase 2: simulated annealing
}


def names(phase: int) -> list[str]:
    """The registered strategies of ``phase`` (1 or 2)."""
    return [n for n, cls in STRATEGIES.items() if cls.phase == phase]


def make(name: str, problem: Problem) -> Strategy:
    """The strategy called ``name`` for ``problem``; ValueError for an unknown name."""
    if name not in STRATEGIES:
        raise ValueError(f"method: expected one of {list(STRATEGIES)}, got {name!r}")
    return STRATEGIES[name](problem)


__all__ = ["BODIES", "STRATEGIES", "make", "make_bodies", "names"]
