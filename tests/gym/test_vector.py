"""The vector environment (``sanlab.gym.vector``): shapes, autoreset, seeding and determinism.

Gymnasium 1.4 has no checker for vector environments, so its reference implementation is the
check: ``make_vec(..., vectorization_mode="sync")`` (Gymnasium's ``SyncVectorEnv`` over the
single environment) must give the same numbers, bit for bit, as the batched one, in both
autoreset modes that return observations. Then: the numbers do not depend on the devices or on
``num_envs``, Gymnasium's episode statistics wrapper sees each episode's score as its return,
and SANs driven through the batch score what they score alone.

The configurations share one compiled program, the single environment's (the same creature and
metric, two rows on one device): 2 sub-environments of the bounder, most with 20-step (20 ms)
episodes so that autoresets happen.
"""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import sanlab.gym  # noqa: F401  (registers the ids)
from sanlab.gym import SanlabVectorEnv, SanPolicy
from sanlab.san import San, SanParams

N = 2  # two rows on one device: the single environment's program, compiled once for both modules
SHORT = {"seconds": 0.02, "reset_noise_scale": 1.0}  # 20-step episodes from perturbed starts


def make(**kw):
    return gymnasium.make_vec("sanlab/Bounder-v0", num_envs=N, vectorization_mode="vector_entry_point", **kw)


@pytest.fixture(scope="module")
def envs():
    e = make()
    yield e
    e.close()


def actions(space, seed: int, steps: int) -> list[np.ndarray]:
    space.seed(seed)
    return [space.sample() for _ in range(steps)]


def test_spaces_and_shapes(envs):
    """Batched spaces as Gymnasium batches the single ones; reset and step return arrays of
    those shapes and dtypes, with a masked info."""
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert envs.single_observation_space == gymnasium.spaces.MultiBinary(8)
    assert envs.observation_space.shape == (N, 8) and envs.action_space.shape == (N, 4)
    obs, info = envs.reset(seed=0)
    assert obs.shape == (N, 8) and obs.dtype == np.int8 and obs in envs.observation_space
    assert set(info) == {"score", "t", "fell", "nonfinite", "_score", "_t", "_fell", "_nonfinite"}
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    assert obs in envs.observation_space
    assert reward.shape == (N,) and reward.dtype == np.float64
    assert terminated.dtype == truncated.dtype == np.bool_ and terminated.shape == truncated.shape == (N,)
    np.testing.assert_array_equal(info["t"], np.full(N, 0.001))
    assert info["_score"].all() and np.array_equal(info["score"], reward)  # the first step's reward is its score


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_matches_gymnasiums_sync_vector_env(mode):
    """The batched environment and Gymnasium's SyncVectorEnv over the single one: the same
    observations, rewards, ends and scores, bit for bit, over 50 steps of 20-step episodes
    from seeded perturbed starts (sub-environment i seeded seed + i), across the autoresets;
    with SAME_STEP the same final observations too."""
    ours = make(autoreset_mode=mode, **SHORT)
    ref = gymnasium.make_vec("sanlab/Bounder-v0", num_envs=N, vectorization_mode="sync",
                             vector_kwargs={"autoreset_mode": mode}, **SHORT)
    a, _ = ours.reset(seed=11)
    b, _ = ref.reset(seed=11)
    np.testing.assert_array_equal(a, b)
    ended = 0
    for act in actions(ours.action_space, 5, 50):
        x, y = ours.step(act), ref.step(act)
        for k in range(4):  # obs, reward, terminated, truncated
            np.testing.assert_array_equal(x[k], y[k])
        np.testing.assert_array_equal(x[4]["score"], y[4]["score"])
        ended += int(np.sum(x[2] | x[3]))
        if mode == AutoresetMode.SAME_STEP and (x[2] | x[3]).any():
            np.testing.assert_array_equal(x[4]["_final_obs"], y[4]["_final_obs"])
            for i in np.flatnonzero(x[4]["_final_obs"]):
                np.testing.assert_array_equal(x[4]["final_obs"][i], y[4]["final_obs"][i])
    assert ended >= 2 * N  # the episodes did end, and restart
    ours.close()
    ref.close()


