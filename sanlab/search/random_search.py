"""Phase 1 (paper §5.2): random generation and evaluation.

Controller ``idx`` of a run seeded ``seed`` always has the same weights (its own random stream),
so a search interrupted at any point resumes by asking only for the indices not yet stored, and
ends exactly as an uninterrupted one.
"""

from __future__ import annotations

from collections.abc import Set

import numpy as np

from sanlab.san import San
from sanlab.search.base import Candidate


class RandomSearch:
    """N random SANs, weights uniform integers in [-2, 2]."""

    def __init__(self, san: San, total: int, seed: int, params: dict, done: Set[int] = frozenset()):
        self.san, self.total, self.seed, self.params = san, total, seed, dict(params)
        self._todo = [i for i in range(total) if i not in done]

    @property
    def done(self) -> bool:
        """Every controller not stored before has been asked for."""
        return not self._todo

    def ask(self, n: int) -> list[Candidate]:
        take, self._todo = self._todo[:n], self._todo[n:]
        return [Candidate(i, self.san.random_weights(self.seed, i), self.params) for i in take]

    def tell(self, candidates: list[Candidate], results: dict[str, np.ndarray]) -> None:
        pass  # random search learns nothing
