"""The world against analytic answers: slopes and friction, terrain, water, springs, servos,
sensors, the follow point and ground penetration.

Every check runs in float64 and compares with a closed-form answer written next to it. The
tolerances sit well above the measured errors (given in each comment) and well below what a
wrong factor, sign or frame would produce, so every test can fail. Where the error is known to
come from the integrator (semi-implicit Euler whose stiff terms are linearly implicit, i.e.
backward Euler for springs, dampers, drag and sticking friction), the comment gives its size.

Runs sharing one creature structure are batched into one compiled rollout (``stack`` puts
models that differ only in numbers into one batched model) to keep the file fast.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest

from sanlab import sim
from sanlab.creature import load, loads
from sanlab.creature.spec import (
    AngleSensor,
    AngularActuator,
    Creature,
    EyeSensor,
    Follow,
    Friction,
    Ground,
    JointSpring,
    LengthSensor,
    LinearActuator,
    LinearSpring,
    Link,
    PointRef,
    Shape,
    Terrain,
    TouchSensor,
    World,
)

G = 9.81
DEG = math.pi / 180


# ------------------------------------------------------------------------------------ helpers


def compile64(spec: Creature) -> sim.Model:
    return sim.compile_creature(spec, "float64")


def stack(models: list[sim.Model]) -> sim.Model:
    """One model whose every parameter carries a leading batch axis (same structure, different
    numbers): a batch of variants in one compiled rollout (``params_batched=True``)."""
    fields = [f.name for f in dataclasses.fields(models[0].params)]
    return models[0].with_params(**{f: np.stack([np.asarray(getattr(m.params, f)) for m in models]) for f in fields})


def roll(model, seconds, u=None, B=1, state0=None, batched=False):
    """Roll ``model`` out with constant activations ``u`` [B, A] (default: no actuators),
    recording every step (one copy of the step in the compiled program: the fastest to compile)."""
    if u is None:
        u = np.zeros((B, model.structure.n_actuators))
    return sim.rollout(
        model, sim.ConstantController(), np.asarray(u, np.float64), seconds=seconds,
        record_fps=1.0 / model.structure.dt, state0=state0, params_batched=batched,
    )  # fmt: skip


def states(model, q, qd=None, t=0.0) -> sim.State:
    q = np.atleast_2d(np.asarray(q, float))
    qd = np.zeros_like(q) if qd is None else np.atleast_2d(np.asarray(qd, float))
    return sim.make_state(model, q, qd, t)


def point(name, mass, pos=(0.0, 0.0), **kw) -> Link:
    return Link(
        name=name, mass=mass, inertia=0.0, com=(0.0, 0.0), shape=Shape("point"),
        contacts=((0.0, 0.0),), position=pos, **kw,
    )  # fmt: skip


def crossings(t, x) -> np.ndarray:
    """Times where x changes sign (linear interpolation between frames)."""
    t, x = np.asarray(t), np.asarray(x)
    i = np.nonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))[0]
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def peaks(t, x) -> tuple[np.ndarray, np.ndarray]:
    """Positive local maxima of x, refined by a parabola through three frames."""
    t, x = np.asarray(t), np.asarray(x)
    i = np.nonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:]) & (x[1:-1] > 0))[0] + 1
    y0, y1, y2 = x[i - 1], x[i], x[i + 1]
    d = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    return t[i] + d * (t[1] - t[0]), y1 - 0.25 * (y0 - y2) * d


# ------------------------------------------------------------------------- 1. box on a slope

ALPHA = 20 * DEG  # tan(alpha) = 0.364
BOX_W, BOX_H, BOX_M = 0.2, 0.1, 1.0
# (friction mu, slip speed eps): sticking with a tiny eps, sticking with a large eps (once crept),
# sliding with friction, frictionless
SLOPE_CASES = [(0.6, 1e-4), (0.6, 0.01), (0.2, 0.01), (0.0, 0.01)]


def slope_box(mu: float, slip: float) -> Creature:
    """A box whose bottom-left corner is its frame origin, turned by alpha and put down with both
    bottom corners on the slope y = tan(alpha) x (parsed from TOML, so the loader's degrees and
    default polygon mass properties are part of the check)."""
    x0 = 0.5
    return loads(f"""
        name = "slope_box"
        dt = 0.001
        [world]
        plane = "vertical"
        ground = {{ friction = {mu}, slip_speed = {slip} }}
        terrain = {{ kind = "slope", angle_deg = {ALPHA / DEG} }}
        [[links]]
        name = "box"
        mass = {BOX_M}
        shape = "polygon"
        points = [[0, 0], [{BOX_W}, 0], [{BOX_W}, {BOX_H}], [0, {BOX_H}]]
        position = [{x0}, {x0 * math.tan(ALPHA)}]
        angle_deg = {ALPHA / DEG}
        """)


@functools.lru_cache(maxsize=None)
def _slope_run():
    """All slope cases in one batched rollout, 1.5 s. Returns (t, s, v, angle) per case: the
    position and velocity of the box's origin along the slope direction (cos a, sin a)."""
    model = stack([compile64(slope_box(*c)) for c in SLOPE_CASES])
    res = roll(model, 1.5, B=len(SLOPE_CASES), batched=True)
    e = np.array([math.cos(ALPHA), math.sin(ALPHA)])
    q, qd = np.asarray(res.frames.q), np.asarray(res.frames.qd)
    assert np.all(np.asarray(res.finite))
    return res.frames.t, q[..., :2] @ e, qd[..., :2] @ e, q[..., 2]


