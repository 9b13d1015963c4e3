"""The one evaluator: ensemble draws, robust statistics, single-sample scoring as before, and
scores that depend on nothing but the controller and its key."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.evaluate import Ensemble, Evaluator, GaitParams, Scores
from sanlab.evaluate.ensemble import heldout_key, search_key, start_key, trial_key
from sanlab.evaluate.evaluator import robust
from sanlab.metrics import scores

BOUNDER = creature.load("bounder")


def test_ensemble_draws_perturb_the_start_pose_per_key():
    st = sim.compile_creature(BOUNDER).structure
    L = len(BOUNDER.links)
    ens = Ensemble(members=8, pose=1e-3, angle=0.5, friction=0.05)
    dq, mu = ens.draws(st, search_key(0, 7), L)
    assert dq.shape == (8, st.ndof) and mu.shape == (8, L)
    assert not dq[0].any() and (mu[0] == 1).all()  # member 0 is the unperturbed start
    again, _ = ens.draws(st, search_key(0, 7), L)
    np.testing.assert_array_equal(dq, again)  # one stream per evaluation: the same draws every time
    other, _ = ens.draws(st, search_key(0, 8), L)
    assert not np.array_equal(dq, other)
    roots = [st.links[t.root] for t in st.trees if t.free]
    pose = [d for r in roots for d in (r.dof_x, r.dof_y)]
    angles = [ls.dof_rot for ls in st.links if ls.dof_rot >= 0]
    assert sorted(pose + angles) == list(range(st.ndof))  # every coordinate of the bounder is one or the other
    assert np.abs(dq[1:, pose]).max() <= 3e-3 and np.abs(dq[1:, pose]).max() > 1e-4  # clipped at 3 sigma
    assert np.abs(dq[1:, angles]).max() <= math.radians(1.5) and np.abs(dq[1:, angles]).max() > 1e-4
    assert (np.abs(mu - 1) <= 0.05).all() and np.ptp(mu) > 0
    # friction is drawn after the pose: turning it off changes nothing else
    dq0, mu0 = Ensemble(members=8, friction=0.0).draws(st, search_key(0, 7), L)
    np.testing.assert_array_equal(dq0, dq)
    assert (mu0 == 1).all()
    # every kind of evaluation has its own streams
    keys = {search_key(1, 2), trial_key(1, 2, 0), start_key(1, 2), heldout_key(1, 2)}
    assert len({ens.draws(st, k, L)[0][1:].tobytes() for k in keys}) == 4


def test_ensemble_settings_are_checked_and_round_trip():
    e = Ensemble(members=4, pose=2e-3, angle=1.0, friction=0.1)
    assert Ensemble.from_json(e.to_json()) == e
    assert Ensemble.from_json(None) == Ensemble(members=1)  # runs stored before ensembles
    for bad in ({"members": 0}, {"pose": -1.0}, {"friction": 1.5}):
        with pytest.raises(ValueError, match="ensemble"):
            Ensemble(**bad)


def test_one_member_is_todays_single_sample_score():
    ev = Evaluator(BOUNDER, seconds=1.0, batch=32, ensemble=Ensemble(members=1))
    W = np.stack([ev.san.random_weights(0, i) for i in range(32)])
    got = ev(W)
    m = sim.compile_creature(BOUNDER)
    r = sim.rollout(m, ev.san, ev.san.params(W, BOUNDER.san.delay_on, BOUNDER.san.delay_off), 1.0,
                    observer=ev.metric)
    before = scores(ev.metric, r.acc, r.finite, 1.0, "vertical")
    np.testing.assert_array_equal(got.score, before["score"])
    np.testing.assert_array_equal(got.speed_cm_s, before["speed_cm_s"])
    np.testing.assert_array_equal(got.member_score[:, 0], before["score"])


def test_ensemble_scores_are_member_medians_and_do_not_depend_on_the_batch():
    ev = Evaluator(BOUNDER, seconds=1.0, batch=32, ensemble=Ensemble(members=8))
    n = 24
    W = np.stack([ev.san.random_weights(0, i) for i in range(n)])
    keys = [search_key(0, i) for i in range(n)]
    a = ev(W, keys=keys)
    np.testing.assert_array_equal(a.score, np.median(a.member_score, axis=1))
    np.testing.assert_array_equal(a.speed_cm_s, np.median(a.member_speed_cm_s, axis=1))
    assert np.ptp(a.member_score, axis=1).max() > 0  # the members really differ
    b = ev(W[::-1], keys=keys[::-1])
    np.testing.assert_array_equal(a.member_score, b.member_score[::-1])
    c = ev(W[5:9], keys=keys[5:9])  # alone, in a smaller batch
    np.testing.assert_array_equal(a.member_score[5:9], c.member_score)
    single = Evaluator(BOUNDER, seconds=1.0, batch=32, ensemble=Ensemble(members=1))(W)
    np.testing.assert_array_equal(a.member_score[:, 0], single.score)  # member 0: the unperturbed start
    with pytest.raises(ValueError, match="key"):
        ev(W)


def test_robust_statistics_follow_the_majority_and_flag_any_blow_up():
    B, T, K = 3, 1, 5
    score = np.array([[1.0, 2.0, 3.0, 4.0, 0.0], [1.0, 1.0, 1.0, 1.0, 1.0], [5.0, 1.0, 4.0, 2.0, 3.0]]).reshape(B, T, K)
    fell = np.array([[1, 1, 1, 0, 0], [1, 1, 0, 0, 0], [0, 0, 0, 0, 0]], bool).reshape(B, T, K)
    nonfinite = np.array([[0, 0, 0, 0, 1], [0, 0, 0, 0, 0], [0, 0, 0, 0, 0]], bool).reshape(B, T, K)
    out = robust({"score": score, "speed_cm_s": 100 * score, "distance_m": score, "fell": fell, "nonfinite": nonfinite,
                  "dx_m": -score})
    # one blown-up member flags the evaluation and scores it 0, whatever its other members did (a
    # median of 2.0 here); the members' own values are kept
    assert list(out.nonfinite) == [True, False, False]
    assert list(out.score) == [0.0, 1.0, 3.0] and list(out.speed_cm_s) == [0.0, 100.0, 300.0]
    assert list(out.distance_m) == [0.0, 1.0, 3.0] and list(out.dx_m) == [0.0, -1.0, -3.0]
    assert list(out.member_score[0]) == [1.0, 2.0, 3.0, 4.0, 0.0]
    assert list(out.fell) == [True, False, False]  # 3 of 5 fell; 2 of 5 did not make it a fall
    # over several terrains a member's score is its mean, and it fell (or blew up) if it did on any
    two = robust({k: np.concatenate([v, v if k != "score" else 3 * v], axis=1)
                  for k, v in {"score": score, "speed_cm_s": score, "distance_m": score, "fell": fell,
                               "nonfinite": nonfinite}.items()})
    assert list(two.score) == [0.0, 2.0, 6.0] and list(two.nonfinite) == [True, False, False]


def test_records_round_trip_through_json():
    s = Scores(1.5, 25.0, 1.5, True, False, (1.0, 1.5, 2.0), (16.7, 25.0, 33.3))
    assert Scores.from_json(s.to_json()) == s
    old = Scores.from_json({"score": 0.5, "speed_cm_s": 8.0, "fell": False, "nonfinite": False})
    assert old.member_scores == (0.5,) and old.member_speeds == (8.0,)  # stored before ensembles: one member
    phase1 = GaitParams(delay_on=0.1, delay_off=0.12)
    assert phase1.to_json() == {"delay_on": 0.1, "delay_off": 0.12}
    assert GaitParams.from_json(phase1.to_json()) == phase1
    tuned = GaitParams(k1=(10.0, 8.0), k2=(-10.0, -9.0), model={"act_ks": [1.0]}, scale=(1.0, 1.1))
    assert GaitParams.from_json(tuned.to_json()) == tuned
    k1, k2 = phase1.rates(3, 0.5, 0.5)
    assert list(k1) == [10.0] * 3 and list(k2) == pytest.approx([-1 / 0.12] * 3)


def test_the_step_jitter_runs_each_member_at_its_own_step_and_scores_it_over_the_nominal_time():
    from sanlab.creature import loads
    from tests.test_audit import SLED

    ens = Ensemble(members=6, dt=0.2)
    key = search_key(0, 3)
    s = ens.step_scales(key)
    assert s[0] == 1.0 and (np.abs(s - 1) <= 0.2).all() and np.ptp(s) > 0.05
    np.testing.assert_array_equal(s, ens.step_scales(key))  # one stream per evaluation
    assert (Ensemble(members=6).step_scales(key) == 1).all()  # off by default
    st = sim.compile_creature(BOUNDER).structure
    np.testing.assert_array_equal(ens.draws(st, key, 5)[0], Ensemble(members=6).draws(st, key, 5)[0])  # pose draws unchanged
    assert "dt" not in Ensemble(members=6).to_json() and Ensemble.from_json(ens.to_json()) == ens
    with pytest.raises(ValueError, match="dt"):
        Ensemble(dt=0.5)
    # a sled sliding down a slope covers d(t) ~ a t^2 / 2: a member with step s runs s T seconds and,
    # divided by s, scores about s times member 0's distance
    sled = loads(SLED, source="sled.toml")
    ev = Evaluator(sled, seconds=2.0, batch=1, ensemble=Ensemble(members=6, pose=0.0, angle=0.0, dt=0.2))
    W = ev.san.random_weights(0, 0)[None]
    r = ev(W, keys=[key])
    ratio = r.member_score[0] / r.member_score[0, 0]
    np.testing.assert_allclose(ratio, s, rtol=0.02)
    plain = Evaluator(sled, seconds=2.0, batch=1, ensemble=Ensemble(members=6, pose=0.0, angle=0.0))(W, keys=[key])
    # member 0 runs at the creature's own step (the batched-parameter program may differ in the last bits)
    assert r.member_score[0, 0] == pytest.approx(plain.member_score[0, 0], rel=1e-5)


def test_members_at_several_steps_run_each_group_at_its_step_and_score_the_lowest_group():
    """Issue 28's objective: members take the factors on the step in turn; those at dt are
    exactly the plain ensemble's members of the same index (the same draws, the same step), and
    the score is the lower of the two groups' medians."""
    from sanlab.evaluate.ensemble import DEFAULT_DT_FACTORS, default_ensemble

    san_w = np.stack([Evaluator(BOUNDER).san.random_weights(0, i) for i in range(4)])
    keys = [search_key(0, i) for i in range(4)]
    plain = Evaluator(BOUNDER, seconds=1.0, batch=4, ensemble=Ensemble(4))(san_w, keys=keys)
    two = Evaluator(BOUNDER, seconds=1.0, batch=4, ensemble=Ensemble(4, dt_factors=(1.0, 0.5)))(san_w, keys=keys)
    np.testing.assert_array_equal(two.member_score[:, 0::2], plain.member_score[:, 0::2])
    assert not np.array_equal(two.member_score[:, 1::2], plain.member_score[:, 1::2])  # dt/2: another trajectory
    groups = np.stack([np.median(two.member_score[:, 0::2], 1), np.median(two.member_score[:, 1::2], 1)], 1)
    np.testing.assert_allclose(two.score, np.where(two.nonfinite, 0.0, groups.min(1)))
    # the default of searches and tuning, except for one member (a single unperturbed rollout)
    assert default_ensemble(8).dt_factors == DEFAULT_DT_FACTORS == (1.0, 0.5)
    assert default_ensemble(1).dt_factors == (1.0,)


