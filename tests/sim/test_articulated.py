"""The O(n) articulated-body route of the step (``sim.articulated``) against the dense route.

Both routes solve the same linear systems (the step's matrix M + sum c g g^T, the mass matrix
for the velocity M^-1 p, and M du for the momentum update), so a step agrees to round-off; over
long horizons a chaotic gait may drift apart, as it would with any change of rounding, which is
why the comparisons are over a few dozen steps.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.metrics import Metric
from sanlab.sim import dynamics
from sanlab.sim.model import articulated_supported
from tests.sim.test_physics import on_ice, random_sans

WELDED = """
name = "rig"
dt = 0.001
[world]
plane = "vertical"
[[links]]
name = "post"
mass = 1.0
shape = "segment"
points = [[0.0, 0.0], [0.0, 0.3]]
fixed = true
position = [0.0, 0.1]
[[links]]
name = "arm"
mass = 0.4
shape = "segment"
points = [[0.0, 0.0], [0.3, 0.0]]
contacts = [[0.3, 0.0]]
parent = "post"
anchor = [0.0, 0.3]
angle_deg = -20
[[links]]
name = "forearm"
mass = 0.2
shape = "polygon"
points = [[0.0, -0.02], [0.25, -0.02], [0.25, 0.02], [0.0, 0.02]]
contacts = [[0.25, 0.0]]
parent = "arm"
anchor = [0.3, 0.0]
angle_deg = -40
[[links]]
name = "side"
mass = 0.2
shape = "segment"
points = [[0.0, 0.0], [0.2, 0.0]]
contacts = [[0.2, 0.0]]
parent = "post"
anchor = [0.0, 0.15]
angle_deg = -150
[[actuators]]
name = "shoulder"
type = "angular"
joint = "arm"
min_deg = -60
max_deg = 20
ks = 0.2
kd = 0.02
[[actuators]]
name = "elbow"
type = "angular"
joint = "forearm"
min_deg = -90
max_deg = 0
ks = 0.1
kd = 0.01
"""


def chain(n: int) -> str:
    """An n-segment chain lying on the ground: a contact at each joint; a touch sensor, an angle
    sensor and a servo per joint."""
    out = ['name = "chain"', "dt = 0.001", "[world]", 'plane = "vertical"']
    for i in range(n):
        out += ["[[links]]", f'name = "s{i}"', "mass = 0.1", 'shape = "segment"', "points = [[0.0, 0.0], [0.1, 0.0]]"]
        out += ["contacts = [[0.0, 0.0], [0.1, 0.0]]" if i == 0 else "contacts = [[0.1, 0.0]]"]
        out += ["position = [0.0, 0.0]"] if i == 0 else [f'parent = "s{i - 1}"', "anchor = [0.1, 0.0]"]
    for i in range(1, n):
        out += ["[[sensors]]", f'name = "a{i}"', 'type = "angle"', f'link = "s{i}"', "min_deg = 20", "max_deg = 180"]
        out += ["[[sensors]]", f'name = "t{i}"', 'type = "touch"', f'link = "s{i}"', "contact = 0"]
        out += ["[[actuators]]", f'name = "m{i}"', 'type = "angular"', f'joint = "s{i}"', "min_deg = -45",
                "max_deg = 45", "ks = 0.02", "kd = 0.002"]
    return "\n".join(out) + "\n"


def spec_of(name: str):
    if name == "rig":
        return creature.loads(WELDED)
    if name.startswith("chain"):
        return creature.loads(chain(int(name[5:])))
    return creature.load(name)


def eager_steps(spec, articulated: bool, n_steps: int, seed: int = 0):
    """n_steps of the float64 step, run op by op (no compilation), under random activations."""
    m = sim.compile_creature(spec, "float64", articulated=articulated)
    rng = np.random.default_rng(seed)
    state = sim.make_state(m)
    for _ in range(n_steps):
        u = rng.uniform(0.0, 1.0, m.structure.n_actuators)
        fr = dynamics.prepare(m, state)
        state, _ = dynamics.advance(m, fr, state, u)
    return m, state


@pytest.mark.parametrize("name", ["bounder", "fish", "rig", "chain5"])
def test_a_step_agrees_with_the_dense_route_to_round_off(name):
    # bounder: a branching free tree with ground contact and sticking friction; fish: water drag
    # on edges and a passive joint spring, horizontal plane; rig: a tree welded to the world;
    # chain5: an unbranched free chain
    spec = spec_of(name)
    md, dense = eager_steps(spec, False, 25)
    ma, art = eager_steps(spec, True, 25)
    assert not md.structure.articulated and ma.structure.articulated
    scale = 1.0 + float(np.max(np.abs(np.asarray(dense.p))))
    np.testing.assert_allclose(np.asarray(art.q), np.asarray(dense.q), rtol=0, atol=1e-11)
    np.testing.assert_allclose(np.asarray(art.p), np.asarray(dense.p), rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(np.asarray(art.anchor), np.asarray(dense.anchor), rtol=0, atol=1e-11)
    # and the state really moved (a step that does nothing would agree too)
    assert float(np.max(np.abs(np.asarray(dense.q) - np.asarray(md.params.q0)))) > 1e-5


def test_the_velocity_and_energy_helpers_agree():
    spec = spec_of("bounder")
    md, dense = eager_steps(spec, False, 10, seed=2)
    ma = sim.compile_creature(spec, "float64", articulated=True)
    np.testing.assert_allclose(np.asarray(sim.velocity(ma, dense)), np.asarray(sim.velocity(md, dense)), atol=1e-12)
    qd = np.asarray(sim.velocity(md, dense))
    np.testing.assert_allclose(np.asarray(sim.make_state(ma, dense.q, qd).p),
                               np.asarray(sim.make_state(md, dense.q, qd).p), atol=1e-12)
    ea, ed = sim.energy(ma, dense), sim.energy(md, dense)
    assert abs(float(ea["kinetic"]) - float(ed["kinetic"])) < 1e-12


def test_creatures_with_linear_elements_stay_on_the_dense_route():
    spec = creature.load("crawler")  # linear actuators join two bodies
    assert not articulated_supported(spec)
    assert not sim.compile_creature(spec).structure.articulated
    with pytest.raises(ValueError, match="articulated route"):
        sim.compile_creature(spec, articulated=True)


def test_no_controller_moves_a_long_chain_on_ice():
    # the momentum form's guarantee (test_physics, case 1) holds on the articulated route
    spec = on_ice(spec_of("chain12"))
    m = sim.compile_creature(spec, articulated=True)
    assert m.structure.articulated
    san, p = random_sans(spec, 16, seed=1)
    r = sim.rollout(m, san, p, 2.0, observer=Metric.for_creature(spec, "distance"))
    dx = np.asarray(r.acc.p[0]) - np.asarray(r.acc.p0[0])
    assert bool(np.all(np.asarray(r.finite)))
    assert np.max(np.abs(dx)) < 1e-3
    # the joints really moved, and differently under different networks
    assert np.max(np.abs(np.asarray(r.state.q[:, 3:]) - np.asarray(m.params.q0[3:]))) > 0.2
    assert np.max(np.ptp(np.asarray(r.state.q[:, 3:]), axis=0)) > 0.05


def test_one_controller_is_bit_identical_alone_and_in_a_batch():
    spec = spec_of("chain6")
    m = sim.compile_creature(spec, articulated=True)
    san, p = random_sans(spec, 9, seed=3)
    full = sim.rollout(m, san, p, seconds=0.3)
    for i in (0, 5):
        alone = sim.rollout(m, san, jax.tree_util.tree_map(lambda x: x[i:i + 1], p), seconds=0.3)
        np.testing.assert_array_equal(np.asarray(alone.state.q[0]), np.asarray(full.state.q[i]))


def test_the_route_is_chosen_by_size():
    # every built-in stays on the dense route (their results keep their last bits); a long chain
    # goes articulated
    assert not any(sim.compile_creature(creature.load(n)).structure.articulated for n in ("bounder", "walker"))
    assert sim.compile_creature(spec_of("chain12")).structure.articulated
    assert not sim.compile_creature(spec_of("chain12"), articulated=False).structure.articulated