def test_slope_box_stays_put_when_mu_exceeds_tan_alpha():
    # Coulomb: static friction holds the box if mu >= tan(alpha) (0.6 > 0.364). The regularised
    # friction (viscous below eps) lets it creep at eps tan(a) / mu, here 6e-5 m/s with eps = 1e-4.
    # Measured: 6.1e-5 m over the 1 s after settling.
    t, s, _, ang = _slope_run()
    i0, i1 = np.searchsorted(t, 0.5), len(t) - 1
    assert t[i1] - t[i0] == pytest.approx(1.0, abs=2e-3)
    assert abs(s[0, i1] - s[0, i0]) < 1e-3
    assert abs(ang[0, i1] - ALPHA) < 1e-3  # still flat on the slope


def test_slope_box_does_not_creep_whatever_the_slip_speed():
    # The regularised friction of old (viscous below the slip speed eps) let the box creep
    # downhill at eps tan(a) / mu, 6.07 mm/s at eps = 0.01 m/s. Friction now sticks: each contact
    # holds on to an anchor, and the slip speed only sets how stiff the hold's damper is.
    # Right value: no creep with eps = 0.01 m/s either. Measured: 0 over 1 s.
    t, s, _, _ = _slope_run()
    i0, i1 = np.searchsorted(t, 0.5), len(t) - 1
    v = (s[1, i1] - s[1, i0]) / (t[i1] - t[i0])
    assert abs(v) < 1e-6


@pytest.mark.parametrize("case", [2, 3], ids=["mu=0.2", "frictionless"])
def test_slope_box_slides_with_g_sin_minus_mu_cos(case):
    # mu < tan(alpha): the box slides downhill with a = g (sin a - mu cos a) (1.51 m/s^2 for
    # mu = 0.2, 3.36 for mu = 0). Fitted to the velocity along the slope over 0.2-1.5 s.
    # Measured error ~1e-14 (constant acceleration is exact for the integrator).
    mu = SLOPE_CASES[case][0]
    t, _, v, ang = _slope_run()
    sel = t > 0.2
    acc = np.polyfit(t[sel], v[case, sel], 1)[0]
    expected = -G * (math.sin(ALPHA) - mu * math.cos(ALPHA))
    assert acc == pytest.approx(expected, rel=0.02)
    assert np.max(np.abs(ang[case] - ALPHA)) < 1e-3  # slides flat, does not tip


# ----------------------------------------------------------------------- 2. hill and rough terrain


def terrain_world(**terrain) -> Creature:
    """A 1 kg point mass in a vertical-plane world with the given terrain."""
    world = World(ground=Ground(friction=1.0), terrain=Terrain(**terrain))
    return Creature("probe", (point("p", 1.0),), world=world)


def heights(model, x) -> tuple[np.ndarray, np.ndarray]:
    h, dh = sim.terrain_height(model, np.asarray(x, float))
    x = np.asarray(x, float)
    return np.broadcast_to(np.asarray(h), x.shape), np.broadcast_to(np.asarray(dh), x.shape)


HILL = dict(kind="hill", height=0.2, width=2.0, center=1.0)
ROUGH = dict(kind="rough", height=0.03, wavelength=0.5, seed=3)


def test_slope_and_hill_height_functions():
    x = np.linspace(-1.0, 3.0, 401)
    # slope: h = tan(a) x
    m = compile64(terrain_world(kind="slope", angle=0.3))
    h, dh = heights(m, x)
    np.testing.assert_allclose(h, math.tan(0.3) * x, atol=1e-12)
    np.testing.assert_allclose(dh, math.tan(0.3), atol=1e-12)
    # hill: h = H (1 + cos(pi (x - c) / (w/2))) / 2 inside |x - c| < w/2, else 0
    m = compile64(terrain_world(**HILL))
    h, dh = heights(m, x)
    H, hw, c = 0.2, 1.0, 1.0
    ref = np.where(np.abs(x - c) < hw, H * (1 + np.cos(np.pi * (x - c) / hw)) / 2, 0.0)
    np.testing.assert_allclose(h, ref, atol=1e-12)
    assert heights(m, 1.0)[0] == pytest.approx(0.2, abs=1e-12)  # the peak, at the centre
    assert np.all(h[np.abs(x - c) >= hw] == 0.0)  # zero outside
    # the slope the contacts use is the derivative of the height
    fd = (heights(m, x + 1e-6)[0] - heights(m, x - 1e-6)[0]) / 2e-6
    np.testing.assert_allclose(dh, fd, atol=1e-6)