def test_step_factors_are_checked_stored_and_older_runs_read_as_one_step():
    e = Ensemble(8, dt_factors=(1.0, 0.5))
    assert Ensemble.from_json(e.to_json()) == e and e.to_json()["dt_factors"] == [1.0, 0.5]
    assert "dt_factors" not in Ensemble(8).to_json()  # a plain ensemble's settings read as before
    assert Ensemble.from_json({"members": 8}).dt_factors == (1.0,)
    assert [list(g) for g in Ensemble(5, dt_factors=(1.0, 0.5)).groups()] == [[0, 2, 4], [1, 3]]
    for bad in ((0.5, 1.0), (1.0, 2.0), (1.0, 1.0), (), (1.0, 0.0)):
        with pytest.raises(ValueError, match="dt_factors"):
            Ensemble(8, dt_factors=bad)
    with pytest.raises(ValueError, match="at least as many members"):
        Ensemble(1, dt_factors=(1.0, 0.5))


POWERED_CHANGES = (("mass", "0.001"), ("ks", "1e6"), ("kd", "0.0"))


def powered_bounder() -> str:
    """Issue 28's case: the built-in bounder with every link at 1 g, servos at ks = 1e6 N m/deg and
    kd = 0, ground stiffness 1000 N/m (it scored 251 m/s under --metric distance)."""
    import re

    text, _ = creature.read_source("bounder")
    for field, value in POWERED_CHANGES:
        text = re.sub(rf"^{field} = [0-9.]+", f"{field} = {value}", text, flags=re.M)
    return text.replace("gravity = 9.81\n", "gravity = 9.81\n\n[world.ground]\nstiffness = 1000.0\n", 1)


