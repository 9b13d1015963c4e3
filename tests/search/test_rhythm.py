"""The rhythm search's clocks (``sanlab.search.rhythm``): a SAN built from a pattern plays that
pattern, step for step, from its first step; the search drives toward a known best rhythm; and
its gaits are scored, stored, replayed and audited as the SANs they are."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sanlab import __version__, creature
from sanlab.evaluate import ScoreBatch
from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.evaluator import Evaluator
from sanlab.library import Library
from sanlab.search.base import Problem
from sanlab.search.pattern import decode
from sanlab.search.rhythm import ReflexSearch, RhythmSearch, bias_sensor, clock
from sanlab.search.space import Space


def targets(space: Space, c, steps: int, rng) -> np.ndarray:
    """The actuator targets [steps, A] (rad or m) the clock's SAN asks for, stepped in NumPy
    (``San.step``, the kernel's arithmetic) with its bias on and every other sensor at random."""
    san, spec = space.san, space.spec
    k1, k2, over = space._arrays(c.theta)
    params = san.params(c.weights, 1.0, 1.0)._replace(k1=k1, k2=k2)
    istate, out = np.zeros(san.n_nodes), np.zeros(san.n_nodes)
    bias = bias_sensor(space)
    rows = []
    for _ in range(steps):
        bits = rng.integers(0, 2, san.n_sensors).astype(float)
        if bias is not None:
            bits[bias] = 1.0
        else:  # a touch-only creature: its feet on the ground at rest latch the clock's bias on
            bits[[i for i, x in enumerate(spec.sensors) if x.kind == "touch"]] = 1.0
        istate, out, u = san.step(params, istate, out, bits, spec.dt)
        rows.append(over["act_min"] + u * (over["act_max"] - over["act_min"]))
    return np.array(rows)


def wanted(spec, pattern: np.ndarray, steps: int) -> np.ndarray:
    """The pattern's targets [steps, A] (``sim.PatternController``'s rule) at the end of each step."""
    A = len(spec.actuators)
    t = np.arange(1, steps + 1) * spec.dt
    lo, hi = np.array([a.min for a in spec.actuators]), np.array([a.max for a in spec.actuators])
    out = np.empty((steps, A))
    for a in range(A):
        up = np.mod(t / pattern[4 * A] - pattern[4 * a], 1.0) < pattern[4 * a + 1]
        level = np.where(up, pattern[4 * a + 3], pattern[4 * a + 2])
        out[:, a] = lo[a] + level * (hi[a] - lo[a])
    return out


@pytest.mark.parametrize("name", ["bounder", "walker", "cart", "fish", "crawler", "fourlink"])
def test_a_clock_plays_its_pattern_from_the_first_step(name):
    spec = creature.load(name)
    space = Space(spec)
    rng = np.random.default_rng(56)
    played = 0
    for _ in range(6):
        pattern = decode(rng.uniform(0, 1, 2 * len(spec.actuators) + 1), len(spec.actuators))
        pattern[-1] = rng.uniform(0.15, 0.9)  # periods whose halves the delays can hold (0.01-1 s)
        pattern[1:-1:4] = rng.uniform(0.15, 0.85, len(spec.actuators))
        c = clock(space, pattern)
        assert space.valid(c.theta)
        if c.slip:
            continue  # the followers could not all keep their phase: a slip, said, not hidden
        played += 1
        steps = int(round(3 * pattern[-1] / spec.dt))
        got, want = targets(space, c, steps, rng), wanted(spec, pattern, steps)
        # the same two levels (where the widened range fits the actuator's bounds) ...
        assert np.allclose(np.unique(np.round(got, 9)), np.unique(np.round(want, 9)))
        # ... switched on the same steps, but for a step of rounding and the node's one-step lag
        # at each edge, from the very first step (every node starts off, as the SAN starts)
        edges = int(np.count_nonzero(np.diff(want, axis=0))) + len(spec.actuators)
        assert np.count_nonzero(~np.isclose(got, want)) <= 2 * edges
    assert played >= 3


def test_a_range_too_wide_to_widen_gets_a_twin_and_switches_end_to_end():
    spec = creature.load("cart")  # one actuator, -140..140 deg: doubled it would pass 180
    space = Space(spec)
    pattern = decode(np.array([0.3, 0.4, 0.5]), 1)
    c = clock(space, pattern)
    H = space.san.n_hidden
    S = space.san.n_sensors
    drive = c.weights[H, S:S + H]
    assert np.count_nonzero(drive) == 2  # its clock node and the twin
    got = targets(space, c, 2000, np.random.default_rng(0))[:, 0]
    assert np.isclose(got.min(), spec.actuators[0].min) and np.isclose(got.max(), spec.actuators[0].max)


def test_with_fewer_nodes_than_actuators_the_others_follow_a_node_or_its_inverse():
    from pathlib import Path

    spec = creature.load_file(Path(__file__).parent.parent / "data" / "caterpillar.toml")
    assert (spec.n_hidden, len(spec.actuators)) == (2, 4)  # one node for the clock beside the latch
    space = Space(spec)
    # two segments in phase and two against them, half on: all from one node and its inverse
    pattern = decode(np.array([0.1, 0.5, 0.1, 0.5, 0.6, 0.5, 0.6, 0.5, 0.6]), 4)
    c = clock(space, pattern)
    assert c.slip <= 8  # a step of rounding at each edge
    H, S = space.san.n_hidden, space.san.n_sensors
    assert sorted(c.weights[H:, S].tolist()) == [-2, -2, 2, 2]  # every actuator from node 1, two inverted
    steps = int(round(3 * pattern[-1] / spec.dt))
    got, want = targets(space, c, steps, np.random.default_rng(1)), wanted(spec, pattern, steps)
    # its only sensors are touch sensors: a hidden node latched on by them is the bias, 10 ms (its
    # shortest delay) after the start; with no node to spare for a root of its own, node 1 is the
    # root and the rhythm starts where that one switches off: the pattern's, some steps late
    assert bias_sensor(space) is None and c.weights[H - 1, S + H - 1] == 2
    P = int(round(pattern[-1] / spec.dt))
    lag = min(range(1, P), key=lambda k: np.count_nonzero(~np.isclose(got[k:], want[:-k])))
    edges = int(np.count_nonzero(np.diff(want, axis=0))) + 4
    assert np.count_nonzero(~np.isclose(got[lag:], want[:-lag])) <= 2 * edges
    # a rhythm the shared nodes cannot play says so in its slip
    assert clock(space, decode(np.array([0.1, 0.5, 0.2, 0.3, 0.6, 0.7, 0.9, 0.2, 0.6]), 4)).slip > 50


def test_a_clock_needs_a_hidden_node_and_a_bias():
    walker = creature.load("walker")
    none = dataclasses.replace(walker, san=dataclasses.replace(walker.san, hidden=0))
    with pytest.raises(ValueError, match="hidden node"):
        clock(Space(none), decode(np.full(11, 0.5), 5))
    bounder = creature.load("bounder")
    blind = dataclasses.replace(bounder, sensors=())
    with pytest.raises(ValueError, match="a sensor to start it"):
        clock(Space(blind), decode(np.full(9, 0.5), 4))
    touch_only = dataclasses.replace(bounder, sensors=bounder.sensors[:2], san=dataclasses.replace(bounder.san, hidden=1))
    with pytest.raises(ValueError, match="besides the one a touch sensor latches on"):
        clock(Space(touch_only), decode(np.full(9, 0.5), 4))


def test_the_rhythm_search_drives_toward_a_known_best_period(tmp_path):
    spec = creature.load("cart")
    space = Space(spec)
    ton = [i for i, p in enumerate(space.params) if p.kind == "t_on"]
    toff = [i for i, p in enumerate(space.params) if p.kind == "t_off"]

    def score(c) -> float:
        if c.idx < 6:  # the warm-up's random SANs: any score below the clocks'
            return -10.0
        period = c.theta[ton[0]] + c.theta[toff[0]]  # the root's cycle
        return -abs(period - 0.6)

    with Library(str(tmp_path / "a.db")) as lib:
        run_id = lib.create_run("search", "cart", "text", {}, seed=0, total=1, sanlab_version=__version__).run_id
        s = RhythmSearch(Problem(run_id, space.san, 40 * 12 + 6, seed=2, space=space, generation=12))
        assert s.warmup == 81  # a sixth of the budget
        told = []
        while not s.done:
            cands = s.ask(64)
            x = [score(c) for c in cands]
            told += x
            b = np.asarray(x)
            no = np.zeros(len(b), bool)
            t = s.tell(cands, ScoreBatch(b, b, b, no, no, b[:, None], b[:, None]))
            lib.commit(t.evaluations, t.trace, t.finished)
        clocks = told[81:]
        assert max(clocks[:12]) < max(clocks) and max(clocks) > -0.01  # within 10 ms of the best period
        stored = lib.top(run_id, None)
        warm = [e for e in stored if e.idx < 81]
        assert all("k1" not in e.params for e in warm)  # stored as a random search stores its SANs
        assert all("k1" in e.params and "model" in e.params for e in stored if e.idx >= 81)


def test_a_rhythm_gait_replays_and_audits_at_its_stored_score(tmp_path):
    from sanlab.audit import audit
    from sanlab.gait import Gait
    from sanlab.search.runner import run_search

    text, source = creature.read_source("twolink")
    with Library(str(tmp_path / "a.db")) as lib:
        run_id = run_search(lib, text, source, controllers=44, seed=1, batch=32, strategy="rhythm", ensemble=2,
                            seconds=2.0)
        best = next(e for e in lib.top(run_id, None) if e.idx >= 7)  # a clock, not a warm-up SAN
        g = Gait.from_library(lib, best.gait_id)
        space = Space(g.spec)
        ev = Evaluator(g.spec, seconds=g.seconds, ensemble=g.ensemble, space=space, batch=1)
        again = ev(g.weights[None], space.nominal(g.params)[None], [search_key(1, best.idx)])
        assert float(again.score[0]) == best.score  # bit for bit: delays, ranges and all
        a = audit(lib, best.gait_id, members=4, max_members=4)
        assert a.nominal_cm_s == pytest.approx(best.speed_cm_s, abs=1e-9)  # re-scored as stored


def test_reflexes_move_only_the_sensors_weights_to_the_actuators_of_the_best_clock(tmp_path):
    spec = creature.load("cart")
    space = Space(spec)
    H, S = space.san.n_hidden, space.san.n_sensors
    bias = bias_sensor(space)
    target = next(s for s in range(S) if s != bias)  # the toy's best reflex: this sensor, +2, to the actuator

    def score(c) -> float:
        if c.idx < 48:  # the warm-up's random SANs: below any clock
            return -10.0
        return 1.0 + 0.5 * float(c.weights[H, target]) - 0.1 * float(np.count_nonzero(c.weights[H, :S]))

    with Library(str(tmp_path / "a.db")) as lib:
        run_id = lib.create_run("search", "cart", "text", {}, seed=0, total=1, sanlab_version=__version__).run_id
        s = ReflexSearch(Problem(run_id, space.san, 288, seed=2, space=space, generation=12))
        assert s.warmup == 48 and s.reflex_from == 15  # 180 clocks (15 generations), then 60 reflexes
        cands = []
        while not s.done:
            asked = s.ask(64)
            cands += asked
            b = np.asarray([score(c) for c in asked])
            no = np.zeros(len(b), bool)
            t = s.tell(asked, ScoreBatch(b, b, b, no, no, b[:, None], b[:, None]))
            lib.commit(t.evaluations, t.trace, t.finished)
        clocks = [c for c in cands if 48 <= c.idx < 48 + 180]
        reflexes = [c for c in cands if c.idx >= 48 + 180]
        assert len(reflexes) == 60 and max(score(c) for c in reflexes) > max(score(c) for c in clocks)
        assert max(int(c.weights[H, target]) for c in reflexes) == 2  # the best reflex found
        for c in reflexes:  # the clock's nodes, its delays and ranges, and the bias untouched
            base = next(k for k in clocks if np.array_equal(k.weights[:H], c.weights[:H]))
            assert np.array_equal(c.theta, base.theta) and c.weights[H, bias] == base.weights[H, bias]
            assert np.array_equal(c.weights[H:, S:], base.weights[H:, S:])
    plain = RhythmSearch(Problem("r", space.san, 288, seed=2, space=space, generation=12))
    assert plain.reflex_from > (288 - 48) // 12  # the rhythm search alone has none


def test_phase_two_on_a_clock_search_starts_one_chain_on_the_warm_ups_best_san(tmp_path):
    """Issue 56: a clock is an open loop; the k - 1 best and the best random SAN of the warm-up
    start phase 2 where no warm-up SAN is among the k best. Other searches: the k best."""
    from sanlab.search.rhythm import WARMUP, starts
    from sanlab.search.runner import run_search

    text, source = creature.read_source("twolink")
    with Library(str(tmp_path / "a.db")) as lib:
        run_id = run_search(lib, text, source, controllers=96, seed=1, batch=32, strategy="rhythm", ensemble=2,
                            seconds=2.0)
        n = int(96 * WARMUP)
        ranked = lib.top(run_id, None)
        warm = next(e for e in ranked if e.idx < n)
        assert all(e.idx >= n for e in ranked[:3]), "the test wants clocks ahead of every warm-up SAN"
        got = starts(lib, run_id, 3)
        assert [e.idx for e in got] == [ranked[0].idx, ranked[1].idx, warm.idx]
        assert [e.idx for e in starts(lib, run_id, 1)] == [ranked[0].idx]  # one chain: the best
        plain = run_search(lib, text, source, controllers=16, seed=1, batch=16, ensemble=2, seconds=2.0)
        assert [e.idx for e in starts(lib, plain, 3)] == [e.idx for e in lib.top(plain, 3)]