def test_rough_terrain_is_seeded_and_has_the_requested_rms():
    x = np.linspace(0.0, 400.0, 400_001)  # 1 mm steps, 100 of the longest wavelength (4 m)
    a = compile64(terrain_world(**ROUGH))
    b = compile64(terrain_world(**ROUGH))
    c = compile64(terrain_world(**{**ROUGH, "seed": 4}))
    ha, dha = heights(a, x)
    hb, _ = heights(b, x)
    hc, _ = heights(c, x)
    np.testing.assert_array_equal(ha, hb)  # same seed, same ground
    assert np.sqrt(np.mean((ha - hc) ** 2)) > 0.01  # another seed, other ground
    # RMS of h over a long range: the requested height (measured 0.4 % off for seed 3)
    rms = np.sqrt(np.mean(ha**2))
    assert rms == pytest.approx(0.03, rel=0.3)
    assert abs(np.mean(ha)) < 0.1 * 0.03
    fd = np.gradient(ha, x)
    np.testing.assert_allclose(dha[1:-1], fd[1:-1], atol=1e-3)


@pytest.mark.parametrize("terrain", [HILL, ROUGH], ids=["hill", "rough"])
def test_dropped_point_mass_settles_at_the_terrain_height(terrain):
    # A 1 kg point dropped from 1 cm above h(x) at 13 places comes to rest on the ground. At rest
    # the normal spring carries the weight: N = m g cos(a) = k d with d = (h - y) cos(a), so
    # y = h(x) - m g / k (0.2 mm at k = 5e4) on any slope. Measured |error| < 1e-10 m.
    # (It may slide or be kicked along first, see test_friction_never_reverses_the_slip_on_landing,
    # so h is taken at the final x.)
    spec = terrain_world(**terrain)
    m = compile64(spec)
    x0 = np.linspace(-0.5, 2.5, 13)
    q0 = np.stack([x0, heights(m, x0)[0] + 0.01], 1)
    res = roll(m, 2.0, B=len(x0), state0=states(m, q0))
    q, qd = np.asarray(res.state.q), np.asarray(res.state.qd)
    sink = 1.0 * G / spec.world.ground.stiffness
    np.testing.assert_allclose(q[:, 1], heights(m, q[:, 0])[0] - sink, atol=1e-4)
    assert np.all(np.hypot(qd[:, 0], qd[:, 1]) < 0.01)  # at rest (only the slow friction creep)


# ------------------------------------------------------------------------------- 3. water drag

ROD_L, ROD_M, WATER_K = 0.4, 0.2, 0.5
ROD_I = 2 * ROD_M * ROD_L**2 / 12  # not the uniform rod's, so that spin and translation differ
SQ_A, SQ_M = 0.3, 0.5
SQ_I = SQ_M * SQ_A**2 / 6
ROD_ANGLE = 0.5


@functools.lru_cache(maxsize=None)
def _water_run():
    """A rod (centred segment) and a square in water, horizontal plane, no friction. Three runs:
    0: rod moving across itself, square along x; 1: rod along its axis, square diagonally;
    2: both spinning about their centres."""
    rod = Link(
        name="rod", mass=ROD_M, inertia=ROD_I, com=(0.0, 0.0),
        shape=Shape("segment", ((-ROD_L / 2, 0.0), (ROD_L / 2, 0.0))), position=(0.3, -0.2),
        angle=ROD_ANGLE,
    )  # fmt: skip
    a = SQ_A / 2
    sq = Link(
        name="square", mass=SQ_M, inertia=SQ_I, com=(0.0, 0.0),
        shape=Shape("polygon", ((-a, -a), (a, -a), (a, a), (-a, a))), position=(2.0, 1.0),
        angle=0.2,
    )  # fmt: skip
    # the paper's normal-only model (the tangential part has its own test in test_physics.py)
    world = World(plane="horizontal", ground=Ground(friction=0.0), water_drag=WATER_K, water_tangential=0.0)
    m = compile64(Creature("swimmers", (rod, sq), world=world))
    c, s = math.cos(ROD_ANGLE), math.sin(ROD_ANGLE)
    v = 0.7
    qd = np.array([
        [-s * v, c * v, 0.0, v, 0.0, 0.0],
        [c * v, s * v, 0.0, 0.6 * v, 0.8 * v, 0.0],
        [0.0, 0.0, 3.0, 0.0, 0.0, 3.0],
    ])  # fmt: skip
    q = np.broadcast_to(np.asarray(m.params.q0), qd.shape)
    res = roll(m, 1.0, B=3, state0=states(m, q, qd))
    return res.frames.t, np.asarray(res.frames.qd)


