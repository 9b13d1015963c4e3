"""Sensor-actuator networks (paper §4): the node dynamics of Figure 7 as a controller.

A SAN for a creature with S sensors, H hidden nodes and A actuators has H + A nodes, each fed by
every sensor and by every node's binary output: weights W [H + A, S + H + A], integers in
[-2, 2]. Each node integrates its weighted sum (istate += k1 dt when the sum is positive, else
k2 dt, k2 < 0), clamps istate to [0, 1], and switches its output on when istate reaches 1 and
off when it reaches 0 (hysteresis). An actuator node also drives its actuator with its sum,
bounded to [-2, 2] and mapped linearly onto [0, 1] (the actuator's [min, max]).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

WEIGHT_MIN, WEIGHT_MAX = -2, 2
MAX_PACKED_INPUTS = 31  # inputs packed into one int32 for the popcount sum


class SanParams(NamedTuple):
    """One network (add a leading batch axis for many). N = H + A nodes, I = S + H + A inputs."""

    weights: Any  # [N, I] integer-valued (stored as float for the arithmetic)
    k1: Any  # [N] 1/s, on-rate (T_on = 1 / k1)
    k2: Any  # [N] 1/s, off-rate, negative (T_off = -1 / k2)


class SanState(NamedTuple):
    istate: Any  # [N] integrator state in [0, 1]
    out: Any  # [N] binary outputs
    planes: Any  # [3, N] int32 bit planes of (weights + 2), one bit per input (constant); None
    # when there are too many inputs to pack, and the sum is a float dot product instead


@dataclass(frozen=True)
class San:
    """The SAN as a simulator controller (see ``sanlab.sim.rollout``)."""

    n_sensors: int
    n_hidden: int
    n_actuators: int

    @property
    def n_nodes(self) -> int:
        return self.n_hidden + self.n_actuators

    @property
    def n_inputs(self) -> int:
        return self.n_sensors + self.n_nodes

    def init(self, params: SanParams, model) -> SanState:
        z = jnp.zeros((self.n_nodes,), params.k1.dtype)
        planes = bit_planes(params.weights) if self.n_inputs <= MAX_PACKED_INPUTS else None
        return SanState(z, z, planes)

    def apply(self, params: SanParams, s: SanState, bits, dt):
        # Every input is binary, so sum_i w_i x_i = sum_k 2^k popcount(x & plane_k) - 2 popcount(x)
        # with x the inputs packed into one integer and plane_k bit k of (w + 2) per input:
        # ~40 integer operations per node instead of a 20-wide float dot product per node.
        p = s.planes
        if p is None:
            x = jnp.concatenate([bits.astype(params.k1.dtype), s.out])
            total = jnp.sum(params.weights * x[None, :], axis=1)
        else:
            inputs = jnp.concatenate([bits.astype(jnp.int32), s.out.astype(jnp.int32)])
            x = jnp.sum(inputs << jnp.arange(self.n_inputs, dtype=jnp.int32))
            pc = jax.lax.population_count
            total = pc(x & p[0]) + 2 * pc(x & p[1]) + 4 * pc(x & p[2]) - 2 * pc(x)
            total = total.astype(params.k1.dtype)
        istate = jnp.clip(s.istate + jnp.where(total > 0, params.k1, params.k2) * dt, 0.0, 1.0)
        out = jnp.where((s.out == 1) & (istate == 0.0), 0.0, s.out)
        out = jnp.where((out == 0) & (istate == 1.0), 1.0, out)
        u = (jnp.clip(total[self.n_hidden :], -2.0, 2.0) + 2.0) * 0.25
        return SanState(istate, out, p), u


def bit_planes(weights) -> Any:
    """[N, I] integer weights in [-2, 2] -> [3, N] int32: bit k of (w + 2) for each input i at
    bit position i. Needs I <= 31."""
    w = jnp.round(weights).astype(jnp.int32) + 2
    shifts = jnp.arange(w.shape[-1], dtype=jnp.int32)
    return jnp.stack([jnp.sum(((w >> k) & 1) << shifts, axis=-1) for k in range(3)])
