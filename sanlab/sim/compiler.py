"""Compile a creature: its arrays (:mod:`sanlab.sim.model`), then its bodies seated on the
ground with the same contact geometry the step uses (:mod:`sanlab.sim.dynamics`)."""

from __future__ import annotations

from functools import cache
from typing import Any

import jax.numpy as jnp
import numpy as np

from sanlab.creature.spec import Creature
from sanlab.sim import executables
from sanlab.sim.dynamics import seat_on_ground
from sanlab.sim.model import Model, assemble


@cache
def _seat():
    import jax

    return jax.jit(seat_on_ground)


def compile_creature(spec: Creature, dtype: Any = "float32", articulated: bool | None = None) -> Model:
    """The compiled model of ``spec``: structure static, numbers as arrays of ``dtype``
    ("float32", the default, or "float64"); articulated: the step's linear algebra (see
    :func:`sanlab.sim.model.assemble`; None picks by size). Both routes give the same step to
    round-off; the articulated one costs O(n) per step for an n-link creature instead of up to
    O(n^3).

    In the vertical plane every free tree whose contact points start below the ground is lifted
    just clear of it: a body started inside the ground would be launched by the penalty spring.
    """
    model = assemble(spec, dtype, articulated)
    if spec.world.plane == "vertical" and model.structure.contacts:
        # compiled and stored, not run op by op: that took 0.4-0.7 s of every replay's start
        q0 = executables.call(("seat_on_ground",), _seat(), (model, model.params.q0))
        # uncommitted, as every other parameter is: a committed leaf would be another jit cache
        # entry for every compiled program that takes this model
        model = model.with_params(q0=jnp.asarray(np.asarray(q0)))
    return model