def test_water_drag_on_a_rod_moving_across_itself_decays_exponentially():
    # F = -k L v for a segment of length L moving along its normal: v = v0 exp(-k L t / m).
    # Backward Euler decays by (1 + h r)^-n: relative error r^2 h t / 2 = 5e-4 at t = 1 s (r = 1/s);
    # measured 4.9e-4.
    t, qd = _water_run()
    n = np.array([-math.sin(ROD_ANGLE), math.cos(ROD_ANGLE)])
    v = qd[0, :, :2] @ n
    np.testing.assert_allclose(v, 0.7 * np.exp(-WATER_K * ROD_L * t / ROD_M), rtol=0.01)
    assert np.max(np.abs(qd[0, :, 2])) < 1e-12  # and it does not turn


def test_water_drag_does_not_act_along_a_rods_axis():
    # (v . N) = 0 for motion along the segment: no force at all.
    t, qd = _water_run()
    e = np.array([math.cos(ROD_ANGLE), math.sin(ROD_ANGLE)])
    np.testing.assert_allclose(qd[1, :, :2] @ e, 0.7, rtol=1e-9)
    assert np.max(np.abs(qd[1, :, 2])) < 1e-12


def test_water_drag_on_a_spinning_rod():
    # A rod spinning about its centre: torque -k w ∫ s^2 ds over [-L/2, L/2] = -k L^3 w / 12, so
    # w = w0 exp(-k L^3 t / (12 I)). Measured error 1.2e-4 (backward Euler, as above).
    t, qd = _water_run()
    rate = WATER_K * ROD_L**3 / (12 * ROD_I)
    np.testing.assert_allclose(qd[2, :, 2], 3.0 * np.exp(-rate * t), rtol=0.01)
    assert np.max(np.abs(qd[2, :, :2])) < 1e-12  # spinning about the centre does not push it


def test_water_drag_on_a_square_counts_every_edge():
    # Every edge of the closed outline feels -k ∫ (v.N) N ds. For a square of side a translating
    # at v, the two edges across each axis give -2 k a v_axis each: F = -2 k a v in any direction,
    # v = v0 exp(-2 k a t / m). Spinning: each edge gives -k w a^3 / 12, so w decays at
    # 4 k a^3 / (12 I). Measured errors 1.8e-4 (backward Euler).
    t, qd = _water_run()
    decay = np.exp(-2 * WATER_K * SQ_A * t / SQ_M)
    np.testing.assert_allclose(qd[0, :, 3], 0.7 * decay, rtol=0.01)
    np.testing.assert_allclose(qd[1, :, 3:5], 0.7 * np.outer(decay, [0.6, 0.8]), rtol=0.01)
    spin = 4 * WATER_K * SQ_A**3 / (12 * SQ_I)
    np.testing.assert_allclose(qd[2, :, 5], 3.0 * np.exp(-spin * t), rtol=0.01)


# ------------------------------------------------------------------- 4. anisotropic friction


def test_anisotropic_friction_of_point_masses_and_shared_normal_load():
    # Horizontal plane: each contact carries m g / (contacts of its link) as normal load, and
    # Coulomb friction decelerates a sliding link at mu g. Two point masses on a stiff spring,
    # axis rear -> front along (0.6, 0.8) (not a world axis): forward slides decelerate at
    # 0.1 g, backward at 0.5 g, lateral at 0.3 g. A separate rod (two contacts, each m g / 2)
    # with the world's isotropic mu = 0.4 decelerates at 0.4 g in any direction (m g per
    # contact would give 0.8 g). Measured errors ~1e-11.
    fr = Friction(forward=0.1, backward=0.5, lateral=0.3, axis=("rear", "front"))
    ax = np.array([0.6, 0.8])
    links = (
        point("rear", 1.0, (0.0, 0.0), friction=fr),
        point("front", 0.5, tuple(0.3 * ax), friction=fr),
        Link(
            name="iso", mass=2.0, inertia=2.0 * 0.25 / 12, com=(0.0, 0.0),
            shape=Shape("segment", ((-0.25, 0.0), (0.25, 0.0))),
            contacts=((-0.25, 0.0), (0.25, 0.0)), position=(5.0, 0.0),
        ),  # fmt: skip
    )
    spring = LinearSpring("K", PointRef("rear"), PointRef("front"), 1e4, 20.0, 0.3)
    world = World(plane="horizontal", ground=Ground(friction=0.4))
    m = compile64(Creature("crawler", links, springs=(spring,), world=world))
    lat = np.array([-0.8, 0.6])
    dirs = [ax, -ax, lat]  # of the pair
    iso_dirs = [np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.array([0.6, -0.8])]
    qd0 = np.stack([np.concatenate([d, d, e, [0.0]]) for d, e in zip(dirs, iso_dirs)])
    q0 = np.broadcast_to(np.asarray(m.params.q0), qd0.shape)
    res = roll(m, 1.2, B=3, state0=states(m, q0, qd0))
    t, qd = res.frames.t, np.asarray(res.frames.qd)
    for b, (d, mu) in enumerate(zip(dirs, [0.1, 0.5, 0.3])):
        cases = ((slice(0, 2), d, mu), (slice(2, 4), d, mu), (slice(4, 6), iso_dirs[b], 0.4))
        for sl, dd, mm in cases:
            v = qd[b, :, sl] @ dd
            sel = (v > 0.1) & (t > 0.005)
            assert sel.sum() > 10
            acc = np.polyfit(t[sel], v[sel], 1)[0]
            assert acc == pytest.approx(-mm * G, rel=0.03), (b, sl, acc)
            side = qd[b, :, sl] @ np.array([-dd[1], dd[0]])
            assert np.max(np.abs(side)) < 1e-9  # friction opposes the slip, no sideways push
    # and everything comes to rest
    assert np.max(np.abs(np.asarray(res.state.qd))) < 0.01


