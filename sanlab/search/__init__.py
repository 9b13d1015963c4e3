"""Searches over controllers: strategies behind one ask/tell interface (``base.Strategy``), all
registered by name (``registry``), driven by one driver (``driver.run``) that evaluates on a
backend and commits every batch; ``runner.run_search`` (phase 1) and ``tune.tune`` (phase 2)
set runs up for it."""

from sanlab.search.base import Candidate, Problem, Start, Strategy, Together, Told
from sanlab.search.driver import Progress, Reporter, run
from sanlab.search.random_search import RandomSearch
from sanlab.search.registry import STRATEGIES
from sanlab.search.runner import SearchProgress, run_search

__all__ = ["Candidate", "Problem", "Start", "Strategy", "Together", "Told", "Progress", "Reporter", "run",
           "RandomSearch", "STRATEGIES", "SearchProgress", "run_search"]
