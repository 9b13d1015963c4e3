"""What a rollout accumulates besides the state (:class:`Observe`): a metric's ingredients and the
behaviour descriptors, summed inside the kernel (``_kernel/observe.h``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sanlab.sim import layout
from sanlab.sim.tables import W_FOLLOW, Packed

ACC = layout.ACC  # what the observers accumulate per row (layout.py says what each is)
EVENTS = layout.EVENTS
METRIC_KINDS = layout.METRIC_KINDS


@dataclass(frozen=True)
class Observe:
    """What a rollout accumulates besides the state: the ingredients of a metric (paper §5.1; see
    ``sanlab.metrics``) and the behaviour descriptors (``sanlab.descriptors``). Link, dof and sensor
    numbers index the model's; angles in rad, heights in m above the ground."""

    kind: str = "distance"  # one of METRIC_KINDS: which integral to keep (hopping's, pursuit's, tracking's)
    fell_links: tuple[int, ...] = ()  # fallen once one turns past fell_angle from upright
    fell_angle: float = math.pi / 2
    fell_com_height: float | None = None  # fallen once the centre of mass comes closer to the ground
    fell_link_height: float | None = None  # or a fell link's centre of mass
    depth: bool = False  # keep the deepest contact
    root: int = -1  # the descriptors' rotating root link (-1: none)
    sensors: int = 0  # sensors in the descriptors' word (0: no word; at most 30)
    joints: tuple[int, ...] = ()  # dofs of the joints whose mean speed is kept
    touch: tuple[int, ...] = ()  # sensor indices whose duty is kept

    @property
    def size(self) -> int:
        """Accumulator values per row."""
        return len(ACC) + len(self.touch) + 2 * EVENTS

    def check(self, pk: Packed) -> None:
        """Raise ValueError unless every index it names is one of ``pk``'s (the kernel reads and
        writes by them: an index past a table would be read or written past it)."""
        L, S, D = pk.li.shape[0], pk.si.shape[0], pk.ndof
        if self.kind not in METRIC_KINDS:
            raise ValueError(f"observe.kind: expected one of {METRIC_KINDS}, got {self.kind!r}")
        if self.kind in ("pursuit", "tracking") and not pk.wi[W_FOLLOW]:
            raise ValueError(f"observe.kind: {self.kind} needs a follow path (the model has none)")
        for name, values, n in (("fell_links", self.fell_links, L), ("joints", self.joints, D),
                                ("touch", self.touch, S), ("root", () if self.root == -1 else (self.root,), L)):
            bad = [v for v in values if not (isinstance(v, (int, np.integer)) and 0 <= v < n)]
            if bad:
                raise ValueError(f"observe.{name}: expected indices in [0, {n}), got {bad[0]!r}")
        if not (isinstance(self.sensors, (int, np.integer)) and 0 <= self.sensors <= min(30, S)):
            raise ValueError(f"observe.sensors: expected 0 to {min(30, S)} (the creature's sensors, at most 30), "
                             f"got {self.sensors!r}")

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(oi int32, of float64), the kernel's config (_kernel/observe.h)."""
        oi = [METRIC_KINDS.index(self.kind), self.fell_com_height is not None, self.fell_link_height is not None,
              self.depth, self.root, self.sensors, len(self.fell_links), len(self.joints), len(self.touch),
              *self.fell_links, *self.joints, *self.touch]
        of = [self.fell_angle, self.fell_com_height or 0.0, self.fell_link_height or 0.0]
        return np.array(oi, np.int32), np.array(of, np.float64)
