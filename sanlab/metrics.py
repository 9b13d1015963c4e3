"""Evaluation metrics (paper §5.1), computed inside the compiled rollout as an observer.

Positions are those of the creature's centre of mass (COM), so a score does not depend on where
a link's frame happens to sit. With T the evaluation time and p the COM:

- ``distance``: |x(T) - x(0)| (m): how far it got, left or right ("we do usually not care whether
  the creature moves to the right or the left"). In the horizontal plane (seen from above) the
  displacement in the plane, |p(T) - p(0)|.
- ``distance_upright``: the same, but 0 if the creature fell at any time. The creature file says
  what falling means: its ``fell_link`` turned past ``fell_angle`` from upright.
- ``hopping``: |x(T) - x(0)| + k ∫ max(0, y - y(0))^2 dt, the paper's ∫ (x' + k y^2) dt with the
  height measured above the starting height (so standing still scores nothing) and the
  direction free as for distance.
- ``pursuit``: ∫ v · F dt, v the COM velocity and F the unit vector from the COM to the follow
  point: how well pursuit is maintained (m).

Every evaluation also reports speed = displacement / T (cm/s, as in Table 1), whether the
creature fell, and whether the simulation stayed finite; a non-finite run scores 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from sanlab.creature.spec import METRICS
from sanlab.sim.dynamics import centre_of_mass, follow_point, prepare, wrap_angle


class MetricAcc(NamedTuple):
    """What :class:`Metric` accumulates along one rollout (a leading batch axis on every array
    once batched)."""

    p0: tuple[jax.Array, jax.Array]  # COM (x, y) at the start (m)
    y0: jax.Array  # COM height at the start (m)
    hop: jax.Array  # ∫ max(0, y - y0)^2 dt (m^2 s)
    pursuit: jax.Array  # ∫ v . F dt (m)
    fell: jax.Array  # bool: the fell link passed its limit at some step
    p: tuple[jax.Array, jax.Array]  # COM (x, y) at the end (m), set by finish


@dataclass(frozen=True)
class Metric:
    """Observer computing one metric's ingredients (see the module docstring)."""

    kind: str = "distance"
    fell_link: int = -1  # link index, -1: this creature cannot fall
    fell_angle: float = math.pi / 2
    hop_k: float = 1.0

    @classmethod
    def for_creature(cls, spec, kind: str | None = None) -> "Metric":
        kind = kind or spec.evaluation.metric
        if kind not in METRICS:
            raise ValueError(f"metric: expected one of {list(METRICS)}, got {kind!r}")
        ev = spec.evaluation
        if kind == "pursuit" and spec.world.follow is None:
            raise ValueError("metric pursuit needs a follow point ([world.follow] in the creature file)")
        names = [l.name for l in spec.links]
        fell = names.index(ev.fell_link) if ev.fell_link else -1
        return cls(kind, fell, float(ev.fell_angle), float(ev.hop_k))

    def init(self, model, state):
        fr = prepare(model, state)
        p, _ = centre_of_mass(model, fr)
        z = jnp.zeros((), state.q.dtype)
        return MetricAcc(p, p[1], z, z, jnp.zeros((), bool), p)

    def update(self, model, acc: MetricAcc, state, fr, bits, u) -> MetricAcc:
        dt = model.params.dt
        hop, pursuit, fell = acc.hop, acc.pursuit, acc.fell
        if self.fell_link >= 0:
            a = wrap_angle(fr.th[self.fell_link])
            fell = fell | (jnp.abs(a) > self.fell_angle)
        if self.kind in ("hopping", "pursuit"):
            p, v = centre_of_mass(model, fr)
            if self.kind == "hopping":
                hop = hop + jnp.maximum(p[1] - acc.y0, 0.0) ** 2 * dt
            else:
                f = follow_point(model, state.t)
                dx, dy = f[0] - p[0], f[1] - p[1]
                inv = 1.0 / jnp.maximum(jnp.sqrt(dx * dx + dy * dy), 1e-9)
                pursuit = pursuit + (v[0] * dx + v[1] * dy) * inv * dt
        return acc._replace(hop=hop, pursuit=pursuit, fell=fell)

    def finish(self, model, acc: MetricAcc, state) -> MetricAcc:
        p, _ = centre_of_mass(model, prepare(model, state))
        return acc._replace(p=p)


def scores(metric: Metric, acc: MetricAcc, finite, seconds: float, plane: str) -> dict[str, np.ndarray]:
    """Per-controller arrays: score, speed_cm_s, distance_m, fell, nonfinite (batched acc)."""
    dx = np.asarray(acc.p[0]) - np.asarray(acc.p0[0])
    dy = np.asarray(acc.p[1]) - np.asarray(acc.p0[1])
    disp = np.hypot(dx, dy) if plane == "horizontal" else np.abs(dx)
    fell = np.asarray(acc.fell)
    finite = np.asarray(finite) & np.isfinite(disp)
    if metric.kind == "distance":
        score = disp
    elif metric.kind == "distance_upright":
        score = np.where(fell, 0.0, disp)
    elif metric.kind == "hopping":
        score = disp + metric.hop_k * np.asarray(acc.hop)
    else:
        score = np.asarray(acc.pursuit)
    score = np.where(finite & np.isfinite(score), score, 0.0)
    return {
        "score": score.astype(float),
        "speed_cm_s": np.where(finite, disp / seconds * 100.0, 0.0).astype(float),
        "distance_m": np.where(finite, disp, 0.0).astype(float),
        "fell": fell & finite if metric.fell_link >= 0 else np.zeros_like(fell),
        "nonfinite": ~finite,
    }
