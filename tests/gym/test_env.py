"""The single Gymnasium environment (``sanlab.gym.env``): Gymnasium's own checker, the spaces,
the reward as the metric's increments, the episode's end, rendering, bad input, and a SAN found
by ``sanlab search`` scoring through the environment what the library says it scores.

One environment per configuration and module (the compiles are the slow part): ``env`` is the
built-in bounder as ``gymnasium.make`` gives it; ``tippy`` a small creature from a file
(``sanlab/Creature-v0``) that topples, and so falls, within its 0.4 s evaluation, stepped 5
simulator steps at a time.
"""

from __future__ import annotations

import json
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import sanlab.gym
from sanlab import sim
from sanlab.cli import app
from sanlab.creature import CreatureError, load
from sanlab.gait import Gait
from sanlab.gym import SanPolicy, gait_env_kwargs
from sanlab.library import Library
from sanlab.metrics import Metric, scores
from tests.fuzz import bad_widths, huge_ints
from tests.helpers import BASE

runner = CliRunner()
# check_env's advice, not failures: to normalise a Box action space, and to bound a Box
# observation (a creature's position along the ground has no bound)
ADVICE = ("For Box action spaces, we recommend using a symmetric and normalized space",
          "A Box observation space minimum value is -infinity", "A Box observation space maximum value is infinity")


def replay(model, U: np.ndarray, metric: Metric, seconds: float) -> dict:
    """A rollout of the activations U [T, A] (float32, each held for a stretch of steps) on the
    kernel, a stretch per call (state, time and the metric's accumulators carried from one call
    to the next): the sensor values before each step ("bits" [T, S]), the final coordinates
    ("q" [D]) and ``metrics.scores`` of the run (each [1])."""
    from sanlab.sim import kernel

    pk = kernel.pack(model, 0)
    ob = metric.observe()
    q, anchor = kernel.start(pk, np.asarray(model.params.q0, np.float64)[None], seat=False)
    p, t, acc = np.zeros_like(q), np.zeros(1), None
    bits, k = [], 0
    while k < len(U):
        n = int(np.argmax(np.any(U[k:] != U[k], axis=1))) or len(U) - k  # the stretch U[k] is held
        r = kernel.run_open(pk, "hold", U[k][None].astype(np.float64), q, p, anchor, n, t0=t, observe=ob,
                            acc=acc, every=1)
        q, p, anchor, t, acc = r["q"], r["p"], r["anchor"], r["t"], r["acc"]
        bits.append(r["frames_bits"][0])
        k += n
    finite = np.isfinite(q).all(1) & (np.abs(r["qd"]) < 1e4).all(1) & np.isfinite(p).all(1)
    from sanlab.sim.rollout import columns

    out = scores(metric, metric.collect(columns(acc, ob)), finite, seconds, model.spec.world.plane)
    return {"bits": np.concatenate(bits).astype(np.int8), "q": q[0], **out}


@pytest.fixture(scope="module")
def env():
    e = gymnasium.make("sanlab/Bounder-v0")
    yield e
    e.close()


@pytest.fixture(scope="module")
def tippy_file(tmp_path_factory):
    """The test suite's two-segment creature (``tests.helpers.BASE``), standing on end, scored
    by distance_upright and fallen once its centre of mass is below 15 cm (it topples under
    gravity: its servo is weak), for 0.4 s. Small, so it compiles in seconds."""
    text = 'name = "tippy"\n' + BASE + ('\n[evaluation]\nmetric = "distance_upright"\nseconds = 0.4\n'
                                       'fell_com_height = 0.15\n')
    path = tmp_path_factory.mktemp("gym") / "tippy.toml"
    path.write_text(text)
    return str(path)


@pytest.fixture(scope="module")
def tippy(tippy_file):
    e = gymnasium.make("sanlab/Creature-v0", path=tippy_file, frame_skip=5, observation="state", action="activation",
                       render_mode="rgb_array").unwrapped
    yield e
    e.close()


def activations(seed: int, steps: int, A: int, hold: int = 25) -> np.ndarray:
    """A smooth random activation sequence [steps, A] in [0, 1] (float32), each value held for
    ``hold`` steps."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.0, 1.0, (-(-steps // hold), A)).astype(np.float32)
    return np.repeat(u, hold, axis=0)[:steps]


def test_check_env_passes(env, tippy):
    """Gymnasium's checker (spaces, reset and step determinism, seeding, returned data not
    reused, rendering) on both configurations; only its advice (``ADVICE``) may be printed: the
    targets are in the actuators' units by design, and coordinates are unbounded."""
    for e in (env.unwrapped, tippy):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            check_env(e)
        other = [str(w.message) for w in seen if not any(a in str(w.message) for a in ADVICE)]
        assert not other, other


