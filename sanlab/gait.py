"""A gait: a stored controller together with the creature it drives, ready to replay or tune.

A stored evaluation's ``params`` say how the controller was evaluated:

- ``delay_on``, ``delay_off`` (s): every node's delays (phase 1), or
- ``k1``, ``k2`` ([N] 1/s): per-node rates (after tuning), and
- ``model``: {Params field: nested list} overrides of the creature's numbers (after tuning:
  actuator ranges and gains, sensor ranges, and with ``--morphology`` masses and lengths).

Replaying uses the same compiled step as the search (there is no second physics).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sanlab.creature import loads
from sanlab.creature.spec import Creature
from sanlab.san import San, SanParams


@dataclass(frozen=True)
class Gait:
    gait_id: str  # "RUN#IDX" (permanent id)
    spec: Creature
    weights: np.ndarray  # [N, I] int8
    params: dict  # how it is evaluated (see the module docstring)
    run_params: dict = field(default_factory=dict)  # the run's settings: seconds, metric, ...
    score: float = float("nan")
    speed_cm_s: float = float("nan")
    creature_text: str = ""  # the creature file, verbatim, as stored with its run

    @property
    def san(self) -> San:
        return San.for_creature(self.spec)

    @property
    def seconds(self) -> float:
        return float(self.run_params.get("seconds", self.spec.evaluation.seconds))

    @property
    def metric(self) -> str:
        return self.run_params.get("metric", self.spec.evaluation.metric)

    @classmethod
    def from_library(cls, library, gait_id: str) -> "Gait":
        """Look a gait up by "RUN/RANK" or "RUN#IDX" (raises LibraryError if there is none)."""
        e = library.gait(gait_id)
        run = library.get_run(e.run_id)
        spec = loads(run.creature_text, source=run.params.get("source", run.creature))
        san = San.for_creature(spec)
        return cls(e.gait_id, spec, san.decode(e.encoding), dict(e.params), dict(run.params), e.score,
                   e.speed_cm_s, run.creature_text)

    def san_params(self, dtype: str = "float32") -> SanParams:
        """The controller's parameters with a leading batch axis of 1."""
        p = self.params
        if "k1" in p:
            w = np.asarray(self.weights)[None]
            k1, k2 = np.asarray(p["k1"], float)[None], np.asarray(p["k2"], float)[None]
            import jax.numpy as jnp

            return SanParams(*(jnp.asarray(x, dtype) for x in (w, k1, k2)))
        delay_on = p.get("delay_on", self.spec.san.delay_on)
        delay_off = p.get("delay_off", self.spec.san.delay_off)
        return self.san.params(np.asarray(self.weights)[None], delay_on, delay_off, dtype)

    def model(self, dtype: str = "float32"):
        """The compiled creature with this gait's parameter overrides applied."""
        import jax.numpy as jnp

        from sanlab import sim

        m = sim.compile_creature(self.spec, dtype)
        over = self.params.get("model") or {}
        if over:
            m = m.with_params(**{k: jnp.asarray(np.asarray(v), m.dtype) for k, v in over.items()})
        return m

    def replay(self, seconds: float | None = None, fps: float = 30.0, dtype: str = "float32", model=None):
        """Roll the gait out, recording ``fps`` frames per second; returns sim.Result (batch 1)."""
        from sanlab import sim

        model = model if model is not None else self.model(dtype)
        return sim.rollout(model, self.san, self.san_params(dtype), seconds or self.seconds, record_fps=fps)
