"""Compile a creature: its tables (:mod:`sanlab.sim.model`), then its bodies seated on the ground
with the contact geometry the step uses (the kernel's ``start``). Nothing is compiled for the
creature itself: the kernel reads it as data."""

from __future__ import annotations

from typing import Any

import numpy as np

from sanlab.creature.spec import Creature
from sanlab.sim import kernel
from sanlab.sim.model import Model, assemble


def compile_creature(spec: Creature, dtype: Any = "float64", articulated: bool | None = None) -> Model:
    """The compiled model of ``spec``: structure and NumPy arrays of its numbers.

    dtype: "float64" (default) or "float32": the arrays' type and the arithmetic every rollout
    of the model runs in (float32: the kernel's float32 form, 2 to 3 x float64's throughput;
    chaotic runs part from float64's, so scores agree by distribution, not bit for bit). Raises
    ValueError for another dtype. articulated: the step's linear algebra, the O(n)
    articulated-body recursion (True) or the dense L D L^T (False), the same step to round-off;
    None (default): the kernel's choice, articulated wherever it applies (trees of rigid links).
    Raises ValueError for True on a creature with point masses or linear springs or actuators.

    In the vertical plane every free tree whose contact points start below the ground is lifted
    just clear of it: a body started inside the ground would be launched by the penalty spring.
    """
    model = assemble(spec, dtype, articulated)
    if spec.world.plane == "vertical" and model.structure.contacts:
        q, _ = kernel.start(kernel.pack(model, 0), np.asarray(model.params.q0, np.float64)[None], seat=True)
        model = model.with_params(q0=q[0].astype(model.dtype))
    return model
