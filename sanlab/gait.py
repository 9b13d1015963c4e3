"""A gait: a stored controller together with the creature it drives, ready to replay or tune.

Its :class:`~sanlab.evaluate.records.GaitParams` say how the controller is evaluated beside its
weights (phase-1 delays, or a tuned gait's per-node rates and model overrides); its run's
settings say for how long, with which metric and on which ensemble it was scored.

Replaying uses the same compiled step as the search (there is no second physics).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sanlab.creature import loads
from sanlab.creature.spec import Creature
from sanlab.evaluate.ensemble import Ensemble
from sanlab.evaluate.records import GaitParams
from sanlab.san import San, SanParams


@dataclass(frozen=True)
class Gait:
    gait_id: str  # "RUN#IDX" (permanent id)
    spec: Creature
    weights: np.ndarray  # [N, I] int8
    params: GaitParams  # how it is evaluated
    seconds: float  # evaluation time of its run (s)
    metric: str  # its run's metric
    ensemble: Ensemble = field(default_factory=lambda: Ensemble(members=1))  # its run's ensemble
    score: float = float("nan")
    speed_cm_s: float = float("nan")
    creature_text: str = ""  # the creature file, verbatim, as stored with its run
    source: str | None = None  # where the creature file came from (its run's settings)

    @property
    def san(self) -> San:
        return San.for_creature(self.spec)

    @classmethod
    def from_library(cls, library: Any, gait_id: str) -> Gait:
        """Look a gait up in a ``sanlab.library.Library`` by "RUN/RANK" or "RUN#IDX" (raises
        LibraryError if there is none)."""
        e = library.gait(gait_id)
        run = library.get_run(e.run_id)
        s = run.settings
        spec = loads(run.creature_text, source=s.source or run.creature)
        san = San.for_creature(spec)
        seconds = s.seconds if s.seconds is not None else spec.evaluation.seconds
        metric = s.metric if s.metric is not None else spec.evaluation.metric
        return cls(e.gait_id, spec, san.decode(e.encoding), e.gait_params, seconds, metric, s.ensemble,
                   e.score, e.speed_cm_s, run.creature_text, s.source)

    def san_params(self, dtype: str = "float32") -> SanParams:
        """The controller's parameters with a leading batch axis of 1."""
        import jax.numpy as jnp

        k1, k2 = self.params.rates(self.san.n_nodes, self.spec.san.delay_on, self.spec.san.delay_off)
        w = np.asarray(self.weights)[None]
        return SanParams(*(jnp.asarray(x, dtype) for x in (w, k1[None], k2[None])))

    def model(self, dtype: str = "float32"):
        """The compiled creature with this gait's parameter overrides applied."""
        import jax.numpy as jnp

        from sanlab import sim

        m = sim.compile_creature(self.spec, dtype)
        over = self.params.model
        if over:
            m = m.with_params(**{k: jnp.asarray(np.asarray(v), m.dtype) for k, v in over.items()})
        return m

    def replay(self, seconds: float | None = None, fps: float = 30.0, dtype: str = "float32", model=None):
        """Roll the gait out, recording ``fps`` frames per second; returns sim.Result (batch 1)."""
        from sanlab import sim

        model = model if model is not None else self.model(dtype)
        return sim.rollout(model, self.san, self.san_params(dtype), seconds or self.seconds, record_fps=fps)
