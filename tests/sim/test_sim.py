"""The engine against analytic cases, and its contracts (determinism, recording, batching)."""

from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
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


@contextlib.contextmanager
def compile_events(prefix: str = "/jax/core/compile/"):
    """The names of the JAX compile events (tracing, lowering, compiling, cache loads) whose name
    starts with ``prefix``, raised inside the ``with`` block (a list filled as they come)."""
    import jax.monitoring

    seen: list[str] = []

    def count(event: str, duration_secs: float, **_) -> None:
        if event.startswith(prefix):
            seen.append(event)

    jax.monitoring.register_event_duration_secs_listener(count)
    try:
        yield seen
    finally:
        jax.monitoring.unregister_event_duration_listener(count)


def run(spec, cparams, dtype="float64", **kw):
    return sim.rollout(sim.compile_creature(spec, dtype), sim.ConstantController(), cparams, **kw)


def no_act(B=1):
    return jnp.zeros((B, 0))


def test_free_fall_matches_the_integrator_and_the_analytic_parabola():
    dt, n = 1e-3, 1000
    # a rod centred on its frame origin, so that q = (x, y) is its centre of mass
    bar = Link("b", 2.0, 2.0 / 12, (0.0, 0.0), Shape("segment", ((-0.5, 0.0), (0.5, 0.0))), position=(0.0, 10.0))
    spec = Creature("ff", (bar,), dt=dt)
    m = sim.compile_creature(spec, "float64")
    s0 = sim.make_state(m, jnp.array([0.0, 10.0, 0.3]), jnp.array([1.5, 2.0, 4.0]))
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
    s0 = sim.make_state(mdl, mdl.params.q0, jnp.array([2.0, 0.0, 0.0]))
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
    e = jax.vmap(lambda q, qd: sim.energy(m, sim.make_state(m, q, qd)))(r.frames.q[0], r.frames.qd[0])
    E = np.asarray(e["kinetic"] + e["gravity"])
    swing = np.ptp(np.asarray(e["kinetic"]))
    assert swing > 1.0  # it really moved: kinetic energy swings by joules
    assert np.abs(E - E[0]).max() / swing < 1e-3


def test_energy_function_against_hand_formulas():
    spec = double_pendulum()
    m = sim.compile_creature(spec, "float64")
    q, qd = jnp.array([0.4, -0.7]), jnp.array([1.1, -2.3])
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
    return san, SanParams(jnp.asarray(W), jnp.asarray(k1), jnp.asarray(-k1))


def take(p, idx):
    return jax.tree_util.tree_map(lambda x: x[np.asarray(idx)], p)


@pytest.mark.slow  # over 4 s even with a warm compile cache (the pre-commit subset leaves it out)
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
    np.testing.assert_allclose(np.asarray(odd.state.t), 1.013, atol=1e-4)  # float32 time, 1013 steps
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
    W, b = jnp.array([[[-1.0]]]), jnp.array([[1.0]])
    r = sim.rollout(m, sim.ReflexController(), (W, b), seconds=3.0, record_fps=200)
    phi = np.degrees(np.asarray(r.frames.q[0, :, 0]))
    bits = np.asarray(r.frames.bits[0, :, 0])
    crossings = np.count_nonzero(np.diff(bits) != 0)
    assert crossings >= 6  # a sustained limit cycle
    assert phi[100:].max() > 30 and phi[100:].min() < 29  # it swings about the sensor's edge
    held = sim.rollout(m, sim.ConstantController(), jnp.ones((1, 1)), seconds=3.0, record_fps=200)
    assert np.ptp(np.degrees(np.asarray(held.frames.q[0, 400:, 0]))) < 0.1
    assert np.degrees(float(held.state.q[0, 0])) == pytest.approx(60.0, abs=0.1)


def test_float32_and_float64_agree_and_keep_their_dtype():
    spec = double_pendulum(dt=1e-3)
    r32 = run(spec, no_act(), dtype="float32", seconds=1.0)
    r64 = run(spec, no_act(), dtype="float64", seconds=1.0)
    assert r32.state.q.dtype == jnp.float32 and r64.state.q.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(r32.state.q), np.asarray(r64.state.q), atol=1e-4)
    assert abs(float(r64.state.q[0, 0]) - 0.3) > 0.1  # it swung


