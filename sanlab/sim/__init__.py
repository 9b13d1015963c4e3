"""The batched planar simulator: compile a creature, step it, roll controllers out.

    model = compile_creature(spec)              # structure static, numbers as arrays
    state = step(model, state, u)               # one creature, pure
    result = rollout(model, controller, cparams, seconds=6.0)   # a batch, closed loop

Importing it changes no global JAX setting: :func:`sanlab.configure` does (``compile_creature``
calls it on first use).
"""

from sanlab.sim.compiler import compile_creature
from sanlab.sim.dynamics import (
    State,
    advance,
    centre_of_mass,
    energy,
    follow_point,
    from_root_coordinates,
    initial_state,
    make_state,
    poses,
    prepare,
    root_coordinates,
    sense,
    step,
    velocity,
)
from sanlab.sim.model import Model, Params, Structure
from sanlab.sim.rollout import (
    ConstantController,
    Frames,
    ReflexController,
    Result,
    SineController,
    batch_quantum,
    devices,
    frame_capacity,
    rollout,
)

__all__ = [
    "State", "advance", "centre_of_mass", "energy", "follow_point", "poses", "initial_state", "make_state", "prepare", "sense", "step", "velocity",
    "root_coordinates", "from_root_coordinates",
    "Model", "Params", "Structure", "compile_creature",
    "ConstantController", "Frames", "ReflexController", "Result", "SineController",
    "batch_quantum", "devices", "frame_capacity", "rollout",
]
