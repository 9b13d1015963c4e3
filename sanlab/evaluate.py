"""Score controllers on a creature: batched closed-loop rollouts through a metric.

An :class:`Evaluator` compiles its creature once and always rolls out batches padded to the same
size, so a whole search (or a resumed one) runs one compiled program.
"""

from __future__ import annotations

import numpy as np

from sanlab.creature.spec import Creature
from sanlab.metrics import Metric, scores
from sanlab.san import San


class Evaluator:
    """Evaluate SAN weight matrices on ``spec`` for ``seconds`` with ``metric``."""

    def __init__(self, spec: Creature, *, metric: str | None = None, seconds: float | None = None,
                 dtype: str = "float32", batch: int = 256):
        from sanlab import sim

        self.spec = spec
        self.san = San.for_creature(spec)
        self.metric = Metric.for_creature(spec, metric)
        self.seconds = float(seconds if seconds is not None else spec.evaluation.seconds)
        self.dtype = dtype
        self.batch = batch
        self.model = sim.compile_creature(spec, dtype)

    def delays(self) -> dict:
        """The creature's nominal node delays (s), as stored with each controller."""
        return {"delay_on": self.spec.san.delay_on, "delay_off": self.spec.san.delay_off}

    def __call__(self, weights: np.ndarray) -> dict[str, np.ndarray]:
        """weights [n, N, I] (n <= batch) -> per-controller score, speed_cm_s, distance_m, fell,
        nonfinite (see ``sanlab.metrics.scores``)."""
        from sanlab import sim

        d = self.delays()
        params = self.san.params(weights, d["delay_on"], d["delay_off"], self.dtype)
        r = sim.rollout(self.model, self.san, params, self.seconds, observer=self.metric, pad_to=self.batch)
        return scores(self.metric, r.acc, r.finite, self.seconds, self.spec.world.plane)
