"""The audit's statistic on cases whose answer is known (issue 28, part 1): the bootstrap interval
of a nudge's relative change of the mean speed, and its three verdicts. These use synthetic
member speeds (no simulation), so the statistic's error rates can be measured over many draws;
``test_audit_cases.py`` runs it on real gaits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sanlab.audit import DEPENDENT, ROBUST, UNDECIDED, Shift, combine, level_each, needed, shift


def test_an_unmoved_limit_cycle_is_robust():
    a = np.full(32, 40.0) + np.linspace(-0.2, 0.2, 32)  # every start falls into the same cycle
    s = shift(a, a * 1.01)
    assert s.verdict == ROBUST and s.needed is None
    assert s.change == pytest.approx(0.01) and s.lo <= 0.01 <= s.hi and s.hi - s.lo < 0.01


def test_a_limit_cycle_that_loses_most_of_its_speed_is_resolution_dependent():
    a = np.full(32, 114.0) + np.linspace(-3, 3, 32)
    s = shift(a, a * 0.2)  # the walker of docs/table1.md at bc64b5d: 114 cm/s at dt, 23 at dt/4
    assert s.verdict == DEPENDENT and s.change == pytest.approx(-0.8) and s.hi < -0.1


def test_a_wide_distribution_that_did_not_move_is_undecided_not_flagged_and_says_how_many_members_decide_it():
    rng = np.random.default_rng(1)
    a, b = rng.lognormal(np.log(36), 0.4, 32), rng.lognormal(np.log(36), 0.4, 32)
    s = shift(a, b)
    assert s.verdict == UNDECIDED
    assert s.needed is not None and s.needed > 32
    # ... and that many members decide it (the same distribution, drawn again at that size)
    n = s.needed * 2
    big = shift(rng.lognormal(np.log(36), 0.4, n), rng.lognormal(np.log(36), 0.4, n))
    assert big.verdict == ROBUST


def test_a_bimodal_set_that_left_its_gait_is_flagged():
    # a tuned cart (measured): half of the starts fall into a 7.5 cm/s gait at the step, none at dt/2
    rng = np.random.default_rng(2)
    a = np.where(np.arange(32) % 2 == 0, rng.normal(14.5, 1.0, 32), rng.normal(0.4, 0.1, 32))
    b = rng.normal(0.25, 0.05, 32)
    assert shift(a, b).verdict == DEPENDENT


def test_error_rates_over_many_draws():
    """Under no change, the verdict is resolution-dependent at most at the interval's level;
    under a real change of 50 % it is found almost always, and robust almost never."""
    rng = np.random.default_rng(3)
    each = level_each(0.95, 3)
    false, found, passed = 0, 0, 0
    n = 300
    for _ in range(n):
        a, b = rng.lognormal(np.log(30), 0.4, 32), rng.lognormal(np.log(30), 0.4, 32)
        false += shift(a, b, level=each).verdict == DEPENDENT
        c = shift(a, rng.lognormal(np.log(15), 0.4, 32), level=each)
        found += c.verdict == DEPENDENT
        passed += c.verdict == ROBUST
    assert false / n <= 0.02  # nominal rate: (1 - each) / 2 = 0.8 %
    assert found / n >= 0.95 and passed == 0


def test_a_member_that_blew_up_is_an_artefact():
    a = np.full(32, 10.0)
    b = a.copy()
    b[3] = np.nan
    assert shift(a, b).verdict == DEPENDENT
    assert shift(b, a).verdict == DEPENDENT


def test_standing_still_is_not_flagged_for_noise():
    a = np.linspace(0.01, 0.03, 32)  # cm/s: compared against at least 1 cm/s
    assert shift(a, a * 2).verdict == ROBUST


def test_the_verdict_of_several_nudges():
    r, d, u = Shift(0, 0, 0, ROBUST), Shift(-1, -1, -1, DEPENDENT), Shift(0, -0.2, 0.2, UNDECIDED, 90)
    assert combine({"a": r, "b": r}) == ROBUST
    assert combine({"a": r, "b": u}) == UNDECIDED  # undecided is not a pass
    assert combine({"a": u, "b": d}) == DEPENDENT
    assert needed({"a": r, "b": u}) == 90 and needed({"a": r}) is None


def test_the_statistic_is_deterministic_and_checks_its_input():
    rng = np.random.default_rng(4)
    a, b = rng.normal(20, 5, 32), rng.normal(20, 5, 32)
    assert shift(a, b) == shift(a, b)
    with pytest.raises(ValueError, match="equal, non-empty"):
        shift(a, b[:5])
    assert math.isinf(Shift.from_json(Shift(math.inf, math.inf, math.inf, DEPENDENT).to_json()).change)


def _skewed(seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Members that moved 4 % under a nudge, and a few that ran off: a right-skewed interval
    that straddles +10 % from an estimate of about +6 %."""
    rng = np.random.default_rng(seed)
    a = 10 + rng.normal(0, 0.1, n)
    b = a * (1 + rng.normal(0.04, 0.01, n))
    k = rng.integers(1, 4)
    b[:k] += rng.uniform(5, 15, k)
    return a, b