def test_registered_ids_and_module_prefix():
    """Every built-in has its id, with both entry points; the module-prefix form finds the
    same environment."""
    from sanlab.creature import builtin_names

    assert set(sanlab.gym.ENV_IDS.values()) == set(builtin_names())
    for env_id, name in sanlab.gym.ENV_IDS.items():
        spec = gymnasium.spec(env_id)
        assert spec.kwargs == {"creature": name} and spec.vector_entry_point is not None
    e = gymnasium.make("sanlab.gym:sanlab/Bounder-v0")
    assert e.unwrapped.creature.name == "bounder"
    e.close()


def test_spaces_are_the_creatures(env):
    """Observations: the 8 sensors' bits; actions: each servo's target range (rad) as the file
    gives it; one step: one simulator step of 1 ms; an episode: the 6 s evaluation."""
    spec = load("bounder")
    e = env.unwrapped
    assert e.observation_space == gymnasium.spaces.MultiBinary(len(spec.sensors))
    box = e.action_space
    assert box.dtype == np.float64 and box.shape == (len(spec.actuators),)
    np.testing.assert_allclose(box.low, [a.min for a in spec.actuators], rtol=1e-6)
    np.testing.assert_allclose(box.high, [a.max for a in spec.actuators], rtol=1e-6)
    assert e.dt == spec.dt and e.max_episode_steps == round(spec.evaluation.seconds / spec.dt)


def test_overrides_are_a_tuned_gaits_numbers():
    """overrides (a tuned gait's ``params.model``) change the simulated creature, its action
    space with it; a bad one is refused naming the field."""
    spec = load("bounder")
    high = [a.max for a in spec.actuators]
    high[0] -= 0.1
    e = gymnasium.make("sanlab/Bounder-v0", overrides={"act_max": high}).unwrapped
    np.testing.assert_allclose(e.action_space.high, high, rtol=1e-6)
    with pytest.raises(ValueError, match=r"params\.model\.act_max"):
        gymnasium.make("sanlab/Bounder-v0", overrides={"act_max": [1.0]})
    with pytest.raises(ValueError, match=r"params\.model\.wings"):
        gymnasium.make("sanlab/Bounder-v0", overrides={"wings": [1.0]})


def test_reset_is_the_start_at_rest(env, tippy):
    """reset: the creature's start pose (the state observation's coordinates), at rest, with a
    score of 0."""
    for e in (env.unwrapped, tippy):
        obs, info = e.reset(seed=0)
        assert info == {"score": 0.0, "t": 0.0}
    np.testing.assert_array_equal(obs["q"], np.asarray(sim.compile_creature(tippy.creature).params.q0))
    assert not np.any(obs["qd"])


def test_steps_are_a_rollouts_and_the_return_is_its_score(env):
    """Any actions: over 400 steps each observation is the sensor bits a rollout's controller
    sees at that step (the kernel run a held stretch of activations per call, recorded every
    step), the last state is the rollout's, bit for bit (one physics), and the rewards sum to the
    rollout's metric exactly (``metrics.scores``: the telescoping sum of running scores has no
    round-off). The targets go through the float64 action space and back to the same float32
    activations."""
    e = env.unwrapped
    core = e.core
    U = activations(1, 400, core.n_actuators)
    metric = Metric.for_creature(core.spec)
    r = replay(core.model, U, metric, core.seconds)
    seen = r["bits"]  # [400, S]: before each step
    want = r["score"][0]
    obs, _ = e.reset(seed=0)
    total, info = 0.0, {}
    for k, u in enumerate(U):
        np.testing.assert_array_equal(obs, seen[k], err_msg=f"step {k}")
        obs, reward, terminated, truncated, info = e.step(core.targets(u))
        assert not (terminated or truncated)
        total += reward
    assert want != 0.0 and len(np.unique(seen, axis=0)) > 2  # the comparisons mean something
    assert total == want == info["score"]
    np.testing.assert_array_equal(core.q(e._out)[0], r["q"])


def test_under_tracking_the_return_is_the_rollouts_score_too():
    """The crawler scored by tracking (a ratio of the start distance to the follow point over the
    mean distance so far, not an integral): the rewards still sum to the rollout's score exactly."""
    e = gymnasium.make("sanlab/Crawler-v0", metric="tracking", seconds=0.5).unwrapped
    core = e.core
    U = activations(2, 500, core.n_actuators)
    want = replay(core.model, U, Metric.for_creature(core.spec, "tracking"), core.seconds)["score"][0]
    e.reset(seed=0)
    total, info = 0.0, {}
    for u in U:
        _, reward, terminated, truncated, info = e.step(core.targets(u))
        total += reward
    e.close()
    assert 0.5 < want < 2.0  # about its start distance: the point barely moved in 0.5 s
    assert total == want == info["score"]


