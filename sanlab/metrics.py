"""Evaluation metrics (paper §5.1), accumulated inside the kernel's rollout as an observer.

Positions are those of the creature's centre of mass (COM), so a score does not depend on where
a link's frame happens to sit. With T the evaluation time, p the COM and d the displacement
along x that the creature file's ``direction`` asks for (``either``: |x(T) - x(0)|, the paper's
"we do usually not care whether the creature moves to the right or the left"; ``forward``:
x(T) - x(0); ``backward``: x(0) - x(T), so moving the wrong way scores below zero):

- ``distance``: d (m). In the horizontal plane (seen from above) with ``either``, the
  displacement in the plane, |p(T) - p(0)|.
- ``distance_upright``: the same, but 0 if the creature fell at any time.
- ``hopping``: d + k ∫ max(0, y - y(0))^2 dt, the paper's ∫ (x' + k y^2) dt with the height
  measured above the starting height (so standing still scores nothing); 0 if it fell.
- ``pursuit``: ∫ v · F dt, v the COM velocity and F the unit vector from the COM to the follow
  point: how well pursuit is maintained (m).
- ``tracking``: g0 / ḡ, ḡ the mean distance from the COM to the follow point over the evaluation
  and g0 that distance at the start: 1 for a creature that kept its starting distance on
  average, 3 for one that kept a third of it (a ratio). Pursuit saturates once a creature keeps
  pace with the point (closing the gap and falling behind again score the same); this scores how
  close it keeps, which is what tracking asks (§6; the Table 1 report's tracking ratio is the
  same mean distance, over a median random SAN's).

Falling is what the creature file says (``Evaluation``): a fell link turned past ``fell_angle``
from upright, or the COM (``fell_com_height``) or a fell link's COM (``fell_link_height``) came
closer to the ground than the given height.

Every evaluation also reports speed = d / T (cm/s, as in Table 1), the signed displacement along
x (``dx_m``, for arrows in tables and pictures), whether the creature fell, and whether the
simulation stayed finite; a non-finite run scores 0. So does a run that sank into the ground: a
contact point deeper than :func:`max_depth` (a quarter of the creature's size, clamped to
[2, 10] cm; vertical plane) means the ground no longer held the creature, and whatever it
scored is meaningless (``sank``, and flagged non-finite).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from sanlab.creature import geometry
from sanlab.creature.spec import FOLLOW_METRICS, MAX_PENETRATION, METRICS, PENETRATION_FRACTION


class MetricAcc(NamedTuple):
    """What :class:`Metric` accumulates along one rollout (a leading batch axis on every array
    once batched)."""

    p0: tuple[Any, Any]  # COM (x, y) at the start (m)
    y0: Any  # COM height at the start (m)
    hop: Any  # ∫ max(0, y - y0)^2 dt (m^2 s)
    pursuit: Any  # ∫ v . F dt (m)
    fell: Any  # bool: the fell link passed its limit at some step
    p: tuple[Any, Any]  # COM (x, y) at the end (m), set by finish
    deepest: Any  # the deepest any contact point went into the ground (m; vertical plane)
    gap: Any = 0.0  # mean distance from the COM to the follow point so far (m; tracking)
    gap0: Any = 0.0  # that distance at the start (m; tracking)


@dataclass(frozen=True)
class Metric:
    """Observer computing one metric's ingredients (see the module docstring)."""

    kind: str = "distance"
    fell_links: tuple[int, ...] = ()  # link indices judged by angle (and height, if given)
    fell_angle: float = math.pi / 2
    fell_com_height: float | None = None  # m above the ground
    fell_link_height: float | None = None  # m above the ground
    hop_k: float = 1.0
    direction: str = "either"
    max_depth: float | None = None  # m: deeper than this, the run sank (see :func:`max_depth`)

    @property
    def can_fall(self) -> bool:
        return bool(self.fell_links) or self.fell_com_height is not None

    @classmethod
    def for_creature(cls, spec, kind: str | None = None) -> "Metric":
        """The metric ``kind`` (default: the creature file's) for ``spec``; ValueError (one line)
        for an unknown metric, or one this creature cannot be scored by."""
        kind = spec.evaluation.metric if kind is None else kind
        if not isinstance(kind, str) or kind not in METRICS:
            shown = repr(kind) if isinstance(kind, str) and len(kind) < 40 else type(kind).__name__
            raise ValueError(f"metric: expected one of {list(METRICS)}, got {shown}")
        ev = spec.evaluation
        if kind in FOLLOW_METRICS and spec.world.follow is None:
            raise ValueError(f"metric {kind} needs a follow point ([world.follow] in the creature file)")
        if kind == "distance_upright" and not ev.can_fall:
            raise ValueError("metric distance_upright needs a way to fall (evaluation.fell_link or "
                             "fell_com_height in the creature file)")
        names = [l.name for l in spec.links]
        fell = tuple(names.index(n) for n in ev.fell_links)
        return cls(kind, fell, float(ev.fell_angle), ev.fell_com_height, ev.fell_link_height, float(ev.hop_k),
                   ev.direction, max_depth(spec))

    def observe(self):
        """What the kernel accumulates for this metric (``sanlab.sim.rollout``'s observers)."""
        from sanlab.sim import Observe

        return Observe(kind=self.kind, fell_links=self.fell_links, fell_angle=self.fell_angle,
                       fell_com_height=self.fell_com_height, fell_link_height=self.fell_link_height,
                       depth=self.max_depth is not None)

    def collect(self, c: dict) -> MetricAcc:
        """The accumulator from the kernel's columns (``sanlab.sim.rollout.columns``)."""
        return MetricAcc((c["p0x"], c["p0y"]), c["y0"], c["hop"], c["pursuit"], c["fell"] > 0, (c["px"], c["py"]),
                         np.maximum(c["deepest"], 0.0), c["gap"] / np.maximum(c["steps"], 1.0), c["gap0"])


