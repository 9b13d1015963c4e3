"""The batched planar simulator: compile a creature, roll controllers out, read its state.

    model = compile_creature(spec)              # the creature's tables (structure, numbers)
    result = rollout(model, controller, cparams, seconds=6.0)   # a batch, closed loop
    state = make_state(model); frame = poses(model, state.q)
    rows = Rows(model, 4, observe=...); rows.step(u, steps=2)   # copies stepped a few steps at a time

Nothing outside this package imports its kernel (:mod:`sanlab.sim.kernel`): what the layers above
need of it is here (``Observe``, ``ACC``, ``lanes``; tests/test_layers.py holds them to it).

Every step runs in one compiled kernel that reads the creature as data (:mod:`sanlab.sim.kernel`):
no creature is ever compiled. It replaced an XLA engine (issue 46; ``docs/engine-history.md``),
whose numbers the tests keep (``tests/sim/test_kernel_reference.py``).
"""

from sanlab.sim.compiler import compile_creature
from sanlab.sim.kernel import ACC, Observe, lanes
from sanlab.sim.model import Model, Params, Structure
from sanlab.sim.rollout import (
    ConstantController,
    Frames,
    PatternController,
    ReflexController,
    Result,
    SineController,
    devices,
    rollout,
)
from sanlab.sim.rows import Rows
from sanlab.sim.state import (
    SanState,
    State,
    centre_of_mass,
    energy,
    follow_point,
    from_root_coordinates,
    initial_state,
    make_state,
    poses,
    root_coordinates,
    sense,
    step,
    terrain_height,
    velocity,
    wrap_angle,
)

__all__ = [
    "State", "SanState", "centre_of_mass", "energy", "follow_point", "poses", "initial_state", "make_state", "sense",
    "step", "terrain_height", "velocity", "wrap_angle", "root_coordinates", "from_root_coordinates",
    "Model", "Params", "Structure", "compile_creature",
    "ConstantController", "Frames", "PatternController", "ReflexController", "Result", "SineController",
    "devices", "rollout", "Rows", "Observe", "ACC", "lanes",
]
