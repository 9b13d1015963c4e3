"""Evaluation metrics (paper §5.1) against cases with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.creature.spec import Creature, Evaluation, Follow, Ground, Link, Shape, World
from sanlab.evaluate import Ensemble, Evaluator
from sanlab.metrics import Metric, scores

G = 9.81


def box(name="box", w=0.4, h=0.1, m=2.0, **kw):
    pts = ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2))
    return Link(name, m, m * (w * w + h * h) / 12, (0.0, 0.0), Shape("polygon", pts), contacts=pts, **kw)


def evaluate(spec, kind, qd0=None, q0=None, seconds=1.0):
    m = sim.compile_creature(spec, "float64")
    metric = Metric.for_creature(spec, kind)
    q = m.params.q0 if q0 is None else np.asarray(q0, np.float64)
    qd = np.zeros_like(q) if qd0 is None else np.asarray(qd0, np.float64)
    s0 = sim.make_state(m, q, qd)
    r = sim.rollout(m, sim.ConstantController(), np.zeros((1, 0)), seconds, observer=metric, state0=s0)
    return {k: v[0] for k, v in scores(metric, r.acc, r.finite, seconds, spec.world.plane).items()}


def resting_box(mu=0.5, **ev):
    k = 5.0e4
    link = box(position=(0.0, 0.05 - 2.0 * G / (2 * k)))
    world = World(ground=Ground(stiffness=k, damping=300.0, friction=mu))
    return Creature("box", (link,), world=world, evaluation=Evaluation(**ev))


def test_distance_is_how_far_the_centre_of_mass_got_either_way():
    mu = 0.5
    for v0 in (1.5, -1.5):
        r = evaluate(resting_box(mu), "distance", qd0=[v0, 0, 0], seconds=1.0)
        expected = v0 * v0 / (2 * mu * G)  # slides to a stop
        assert r["score"] == pytest.approx(expected, rel=0.03)
        assert r["speed_cm_s"] == pytest.approx(expected * 100, rel=0.03)
        assert not r["fell"] and not r["nonfinite"]


def test_distance_upright_is_zero_once_the_creature_fell():
    spec = resting_box(0.5, metric="distance_upright", fell_links=("box",), fell_angle=math.radians(60))
    ok = evaluate(spec, None, qd0=[1.0, 0, 0])
    assert ok["score"] > 0.05 and not ok["fell"]
    # thrown into a somersault: it moves, but it fell
    flipped = evaluate(spec, None, q0=[0.0, 0.3, 0.0], qd0=[1.0, 2.0, 15.0])
    assert flipped["fell"] and flipped["score"] == 0.0 and flipped["speed_cm_s"] > 0


def test_hopping_adds_the_integral_of_squared_height_above_the_start():
    spec = resting_box(0.5, metric="hopping", hop_k=3.0)
    v0 = 2.0
    r = evaluate(spec, None, qd0=[0.0, v0, 0.0], seconds=1.0)
    t = np.linspace(0, 2 * v0 / G, 20001)
    hop = np.trapezoid((v0 * t - G * t * t / 2) ** 2, t)  # in the air until it lands again
    assert r["score"] == pytest.approx(3.0 * hop, rel=0.03)
    assert r["distance_m"] < 1e-3


def test_pursuit_integrates_velocity_towards_the_follow_point():
    dot = Link("dot", 1.0, 0.0, (0.0, 0.0), Shape("point"), contacts=())
    spec = Creature(
        "dot",
        (dot,),
        world=World(plane="horizontal", ground=Ground(friction=0.0), follow=Follow(((10.0, 0.0), (10.0, 1.0)), 0.0)),
        evaluation=Evaluation(metric="pursuit"),
    )
    towards = evaluate(spec, None, qd0=[0.5, 0.0], seconds=2.0)
    assert towards["score"] == pytest.approx(1.0, rel=1e-3)  # 0.5 m/s straight at it for 2 s
    # for a still target the integral is the decrease of the distance to it
    across = evaluate(spec, None, qd0=[0.0, 0.5], seconds=2.0)
    assert across["score"] == pytest.approx(10.0 - math.hypot(10.0, 1.0), rel=1e-3)
    away = evaluate(spec, None, qd0=[-0.5, 0.0], seconds=2.0)
    assert away["score"] == pytest.approx(-1.0, rel=1e-3)


def test_tracking_is_the_start_distance_over_the_mean_distance_to_the_follow_point():
    dot = Link("dot", 1.0, 0.0, (0.0, 0.0), Shape("point"), contacts=())

    def spec(points, speed):
        world = World(plane="horizontal", ground=Ground(friction=0.0), follow=Follow(points, speed))
        return Creature("dot", (dot,), world=world, evaluation=Evaluation(metric="tracking"))

    still = spec(((10.0, 0.0), (10.0, 1.0)), 0.0)
    # 0.5 m/s straight at a still point 10 m away for 2 s: the distance falls from 10 to 9 m
    towards = evaluate(still, None, qd0=[0.5, 0.0], seconds=2.0)
    assert towards["score"] == pytest.approx(10.0 / 9.5, rel=1e-3)
    away = evaluate(still, None, qd0=[-0.5, 0.0], seconds=2.0)
    assert away["score"] == pytest.approx(10.0 / 10.5, rel=1e-3)
    # across: the distance is hypot(10, 0.5 t), whose mean exceeds 10 by about 1/60 m
    t = np.linspace(0.0, 2.0, 20001)
    across = evaluate(still, None, qd0=[0.0, 0.5], seconds=2.0)
    assert across["score"] == pytest.approx(10.0 / np.hypot(10.0, 0.5 * t).mean(), rel=1e-4)
    # a still creature, the point leaving it at 0.5 m/s: 1 m at the start, 1.5 m on average
    leaving = evaluate(spec(((1.0, 0.0), (3.0, 0.0)), 0.5), None, seconds=2.0)
    assert leaving["score"] == pytest.approx(1.0 / 1.5, rel=1e-3)
    # keeping pace with it keeps the start distance: 1
    pace = evaluate(spec(((1.0, 0.0), (3.0, 0.0)), 0.5), None, qd0=[0.5, 0.0], seconds=2.0)
    assert pace["score"] == pytest.approx(1.0, rel=1e-6)
    assert pace["speed_cm_s"] == pytest.approx(50.0, rel=1e-6)


def test_a_run_that_blows_up_scores_zero_and_is_flagged():
    spec = resting_box()
    m = sim.compile_creature(spec)
    metric = Metric.for_creature(spec, "distance")
    q = np.stack([m.params.q0, m.params.q0])
    qd = np.array([[1.0, 0.0, 0.0], [np.nan, 0.0, 0.0]], np.float32)
    s0 = sim.make_state(m, q, qd)
    r = sim.rollout(m, sim.ConstantController(), np.zeros((2, 0)), 0.5, observer=metric, state0=s0)
    out = scores(metric, r.acc, r.finite, 0.5, "vertical")
    assert list(out["nonfinite"]) == [False, True]
    assert out["score"][1] == 0.0 and out["score"][0] > 0


def test_unknown_metric_and_missing_follow_point_are_clear_errors():
    spec = creature.load("cart")
    with pytest.raises(ValueError, match="expected one of"):
        Metric.for_creature(spec, "speediness")
    for kind in ("pursuit", "tracking"):
        with pytest.raises(ValueError, match=f"metric {kind} needs a follow point"):
            Metric.for_creature(spec, kind)


def test_evaluator_scores_do_not_depend_on_batch_composition():
    spec = creature.load("bounder")
    ev = Evaluator(spec, seconds=1.0, batch=64, ensemble=Ensemble(members=1))
    W = np.stack([ev.san.random_weights(0, i) for i in range(40)])
    a = ev(W)
    b = ev(W[::-1])
    np.testing.assert_array_equal(a.score, b.score[::-1])
    assert np.ptp(a.score) > 0


def test_direction_forward_counts_only_motion_along_plus_x():
    # The same slide to the left and to the right, scored with direction "forward": +d to the
    # right, -d to the left (the wrong way ranks below standing still); "backward" the mirror.
    mu = 0.5
    d = 1.5 * 1.5 / (2 * mu * G)
    for direction, sign in (("forward", 1.0), ("backward", -1.0)):
        spec = resting_box(mu, direction=direction)
        right = evaluate(spec, "distance", qd0=[1.5, 0, 0])
        left = evaluate(spec, "distance", qd0=[-1.5, 0, 0])
        assert right["score"] == pytest.approx(sign * d, rel=0.03)
        assert left["score"] == pytest.approx(-sign * d, rel=0.03)
        assert right["dx_m"] == pytest.approx(d, rel=0.03) and left["dx_m"] == pytest.approx(-d, rel=0.03)
        assert right["speed_cm_s"] == pytest.approx(100 * sign * d, rel=0.03)


def test_a_low_centre_of_mass_means_fallen_and_a_fallen_hop_scores_zero():
    # A box lying on the ground with its COM 5 cm up: with fell_com_height = 0.1 it has fallen
    # (upright by angle, but down by height, like a hopper lying with its torso upright on its
    # hip); with 0.02 it has not. A fallen hopper scores 0 like distance_upright.
    low = evaluate(resting_box(0.5, metric="hopping", fell_com_height=0.1), None, qd0=[1.0, 0, 0])
    assert low["fell"] and low["score"] == 0.0
    ok = evaluate(resting_box(0.5, metric="hopping", fell_com_height=0.02), None, qd0=[1.0, 0, 0])
    assert not ok["fell"] and ok["score"] > 0.05
    # the same criterion on a fell link's own centre of mass
    by_link = evaluate(resting_box(0.5, metric="distance_upright", fell_links=("box",), fell_link_height=0.1), None,
                       qd0=[1.0, 0, 0])
    assert by_link["fell"] and by_link["score"] == 0.0


def test_a_run_that_sank_into_the_ground_is_flagged_like_a_non_finite_one():
    from sanlab.creature import load
    from sanlab.metrics import MetricAcc, max_depth, scores

    spec = load("bounder")
    m = Metric.for_creature(spec)
    assert m.max_depth == max_depth(spec) == 0.1  # a quarter of 0.57 m, clamped to 10 cm
    assert Metric.for_creature(load("fish")).max_depth is None  # horizontal plane: no ground to sink into
    two = np.zeros(2)
    acc = MetricAcc((two, two), two, two, two, np.zeros(2, bool), (np.array([0.5, 0.5]), two), np.array([0.01, 0.5]))
    s = scores(m, acc, np.array([True, True]), 6.0, "vertical")
    assert s["sank"].tolist() == [False, True] and s["nonfinite"].tolist() == [False, True]
    assert s["score"].tolist() == [0.5, 0.0] and s["speed_cm_s"][1] == 0.0
