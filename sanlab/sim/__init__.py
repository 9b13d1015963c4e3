"""The batched planar simulator: compile a creature, step it, roll controllers out.

    model = compile_creature(spec)              # structure static, numbers as arrays
    state = step(model, state, u)               # one creature, pure
    result = rollout(model, controller, cparams, seconds=6.0)   # a batch, closed loop
"""

from sanlab import _jax

_jax.configure()

from sanlab.sim.dynamics import (  # noqa: E402
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
from sanlab.sim.model import Model, Params, Structure, compile_creature  # noqa: E402
from sanlab.sim.rollout import (  # noqa: E402
    ConstantController,
    Frames,
    ReflexController,
    Result,
    SineController,
    batch_quantum,
    devices,
    rollout,
)

__all__ = [
    "State", "advance", "centre_of_mass", "energy", "follow_point", "poses", "initial_state", "make_state", "prepare", "sense", "step", "velocity",
    "root_coordinates", "from_root_coordinates",
    "Model", "Params", "Structure", "compile_creature",
    "ConstantController", "Frames", "ReflexController", "Result", "SineController",
    "batch_quantum", "devices", "rollout",
]