def test_next_step_autoreset_restarts_the_next_step():
    """NEXT_STEP: the step after the episode's last returns the start's observation with reward
    0, not ended, at t = 0 (the action ignored), and the episode then runs again."""
    e = make(seconds=0.02)
    first, _ = e.reset(seed=0)
    acts = actions(e.action_space, 1, 21)
    for k, act in enumerate(acts[:20]):
        obs, reward, terminated, truncated, info = e.step(act)
        assert truncated.all() == (k == 19) and not terminated.any()
    obs, reward, terminated, truncated, info = e.step(acts[20])
    np.testing.assert_array_equal(obs, first)
    assert not reward.any() and not terminated.any() and not truncated.any() and not info["t"].any()
    obs, reward, *_ , info = e.step(acts[0])
    np.testing.assert_array_equal(info["t"], np.full(N, 0.001))
    e.close()


def test_disabled_autoreset_and_reset_mask():
    """DISABLED: an ended sub-environment must be reset through reset_mask before it is stepped
    again; reset_mask resets only those it names."""
    e = make(autoreset_mode="Disabled", observation="state", **SHORT)
    e.reset(seed=0)
    for act in actions(e.action_space, 2, 20):
        obs, *_ = e.step(act)
    with pytest.raises(RuntimeError, match="sub-environment 0 ended"):
        e.step(act)
    mask = np.array([False, True])
    fresh, info = e.reset(options={"reset_mask": mask})
    np.testing.assert_array_equal(fresh["q"][0], obs["q"][0])  # untouched
    assert not np.array_equal(fresh["q"][1], obs["q"][1]) and np.array_equal(info["_score"], mask)
    with pytest.raises(RuntimeError, match="sub-environment 0 ended"):
        e.step(act)
    e.reset(options={"reset_mask": ~mask})
    e.step(act)
    for bad in (np.array([1, 0]), np.zeros(N, bool), np.ones(N + 1, bool)):
        with pytest.raises(ValueError, match="reset_mask"):
            e.reset(options={"reset_mask": bad})
    e.close()


def test_seeding_and_determinism():
    """The same seed and actions give the same numbers; each sub-environment has its own
    start; another seed another start."""
    e = make(observation="state", **SHORT)
    runs = []
    for seed in (3, 3, 4):
        obs, _ = e.reset(seed=seed)
        trace = [obs["q"]]
        for act in actions(e.action_space, 0, 10):
            obs, reward, *_ = e.step(act)
            trace += [obs["q"], reward]
        runs.append(trace)
    for x, y in zip(runs[0], runs[1], strict=True):
        np.testing.assert_array_equal(x, y)
    q0 = runs[0][0]
    assert not np.array_equal(q0[0], q0[1]) and not np.array_equal(q0, runs[2][0])
    e.close()


def test_numbers_do_not_depend_on_num_envs():
    """A sub-environment's numbers are the same in a batch of 2 or of 3 (its neighbours and the
    kernel's padding lanes do not matter)."""
    acts = actions(SanlabVectorEnv(3, "bounder", **SHORT).action_space, 9, 30)  # [3, A] each; the first N rows for N
    runs = []
    for n in (N, 3):
        e = SanlabVectorEnv(n, "bounder", **SHORT)
        e.reset(seed=2)
        trace = []
        for act in acts:
            obs, reward, *_ = e.step(act[:n])
            trace.append((obs[:N], reward[:N]))
        runs.append(trace)
        e.close()
    for other in runs[1:]:
        for (a, r), (b, s) in zip(runs[0], other, strict=True):
            np.testing.assert_array_equal(a, b)
            np.testing.assert_array_equal(r, s)


def test_episode_statistics_see_the_score_as_the_return():
    """Gymnasium's RecordEpisodeStatistics over the batch: each finished episode's return is the
    score the environment reported at its end."""
    e = gymnasium.wrappers.vector.RecordEpisodeStatistics(make(**SHORT))
    e.reset(seed=1)
    seen = 0
    score = np.zeros(N)
    for act in actions(e.action_space, 3, 45):
        obs, reward, terminated, truncated, info = e.step(act)
        done = terminated | truncated
        if done.any():
            np.testing.assert_array_equal(info["episode"]["r"][done], info["score"][done])
            seen += int(done.sum())
        score = info["score"]
    assert seen >= N and np.isfinite(score).all()
    e.close()