# ------------------------------------------------------------------------ 5. linear spring


def test_linear_spring_period_and_energy():
    # Two free point masses on a spring k: the stretch oscillates with period 2 pi sqrt(mu / k),
    # mu = m1 m2 / (m1 + m2) the reduced mass (here 2 s). With no damping, kinetic + elastic
    # energy is conserved; backward Euler (the spring is implicit) loses a fraction h w^2 per
    # second, 4.3e-4 over the 2.2 s here at dt = 2e-5. Measured: period 1.3e-9, energy 4.3e-4.
    m1, m2 = 1.0, 3.0
    mu = m1 * m2 / (m1 + m2)
    period = 2.0
    k = mu * (2 * math.pi / period) ** 2
    d, rest, x0 = np.array([0.6, -0.8]), 0.5, 0.05
    links = (point("a", m1), point("b", m2, tuple(d * rest)))
    spring = LinearSpring("K", PointRef("a"), PointRef("b"), k, 0.0, rest)
    world = World(plane="horizontal", ground=Ground(friction=0.0))
    m = compile64(Creature("dumbbell", links, springs=(spring,), world=world, dt=2e-5))
    q0 = np.concatenate([[0.1, 0.2], [0.1, 0.2] + d * (rest + x0)])
    res = roll(m, 1.1 * period, state0=states(m, q0))
    q = np.asarray(res.frames.q[0])
    stretch = np.linalg.norm(q[:, 2:] - q[:, :2], axis=1) - rest
    zc = crossings(res.frames.t, stretch)
    assert len(zc) == 2
    assert 2 * (zc[1] - zc[0]) == pytest.approx(period, rel=0.005)
    assert zc[0] == pytest.approx(period / 4, rel=0.005)
    E = sim.energy(m, sim.make_state(m, res.frames.q[0], res.frames.qd[0]))
    total = np.asarray(E["kinetic"] + E["elastic"])
    assert total[0] == pytest.approx(0.5 * k * x0**2, rel=1e-12)
    assert np.max(np.abs(total / total[0] - 1)) < 1e-3
    assert np.max(np.asarray(E["kinetic"])) > 0.9 * total[0]  # it did swap into motion
    # the centre of mass does not move (momentum conserved)
    com = (m1 * q[:, :2] + m2 * q[:, 2:]) / (m1 + m2)
    assert np.max(np.abs(com - com[0])) < 1e-12


# ------------------------------------------------------------------- 6. passive joint spring


def test_passive_joint_spring_period_and_damping():
    # A rod on a torsional spring at a welded base (the fish's tail), horizontal plane, no gravity.
    # Small oscillation: I_pivot phi'' = -k (phi - rest) - c phi', I_pivot = I_c + m (L/2)^2.
    # Undamped period 2 pi sqrt(I_pivot / k) (1 s here); with damping the amplitude decays at
    # sigma = c / (2 I_pivot) (0.5 /s) and the period becomes 2 pi / sqrt(w^2 - sigma^2).
    # Backward Euler adds h w^2 / 2 = 2e-3 /s of decay at dt = 1e-4.
    # Measured: period 1.3e-7, damped period 5e-5, decay rate 0.39 %.
    L, m, rest = 0.3, 0.2, 0.1
    Ic = 1.5 * m * L * L / 12  # not a uniform rod's, so that I_c matters on its own
    Ip = Ic + m * (L / 2) ** 2
    w = 2 * math.pi
    k, sigma = Ip * w * w, 0.5

    def tail(c):
        base = Link(
            name="base", mass=1.0, inertia=0.01, com=(0.0, 0.0),
            shape=Shape("segment", ((-0.1, 0.0), (0.0, 0.0))), contacts=(), position=(0.2, 0.1),
            angle=0.4, fixed=True,
        )  # fmt: skip
        t = Link(
            name="tail", mass=m, inertia=Ic, com=(L / 2, 0.0),
            shape=Shape("segment", ((0.0, 0.0), (L, 0.0))), parent="base", anchor=(0.0, 0.0),
            spring=JointSpring(k, c, rest),
        )  # fmt: skip
        world = World(plane="horizontal", gravity=0.0)
        return compile64(Creature("tail", (base, t), world=world, dt=1e-4))

    model = stack([tail(0.0), tail(2 * Ip * sigma)])
    assert model.structure.ndof == 1
    res = roll(model, 3.0, B=2, state0=states(tail(0.0), [[rest + 0.05]] * 2), batched=True)
    t = res.frames.t
    phi = np.asarray(res.frames.q[:, :, 0]) - rest
    zc = crossings(t, phi[0])
    assert 2 * np.mean(np.diff(zc)) == pytest.approx(2 * math.pi / w, rel=0.005)
    zc = crossings(t, phi[1])
    damped = 2 * math.pi / math.sqrt(w * w - sigma**2)
    assert 2 * np.mean(np.diff(zc)) == pytest.approx(damped, rel=0.005)
    tp, ap = peaks(t, phi[1])
    assert len(tp) >= 2
    rate = -np.polyfit(tp, np.log(ap), 1)[0]
    assert rate == pytest.approx(sigma, rel=0.02)
    tp, ap = peaks(t, phi[0])  # undamped: only the integrator's 2e-3 /s
    assert -np.polyfit(tp, np.log(ap), 1)[0] < 0.01