def test_a_creature_whose_servos_the_step_cannot_resolve_scores_nothing():
    from sanlab.check import resolution
    from sanlab.evaluate.resolution import Servos

    spec = creature.loads(powered_bounder(), source="powered.toml")
    assert [a.ks for a in spec.actuators] == [pytest.approx(1e6 * 180 / math.pi)] * 4
    ev = Evaluator(spec, metric="distance", seconds=1.0, batch=8, ensemble=Ensemble(2))
    w = np.stack([ev.san.random_weights(0, i) for i in range(8)])
    r = ev(w, keys=[search_key(0, i) for i in range(8)])
    assert r.nonfinite.all() and (r.score == 0).all() and (r.speed_cm_s == 0).all()
    warned = [f for f in resolution(spec) if f.warning]
    assert len(warned) == 4 and "cannot follow it" in warned[0].message
    # the same servos with enough damping settle within a step, as the implicit step settles them
    damped = creature.loads(powered_bounder().replace("kd = 0.0", "kd = 1e6"), source="damped.toml")
    sv = Servos.of(damped)
    assert not sv.unresolved([a.ks for a in damped.actuators], [a.kd for a in damped.actuators], damped.dt)
    from sanlab.creature.files import builtin_names

    for name in builtin_names():  # every built-in is resolved
        assert not [f for f in resolution(creature.load(name)) if f.warning], name


def test_a_creature_whose_joint_spring_the_step_cannot_resolve_scores_nothing():
    """Issue 48: the twolink with a 1e6 N m/deg undamped joint spring at a 90 degree rest angle
    topped the search table at 67 cm/s (4x the built-in) unflagged; now every evaluation of it is
    flagged as a servo of that stiffness is, and scores 0."""
    text, _ = creature.read_source("twolink")
    text = text.replace("anchor = [0.2, 0.0]", "anchor = [0.2, 0.0]\nspring = { stiffness = 1e6, rest_deg = 90 }", 1)
    spec = creature.loads(text, source="sprung.toml")
    ev = Evaluator(spec, metric="distance", seconds=0.2, batch=4, ensemble=Ensemble(1))
    w = np.stack([ev.san.random_weights(0, i) for i in range(4)])
    r = ev(w, keys=[search_key(0, i) for i in range(4)])
    assert r.nonfinite.all() and (r.score == 0).all() and (r.speed_cm_s == 0).all()
