"""Searches over controllers, all behind one ask/tell interface (``base.Strategy``)."""

from sanlab.search.base import Candidate, Strategy
from sanlab.search.random_search import RandomSearch
from sanlab.search.runner import SearchProgress, run_search

__all__ = ["Candidate", "Strategy", "RandomSearch", "SearchProgress", "run_search"]