def test_parameters_are_batched_arrays_and_never_recompile():
    """Every number is an array input: a batch of different masses runs in one compiled
    program, and each member equals the unbatched run with that mass."""
    # float64: a batched mass array and a scalar one round differently in the last bit, and the
    # closed loop (binary sensors, stick-slip) amplifies that in float32
    spec = creature.load("cart")
    m = sim.compile_creature(spec, "float64")
    san, p = random_sans(spec, 1, seed=5)
    p = jax.tree_util.tree_map(lambda x: x.astype(jnp.float64), p)
    p3 = jax.tree_util.tree_map(lambda x: jnp.repeat(x, 3, axis=0), p)
    masses = jnp.array([[0.1, 0.1], [0.1, 0.2], [0.05, 0.1]], jnp.float64)
    mb = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (3,) + x.shape), m)
    mb = mb.with_params(mass=masses)
    batched = sim.rollout(mb, san, p3, seconds=0.5, params_batched=True)
    for i in range(3):
        single = sim.rollout(m.with_params(mass=masses[i]), san, p, seconds=0.5)
        np.testing.assert_allclose(np.asarray(batched.state.q[i]), np.asarray(single.state.q[0]), atol=1e-5)
    assert np.ptp(np.asarray(batched.state.q[:, 1])) > 1e-4  # the masses matter


def test_rollouts_of_any_duration_share_one_compiled_program():
    """Without recording, the number of steps is an input of the compiled rollout: a second
    duration traces and compiles nothing (it used to cost a whole compilation, about 12 s for the
    bounder without a compile cache), and runs exactly as many steps as asked."""
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 4, seed=2)
    short = sim.rollout(m, san, p, seconds=0.2)
    with compile_events() as compiles:  # tracing, lowering, compiling (or a cache load)
        long = sim.rollout(m, san, p, seconds=0.5)
    assert compiles == []
    assert np.allclose(np.asarray(short.state.t), 0.2, atol=1e-6)
    assert np.allclose(np.asarray(long.state.t), 0.5, atol=1e-6)
    # the same steps as a run that records frames (a program with the count built in)
    recorded = sim.rollout(m, san, p, seconds=0.5, record_fps=10)
    np.testing.assert_array_equal(np.asarray(long.state.q), np.asarray(recorded.state.q))


def test_recordings_whose_frames_fit_one_buffer_share_a_compiled_program():
    """A recording's steps and its steps between frames are inputs of the compiled rollout too;
    only the size of its frame buffers (the frame count rounded up to a power of two, at least
    256) is built in. Another duration and frame rate whose frames fit the same buffers compiles nothing, and
    records the states of the plain runs it samples, and no more frames than asked."""
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 4, seed=2)
    sim.rollout(m, san, p, seconds=1.0, record_fps=50)  # 50 frames (a frame every 20 steps), buffers of 256
    assert [sim.frame_capacity(n) for n in (0, 1, 50, 256, 257, 1000, 1024, 1025)] == [256] * 4 + [512, 1024, 1024, 2048]
    with compile_events() as compiles:
        other = sim.rollout(m, san, p, seconds=0.9, record_fps=40)  # 36 frames, one every 25 steps
    assert compiles == []
    assert other.frames.q.shape == (4, 36, m.structure.ndof) and other.frames.u.shape == (4, 36, 1)
    np.testing.assert_allclose(other.frames.t[:3], [0.0, 0.025, 0.05])
    at25 = sim.rollout(m, san, p, steps=25)
    np.testing.assert_array_equal(np.asarray(other.frames.q[:, 1]), np.asarray(at25.state.q))
    plain = sim.rollout(m, san, p, seconds=0.9)
    np.testing.assert_array_equal(np.asarray(other.state.q), np.asarray(plain.state.q))


def test_a_recording_refuses_a_negative_duration_or_rate_and_records_none_at_a_tiny_rate():
    """Negative durations and rates, and rates that are not numbers, are refused (a negative
    duration once came back as a buffer of zeroed frames); a rate too low for one frame in the
    run records none (its steps between frames are an int32 input of the program)."""
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    san, p = random_sans(spec, 2, seed=3)
    for kw in ({"steps": -5, "record_fps": 30}, {"seconds": -0.1, "record_fps": 30}, {"steps": -1}):
        with pytest.raises(ValueError, match="steps: expected >= 0"):
            sim.rollout(m, san, p, **kw)
    for fps in (-30.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="record_fps"):
            sim.rollout(m, san, p, seconds=0.1, record_fps=fps)
    for fps in (1e-7, 1e-310, 5e-324):  # the last two: a frame spacing of inf steps
        tiny = sim.rollout(m, san, p, seconds=0.1, record_fps=fps)
        assert tiny.frames.q.shape == (2, 0, m.structure.ndof) and tiny.frames.t.shape == (0,)
    np.testing.assert_array_equal(np.asarray(tiny.state.q), np.asarray(sim.rollout(m, san, p, seconds=0.1).state.q))