# ------------------------------------------------------------------- 7. linear actuator (+ length)

PISTON_LO, PISTON_HI = 0.1, 0.5


def piston() -> sim.Model:
    """Two point masses joined by a linear PD servo (0.1-0.5 m), with three length sensors."""
    a, b = PointRef("a"), PointRef("b")
    spec = Creature(
        "piston",
        (point("a", 1.0), point("b", 0.5, (0.2, 0.1))),
        sensors=(
            LengthSensor("short", a, b, 0.05, 0.15),
            LengthSensor("mid", a, b, 0.25, 0.35),
            LengthSensor("long", a, b, 0.45, 0.55),
        ),
        actuators=(LinearActuator("A", a, b, PISTON_LO, PISTON_HI, 200.0, 15.0),),
        world=World(plane="horizontal", ground=Ground(friction=0.0)),
    )
    return compile64(spec)


def test_linear_actuator_settles_at_its_target_length_and_length_sensors_follow():
    # PD servo F = ks (Ld - L) - kd L' with Ld = min + u (max - min): the length settles at Ld.
    # Measured error 1e-15 m.
    m = piston()
    u = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    res = roll(m, 2.0, u=u[:, None])
    q = np.asarray(res.state.q)
    length = np.linalg.norm(q[:, 2:] - q[:, :2], axis=1)
    np.testing.assert_allclose(length, PISTON_LO + u * (PISTON_HI - PISTON_LO), atol=1e-4)
    # length sensors: on only within [min, max]; lengths 0.1, 0.2, 0.3, 0.4, 0.5
    bits = np.asarray(res.frames.bits)
    expected = [[1, 0, 0], [0, 0, 0], [0, 1, 0], [0, 0, 0], [0, 0, 1]]
    np.testing.assert_array_equal(bits[:, -1], expected)
    np.testing.assert_array_equal(bits[:, 0], 0)  # initial length 0.224: all off


# ------------------------------------------------------------------------------- 8. sensors


def _box(name: str, bottom_contacts: int, x: float) -> Link:
    """A 4 kg box, 0.4 x 0.1 m, its frame origin the middle of its bottom edge, which starts 1 cm
    above the ground. Contacts: the bottom corners (and the bottom middle if 3), then the
    top-right corner."""
    w, h = 0.4, 0.1
    bottom = [(-w / 2, 0.0), (w / 2, 0.0)] + ([(0.0, 0.0)] if bottom_contacts == 3 else [])
    pts = ((-w / 2, 0.0), (w / 2, 0.0), (w / 2, h), (-w / 2, h))
    return Link(
        name=name, mass=4.0, inertia=4.0 * (w * w + h * h) / 12, com=(0.0, h / 2),
        shape=Shape("polygon", pts), contacts=(*bottom, (w / 2, h)), position=(x, 0.01),
    )  # fmt: skip


@functools.lru_cache(maxsize=None)
def _box_drop():
    """Two independent boxes dropped 1 cm onto the default ground (vertical plane), 1 s; the first
    has 2 bottom contacts and touch sensors on its 3 contacts, the second 3 bottom contacts."""
    touch = tuple(TouchSensor(f"T{i}", "box2", i) for i in range(3))
    spec = Creature("boxes", (_box("box2", 2, 0.0), _box("box3", 3, 1.0)), sensors=touch)
    res = roll(compile64(spec), 1.0)
    return spec, res


def test_touch_sensors_off_in_the_air_on_when_resting():
    _, res = _box_drop()
    bits = np.asarray(res.frames.bits[0])
    np.testing.assert_array_equal(bits[0], [0, 0, 0])  # 1 cm up
    np.testing.assert_array_equal(bits[-1], [1, 1, 0])  # bottom corners down, top corner up


