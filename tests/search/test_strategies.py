"""The ask/tell contract, checked on every registered strategy (``sanlab.search.registry``).

A synthetic score (a cheap deterministic function of a candidate's weights, vector and ensemble
key) stands in for the simulator, and a real library stores what each ``tell`` returns, so every
strategy is driven exactly as the driver drives it: the same stored rows whatever the batch
size, every unit asked once, and a run interrupted half-way and resumed from its library ends
with exactly the rows of an uninterrupted one.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from sanlab import __version__, creature
from sanlab.descriptors import NAMES
from sanlab.evaluate import ScoreBatch
from sanlab.evaluate.records import GaitParams
from sanlab.library import Library
from sanlab.search.base import Grid, Problem, Start
from sanlab.search.registry import STRATEGIES, make, names
from sanlab.search.space import Space

SPEC = creature.load("cart")
SPACE = Space(SPEC)
BUDGET = 24


def synthetic(cands) -> ScoreBatch:
    """A bumpy score of each candidate, with a small part that depends on its ensemble key (as the
    ensemble's draws do)."""
    out = []
    for c in cands:
        base = 0.1 * float(np.mean(c.weights)) if c.theta is None else -float(np.sum((c.theta - SPACE.nominal() - 0.03) ** 2))
        noise = (zlib.crc32(repr(c.key).encode()) % 1000) * 1e-6
        out.append(base + noise + 1.0)
    s = np.asarray(out)
    no = np.zeros(len(s), bool)
    # behaviour descriptors for quality-diversity strategies: functions of the weights alone
    w = np.stack([np.asarray(c.weights, float).reshape(-1) for c in cands]) if cands else np.zeros((0, 1))
    desc = {name: np.full(len(s), 0.5) for name in NAMES}
    desc["vx_cm_s"] = np.tanh(w[:, ::2].mean(1))
    desc["airborne"] = 0.5 + 0.5 * np.tanh(w[:, 1::2].mean(1))
    desc["duty"] = np.zeros((len(s), 0))
    return ScoreBatch(s, 100 * s, s, no, no, s[:, None], 100 * s[:, None], descriptors=desc)


def problem(name: str, run_id: str) -> Problem:
    cls = STRATEGIES[name]
    san = SPACE.san
    if cls.phase == 1:
        grid = Grid(("vx_cm_s", "airborne"), ((-0.5, 0.5), (0.25, 0.75)), (4, 4))
        space = SPACE if getattr(cls, "needs_space", False) else None  # the rhythm search builds clocks in it
        return Problem(run_id, san, BUDGET, seed=3, gait_params=GaitParams(0.1, 0.1), grid=grid, generation=6,
                       space=space)
    weights = san.random_weights(3, 0)
    return Problem(run_id, san, BUDGET, seed=3, stream=1, space=SPACE, start=Start(weights, SPACE.nominal(), None))


def new_run(lib: Library) -> str:
    return lib.create_run("search", "cart", "text", {}, seed=3, total=BUDGET, sanlab_version=__version__).run_id


def drive(strategy, lib: Library, window: int, stop_after: int | None = None) -> int:
    """Ask/tell until done (or until ``stop_after`` batches), committing what is told; returns
    the number of candidates evaluated."""
    evaluated = batches = 0
    while not strategy.done:
        if stop_after is not None and batches >= stop_after:
            break
        cands = strategy.ask(window)
        assert cands, "a strategy that is not done and has nothing in flight must ask something"
        assert len(cands) <= max(window, 1)
        assert len({(c.role, c.idx) for c in cands}) == len(cands)
        told = strategy.tell(cands, synthetic(cands))
        lib.commit(told.evaluations, told.trace, told.finished)
        evaluated += len(cands)
        batches += 1
        before = strategy.progress()[0]
        assert 0 <= before <= strategy.progress()[1]
    return evaluated


def stored(lib: Library, run_id: str):
    rows = sorted((e.idx, e.encoding, e.params, e.score, e.extra) for e in lib.top(run_id, None))
    trace = [(t.trial, t.score, t.accepted) for t in lib.trace(run_id)]
    return rows, trace, lib.get_run(run_id).status


def test_the_registry_has_both_phases():
    assert names(1) == ["random", "catcma", "map-elites", "rhythm", "reflex", "pattern"] and set(names(2)) == {"sga", "sa"}
    with pytest.raises(ValueError, match="expected one of"):
        make("newton", problem("random", "x"))


@pytest.mark.parametrize("name", sorted(STRATEGIES))
def test_every_strategy_keeps_the_ask_tell_contract(name, tmp_path):
    with Library(str(tmp_path / "a.db")) as lib:
        runs = [new_run(lib) for _ in range(3)]
        one = make(name, problem(name, runs[0]))
        assert one.phase in (1, 2) and one.run_ids == (runs[0],)
        n_one = drive(one, lib, 1)
        assert one.done and one.ask(8) == []
        done, total, best = one.progress()
        assert done == total == BUDGET and best > 0

        # the batch size changes nothing that is stored
        many = make(name, problem(name, runs[1]))
        drive(many, lib, 7)
        a, b = stored(lib, runs[0]), stored(lib, runs[1])
        assert a[0] == b[0] and a[1] == b[1] and a[2] == b[2] == "done"
        assert len(a[0]) == (BUDGET if one.phase == 1 else 1)
        assert n_one >= BUDGET

        # interrupted after two batches, then resumed from what the library holds
        cut = make(name, problem(name, runs[2]))
        drive(cut, lib, 5, stop_after=2)
        assert not cut.done
        again = make(name, problem(name, runs[2]))
        rows, trace, _ = stored(lib, runs[2])
        assert rows or trace  # something was committed before the interruption
        again.resume(lib.top(runs[2], None), lib.trace(runs[2]))
        drive(again, lib, 5)
        assert stored(lib, runs[2])[:2] == a[:2]


@pytest.mark.parametrize("name", names(2))
def test_a_chain_stores_its_held_out_score_not_its_luckiest_sample(name, tmp_path):
    with Library(str(tmp_path / "a.db")) as lib:
        run = new_run(lib)
        chain = make(name, problem(name, run))
        drive(chain, lib, 4)
        final = lib.gait(f"{run}#0")
        best_seen = max(t.score for t in lib.trace(run) if t.accepted)
        assert final.extra is not None and final.extra["chain_best"] >= best_seen
        assert final.extra["before"]["score"] > 0
        # the held-out draw is its own: its score is the best vector's under another key
        assert final.score != final.extra["chain_best"]
