"""Scoring controllers: one evaluator for both phases, robust (ensemble) scores, typed score and
parameter records, and the backends evaluations run on.

Modules: ``evaluator`` (:class:`Evaluator`, :class:`Request`, the named terrain sets),
``ensemble`` (:class:`Ensemble`: perturbed copies and their random streams), ``records``
(:class:`GaitParams`, :class:`Scores`, :class:`ScoreBatch`), ``backends`` (the
:class:`~sanlab.evaluate.backends.Backend` protocol and the local backend) and ``ray_backend``
(Ray workers; needs ``pip install 'sanlab[cluster]'``).
"""

from sanlab.evaluate.backends import Backend, Local, make_backend
from sanlab.evaluate.ensemble import Ensemble
from sanlab.evaluate.evaluator import TERRAINS, Evaluator, Request, describe_devices
from sanlab.evaluate.records import GaitParams, ScoreBatch, Scores

__all__ = [
    "Backend", "Local", "make_backend", "Ensemble", "TERRAINS", "Evaluator", "Request", "describe_devices",
    "GaitParams", "ScoreBatch", "Scores",
]
