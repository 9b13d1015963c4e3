"""Physics a search cannot cheat (issue 10): momentum, sticking friction, energy, bodies started
inside the ground, water along a segment, joint stops.

Each case is a small creature written here and a value it must reach; each value is the
physical answer (a conserved quantity, a force balance) rather than whatever the integrator
happens to give, so a regression in the integrator shows up here first.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.creature.spec import (
    AngularActuator,
    Creature,
    Ground,
    JointLimit,
    Link,
    Shape,
    Terrain,
    World,
)
from sanlab.evaluate.records import GaitParams
from sanlab.metrics import Metric, scores
from sanlab.san import San
from sanlab.search.space import Space

G = 9.81
DEG = math.pi / 180


def random_sans(spec, n, seed, dtype="float32"):
    san = San.for_creature(spec)
    w = np.stack([san.random_weights(seed, i) for i in range(n)])
    return san, san.params(w, spec.san.delay_on, spec.san.delay_off, dtype)


def on_ice(spec: Creature) -> Creature:
    ground = dataclasses.replace(spec.world.ground, friction=0.0)
    return dataclasses.replace(spec, world=dataclasses.replace(spec.world, ground=ground))


# ------------------------------------------------------------------------ 1. walking on ice


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_no_controller_moves_the_centre_of_mass_on_frictionless_ground(dtype):
    # Frictionless flat ground pushes only vertically, so no horizontal external force acts and
    # the centre of mass cannot move along x, whatever the legs do. 64 random SANs for 6 s on the
    # bounder; right value |dx| < 1 mm. Measured: 2e-3 mm (float32 arithmetic), 5e-12 mm (float64); the old
    # velocity-form step drifted up to about 3 cm.
    spec = on_ice(creature.load("bounder"))
    m = sim.compile_creature(spec, dtype)
    san, p = random_sans(spec, 64, seed=1, dtype=dtype)
    metric = Metric.for_creature(spec, "distance")
    r = sim.rollout(m, san, p, 6.0, observer=metric)
    dx = np.asarray(r.acc.p[0]) - np.asarray(r.acc.p0[0])
    assert bool(np.all(np.asarray(r.finite)))
    assert np.max(np.abs(dx)) < 1e-3
    # the legs really moved: the body went up and down (these are not 64 creatures standing still)
    dy = np.abs(np.asarray(r.state.q[:, 1]) - float(m.params.q0[1]))
    assert np.max(dy) > 0.02


@pytest.mark.parametrize("articulated", [True, False])
def test_no_controller_moves_a_long_chain_on_ice(articulated):
    # the momentum form's guarantee on a 12-link chain (14 dofs), by both routes of the step's
    # linear algebra: 16 random SANs for 2 s
    out = ['name = "chain"', "dt = 0.001", "[world]", 'plane = "vertical"']
    for i in range(12):  # a contact at each joint; a touch sensor, an angle sensor and a servo per joint
        out += ["[[links]]", f'name = "s{i}"', "mass = 0.1", 'shape = "segment"', "points = [[0.0, 0.0], [0.1, 0.0]]"]
        out += ["contacts = [[0.0, 0.0], [0.1, 0.0]]" if i == 0 else "contacts = [[0.1, 0.0]]"]
        out += ["position = [0.0, 0.0]"] if i == 0 else [f'parent = "s{i - 1}"', "anchor = [0.1, 0.0]"]
    for i in range(1, 12):
        out += ["[[sensors]]", f'name = "a{i}"', 'type = "angle"', f'link = "s{i}"', "min_deg = 20", "max_deg = 180"]
        out += ["[[sensors]]", f'name = "t{i}"', 'type = "touch"', f'link = "s{i}"', "contact = 0"]
        out += ["[[actuators]]", f'name = "m{i}"', 'type = "angular"', f'joint = "s{i}"', "min_deg = -45",
                "max_deg = 45", "ks = 0.02", "kd = 0.002"]
    spec = on_ice(creature.loads("\n".join(out) + "\n", source="chain12"))
    m = sim.compile_creature(spec, articulated=articulated)
    san, p = random_sans(spec, 16, seed=1)
    r = sim.rollout(m, san, p, 2.0, observer=Metric.for_creature(spec, "distance"))
    dx = np.asarray(r.acc.p[0]) - np.asarray(r.acc.p0[0])
    assert bool(np.all(np.asarray(r.finite)))
    assert np.max(np.abs(dx)) < 1e-3
    # the joints really moved, and differently under different networks
    assert np.max(np.abs(np.asarray(r.state.q[:, 3:]) - np.asarray(m.params.q0[3:]))) > 0.2
    assert np.max(np.ptp(np.asarray(r.state.q[:, 3:]), axis=0)) > 0.05


def test_tuned_parameters_cannot_buy_motion_on_ice():
    # What a tuner could reach: every parameter of phase 2 (delays, actuator ranges and gains,
    # sensor ranges, link lengths and masses) moved far from nominal, 48 random variants, each
    # driven by a random SAN. None moves the centre of mass by 1 mm.
    spec = on_ice(creature.load("bounder"))
    space = Space(spec, morphology=True)
    model = sim.compile_creature(spec)
    rng = np.random.default_rng(7)
    theta0 = space.nominal(GaitParams(spec.san.delay_on, spec.san.delay_off))
    thetas = []
    for _ in range(48):
        th = theta0.copy()
        for _ in range(60):
            th = space.perturb(th, int(rng.integers(len(space))), float(rng.choice([-1.0, 1.0])))
        thetas.append(th)
    thetas = np.stack(thetas)
    k1, k2, mb = space.batch(thetas, model)
    san, p = random_sans(spec, 48, seed=2)
    p = p._replace(k1=np.asarray(k1, np.float32), k2=np.asarray(k2, np.float32))
    metric = Metric.for_creature(spec, "distance")
    r = sim.rollout(mb, san, p, 6.0, observer=metric, params_batched=True)
    dx = np.asarray(r.acc.p[0]) - np.asarray(r.acc.p0[0])
    assert bool(np.all(np.asarray(r.finite)))
    assert np.max(np.abs(dx)) < 1e-3


def test_linear_and_angular_momentum_are_kept_in_flight():
    # A bounder thrown into the air without gravity, legs driven by random SANs: its linear
    # momentum and its angular momentum about its centre of mass stay what they were (the root
    # angle is a cyclic coordinate in flight). Right value: to round-off (float64).
    spec = creature.load("bounder")
    spec = dataclasses.replace(spec, world=dataclasses.replace(spec.world, gravity=0.0))
    m = sim.compile_creature(spec, "float64")
    q = np.asarray(m.params.q0).copy()
    q[1] += 2.0  # far above the ground: no contact for the whole run
    qd = np.zeros_like(q)
    qd[:3] = [0.7, -0.2, 3.0]
    s0 = sim.make_state(m, np.asarray(q), np.asarray(qd))
    san, p = random_sans(spec, 4, seed=3, dtype="float64")
    r = sim.rollout(m, san, p, 2.0, state0=s0, record_fps=50)
    p0 = np.asarray(s0.p)
    pf = np.asarray(r.state.p)
    np.testing.assert_allclose(pf[:, :3], np.broadcast_to(p0[:3], (4, 3)), rtol=0, atol=1e-10)
    assert np.ptp(np.asarray(r.frames.q[:, :, 3:])) > 0.5  # the legs swung meanwhile


# ----------------------------------------------------------------- 2. friction that holds


def slope_box(mu: float, angle_deg: float = 10.0) -> Creature:
    a = angle_deg * DEG
    x0 = 0.5
    return creature.loads(f"""
        name = "slope_box"
        [world]
        ground = {{ friction = {mu} }}
        terrain = {{ kind = "slope", angle_deg = {angle_deg} }}
        [[links]]
        name = "box"
        mass = 1.0
        shape = "polygon"
        points = [[0, 0], [0.2, 0], [0.2, 0.1], [0, 0.1]]
        position = [{x0}, {x0 * math.tan(a)}]
        angle_deg = {angle_deg}
        """)


def test_a_box_on_a_slope_inside_the_friction_cone_holds_for_30_s():
    # tan(10 deg) = 0.18 < mu = 0.6: static friction holds the box. Right value: under 1 mm of
    # drift over 30 s after settling (the old regularised friction crept 2.9 mm/s: 8.7 cm).
    # Measured: 0 (the contacts stick to their anchors).
    m = sim.compile_creature(slope_box(0.6), "float64")
    r = sim.rollout(m, sim.ConstantController(), np.zeros((1, 0)), 31.0, record_fps=10)
    com = sim.poses(m, r.frames.q[0])["com"]
    i0 = np.searchsorted(r.frames.t, 1.0)
    drift = np.linalg.norm(com[-1] - com[i0])
    assert r.frames.t[-1] - r.frames.t[i0] >= 29.9
    assert drift < 1e-3


def test_the_bounder_holding_its_start_pose_stands_for_30_s():
    # The built-in bounder with its servos holding the start pose (constant activations): with
    # friction that sticks it stands still. Right value: no fall and under 1 mm of drift over
    # 30 s after settling (5 s: the servos first sag under the weight, moving the centre of mass
    # about 5 mm); the old friction let it creep and fall over at 17-19 s.
    spec = creature.load("bounder")
    m = sim.compile_creature(spec, "float64")
    u = []
    for a in spec.actuators:
        start = spec.link(a.joint).angle
        u.append((start - a.min) / (a.max - a.min))
    u = np.clip(np.array(u), 0, 1)[None]
    metric = Metric.for_creature(spec)
    r = sim.rollout(m, sim.ConstantController(), np.asarray(u), 35.0, record_fps=10, observer=metric)
    out = scores(metric, r.acc, r.finite, 35.0, "vertical")
    assert not bool(out["fell"][0]) and not bool(out["nonfinite"][0])
    com = sim.poses(m, r.frames.q[0])["com"]
    i0 = np.searchsorted(r.frames.t, 5.0)
    assert np.max(np.linalg.norm(com[i0:] - com[i0], axis=1)) < 1e-3


def test_above_the_friction_cone_the_box_slides_at_g_sin_minus_mu_cos():
    # tan(25 deg) = 0.47 > mu = 0.3: it slides with a = g (sin a - mu cos a) = 1.48 m/s^2.
    m = sim.compile_creature(slope_box(0.3, 25.0), "float64")
    r = sim.rollout(m, sim.ConstantController(), np.zeros((1, 0)), 1.5, record_fps=1000)
    e = np.array([math.cos(25 * DEG), math.sin(25 * DEG)])
    v = np.asarray(r.frames.qd[0, :, :2]) @ e
    t = r.frames.t
    sel = t > 0.2
    acc = np.polyfit(t[sel], v[sel], 1)[0]
    assert acc == pytest.approx(-G * (math.sin(25 * DEG) - 0.3 * math.cos(25 * DEG)), rel=0.02)


# ----------------------------------------------------------------- 3. no energy from nowhere


def chain(n: int, length: float = 0.1, mass: float = 0.1, angles=None, dt: float = 1e-3) -> Creature:
    """A passive, undamped n-link pendulum hanging from a pivot welded at (0, 2)."""
    base = Link("base", 1.0, 0.0, (0.0, 0.0), Shape("point"), position=(0.0, 2.0), fixed=True, contacts=())
    links = [base]
    angles = angles or [0.0] * n
    for i in range(n):
        links.append(Link(
            f"L{i}", mass, mass * length * length / 12, (length / 2, 0.0),
            Shape("segment", ((0.0, 0.0), (length, 0.0))), contacts=(),
            parent="base" if i == 0 else f"L{i - 1}", anchor=(0.0, 0.0) if i == 0 else (length, 0.0),
            angle=angles[i],
        ))  # fmt: skip
    return Creature(f"chain{n}", tuple(links), dt=dt)


def _energy_run(spec: Creature, seconds: float = 10.0):
    """(energy watch of every step, the energy the chain can lose from its release to hanging
    straight down, the rollout)."""
    # every step recorded (the state before it), its energy and centre of mass read by the kernel
    m = sim.compile_creature(spec, "float64")
    r = sim.rollout(m, sim.ConstantController(), np.zeros((1, 0)), seconds, record_fps=1.0 / float(m.params.dt))
    q, qd = r.frames.q[0], r.frames.qd[0]
    e = sim.energy(m, sim.make_state(m, q, qd))
    e = e["kinetic"] + e["gravity"]
    y = sim.poses(m, q)["com"][:, 1]
    w = {"e0": e[0], "e_max": e.max(), "y0": y[0], "y_max": y.max(), "y_min": y.min()}
    # hanging straight down from the pivot: each link's centre of mass below its joint by its
    # offset along the link, each joint below the last by the length of the link above it
    hang, y = 0.0, spec.links[0].position[1]
    for link in spec.links[1:]:
        hang += link.mass * float(m.params.gravity) * (y - link.com[0])
        y -= link.shape.points[1][0]
    return w, w["e0"] - hang, r


def test_a_passive_15_link_pendulum_released_from_rest_gains_no_energy():
    # Released horizontal from rest; 10 s at the creature's dt (1 ms). Right value: the energy
    # never rises more than 1 % of what the fall can release, and the centre of mass never rises
    # above its release height. Measured: never above the start (the old velocity-form step
    # gained up to 23 % and rose 2.7 cm); it loses energy instead (about 40 % over 10 s: the
    # step's numerical damping of the whip).
    w, scale, r = _energy_run(chain(15))
    assert bool(r.finite[0])
    assert (w["e_max"] - w["e0"]) / scale < 0.01
    assert w["y_max"] <= w["y0"] + 1e-4
    assert w["y_max"] - w["y_min"] > 0.3  # it fell and swung


@pytest.mark.parametrize("angles", [[0.0, 0.0], [0.4, -1.2], [0.0, 0.5, -0.7], [0.3, -0.4, 0.8, -1.0, 0.6, -0.2]],
                         ids=["2 straight", "2 bent", "3 bent", "6 bent"])
def test_short_pendulums_released_from_rest_gain_no_energy(angles):
    w, scale, r = _energy_run(chain(len(angles), angles=angles))
    assert bool(r.finite[0])
    assert (w["e_max"] - w["e0"]) / scale < 0.01
    assert w["y_max"] <= w["y0"] + 1e-4


# ----------------------------------------------------------- 4. bodies started inside the ground


def test_a_body_started_inside_the_ground_is_placed_on_it_not_launched():
    # A box whose file puts it 10 cm into the ground: compiled, it starts resting on the ground
    # (its lowest contact at the surface) and stays there; the penalty spring would otherwise
    # throw it about 1.5 m up.
    spec = creature.loads("""
        name = "sunk"
        [[links]]
        name = "box"
        mass = 2.0
        shape = "polygon"
        points = [[-0.2, -0.05], [0.2, -0.05], [0.2, 0.05], [-0.2, 0.05]]
        position = [0.0, -0.05]
        """)
    m = sim.compile_creature(spec, "float64")
    low = float(np.min(np.asarray(sim.poses(m, m.params.q0)["contacts"][:, 1])))
    assert low == pytest.approx(0.0, abs=1e-9)
    r = sim.rollout(m, sim.ConstantController(), np.zeros((1, 0)), 1.0, record_fps=100)
    y = sim.poses(m, r.frames.q[0])["com"][:, 1]
    assert y.max() < 0.05 + 1e-3  # never thrown up


@pytest.mark.parametrize("terrain", [Terrain(kind="rough", height=0.015, wavelength=0.25, seed=s) for s in (1, 2, 3)]
                         + [Terrain(kind="hill", height=0.08, width=1.0, center=c) for c in (0.7, -0.7, 0.1)],
                         ids=["rough1", "rough2", "rough3", "hill+0.7", "hill-0.7", "hill-under"])
def test_terrains_place_the_bounder_on_the_ground(terrain):
    # tune --terrain rough started the bounder with a foot 1.6-1.9 cm inside two of its grounds.
    spec = creature.load("bounder")
    spec = dataclasses.replace(spec, world=dataclasses.replace(spec.world, terrain=terrain))
    m = sim.compile_creature(spec, "float64")
    depth = np.asarray(sim.poses(m, m.params.q0)["depth"])
    assert depth.max() <= 1e-9  # no contact inside the ground
    assert depth.max() > -0.02  # and not thrown clear of it either


# ------------------------------------------------------------------- 6. water along a segment


def swimmer(tangential: float) -> Creature:
    rod = Link("rod", 0.2, 0.2 * 0.16 / 12, (0.0, 0.0), Shape("segment", ((-0.2, 0.0), (0.2, 0.0))), contacts=())
    world = World(plane="horizontal", ground=Ground(friction=0.0), water_drag=0.5, water_tangential=tangential)
    return Creature("swimmer", (rod,), world=world)


def test_a_segment_coasting_along_its_axis_slows_down_by_skin_drag():
    # Skin drag -k_t L v along the segment: v = v0 exp(-k_t L t / m), k_t = 0.1 x 0.5 N s/m^2,
    # L = 0.4 m, m = 0.2 kg: rate 0.1 /s. The paper's normal-only model (water_tangential = 0)
    # lets it coast for ever (the old behaviour: 0.3 m/s for 30 s).
    for tangential, rate in ((0.1, 0.1 * 0.5 * 0.4 / 0.2), (0.0, 0.0)):
        m = sim.compile_creature(swimmer(tangential), "float64")
        s0 = sim.make_state(m, m.params.q0, np.array([0.3, 0.0, 0.0]))
        r = sim.rollout(m, sim.ConstantController(), np.zeros((1, 0)), 30.0, state0=s0, record_fps=10)
        v = np.asarray(r.frames.qd[0, :, 0])
        np.testing.assert_allclose(v, 0.3 * np.exp(-rate * r.frames.t), rtol=2e-3)
        assert np.max(np.abs(np.asarray(r.frames.qd[0, :, 1:]))) < 1e-12  # no sideways push, no turn


# -------------------------------------------------------------------------- 7. joint stops


def stop_rig(limit: JointLimit | None) -> Creature:
    base = Link("base", 1.0, 0.0, (0.0, 0.0), Shape("point"), fixed=True, contacts=())
    arm = Link("arm", 0.2, 0.2 * 0.09 / 12, (0.15, 0.0), Shape("segment", ((0.0, 0.0), (0.3, 0.0))),
               contacts=(), parent="base", limit=limit)
    act = AngularActuator("A", "arm", -80 * DEG, 80 * DEG, 2.0, 0.05)
    return Creature("stop", (base, arm), actuators=(act,), world=World(plane="horizontal"))


def test_a_joint_stop_holds_a_servo_pushing_past_it():
    # The servo asks for 80 deg, the stop is at 30 deg: at rest the stop's spring balances the
    # servo, k_stop (phi - 30) = ks (80 - phi), phi = 30 + 2 x 50 / (57.3 + 2) = 31.7 deg.
    # Without the stop the arm goes to 80 deg.
    lim = JointLimit(-30 * DEG, 30 * DEG)
    for limit, expected in ((lim, (30 * DEG * lim.stiffness + 2.0 * 80 * DEG) / (lim.stiffness + 2.0)), (None, 80 * DEG)):
        m = sim.compile_creature(stop_rig(limit), "float64")
        r = sim.rollout(m, sim.ConstantController(), np.ones((1, 1)), 3.0, record_fps=100)
        assert float(r.state.q[0, 0]) == pytest.approx(expected, abs=1e-4)
    # and it never pulls: driven back to -80 deg, the arm leaves the stop freely
    m = sim.compile_creature(stop_rig(lim), "float64")
    r = sim.rollout(m, sim.ConstantController(), np.zeros((1, 1)), 3.0, record_fps=100)
    assert float(r.state.q[0, 0]) == pytest.approx((-30 * DEG * lim.stiffness - 2.0 * 80 * DEG) / (lim.stiffness + 2.0),
                                                   abs=1e-4)


def test_a_tilt_sensor_reads_the_link_in_the_world_not_at_its_joint():
    # A leg hanging from a body: its joint angle stays 0 while the body turns, so an angle sensor
    # on it never changes; a tilt sensor on it sees the world angle (body + joint).
    from sanlab.creature.spec import AngleSensor, TiltSensor

    body = Link("body", 1.0, 0.01, (0.0, 0.0), Shape("segment", ((-0.1, 0.0), (0.1, 0.0))), contacts=())
    leg = Link("leg", 0.2, 0.001, (0.0, -0.1), Shape("segment", ((0.0, 0.0), (0.0, -0.2))), contacts=(), parent="body")
    sensors = (AngleSensor("joint", "leg", -10 * DEG, 10 * DEG), TiltSensor("level", "leg", -10 * DEG, 10 * DEG),
               TiltSensor("tipped", "leg", 30 * DEG, 60 * DEG))
    m = sim.compile_creature(Creature("tilt", (body, leg), sensors=sensors, world=World(plane="horizontal")), "float64")

    def bits(q):
        return sim.sense(m, q)

    np.testing.assert_array_equal(np.asarray(bits(np.array([0.0, 0.0, 0.0, 0.0]))), [1, 1, 0])
    np.testing.assert_array_equal(np.asarray(bits(np.array([0.0, 0.0, 45 * DEG, 0.0]))), [1, 0, 1])
    np.testing.assert_array_equal(np.asarray(bits(np.array([0.0, 0.0, 45 * DEG, -45 * DEG]))), [0, 1, 0])