def angle_rig(base_angle: float = 0.4) -> sim.Model:
    """A welded base turned by 0.4 rad (22.9 deg) and a rod on an angular servo whose target
    runs over 0..360 deg, horizontal plane without gravity; angle sensors on both."""
    base = Link(
        name="base", mass=1.0, inertia=0.01, com=(0.0, 0.0),
        shape=Shape("segment", ((-0.1, 0.0), (0.0, 0.0))), contacts=(), angle=base_angle,
        fixed=True,
    )  # fmt: skip
    rod = Link(
        name="rod", mass=0.2, inertia=0.2 * 0.09 / 12, com=(0.15, 0.0),
        shape=Shape("segment", ((0.0, 0.0), (0.3, 0.0))), contacts=(), parent="base",
    )  # fmt: skip
    sensors = (
        AngleSensor("base", "base", 20 * DEG, 25 * DEG),  # a root: its absolute angle
        AngleSensor("fwd", "rod", 30 * DEG, 60 * DEG),
        AngleSensor("up", "rod", 60 * DEG, 90 * DEG),
        AngleSensor("back", "rod", -60 * DEG, -30 * DEG),
        AngleSensor("near+180", "rod", 170 * DEG, 180 * DEG),
        AngleSensor("near-180", "rod", -180 * DEG, -170 * DEG),
    )
    act = AngularActuator("A", "rod", 0.0, 2 * math.pi, 5.0, 0.5)
    world = World(plane="horizontal", gravity=0.0)
    return compile64(Creature("rig", (base, rod), sensors=sensors, actuators=(act,), world=world))


def test_angle_sensors_of_a_servoed_joint_with_wrapping():
    # The servo holds the joint angle (relative to the base, which is turned by 22.9 deg) at
    # u * 360 deg (measured within 1.1e-5 deg after 1.5 s); the sensors see it wrapped to
    # [-180, 180): 185 deg reads as -175 deg.
    # The base sensor reads the root's absolute angle, also after it is turned by a full 360 deg.
    targets = np.array([45.0, 175.0, 185.0, 315.0])
    model = stack([angle_rig(0.4)] * 2 + [angle_rig(0.4 + 2 * math.pi)] * 2)
    res = roll(model, 1.5, u=targets[:, None] / 360, batched=True)
    held = np.degrees(np.asarray(res.state.q[:, 0]))
    np.testing.assert_allclose(held, targets, rtol=0, atol=1e-3)
    expected = [
        [1, 1, 0, 0, 0, 0],  # 45
        [1, 0, 0, 0, 1, 0],  # 175
        [1, 0, 0, 0, 0, 1],  # 185 = -175
        [1, 0, 0, 1, 0, 0],  # 315 = -45
    ]
    np.testing.assert_array_equal(np.asarray(res.frames.bits[:, -1]), expected)


def test_eye_sensors_see_a_fixed_follow_point_and_swap_when_turned():
    # Follow point fixed at (1, 0) (speed 0). Eyes on a free head at the origin: looking along +x
    # the target is at 0 deg (in [-30, 30], not in [60, 120]); turned by -90 deg it is at +90 deg
    # relative to the head's axis, and the two swap. An eye at (0, 2) on the head sees it at
    # atan2(-2, 1) = -63.4 deg (in [-70, -60]); turned, from (2, 0), at -90 deg.
    head = Link(
        name="head", mass=1.0, inertia=0.01, com=(0.0, 0.0),
        shape=Shape("segment", ((-0.1, 0.0), (0.1, 0.0))), contacts=(),
    )  # fmt: skip
    eyes = (
        EyeSensor("ahead", PointRef("head"), -30 * DEG, 30 * DEG),
        EyeSensor("left", PointRef("head"), 60 * DEG, 120 * DEG),
        EyeSensor("offset", PointRef("head", (0.0, 2.0)), -70 * DEG, -60 * DEG),
    )
    world = World(plane="horizontal", gravity=0.0, follow=Follow(((1.0, 0.0), (1.0, 0.001)), 0.0))
    m = compile64(Creature("eyes", (head,), sensors=eyes, world=world))

    def look(angle, t=0.0):
        return sim.sense(m, np.array([0.0, 0.0, angle]), t)

    np.testing.assert_array_equal(look(0.0), [1, 0, 1])
    np.testing.assert_array_equal(look(-math.pi / 2), [0, 1, 0])
    np.testing.assert_array_equal(look(2 * math.pi, t=5.0), [1, 0, 1])  # speed 0: still there
    np.testing.assert_array_equal(look(math.pi / 2), [0, 0, 0])  # turned +90: target at -90 deg


def _follow_model(points, speed, loop=False):
    world = World(plane="horizontal", follow=Follow(tuple(map(tuple, points)), speed, loop))
    return sim.compile_creature(Creature("f", (point("p", 1.0),), world=world), "float64")