def test_frame_skip_is_that_many_steps_and_falling_ends_it(tippy, tippy_file):
    """With frame_skip 5 an environment step is 5 simulator steps under one action (the same
    numbers as a rollout holding each activation 5 steps); the fall ends the episode
    (terminated) and, under distance_upright, the return is then 0, as a fallen evaluation
    scores; without termination the episode runs its 0.4 s: 80 steps, then truncated."""
    core = tippy.core
    assert tippy.dt == pytest.approx(0.005) and tippy.max_episode_steps == 80
    U = activations(2, 80, core.n_actuators, hold=4)
    metric = Metric.for_creature(core.spec)
    want = r = replay(core.model, np.repeat(U, 5, axis=0), metric, core.seconds)
    assert want["fell"][0]  # the creature of this test does topple
    tippy.reset(seed=0)
    total, steps, terminated = 0.0, 0, False
    for u in U:
        obs, reward, terminated, truncated, info = tippy.step(u)
        total, steps = total + reward, steps + 1
        if terminated or truncated:
            break
    assert terminated and not truncated and info["fell"] and steps < 80
    assert total == 0.0 == info["score"]
    with pytest.raises(RuntimeError, match="after the episode ended"):
        tippy.step(U[0])

    free = gymnasium.make("sanlab/Creature-v0", path=tippy_file, frame_skip=5, terminate_on_fall=False,
                          observation="state", action="activation").unwrapped
    free.reset(seed=0)
    for k, u in enumerate(U):
        obs, reward, terminated, truncated, info = free.step(u)
        assert not terminated and truncated == (k == 79)
    assert info["t"] == pytest.approx(0.4) and info["score"] == want["score"][0] == 0.0
    np.testing.assert_array_equal(obs["q"], r["q"])


def test_reset_noise_is_seeded(tippy_file):
    """reset_noise_scale perturbs the start as an ensemble member is perturbed: small (within
    3 sigma: 3 mm, 1.5 deg), the same for the same seed, different for another."""
    e = gymnasium.make("sanlab/Creature-v0", path=tippy_file, frame_skip=5, observation="state", action="activation",
                       reset_noise_scale=1.0).unwrapped
    q0 = np.asarray(e.core.q0, float)
    a, _ = e.reset(seed=7)
    b, _ = e.reset(seed=7)
    c, _ = e.reset(seed=8)
    np.testing.assert_array_equal(a["q"], b["q"])
    assert not np.array_equal(a["q"], c["q"]) and not np.array_equal(a["q"], q0)
    assert np.max(np.abs(a["q"] - q0)) < np.radians(1.5) + 1e-6  # seated: lifted by at most a few mm


def test_render_draws_the_creature(tippy, env):
    """rgb_array: a 640 x 360 RGB picture that changes as the creature moves; no picture without
    a render mode."""
    tippy.reset(seed=0)
    first = tippy.render()
    assert first is not None and first.shape == (360, 640, 3) and first.dtype == np.uint8
    assert len(np.unique(first.reshape(-1, 3), axis=0)) > 10  # ground, sky, creature, labels
    for _ in range(30):
        *_, terminated, truncated, _ = tippy.step(np.zeros(tippy.core.n_actuators))
        if terminated or truncated:
            break
    later = tippy.render()
    assert later is not None and np.mean(np.any(later != first, axis=2)) > 0.001
    env.reset(seed=0)
    assert env.render() is None


def test_bad_input_says_what_was_wrong(env, tmp_path):
    """Unknown creatures, bad files, bad options and actions outside the space each raise one
    clear error naming what was wrong."""
    with pytest.raises(CreatureError, match="no-such-creature"):
        gymnasium.make("sanlab/Creature-v0", path="no-such-creature")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[[links]]\nname = 'a'\nmass = -1\n")
    with pytest.raises(CreatureError, match=r"bad\.toml"):
        gymnasium.make("sanlab/Creature-v0", path=str(bad))
    with pytest.raises(ValueError, match="path="):
        gymnasium.make("sanlab/Creature-v0")
    for kw, what in (({"observation": "pixels"}, "observation"), ({"action": "torque"}, "action"),
                     ({"frame_skip": 0}, "frame_skip"), ({"reset_noise_scale": -1.0}, "reset_noise_scale"),
                     ({"metric": "speed"}, "metric"), ({"seconds": 0.0}, "seconds"), ({"dtype": "int8"}, "dtype")):
        with pytest.raises(ValueError, match=what):
            gymnasium.make("sanlab/Bounder-v0", **kw)
    e = env.unwrapped
    e.reset(seed=0)
    high = e.action_space.high.copy()
    high[1] += 0.1
    with pytest.raises(ValueError, match=r"action\[1\] \(actuator 'A2'\).*outside its range"):
        e.step(high)
    with pytest.raises(ValueError, match="outside its range"):
        e.step(np.full(4, np.nan))
    with pytest.raises(ValueError, match=r"expected shape \(4,\)"):
        e.step(np.zeros(3))


