"""The ask/tell interface every search strategy implements.

A strategy proposes candidates (``ask``) and learns their scores (``tell``); it never simulates.
The runner evaluates what was asked in one batched rollout, stores it, and reports progress, so a
new optimiser is one new module.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class Candidate:
    """One controller to evaluate: its index within the run, SAN weights [N, I] and the
    parameters it is evaluated with (JSON-serialisable)."""

    idx: int
    weights: np.ndarray
    params: dict = field(default_factory=dict)


class Strategy(Protocol):
    """What a driver calls on a search strategy: ``ask`` while not ``done``, ``tell`` the scores
    of what it asked for, in order (``random_search.RandomSearch``, ``chain.Chain``)."""

    @property
    def done(self) -> bool:
        """Whether the search has nothing more to ask (then ``ask`` returns [])."""
        ...

    def ask(self, n: int) -> list[Candidate]:
        """Up to n candidates to evaluate next; [] when the search is finished."""
        ...

    def tell(self, candidates: list[Candidate], results: dict[str, np.ndarray]) -> None:
        """Scores of the candidates just asked for (arrays aligned with ``candidates``)."""
        ...
