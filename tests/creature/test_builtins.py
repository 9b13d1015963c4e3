"""The ten built-in creatures of the paper's Table 1: they load, have the paper's sizes, stay
finite under random networks, and a small phase-1 search finds each of them a gait that moves."""

from __future__ import annotations

import numpy as np
import pytest

from sanlab import sim
from sanlab.creature import builtin_names, load, read_source
from sanlab.creature.table1 import TABLE1
from sanlab.library import Library
from sanlab.metrics import Metric
from sanlab.san import San
from sanlab.search import run_search

NAMES = sorted(TABLE1)
TRACKERS = {"fish", "crawler"}  # the two that pursue the follow point (§6)


def test_every_creature_of_table_1_is_built_in():
    assert set(TABLE1) <= set(builtin_names())


@pytest.mark.parametrize("name", NAMES)
def test_counts_match_table_1(name):
    c = load(name)
    assert c.name == name and c.description
    counts = (len(c.links), len(c.sensors), len(c.actuators), c.san.hidden)
    assert counts == TABLE1[name][:4]


@pytest.mark.parametrize("name", NAMES)
def test_paper_conventions(name):
    c = load(name)
    assert 0.07 <= c.san.delay_on <= 0.15 and 0.07 <= c.san.delay_off <= 0.15  # §4
    tracker = name in TRACKERS
    # §5.1 scores the trackers by pursuit; the crawler, whose row has no speed, by how close it keeps
    assert (c.evaluation.metric in ("pursuit", "tracking")) == tracker
    assert c.evaluation.metric == {"fish": "pursuit", "crawler": "tracking"}.get(name, c.evaluation.metric)
    assert c.evaluation.seconds == (30.0 if tracker else 6.0)  # §6
    assert (c.world.plane == "horizontal") == tracker
    if c.evaluation.metric == "distance_upright":
        assert c.evaluation.fell_link is not None


@pytest.mark.parametrize("name", sorted(TRACKERS))
def test_trackers_have_eyes_and_a_follow_point(name):
    c = load(name)
    assert c.world.follow is not None and c.world.follow.speed > 0
    assert any(s.kind == "eye" for s in c.sensors)


def test_fish_has_a_passive_caudal_fin_and_swims_in_water():
    c = load("fish")
    assert c.world.water_drag > 0 and c.world.ground.friction == 0
    assert c.link("L4").spring is not None and c.link("L4").parent == "L3"
    assert {a.joint for a in c.actuators} == {"L2", "L3"}  # no motor on the fin's joint


def test_crawler_is_four_point_masses_that_slide_forward_more_easily():
    c = load("crawler")
    assert all(link.is_point for link in c.links)
    assert all(link.friction.forward < link.friction.backward for link in c.links)
    assert all(link.friction.axis is not None for link in c.links)
    assert all(a.kind == "linear" for a in c.actuators)
    assert any(s.kind == "length" for s in c.sensors)
    assert all(s.axis is not None for s in c.sensors if s.kind == "eye")


def test_twolink_has_one_link_heavier_than_the_other():
    c = load("twolink")
    assert c.links[0].mass != c.links[1].mass  # §6.1: symmetry would stop it


@pytest.mark.parametrize("name", sorted(set(NAMES) - TRACKERS))
def test_starts_at_rest_on_the_ground(name):
    """Every creature in the vertical plane starts touching the ground but not inside it."""
    m = sim.compile_creature(load(name), "float64")
    depth = np.asarray(sim.poses(m, m.params.q0)["depth"])
    assert depth.max() == pytest.approx(0.0, abs=1e-4)


SECONDS, BATCH = 6.0, 256


@pytest.mark.slow  # about 4 s on 2 busy cores (the pre-commit subset leaves it out)
@pytest.mark.parametrize("name", NAMES)
def test_1000_random_networks_stay_finite_for_6_s(name):
    """Every built-in under 1000 random SANs for 6 s, in batches of 256 (one compiled program
    for the four): no NaN, and the ground stays stiff (the first 200 sink at most 2.5 cm, every
    one at most 5 cm; the deepest, the fourlink's hardest landings: 99th percentile 2.0 cm, the
    deepest of 1000 2.8 cm, on the kernel in float64)."""
    spec = load(name)
    san = San.for_creature(spec)
    model, metric = sim.compile_creature(spec), Metric.for_creature(spec)
    depth = []
    for first in range(0, 1000, BATCH):
        W = np.stack([san.random_weights(5, i) for i in range(first, min(1000, first + BATCH))])
        p = san.params(W, spec.san.delay_on, spec.san.delay_off)
        r = sim.rollout(model, san, p, SECONDS, observer=metric)
        assert bool(np.all(np.asarray(r.finite)))
        assert np.isfinite(np.asarray(r.state.q)).all()
        depth += list(np.asarray(r.max_depth))
    assert max(depth[:200]) < 0.025 and max(depth) < 0.05  # penetration stays around a centimetre or two


@pytest.mark.slow  # about 3 s on 2 busy cores (the pre-commit subset leaves it out)
@pytest.mark.parametrize("name", NAMES)
def test_a_small_search_finds_a_gait_that_moves(name, tmp_path):
    """Phase 1 in miniature: 64 random networks, 6 s each."""
    text, where = read_source(name)
    n = 64
    with Library(str(tmp_path / "gaits.db")) as lib:
        run_id = run_search(lib, text, where, controllers=n, seconds=SECONDS, seed=0, batch=BATCH)
        top = lib.top(run_id, n)
    assert len(top) == n and not any(e.nonfinite for e in top)
    best = top[0].score
    if name in TRACKERS:
        assert best > 0.1  # m gained towards the follow point in 6 s
    else:
        # the score is the distance (m) moved, 0 for a fall: more than 3 cm/s without falling
        assert best / SECONDS * 100 > 3.0
