"""Stochastic gradient ascent (paper §5.3, Figure 9)."""

from __future__ import annotations

from sanlab.search.chain import Chain


class SGA(Chain):
    """Stochastic gradient ascent (Figure 9): keep a change only if the score improved."""

    def accept(self, trial: int, new: float) -> bool:
        return new > self.score