def test_an_undecided_shift_never_asks_for_fewer_members_than_it_had():
    # issue 49: after a look on 96 members the audit said "~88 members" would decide it; the
    # half-width of a skewed interval said so (here 64), where its crossing side needs more
    a, b = _skewed(5, 96)
    s = shift(a, b)
    assert s.verdict == UNDECIDED and s.lo < 0.10 < s.hi and s.needed is not None and s.needed > 96
    for seed in range(40):
        s = shift(*_skewed(seed, 96))
        assert s.verdict != UNDECIDED or s.needed is None or s.needed > 96, seed


def test_the_advice_names_more_members_than_were_used_or_none():
    from sanlab.audit import advice

    assert advice(96, 99) == 128 and advice(256, 300) == 384 and advice(32, 40) == 64
    assert advice(96, 50) == 128  # never fewer than it had, whatever the estimate
    assert advice(256, 5000) is None and advice(256, None) is None  # beyond --members' limit: say so


def test_an_undecided_audit_goes_on_looking_up_to_max_members():
    from types import SimpleNamespace

    from sanlab.audit import decide

    sizes = []

    def evaluate(M: int, rows: list[int]):  # a gait whose nudge moved it by about the threshold: undecided at 32 and 96
        assert rows == [0]
        sizes.append(M)
        a, b = _skewed(42, M)
        batch = lambda v: SimpleNamespace(member_speed_cm_s=v[None], score=np.array([1.0]),
                                          nonfinite=np.array([False]), fell=np.array([False]))
        return batch(a), {"dt/2": batch(b)}

    [x] = decide(evaluate, 1, 32, 256, 0.10, 0.95)
    # it used to stop after the second look (96), undecided, and ask for more --members
    assert sizes == [32, 96, 256] and x.members == 256


def test_a_second_look_simulates_only_the_undecided():
    # two gaits: one the nudge leaves alone (decided robust on the first look), one it moves by
    # about the threshold (undecided): only the second is simulated again, on more members
    from types import SimpleNamespace

    from sanlab.audit import ROBUST, combine, decide

    calls = []

    def evaluate(M: int, rows: list[int]):
        calls.append((M, list(rows)))
        a = [np.full(M, 10.0) + np.random.default_rng(M).normal(0, 0.1, M), _skewed(42, M)[0]]
        b = [a[0].copy(), _skewed(42, M)[1]]
        batch = lambda vs: SimpleNamespace(member_speed_cm_s=np.stack(vs), score=np.ones(len(vs)),
                                           nonfinite=np.zeros(len(vs), bool), fell=np.zeros(len(vs), bool))
        return batch([a[k] for k in rows]), {"dt/2": batch([b[k] for k in rows])}

    x, y = decide(evaluate, 2, 32, 256, 0.10, 0.95)
    assert calls[0] == (32, [0, 1]) and all(rows == [1] for _, rows in calls[1:]) and len(calls) > 1
    assert combine(x.shifts) == ROBUST and x.members == 32 and y.members > 32