def test_sans_through_the_batch_score_as_through_the_single_env(envs):
    """Random SANs (§5.2's phase-1 controllers), one per sub-environment, driven through the
    batch by one ``SanPolicy`` for 300 steps, earn exactly the returns each earns alone in the
    single environment (which ``tests/gym/test_env.py`` holds to ``sim.rollout`` and to the
    library's scores)."""
    e = envs.unwrapped
    core = e.core
    san = San.for_creature(core.spec)
    W = np.stack([san.random_weights(7, i) for i in range(N)])
    params = san.params(W, core.spec.san.delay_on, core.spec.san.delay_off)
    policy = SanPolicy(envs, san, params)
    obs, _ = envs.reset(seed=0)
    policy.reset()
    ret = np.zeros(N)
    for _ in range(300):
        obs, reward, terminated, truncated, info = envs.step(policy(obs))
        ret += reward
    single = gymnasium.make("sanlab/Bounder-v0")
    for i in range(N):
        alone = SanPolicy(single, san, SanParams(*(np.asarray(x)[i : i + 1] for x in params)))
        obs, _ = single.reset(seed=0)
        alone.reset()
        total = 0.0
        for _ in range(300):
            obs, reward, *_ = single.step(alone(obs))
            total += reward
        assert total == ret[i] != 0.0
    np.testing.assert_array_equal(info["score"], ret)
    single.close()


def test_bad_widths_and_actions_too_large_for_a_float(envs):
    """Issue 48: a width outside [64, 4096] is refused before anything is built (0 gave 64 px,
    100,000 18 GB); an action of 10**400 raises the ValueError naming its row and actuator, not
    OverflowError."""
    for width in (0, -5, 20_000, 100_000, 640.5):
        with pytest.raises(ValueError, match=rf"^width: expected an integer in \[64, 4096\] \(px\), got {width!r}$"):
            make(render_mode="rgb_array", width=width)
    envs.reset(seed=0)
    for value, shown in ((10**400, "1e400"), (-(10**1000), "-1e1000")):
        action = np.tile(envs.single_action_space.low, (N, 1)).tolist()
        action[1][2] = value
        with pytest.raises(ValueError, match=rf"^action\[1, 2\] \(actuator 'A3'\): an integer of about {shown} is outside"):
            envs.step(action)


def test_render_and_bad_input(envs):
    """One picture per sub-environment with rgb_array (None without); bad options, policies and
    actions raise ValueError naming what was wrong."""
    e = make(render_mode="rgb_array", **SHORT)
    e.reset(seed=0)
    e.step(e.action_space.sample())
    frames = e.render()
    assert isinstance(frames, tuple) and len(frames) == N and all(f.shape == (360, 640, 3) for f in frames)
    assert envs.render() is None
    e.close()
    with pytest.raises(ValueError, match="num_envs"):
        SanlabVectorEnv(0, "bounder")
    with pytest.raises(ValueError, match="autoreset_mode"):
        make(autoreset_mode="Sometimes")
    with pytest.raises(ValueError, match="max_episode_steps"):
        make(max_episode_steps=0)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"expected shape \(2, 4\)"):
        envs.step(np.zeros((N, 3)))
    san = San(1, 1, 1)
    tiny = san.params(np.zeros((N, 2, 3)), 0.1, 0.1)
    with pytest.raises(ValueError, match="do not match creature 'bounder'"):
        SanPolicy(envs, san, tiny)
    with pytest.raises(ValueError, match=r"expected a sanlab\.gym environment"):
        SanPolicy(gymnasium.make("CartPole-v1"), san, tiny)
    bad = np.tile(envs.single_action_space.low, (N, 1))
    bad[1, 3] -= 1.0
    with pytest.raises(ValueError, match=r"action\[1, 3\] \(actuator 'A4'\)"):
        envs.step(bad)
