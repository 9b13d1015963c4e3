"""The CMA-ES strategies (``catcma``, ``pattern``) find a known best on toy objectives, and the
pattern search's vectors decode into patterns the kernel can play.

The toy objectives stand in for the simulator as in test_strategies.py (which checks the ask/tell
contract and resuming on every registered strategy): a score that is highest at one known point
of the strategy's space, driven through a real library as the driver drives it.
"""

from __future__ import annotations

import numpy as np
import pytest

from sanlab import __version__, creature
from sanlab.evaluate import ScoreBatch
from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.records import GaitParams
from sanlab.library import Library
from sanlab.san import San
from sanlab.search.base import Problem
from sanlab.search.catcma import CatCma, population
from sanlab.search.pattern import PERIOD_RANGE, PatternSearch, decode

SPEC = creature.load("cart")
SAN = San.for_creature(SPEC)


def batch(scores: list[float]) -> ScoreBatch:
    s = np.asarray(scores, float)
    no = np.zeros(len(s), bool)
    return ScoreBatch(s, s, s, no, no, s[:, None], s[:, None])


def drive(strategy, lib: Library, score) -> list[float]:
    """Ask and tell until done, committing as the driver does; the told scores in order."""
    told = []
    while not strategy.done:
        cands = strategy.ask(64)
        s = [score(c) for c in cands]
        told += s
        t = strategy.tell(cands, batch(s))
        lib.commit(t.evaluations, t.trace, t.finished)
    return told


def run(lib: Library) -> str:
    return lib.create_run("search", "cart", "text", {}, seed=0, total=1, sanlab_version=__version__).run_id


def test_catcma_finds_the_weights_of_a_known_best(tmp_path):
    small = San(3, 2, 1)  # 3 x 6 = 18 weights: the toy runs in a second
    target = small.random_weights(7, 0)  # any SAN: the toy's best
    score = lambda c: -float(np.sum((c.weights.astype(float) - target) ** 2))
    with Library(str(tmp_path / "a.db")) as lib:
        s = CatCma(Problem(run(lib), small, 1500, seed=1, gait_params=GaitParams(0.1, 0.1)))
        assert s.popsize == population(small.n_weights) == 12  # 4 + floor(3 ln 18)
        assert population(SAN.n_weights) == 16  # the cart's 72 weights
        told = drive(s, lib, score)
        first, last = max(told[:s.popsize]), max(told)
        assert last == 0.0  # every one of the 18 weights found
        assert first < -10  # and not by a lucky first draw
        best = lib.top(s.run_ids[0], 1)[0]
        assert np.array_equal(small.decode(best.encoding), target)
        assert best.params == {"delay_on": 0.1, "delay_off": 0.1}  # a phase-1 gait: the file's delays


def test_the_pattern_search_finds_a_known_best_pattern(tmp_path):
    A = SAN.n_actuators
    want = decode(np.array([0.3, 0.6] * A + [0.5]), A)

    def score(c):
        p = c.pattern
        phase = np.abs((p[0:4 * A:4] - want[0:4 * A:4] + 0.5) % 1.0 - 0.5)  # round the cycle
        rest = [i for i in range(4 * A + 1) if i % 4 != 0 or i == 4 * A]
        return -float(np.sum(phase**2) + np.sum((p[rest] - want[rest]) ** 2))

    with Library(str(tmp_path / "a.db")) as lib:
        s = PatternSearch(Problem(run(lib), SAN, 1600, seed=2, generation=16))
        told = drive(s, lib, score)
        assert max(told) > -1e-4
        best = lib.top(s.run_ids[0], 1)[0]
        got = np.asarray(best.params["pattern"])
        np.testing.assert_allclose(got[-1], want[-1], rtol=0.02)  # the period, s
        assert not best.params.keys() - {"pattern"}  # a pattern gait: no delays, no SAN parameters
        assert not SAN.decode(best.encoding).any()


def test_a_decoded_pattern_swings_each_actuator_over_its_range():
    rng = np.random.default_rng(0)
    x = rng.normal(0.5, 2.0, (200, 2 * 3 + 1))  # CMA-ES points well outside the unit cube
    p = decode(x, 3)
    assert p.shape == (200, 4 * 3 + 1)
    assert np.all((p[:, :12] >= 0) & (p[:, :12] <= 1))
    assert np.all((p[:, 12] >= PERIOD_RANGE[0]) & (p[:, 12] <= PERIOD_RANGE[1]))
    np.testing.assert_allclose(p[:, 0:12:4], np.mod(x[:, 0:6:2], 1.0))  # phases wrap, they are not clipped
    assert np.all(p[:, 2:12:4] == 0) and np.all(p[:, 3:12:4] == 1)  # low and high: the range's ends


@pytest.mark.parametrize("cls", [CatCma, PatternSearch])
def test_a_search_of_one_seed_asks_the_same_and_another_seed_does_not(cls, tmp_path):
    def first(seed):
        s = cls(Problem("r", SAN, 40, seed=seed, gait_params=GaitParams(0.1, 0.1), generation=8))
        return [c.weights.tobytes() + (b"" if c.pattern is None else c.pattern.tobytes()) for c in s.ask(8)]

    assert first(3) == first(3) and first(3) != first(4)


def test_catcma_warms_up_on_the_random_searchs_own_sans_then_starts_from_the_best(tmp_path):
    p = Problem("r", SAN, 120, seed=5, gait_params=GaitParams(0.1, 0.1))
    s = CatCma(p)
    assert s.warmup == 20  # a sixth of the budget
    warm = s.ask(64)
    assert [c.idx for c in warm] == list(range(20)) and s.ask(8) == []  # waits for the warm-up's scores
    for c in warm:
        assert np.array_equal(c.weights, SAN.random_weights(5, c.idx)) and c.key == search_key(5, c.idx)
    best = 13
    s.tell(warm, batch([1.0 if c.idx == best else 0.1 for c in warm]))
    first = s.ask(64)
    assert [c.idx for c in first] == list(range(20, 20 + s.popsize))
    assert s.elite is not None and s.elite[1] == best
    # the generation is drawn about the best random SAN: most weights stay where it has them
    same = np.mean([np.mean(c.weights == SAN.random_weights(5, best)) for c in first])
    assert same > 0.4


def test_catcma_resumed_in_its_warm_up_ends_as_an_uninterrupted_run(tmp_path):
    score = lambda c: float(np.sum(c.weights == 1)) + 0.001 * c.idx
    with Library(str(tmp_path / "a.db")) as lib:
        whole = CatCma(Problem(run(lib), SAN, 90, seed=2, gait_params=GaitParams(0.1, 0.1)))
        drive(whole, lib, score)
        cut = CatCma(Problem(run(lib), SAN, 90, seed=2, gait_params=GaitParams(0.1, 0.1)))
        cands = cut.ask(7)  # 7 of the 15 warm-up SANs, then the process dies
        t = cut.tell(cands, batch([score(c) for c in cands]))
        lib.commit(t.evaluations, t.trace, t.finished)
        again = CatCma(Problem(cut.run_ids[0], SAN, 90, seed=2, gait_params=GaitParams(0.1, 0.1)))
        again.resume(lib.top(cut.run_ids[0], None), [])
        drive(again, lib, score)
        enc = lambda r: sorted((e.idx, e.encoding) for e in lib.top(r, None))
        assert enc(cut.run_ids[0]) == enc(whole.run_ids[0]) and len(enc(whole.run_ids[0])) == 90