def _follow(m, t) -> np.ndarray:
    """The follow point at times t [N] (s) -> [N, 2] (m)."""
    return sim.follow_point(m, np.atleast_1d(np.asarray(t, np.float64)))


def test_follow_point_moves_along_a_straight_path_at_its_speed():
    # Two points (0, 0) -> (3, 4): a straight 5 m path; after t the point is speed t along it,
    # then stops at the end (after 5 / 0.7 = 7.14 s). Measured error ~1e-9 m.
    m = _follow_model([(0.0, 0.0), (3.0, 4.0)], 0.7)
    t = np.array([0.0, 0.5, 1.0, 2.5, 5.0, 7.0])
    p = _follow(m, t)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 0.7 * t, rtol=0.01, atol=1e-9)
    np.testing.assert_allclose(p[:, 0] * 4 - p[:, 1] * 3, 0.0, atol=1e-9)  # on the line
    np.testing.assert_allclose(_follow(m, [7.2, 20.0]), [[3.0, 4.0]] * 2, atol=1e-9)


def test_follow_point_loops():
    # loop = true through (0, 0) and (1, 0): the closed spline runs there and back along the same
    # straight line (zero tangents at both ends), 2 m per lap; at 0.5 m/s it is back at the start
    # every 4 s, and the distance from the start is a triangle wave: 0.5 t, then 2 - 0.5 t.
    m = _follow_model([(0.0, 0.0), (1.0, 0.0)], 0.5, loop=True)
    t = np.array([0.5, 1.0, 1.5, 2.5, 3.0, 4.0, 4.5, 9.0, 11.0])
    lap = np.mod(t, 4.0)
    x = np.where(lap <= 2.0, 0.5 * lap, 2.0 - 0.5 * lap)
    np.testing.assert_allclose(_follow(m, t), np.stack([x, 0 * x], 1), atol=0.01)
    # a curved loop through a square's corners, three laps: passes every corner (measured within
    # 0.2 mm) and covers speed * dt in every small step dt (measured within 0.05 %)
    sq = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    m = _follow_model(sq, 1.0, loop=True)
    dense = _follow(m, np.arange(0.0, 12.0, 1e-3))
    for c in sq:
        assert np.min(np.linalg.norm(dense - c, axis=1)) < 2e-3
    step = np.linalg.norm(np.diff(dense, axis=0), axis=1)
    np.testing.assert_allclose(step, 1e-3, rtol=0.01)


# ------------------------------------------------------------------------ 9. penetration


def test_bounder_held_still_keeps_penetration_small():
    # The built-in bounder (4 kg, default ground) held at u = 0.5 (hips straight down, knees at
    # -45 deg) for 2 s (it tips over meanwhile, ending with the body at about -70 deg): the
    # deepest contact stays under 2 cm. Measured 3.6 mm.
    m = compile64(load("bounder"))
    res = roll(m, 2.0, u=np.full((1, 4), 0.5))
    assert bool(res.finite[0])
    assert 0.0 < float(res.max_depth[0]) < 0.02


@pytest.mark.parametrize("bottom_contacts", [2, 3])
def test_box_resting_on_the_ground_sinks_mg_over_k_n(bottom_contacts):
    # At rest each of the n touching contacts carries m g / n on a spring k: depth m g / (n k)
    # (0.39 mm and 0.26 mm for 4 kg at k = 5e4). Measured error ~1e-13.
    spec, res = _box_drop()
    k = spec.world.ground.stiffness
    link = bottom_contacts - 2  # the two boxes are links 0 and 1
    m = compile64(spec)
    origin = np.asarray(sim.poses(m, res.state.q[0])["links"][link])
    depth, angle = -origin[1], origin[2]  # the bottom edge's middle is the frame origin
    assert depth == pytest.approx(4.0 * G / (bottom_contacts * k), rel=0.1)
    assert abs(angle) < 1e-6  # level
    # the landing (from 1 cm) went deeper than rest, but not by much
    assert depth <= float(res.max_depth[0]) < 0.02


# ------------------------------------------------------------------- hard landings


def test_friction_never_reverses_the_slip_on_landing():
    # Coulomb friction only opposes the slip: a point landing on flat ground with horizontal
    # velocity 0.1 m/s and vertical -1 m/s can at most be stopped (its normal impulse, about
    # m * 1 m/s, times mu = 0.6 exceeds m * 0.1 m/s), never sent backwards; kinetic energy can only
    # grow by gravity's work over the few mm it falls.
    m = compile64(Creature("pebble", (point("p", 0.1),)))
    res = roll(m, 0.3, state0=states(m, [0.0, 0.0], [0.1, -1.0]))
    qd = np.asarray(res.frames.qd[0])
    assert np.min(qd[:, 0]) > -1e-3
    assert float(res.state.q[0, 0]) > -1e-3
    ke = 0.5 * 0.1 * np.sum(qd**2, axis=1)
    assert np.max(ke) < 1.1 * ke[0]  # measured: 4.1 times