def test_a_nudged_step_reuses_the_traced_program_and_runs_at_its_own_step(monkeypatch):
    """The audit's dt/2 and dt/4 differ from the nominal creature only in dt, which the traced
    step reads from ``params``: they trace nothing new (each used to cost a trace, a lowering and
    a cache load, 1-2 s for the bounder). And the shared program must not carry the first
    model's dt or spec along: the nudged run equals one traced afresh for it, bit for bit."""
    import dataclasses
    import importlib

    from sanlab.sim import executables

    rollout_module = importlib.import_module("sanlab.sim.rollout")  # the module, not the function

    spec = creature.load("cart")
    san, p = random_sans(spec, 4, seed=2)
    nominal = sim.rollout(sim.compile_creature(spec), san, p, seconds=0.3)
    half = sim.compile_creature(dataclasses.replace(spec, dt=spec.dt / 2))
    with compile_events("/jax/core/compile/jaxpr_trace_duration") as traced:
        shared = sim.rollout(half, san, p, seconds=0.3)
    assert traced == []
    assert np.allclose(np.asarray(shared.state.t), 0.3, atol=1e-6)  # 600 steps of 0.5 ms
    assert not np.array_equal(np.asarray(shared.state.q), np.asarray(nominal.state.q))
    # afresh: no program in memory, none from disk
    monkeypatch.setattr(executables, "enabled", lambda: False)
    rollout_module._program.cache_clear()
    jax.clear_caches()
    fresh = sim.rollout(half, san, p, seconds=0.3)
    for field in ("q", "p", "t"):
        np.testing.assert_array_equal(np.asarray(getattr(shared.state, field)), np.asarray(getattr(fresh.state, field)))


def test_bad_runs_are_flagged_not_fatal():
    spec = creature.load("cart")
    m = sim.compile_creature(spec)
    s0 = sim.initial_state(m)
    bad = jax.tree_util.tree_map(lambda x: jnp.stack([x, x]), s0)
    bad = bad._replace(p=bad.p.at[1, 1].set(jnp.nan))
    r = sim.rollout(m, sim.ConstantController(), jnp.full((2, 1), 0.5), seconds=0.1, state0=bad)
    assert list(np.asarray(r.finite)) == [True, False]


@pytest.mark.slow  # over 4 s even with a warm compile cache (the pre-commit subset leaves it out)
def test_persistent_compile_cache_is_written(tmp_path):
    code = (
        "from sanlab import creature, sim; import jax.numpy as jnp;"
        "m = sim.compile_creature(creature.load('cart'));"
        "sim.rollout(m, sim.ConstantController(), jnp.zeros((1, 1)), steps=3)"
    )
    env = dict(os.environ, SANLAB_CACHE=str(tmp_path))
    env.pop("SANLAB_NO_COMPILE_CACHE", None)
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=300)
    entries = list((tmp_path / "jax").iterdir())
    assert entries, "no compiled program was cached"
    assert list((tmp_path / "programs").glob("*.stablehlo")), "no traced program was kept (sim.executables)"


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


@pytest.mark.slow  # over 4 s even with a warm compile cache (the pre-commit subset leaves it out)
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_the_default_start_state_is_the_one_evaluations_start_from(dtype):
    # rollout builds the default start state inside its compiled program; it must be, bit for
    # bit, the state every score starts from (the evaluator's compiled start), so that a replay of
    # a gait starts where its evaluation did; make_state run op by op on the host agrees to round-off
    from sanlab.evaluate.evaluator import _start

    spec = creature.load("walker")  # on the host its foot anchors differ from compiled ones in the last bit
    m = sim.compile_creature(spec, dtype)
    san, params = random_sans(spec, 5, seed=2)
    q0 = np.asarray(m.params.q0)[None].repeat(5, 0)
    scored = _start(m, q0, np.ones(5, bool), False)
    at0 = sim.rollout(m, san, params, steps=0)
    for field in ("q", "p", "anchor", "t"):
        np.testing.assert_array_equal(np.asarray(getattr(at0.state, field)), np.asarray(getattr(scored, field)))
        # round-off: a few ulps of a metre (float32: the walker's hip height differs in its last bit)
        np.testing.assert_allclose(np.asarray(getattr(at0.state, field))[0], np.asarray(getattr(sim.make_state(m), field)),
                                   rtol=0, atol=4 * float(np.finfo(dtype).eps))
    default = sim.rollout(m, san, params, steps=400)
    given = sim.rollout(m, san, params, steps=400, state0=scored)
    np.testing.assert_array_equal(np.asarray(default.state.q), np.asarray(given.state.q))
    np.testing.assert_array_equal(np.asarray(default.state.p), np.asarray(given.state.p))
    assert np.ptp(np.asarray(default.state.q[:, 0])) > 1e-4  # the controllers moved it, differently
    # with a batch of models, each member starts in its own pose
    mb = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (5,) + x.shape), m)
    q0[:, 1] += np.linspace(0.0, 0.04, 5)
    mb = mb.with_params(q0=q0)
    at0 = sim.rollout(mb, san, params, steps=0, params_batched=True)
    scored = _start(mb, q0, np.ones(5, bool), True)
    np.testing.assert_array_equal(np.asarray(at0.state.q), q0.astype(dtype))
    np.testing.assert_array_equal(np.asarray(at0.state.anchor), np.asarray(scored.anchor))
    assert np.ptp(np.asarray(at0.state.anchor[:, 0, 1])) > 0.03  # the poses differ
