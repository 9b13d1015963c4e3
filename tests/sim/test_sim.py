"""The engine against analytic cases, and its contracts (determinism, recording, batching)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.creature.spec import (
    AngleSensor,
    AngularActuator,
    Creature,
    Ground,
    Link,
    Shape,
    World,
)
from sanlab.san import San, SanParams

G = 9.81


def rod(name, L, m, **kw):
    return Link(name, m, m * L * L / 12, (L / 2, 0.0), Shape("segment", ((0.0, 0.0), (L, 0.0))), **kw)


def box(name, w, h, m, **kw):
    pts = ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2))
    return Link(name, m, m * (w * w + h * h) / 12, (0.0, 0.0), Shape("polygon", pts), contacts=pts[:2], **kw)


def run(spec, cparams, dtype="float64", **kw):
    return sim.rollout(sim.compile_creature(spec, dtype), sim.ConstantController(), cparams, **kw)


def no_act(B=1):
    return np.zeros((B, 0))


def test_free_fall_matches_the_integrator_and_the_analytic_parabola():
    dt, n = 1e-3, 1000
    # a rod centred on its frame origin, so that q = (x, y) is its centre of mass
    bar = Link("b", 2.0, 2.0 / 12, (0.0, 0.0), Shape("segment", ((-0.5, 0.0), (0.5, 0.0))), position=(0.0, 10.0))
    spec = Creature("ff", (bar,), dt=dt)
    m = sim.compile_creature(spec, "float64")
    s0 = sim.make_state(m, np.array([0.0, 10.0, 0.3]), np.array([1.5, 2.0, 4.0]))
    r = sim.rollout(m, sim.ConstantController(), no_act(), steps=n, state0=s0)
    x, y, a = np.asarray(r.state.q[0])
    T = n * dt
    # semi-implicit Euler is exact for constant acceleration up to the known O(dt) drift:
    # y_n = y0 + v0 T - g dt^2 n (n + 1) / 2
    assert y == pytest.approx(10.0 + 2.0 * T - G * dt * dt * n * (n + 1) / 2, abs=1e-9)
    assert abs(y - (10.0 + 2.0 * T - 0.5 * G * T * T)) <= G * dt * T  # the continuous answer
    assert x == pytest.approx(1.5 * T, abs=1e-9)
    assert a == pytest.approx(0.3 + 4.0 * T, abs=1e-9)  # free spin keeps its rate


def test_pendulum_period_matches_the_analytic_value():
    L, m, th0 = 0.8, 1.3, 0.05
    base = Link("base", 1.0, 0.0, (0.0, 0.0), Shape("point"), fixed=True)
    arm = rod("arm", L, m, parent="base", angle=-math.pi / 2 + th0)
    spec = Creature("pendulum", (base, arm), dt=1e-4)
    r = run(spec, no_act(), seconds=4.0, record_fps=2000)
    q = np.asarray(r.frames.q[0, :, 0]) + math.pi / 2
    t = r.frames.t
    up = [t[i] - q[i] * (t[i + 1] - t[i]) / (q[i + 1] - q[i]) for i in range(len(q) - 1) if q[i] < 0 <= q[i + 1]]
    period = float(np.mean(np.diff(up)))
    I = m * L * L / 3  # about the pivot
    T0 = 2 * math.pi * math.sqrt(I / (m * G * L / 2))
    expected = T0 * (1 + th0 * th0 / 16)  # first finite-amplitude correction
    assert period == pytest.approx(expected, rel=1e-3)


def test_sliding_block_decelerates_at_mu_g_then_sticks():
    mu, k = 0.4, 5.0e4
    m = 2.0
    blk = box("block", 0.4, 0.1, m, position=(0.0, 0.05 - m * G / (2 * k)))
    spec = Creature("block", (blk,), world=World(ground=Ground(stiffness=k, damping=300.0, friction=mu)))
    mdl = sim.compile_creature(spec, "float64")
    s0 = sim.make_state(mdl, mdl.params.q0, np.array([2.0, 0.0, 0.0]))
    r = sim.rollout(mdl, sim.ConstantController(), no_act(), seconds=1.0, record_fps=1000, state0=s0)
    v = np.asarray(r.frames.qd[0, :, 0])
    t = r.frames.t
    sliding = (t > 0.05) & (t < 0.4)
    slope = np.polyfit(t[sliding], v[sliding], 1)[0]
    assert slope == pytest.approx(-mu * G, rel=0.02)
    stop = 2.0 / (mu * G)
    assert abs(v[t > stop + 0.05]).max() < 1e-3  # static friction holds it
    assert float(r.state.q[0, 0]) == pytest.approx(2.0**2 / (2 * mu * G), rel=0.03)


def double_pendulum(dt=1e-4):
    base = Link("base", 1.0, 0.0, (0.0, 0.0), Shape("point"), fixed=True)
    a = rod("a", 0.5, 1.0, parent="base", angle=0.3)
    b = rod("b", 0.4, 0.6, parent="a", anchor=(0.5, 0.0), angle=-0.8)
    return Creature("double", (base, a, b), dt=dt)


def test_energy_is_conserved_without_damping_or_contact():
    spec = double_pendulum()
    m = sim.compile_creature(spec, "float64")
    r = sim.rollout(m, sim.ConstantController(), no_act(), seconds=1.0, record_fps=100)
    e = sim.energy(m, sim.make_state(m, r.frames.q[0], r.frames.qd[0]))
    E = np.asarray(e["kinetic"] + e["gravity"])
    swing = np.ptp(np.asarray(e["kinetic"]))
    assert swing > 1.0  # it really moved: kinetic energy swings by joules
    assert np.abs(E - E[0]).max() / swing < 1e-3


def test_energy_function_against_hand_formulas():
    spec = double_pendulum()
    m = sim.compile_creature(spec, "float64")
    q, qd = np.array([0.4, -0.7]), np.array([1.1, -2.3])
    e = sim.energy(m, sim.make_state(m, q, qd))
    t1, t2 = 0.4, 0.4 - 0.7
    w1, w2 = 1.1, 1.1 - 2.3
    c1 = np.array([0.25 * math.cos(t1), 0.25 * math.sin(t1)])
    j = np.array([0.5 * math.cos(t1), 0.5 * math.sin(t1)])
    c2 = j + np.array([0.2 * math.cos(t2), 0.2 * math.sin(t2)])
    v1 = w1 * np.array([-c1[1], c1[0]])
    v2 = w1 * np.array([-j[1], j[0]]) + w2 * np.array([-(c2 - j)[1], (c2 - j)[0]])
    ke = 0.5 * 1.0 * v1 @ v1 + 0.5 * (1.0 * 0.25 / 12) * w1**2 + 0.5 * 0.6 * v2 @ v2 + 0.5 * (0.6 * 0.16 / 12) * w2**2
    pe = G * (1.0 * c1[1] + 0.6 * c2[1])
    assert float(e["kinetic"]) == pytest.approx(ke, rel=1e-12)
    assert float(e["gravity"]) == pytest.approx(pe, rel=1e-12)


def random_sans(spec, B, seed):
    san = San.for_creature(spec)
    rng = np.random.default_rng(seed)
    W = rng.integers(-2, 3, (B, san.n_nodes, san.n_inputs)).astype(np.float32)
    k1 = np.full((B, san.n_nodes), 1 / spec.san.delay_on, np.float32)
    return san, SanParams(W, k1, -k1)


def take(p, idx):
    return SanParams(*(np.asarray(x)[np.asarray(idx)] for x in p))


def test_one_controller_is_bit_identical_alone_and_anywhere_in_any_batch():
    spec = creature.load("bounder")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 37, seed=3)
    full = sim.rollout(m, san, p, seconds=0.5, record_fps=100)
    for i in (0, 17, 36):
        alone = sim.rollout(m, san, take(p, [i]), seconds=0.5, record_fps=100)
        np.testing.assert_array_equal(np.asarray(alone.frames.q[0]), np.asarray(full.frames.q[i]))
        np.testing.assert_array_equal(np.asarray(alone.state.qd[0]), np.asarray(full.state.qd[i]))
    # and in a differently sized, shuffled batch
    order = np.random.default_rng(0).permutation(37)[:20]
    other = sim.rollout(m, san, take(p, order), seconds=0.5, record_fps=100)
    for j, i in enumerate(order):
        np.testing.assert_array_equal(np.asarray(other.frames.q[j]), np.asarray(full.frames.q[i]))
    assert np.ptp(np.asarray(full.state.q[:, 0])) > 1e-3  # the controllers really differ


def test_recording_costs_nothing_in_the_result_and_has_the_right_frames():
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 5, seed=1)
    plain = sim.rollout(m, san, p, seconds=1.0)
    rec = sim.rollout(m, san, p, seconds=1.0, record_fps=50)
    assert plain.frames is None
    assert rec.frames.q.shape == (5, 50, m.structure.ndof)
    assert rec.frames.bits.shape == (5, 50, 6) and rec.frames.u.shape == (5, 50, 1)
    np.testing.assert_allclose(rec.frames.t[:3], [0.0, 0.02, 0.04])
    np.testing.assert_array_equal(np.asarray(plain.state.q), np.asarray(rec.state.q))
    # steps left over after the last whole frame are run, not recorded; frame k is the state
    # before step k * every (here every 20 steps)
    odd = sim.rollout(m, san, p, seconds=1.013, record_fps=50)
    assert odd.frames.q.shape == (5, 50, m.structure.ndof)
    np.testing.assert_array_equal(np.asarray(odd.frames.q), np.asarray(rec.frames.q))
    np.testing.assert_allclose(np.asarray(odd.state.t), 1.013, atol=1e-12)  # 1013 steps
    at20 = sim.rollout(m, san, p, steps=20)
    np.testing.assert_array_equal(np.asarray(odd.frames.q[:, 1]), np.asarray(at20.state.q))
    # a run shorter than one frame records none
    short = sim.rollout(m, san, p, seconds=0.01, record_fps=50)
    assert short.frames.q.shape == (5, 0, m.structure.ndof) and short.frames.t.shape == (0,)


def test_closed_loop_hook_runs_sensors_controller_and_physics_each_step():
    """A bang-bang reflex through an angle sensor makes the cart's joint oscillate between the
    sensor's edge and the actuator's far limit; the same actuator held open-loop just settles."""
    base = Link("base", 1.0, 0.0, (0.0, 0.0), Shape("point"), fixed=True)
    arm = rod("arm", 0.3, 0.2, parent="base")
    spec = Creature(
        "flapper",
        (base, arm),
        sensors=(AngleSensor("up", "arm", math.radians(30), math.radians(180)),),
        actuators=(AngularActuator("A", "arm", math.radians(-60), math.radians(60), 2.0, 0.05),),
        world=World(plane="horizontal"),
    )
    m = sim.compile_creature(spec, "float64")
    # u = 1 - sensor: drive up until the arm passes 30 deg, then down, then up again ...
    W, b = np.array([[[-1.0]]]), np.array([[1.0]])
    r = sim.rollout(m, sim.ReflexController(), (W, b), seconds=3.0, record_fps=200)
    phi = np.degrees(np.asarray(r.frames.q[0, :, 0]))
    bits = np.asarray(r.frames.bits[0, :, 0])
    crossings = np.count_nonzero(np.diff(bits) != 0)
    assert crossings >= 6  # a sustained limit cycle
    assert phi[100:].max() > 30 and phi[100:].min() < 29  # it swings about the sensor's edge
    held = sim.rollout(m, sim.ConstantController(), np.ones((1, 1)), seconds=3.0, record_fps=200)
    assert np.ptp(np.degrees(np.asarray(held.frames.q[0, 400:, 0]))) < 0.1
    assert np.degrees(float(held.state.q[0, 0])) == pytest.approx(60.0, abs=0.1)


def test_a_float32_run_agrees_with_a_float64_one_to_float32s_precision():
    # "float32" rounds the creature's numbers and steps them in float32 arithmetic (issue 58;
    # tests/sim/test_float32.py), which moves a smooth run by about float32's precision, no more;
    # the arrays handed back are float64 either way
    spec = double_pendulum(dt=1e-3)
    r32 = run(spec, no_act(), dtype="float32", seconds=1.0)
    r64 = run(spec, no_act(), dtype="float64", seconds=1.0)
    assert r32.state.q.dtype == np.float64 and r64.state.q.dtype == np.float64
    np.testing.assert_allclose(r32.state.q, r64.state.q, atol=1e-4)
    assert not np.array_equal(r32.state.q, r64.state.q)
    assert abs(float(r64.state.q[0, 0]) - 0.3) > 0.1  # it swung


def test_every_row_of_a_batch_may_carry_its_own_numbers():
    """A batch of different masses runs in one call, each row bit for bit the unbatched run with
    that mass."""
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 1, seed=5)
    p3 = SanParams(*(np.repeat(np.asarray(x), 3, axis=0) for x in p))
    masses = np.array([[0.1, 0.1], [0.1, 0.2], [0.05, 0.1]])
    fields = [f.name for f in dataclasses.fields(m.params)]
    mb = m.with_params(**{f: np.broadcast_to(np.asarray(getattr(m.params, f)), (3, *np.shape(getattr(m.params, f))))
                          for f in fields})
    mb = mb.with_params(mass=masses)
    batched = sim.rollout(mb, san, p3, seconds=0.5, params_batched=True)
    for i in range(3):
        single = sim.rollout(m.with_params(mass=masses[i]), san, p, seconds=0.5)
        np.testing.assert_array_equal(batched.state.q[i], single.state.q[0])
    assert np.ptp(batched.state.q[:, 1]) > 1e-4  # the masses matter


def test_a_rollout_runs_exactly_its_steps_and_recording_changes_nothing():
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 4, seed=2)
    short = sim.rollout(m, san, p, seconds=0.2)
    long = sim.rollout(m, san, p, seconds=0.5)
    assert np.allclose(short.state.t, 0.2, atol=1e-12) and np.allclose(long.state.t, 0.5, atol=1e-12)
    recorded = sim.rollout(m, san, p, seconds=0.5, record_fps=10)
    np.testing.assert_array_equal(long.state.q, recorded.state.q)
    # another duration and frame rate records the states of the plain runs it samples
    other = sim.rollout(m, san, p, seconds=0.9, record_fps=40)  # 36 frames, one every 25 steps
    assert other.frames.q.shape == (4, 36, m.structure.ndof) and other.frames.u.shape == (4, 36, 1)
    np.testing.assert_allclose(other.frames.t[:3], [0.0, 0.025, 0.05])
    at25 = sim.rollout(m, san, p, steps=25)
    np.testing.assert_array_equal(other.frames.q[:, 1], at25.state.q)
    plain = sim.rollout(m, san, p, seconds=0.9)
    np.testing.assert_array_equal(other.state.q, plain.state.q)


def test_a_recording_refuses_a_negative_duration_or_rate_and_records_none_at_a_tiny_rate():
    """Negative durations and rates, and rates that are not numbers, are refused (a negative
    duration once came back as a buffer of zeroed frames); a rate too low for one frame in the
    run records none (its steps between frames are an int32 input of the program)."""
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 2, seed=3)
    for kw in ({"steps": -5, "record_fps": 30}, {"seconds": -0.1, "record_fps": 30}, {"steps": -1}):
        with pytest.raises(ValueError, match=r"^(steps|seconds): expected"):
            sim.rollout(m, san, p, **kw)
    for fps in (-30.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="record_fps"):
            sim.rollout(m, san, p, seconds=0.1, record_fps=fps)
    for fps in (1e-7, 1e-310, 5e-324):  # the last two: a frame spacing of inf steps
        tiny = sim.rollout(m, san, p, seconds=0.1, record_fps=fps)
        assert tiny.frames.q.shape == (2, 0, m.structure.ndof) and tiny.frames.t.shape == (0,)
    np.testing.assert_array_equal(np.asarray(tiny.state.q), np.asarray(sim.rollout(m, san, p, seconds=0.1).state.q))


def test_a_nudged_step_runs_at_its_own_step():
    """The audit's dt/2 differs from the nominal creature only in dt, a number of the model's
    tables: the same kernel runs it, 600 steps of 0.5 ms for 0.3 s."""
    import dataclasses as dc

    spec = creature.load("cart")
    san, p = random_sans(spec, 4, seed=2)
    nominal = sim.rollout(sim.compile_creature(spec), san, p, seconds=0.3)
    half = sim.rollout(sim.compile_creature(dc.replace(spec, dt=spec.dt / 2)), san, p, seconds=0.3)
    assert np.allclose(half.state.t, 0.3, atol=1e-12)
    assert not np.array_equal(half.state.q, nominal.state.q)
    np.testing.assert_allclose(half.state.q[:, :2], nominal.state.q[:, :2], atol=0.01)  # where it got to, resolved finer


def test_bad_runs_are_flagged_not_fatal():
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    s0 = sim.initial_state(m)
    bad = sim.State(*(np.stack([x, x]) for x in s0))
    bad.p[1, 1] = np.nan
    r = sim.rollout(m, sim.ConstantController(), np.full((2, 1), 0.5), seconds=0.1, state0=bad)
    assert list(np.asarray(r.finite)) == [True, False]


def test_a_run_continues_exactly_from_its_final_state_and_controller_state():
    # Live mode steps a gait in short rollouts: state0 = result.state, cstate0 = result.cstate
    # must give exactly the trajectory of one long rollout (same compiled step, same order).
    spec = creature.load("bounder")
    m = sim.compile_creature(spec)
    san, params = random_sans(spec, 3, seed=5)
    whole = sim.rollout(m, san, params, steps=600)
    first = sim.rollout(m, san, params, steps=300)
    rest = sim.rollout(m, san, params, steps=300, state0=first.state, cstate0=first.cstate)
    np.testing.assert_array_equal(np.asarray(rest.state.q), np.asarray(whole.state.q))
    np.testing.assert_array_equal(np.asarray(rest.cstate.istate), np.asarray(whole.cstate.istate))
    assert not np.array_equal(np.asarray(first.state.q), np.asarray(whole.state.q))  # it moved on


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_the_default_start_state_is_the_one_evaluations_start_from(dtype):
    # a rollout's default start state must be, bit for bit, the state every score starts from
    # (the evaluator's start), so that a replay of a gait starts where its evaluation did
    from sanlab.evaluate.evaluator import _start

    spec = creature.load("walker")  # on the host its foot anchors differ from compiled ones in the last bit
    m = sim.compile_creature(spec, dtype)
    san, params = random_sans(spec, 5, seed=2)
    q0 = np.asarray(m.params.q0)[None].repeat(5, 0)
    scored = _start(m, q0, np.ones(5, bool), False)
    at0 = sim.rollout(m, san, params, steps=0)
    for field in ("q", "p", "anchor", "t"):
        np.testing.assert_array_equal(np.asarray(getattr(at0.state, field)), np.asarray(getattr(scored, field)))
        np.testing.assert_array_equal(np.asarray(getattr(at0.state, field))[0], getattr(sim.make_state(m), field))
    default = sim.rollout(m, san, params, steps=400)
    given = sim.rollout(m, san, params, steps=400, state0=scored)
    np.testing.assert_array_equal(np.asarray(default.state.q), np.asarray(given.state.q))
    np.testing.assert_array_equal(np.asarray(default.state.p), np.asarray(given.state.p))
    assert np.ptp(np.asarray(default.state.q[:, 0])) > 1e-4  # the controllers moved it, differently
    # with a batch of models, each member starts in its own pose
    fields = [f.name for f in dataclasses.fields(m.params)]
    mb = m.with_params(**{f: np.broadcast_to(np.asarray(getattr(m.params, f)), (5, *np.shape(getattr(m.params, f))))
                          for f in fields})
    q0[:, 1] += np.linspace(0.0, 0.04, 5)
    mb = mb.with_params(q0=q0)
    at0 = sim.rollout(mb, san, params, steps=0, params_batched=True)
    scored = _start(mb, q0, np.ones(5, bool), True)
    np.testing.assert_array_equal(np.asarray(at0.state.q), q0.astype(dtype).astype(np.float64))
    np.testing.assert_array_equal(np.asarray(at0.state.anchor), np.asarray(scored.anchor))
    assert np.ptp(np.asarray(at0.state.anchor[:, 0, 1])) > 0.03  # the poses differ
