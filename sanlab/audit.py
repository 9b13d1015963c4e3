"""The artefact audit: does a gait's speed survive a nudge? (issue 10, "Robust scores")

A SAN in closed loop with contacts is chaotic, and a search finds every flaw of its simulator:
a gait whose speed only exists on one exact float32 trajectory, or at one step size, is an
artefact of the integrator, not a result. :func:`audit` re-scores a stored gait exactly as it
was scored (the same creature, parameters, metric, evaluation time, terrain set, ensemble and
ensemble draws) under each *nudge* of :data:`NUDGES`: the step halved and quartered, and the
arithmetic in float64. It is flagged *resolution-dependent* when a nudge changes its robust
speed by more than ``threshold`` (default 10 %) of the speed re-scored without a nudge; speeds
are compared relative to at least :data:`FLOOR_CM_S`, so a gait that stands still is not flagged
for moving 0.02 instead of 0.01 cm/s.

Every nudged evaluation replays the same compiled step (``sanlab.evaluate.Evaluator``), only
with another ``dt`` or dtype: there is no second physics.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sanlab.evaluate import Evaluator
from sanlab.evaluate.ensemble import Key, heldout_key, search_key
from sanlab.gait import Gait
from sanlab.library import Library, SearchSettings, TuneSettings
from sanlab.search.space import Space

THRESHOLD = 0.10
FLOOR_CM_S = 1.0

# (name, factor on dt, dtype)
NUDGES: tuple[tuple[str, float, str], ...] = (
    ("dt/2", 0.5, "float32"),
    ("dt/4", 0.25, "float32"),
    ("float64", 1.0, "float64"),
)


@dataclass(frozen=True)
class Audit:
    """One gait's audit. Speeds in cm/s, each the robust (ensemble median) speed of the gait's
    own ensemble; ``changes`` are relative to ``nominal_cm_s`` (at least :data:`FLOOR_CM_S`)."""

    gait_id: str  # "RUN#IDX"
    stored_cm_s: float  # as stored in the library
    nominal_cm_s: float  # re-scored as stored (dt, float32)
    speeds: dict[str, float]  # nudge name -> speed
    changes: dict[str, float]  # nudge name -> relative change
    fell: dict[str, bool]  # nudge name -> the ensemble fell (more than half its members)
    threshold: float
    dt: float  # the creature's step (s)
    members: int  # ensemble members

    @property
    def worst(self) -> float:
        return max(self.changes.values(), default=0.0)

    @property
    def flagged(self) -> bool:
        """Resolution-dependent: some nudge changed the speed by more than the threshold."""
        return self.worst > self.threshold

    def summary(self) -> str:
        """One line, e.g. "robust: worst change 3 % (dt/4)"."""
        if not self.changes:
            return "not audited"
        name = max(self.changes, key=lambda k: self.changes[k])
        what = "RESOLUTION-DEPENDENT" if self.flagged else "robust"
        return f"{what}: worst change {100 * self.worst:.0f} % ({name})"

    def to_json(self) -> dict[str, Any]:
        return {"stored_cm_s": _finite(self.stored_cm_s), "nominal_cm_s": _finite(self.nominal_cm_s),
                "speeds": {k: _finite(v) for k, v in self.speeds.items()},
                "changes": {k: _finite(v) for k, v in self.changes.items()}, "fell": dict(self.fell),
                "threshold": self.threshold, "dt": self.dt, "members": self.members}


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def gait_key(lib: Library, gait: Gait) -> Key:
    """The ensemble key a stored gait was scored with: a search's controller ``idx``, a tuning
    run's held-out evaluation (an imported gait: the held-out key of seed 0)."""
    run_id, idx = gait.gait_id.split("#")
    run = lib.get_run(run_id)
    s = run.settings
    if isinstance(s, TuneSettings):
        return heldout_key(s.seed, s.chain)
    if isinstance(s, SearchSettings) and run.kind == "search":
        return search_key(run.seed or 0, int(idx))
    return heldout_key(0, 0)


def audit(lib: Library, gait_id: str, *, nudges: tuple[tuple[str, float, str], ...] = NUDGES,
          threshold: float = THRESHOLD, log=None) -> Audit:
    """Audit the gait ``gait_id`` ("RUN/RANK" or "RUN#IDX") of ``lib`` (see the module
    docstring); store nothing. Raises LibraryError for an unknown gait."""
    g = Gait.from_library(lib, gait_id)
    run = lib.get_run(g.gait_id.split("#")[0])
    s = run.settings
    terrain = s.terrain if isinstance(s, TuneSettings) else "flat"
    key = gait_key(lib, g)
    morphology = g.params.scale is not None
    # A phase-1 gait is scored as its search scored it, with the creature file's own parameters
    # (a parameter vector takes another compiled path, equal only to the last bits, and a chaotic
    # gait would already differ there); a tuned or imported one with its parameter vector.
    theta = None if run.kind == "search" else Space(g.spec, morphology=morphology).nominal(g.params)[None]

    def speed(factor: float, dtype: str) -> tuple[float, bool]:
        spec = dataclasses.replace(g.spec, dt=g.spec.dt * factor)
        ev = Evaluator(spec, metric=g.metric, seconds=g.seconds, dtype=dtype, batch=1, terrain=terrain,
                       ensemble=g.ensemble, space=Space(spec, morphology=morphology))
        r = ev(g.weights[None], theta, [key])
        return float(r.speed_cm_s[0]), bool(r.fell[0])

    nominal, _ = speed(1.0, "float32")
    if log:
        log(f"{g.gait_id}: {nominal:.1f} cm/s as stored (stored {g.speed_cm_s:.1f})")
    speeds, changes, fell = {}, {}, {}
    for name, factor, dtype in nudges:
        v, f = speed(factor, dtype)
        speeds[name], fell[name] = v, f
        changes[name] = abs(v - nominal) / max(abs(nominal), FLOOR_CM_S) if np.isfinite(v) else math.inf
        if log:
            log(f"{g.gait_id}: {v:.1f} cm/s at {name} (changed {100 * changes[name]:.0f} %)")
    return Audit(g.gait_id, g.speed_cm_s, nominal, speeds, changes, fell, threshold, g.spec.dt, g.ensemble.members)


def audit_and_store(lib: Library, gait_id: str, **kw) -> Audit:
    """:func:`audit`, then the result stored in the library (replacing an earlier audit)."""
    a = audit(lib, gait_id, **kw)
    lib.add_audit(a.gait_id, a.to_json(), flagged=a.flagged, worst=a.worst)
    return a
