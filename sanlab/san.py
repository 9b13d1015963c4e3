"""Sensor-actuator networks (paper §4): the node dynamics of Figure 7 as a controller.

A SAN for a creature with S sensors, H hidden nodes and A actuators has H + A nodes, each fed by
every sensor and by every node's binary output: weights W [H + A, S + H + A], integers in
[-2, 2]. Each node integrates its weighted sum (istate += k1 dt when the sum is positive, else
k2 dt, k2 < 0), clamps istate to [0, 1], and switches its output on when istate reaches 1 and
off when it reaches 0 (hysteresis). An actuator node also drives its actuator with its sum,
bounded to [-2, 2] and mapped linearly onto [0, 1] (the actuator's [min, max]).
"""

from __future__ import annotations

import base64
import math
import re
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

WEIGHT_MIN, WEIGHT_MAX = -2, 2
# ASCII digits only (``\d`` matches other scripts' digits too), at most 9 each: sizes, not numbers
_ENCODING = re.compile(r"san1-([0-9]{1,9})-([0-9]{1,9})-([0-9]{1,9})-([A-Za-z0-9_-]+)")


class SanParams(NamedTuple):
    """One network (add a leading batch axis for many). N = H + A nodes, I = S + H + A inputs."""

    weights: Any  # [N, I] integer-valued (stored as float for the arithmetic)
    k1: Any  # [N] 1/s, on-rate (T_on = 1 / k1)
    k2: Any  # [N] 1/s, off-rate, negative (T_off = -1 / k2)


@dataclass(frozen=True)
class San:
    """The SAN as a simulator controller (see ``sanlab.sim.rollout``): the kernel runs it (kind
    "san"); :meth:`step` is the same step in NumPy."""

    kind = "san"
    n_sensors: int
    n_hidden: int
    n_actuators: int

    @property
    def n_nodes(self) -> int:
        return self.n_hidden + self.n_actuators

    @property
    def n_inputs(self) -> int:
        return self.n_sensors + self.n_nodes

    @property
    def n_weights(self) -> int:
        return self.n_nodes * self.n_inputs

    @classmethod
    def for_creature(cls, spec) -> "San":
        """The topology of ``spec``'s networks (hidden nodes: ``spec.n_hidden``)."""
        return cls(len(spec.sensors), spec.n_hidden, len(spec.actuators))

    def random_weights(self, seed: int, index: int) -> np.ndarray:
        """Weights [N, I] (int8, uniform in [-2, 2]) of controller ``index`` of a run seeded
        ``seed``: each controller has its own stream, so any subset can be (re)generated alone."""
        rng = np.random.default_rng([seed, index])
        return rng.integers(WEIGHT_MIN, WEIGHT_MAX + 1, (self.n_nodes, self.n_inputs), dtype=np.int8)

    def params(self, weights, delay_on, delay_off, dtype="float64") -> SanParams:
        """SanParams for weights [..., N, I] with delays T_on, T_off (s): scalars or [..., N]."""
        w = np.asarray(weights)
        batch = w.shape[:-2]
        k1 = np.broadcast_to(1.0 / np.asarray(delay_on, float), batch + (self.n_nodes,))
        k2 = np.broadcast_to(-1.0 / np.asarray(delay_off, float), batch + (self.n_nodes,))
        return SanParams(np.asarray(w, dtype), np.asarray(k1, dtype), np.asarray(k2, dtype))

    # ---- encoding: the paper's "240 weights that can take on 5 values ... in 70 bytes" ----

    @property
    def n_bytes(self) -> int:
        """Bytes of a packed weight matrix: ceil(n_weights * log2(5) / 8) (bounder: 70)."""
        return max(1, math.ceil(self.n_weights * math.log2(5) / 8 - 1e-12))

    def pack(self, weights) -> bytes:
        """Weights [N, I] in [-2, 2] -> bytes: the base-5 digits (w + 2), row-major, as one
        big-endian integer."""
        w = np.asarray(weights).reshape(-1)
        if w.size != self.n_weights:
            raise ValueError(f"expected {self.n_weights} weights, got {w.size}")
        if w.min(initial=0) < WEIGHT_MIN or w.max(initial=0) > WEIGHT_MAX or np.any(w != np.round(w)):
            raise ValueError("weights must be integers in [-2, 2]")
        value = 0
        for d in (w.astype(int) + 2).tolist():
            value = value * 5 + d
        return value.to_bytes(self.n_bytes, "big")

    def unpack(self, data: bytes) -> np.ndarray:
        """Inverse of :meth:`pack`: bytes -> int8 weights [N, I]."""
        if len(data) != self.n_bytes:
            raise ValueError(f"expected {self.n_bytes} bytes, got {len(data)}")
        value = int.from_bytes(data, "big")
        if value >= 5**self.n_weights:
            raise ValueError("not a packed weight matrix (value out of range)")
        digits = []
        for _ in range(self.n_weights):
            value, d = divmod(value, 5)
            digits.append(d - 2)
        return np.array(digits[::-1], np.int8).reshape(self.n_nodes, self.n_inputs)

    def encode(self, weights) -> str:
        """A printable, pasteable controller: ``san1-S-H-A-<base64url of the packed bytes>``."""
        b64 = base64.urlsafe_b64encode(self.pack(weights)).decode().rstrip("=")
        return f"san1-{self.n_sensors}-{self.n_hidden}-{self.n_actuators}-{b64}"

    def decode(self, text: str) -> np.ndarray:
        """Inverse of :meth:`encode`; checks that the sizes match this topology."""
        m = _ENCODING.fullmatch(text.strip())
        if not m:
            raise ValueError("expected an encoding like san1-8-8-4-<base64>, got " + repr(text[:40]))
        sizes = tuple(int(g) for g in m.groups()[:3])
        mine = (self.n_sensors, self.n_hidden, self.n_actuators)
        if sizes != mine:
            raise ValueError(f"encoding is for sensors/hidden/actuators {sizes}, this creature has {mine}")
        b64 = m.group(4)
        return self.unpack(base64.urlsafe_b64decode(b64 + "=" * (-len(b64) % 4)))

    def step(self, params: SanParams, istate, out, bits, dt) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of Figure 7's node dynamics in NumPy, with the kernel's arithmetic (float64):
        node states ``istate`` and binary outputs ``out`` [..., N], sensor values ``bits``
        [..., S] (0/1), the step ``dt`` (s) -> (istate, out, activations u [..., A] in [0, 1]).
        ``params`` as for the kernel: weights [..., N, I], rates k1, k2 [..., N]. The sums are
        of integers, exact in any order, so this is the kernel's SAN bit for bit (the Gymnasium
        policy steps with it)."""
        w = np.asarray(params.weights, np.float64)
        x = np.concatenate([np.asarray(bits, np.float64), np.asarray(out, np.float64)], -1)
        total = np.einsum("...ni,...i->...n", w, x)
        k1, k2 = (np.asarray(k, np.float64) for k in (params.k1, params.k2))
        istate = np.clip(np.asarray(istate, np.float64) + np.where(total > 0, k1, k2) * dt, 0.0, 1.0)
        o = np.asarray(out, np.float64)
        o = np.where((o == 1.0) & (istate == 0.0), 0.0, o)
        o = np.where((o == 0.0) & (istate == 1.0), 1.0, o)
        return istate, o, (np.clip(total[..., self.n_hidden:], -2.0, 2.0) + 2.0) * 0.25