def scores(metric: Metric, acc: MetricAcc, finite, seconds: float, plane: str) -> dict[str, np.ndarray]:
    """Per-controller arrays from a batched accumulator: score, speed_cm_s (d / T), distance_m
    (d), dx_m (signed displacement along x), fell, sank (a contact went deeper than
    ``metric.max_depth``), nonfinite (the simulation went non-finite, or sank)."""
    dx = np.asarray(acc.p[0]) - np.asarray(acc.p0[0])
    dy = np.asarray(acc.p[1]) - np.asarray(acc.p0[1])
    if metric.direction == "forward":
        disp = dx
    elif metric.direction == "backward":
        disp = -dx
    else:
        disp = np.hypot(dx, dy) if plane == "horizontal" else np.abs(dx)
    fell = np.asarray(acc.fell) if metric.can_fall else np.zeros(np.shape(dx), bool)
    sank = np.zeros(np.shape(dx), bool)
    if metric.max_depth is not None:
        sank = np.asarray(acc.deepest) > metric.max_depth
    finite = np.asarray(finite) & np.isfinite(disp) & ~sank
    if metric.kind == "distance":
        score = disp
    elif metric.kind == "distance_upright":
        score = np.where(fell, 0.0, disp)
    elif metric.kind == "hopping":
        score = np.where(fell, 0.0, disp + metric.hop_k * np.asarray(acc.hop))
    elif metric.kind == "pursuit":
        score = np.asarray(acc.pursuit)
    else:
        gap = np.asarray(acc.gap, float)
        score = np.asarray(acc.gap0, float) / np.where(gap > 0.0, gap, np.inf)
    score = np.where(finite & np.isfinite(score), score, 0.0)
    return {
        "score": score.astype(float),
        "speed_cm_s": np.where(finite, disp / seconds * 100.0, 0.0).astype(float),
        "distance_m": np.where(finite, disp, 0.0).astype(float),
        "dx_m": np.where(finite, dx, 0.0).astype(float),
        "fell": fell & finite,
        "sank": sank,
        "nonfinite": ~finite,
    }


def max_depth(spec) -> float | None:
    """How deep (m) a contact point may go into the ground before the run counts as sunk: a
    quarter of the creature's size at rest, clamped to [0.02, 0.1] m (FORMAT.md, "Limits"); None
    where nothing touches a ground (the horizontal plane, or no contact points)."""
    if spec.world.plane != "vertical" or not any(link.contacts for link in spec.links):
        return None
    return float(min(MAX_PENETRATION, max(0.02, PENETRATION_FRACTION * geometry.size(spec))))