FUZZ = dict(database=None, deadline=None, derandomize=True, max_examples=30,
            suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@settings(**FUZZ)
@given(width=bad_widths(), render_mode=st.sampled_from(["rgb_array", None]))
def test_a_width_outside_its_range_is_refused_before_anything_is_built(width, render_mode):
    """Issue 48: widths 0 and -5 gave a 64-pixel picture, 20,000 a MemoryError and 100,000 grew
    the process to 18.6 GB; now each is one ValueError, raised before the creature is read."""
    with pytest.raises(ValueError) as e:
        gymnasium.make("sanlab/Bounder-v0", render_mode=render_mode, width=width)
    assert str(e.value) == f"width: expected an integer in [64, 4096] (px), got {width!r}"


@settings(**FUZZ)
@given(value=huge_ints(), k=st.integers(0, 3))
def test_an_action_too_large_for_a_float_is_refused_naming_its_actuator(env, value, k):
    """Issue 48: [10**400] raised OverflowError, not the ValueError naming the actuator."""
    e = env.unwrapped
    e.reset(seed=0)
    action = [0.0] * 4
    action[k] = value
    sign = "-" if value < 0 else ""
    with pytest.raises(ValueError, match=rf"^action\[{k}\] \(actuator 'A{k + 1}'\): an integer of about {sign}1e\d+ "
                                         r"is outside its range \["):
        e.step(action)
    with pytest.raises(ValueError, match=rf"^action\[{k}\] \(actuator 'A{k + 1}'\)"):
        e.step(np.array(action, dtype=object))


def test_step_before_reset_raises(tippy_file):
    e = gymnasium.make("sanlab/Creature-v0", path=tippy_file, frame_skip=5, observation="state", action="activation",
                       disable_env_checker=True).unwrapped
    with pytest.raises(RuntimeError, match="before reset"):
        e.step(np.zeros(1))


# ------------------------------------------------------------------- a found SAN as a policy


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    """The three best gaits of ``sanlab search bounder -n 12 --seconds 1`` (the default robust
    ensemble: 8 perturbed members at dt and dt/2) in a temporary library, with their stored
    scores."""
    db = tmp_path_factory.mktemp("gym-search") / "gaits.db"
    r = runner.invoke(app, ["search", "bounder", "-n", "12", "--seconds", "1", "--seed", "4", "--db", str(db), "--json"])
    assert r.exit_code == 0, r.output
    run_id = json.loads(r.stdout)["run_id"]
    with Library(str(db)) as lib:
        return [(Gait.from_library(lib, e.gait_id), e.scores) for e in lib.top(run_id, 3)]


@pytest.mark.slow  # about 16 s on 2 busy cores (the pre-commit subset leaves it out)
def test_a_found_san_scores_through_the_env_what_the_library_says(found):
    """A SAN found by ``sanlab search``, driven through the environment as a policy (sensor bits
    in, actuator targets out, ``sanlab.san.San`` every step), earns as its return exactly what
    the library stored for its evaluation's unperturbed member: ``member_scores[0]``, member 0
    of the robust ensemble (the creature's own start at the creature's dt; the stored score is
    the lower group median over all eight members, docs/robust-objective.md). Exact, not to
    round-off: the environment's step is the rollout's arithmetic bit for bit, and the return
    is ``metrics.scores`` of the same float32 accumulator."""
    gait, _ = found[0]
    env = gymnasium.make("sanlab/Creature-v0", **gait_env_kwargs(gait))
    assert env.unwrapped.max_episode_steps == 1000
    assert found[0][1].member_scores[0] > 0  # the best of the run moved
    for gait, stored in found:
        policy = SanPolicy.from_gaits(env, [gait])
        obs, _ = env.reset(seed=0)
        policy.reset()
        ret, done, info = 0.0, False, {}
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            ret += reward
            done = terminated or truncated
        assert ret == stored.member_scores[0] == info["score"], gait.gait_id
    env.close()


def test_a_float32_policy_at_the_bounds_is_accepted():
    # a float32 policy clipped to the Box rounds its bounds outward by up to half a float32 step
    import gymnasium

    import sanlab.gym  # noqa: F401

    env = gymnasium.make("sanlab/Bounder-v0")
    env.reset(seed=0)
    space = env.action_space
    for edge in (space.high, space.low):
        rounded = edge.astype(np.float32)
        assert np.any(rounded.astype(np.float64) != edge)  # really past a bound somewhere
        env.step(rounded)
    with pytest.raises(ValueError, match="outside its range"):
        env.step(space.high + 0.01 * (space.high - space.low))
