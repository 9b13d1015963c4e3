"""Phase-1 search end to end: determinism, interruption and resume, the CLI around it."""

from __future__ import annotations

from sanlab.creature import read_source
from sanlab.library import Library
from sanlab.search import run_search


def search(db, n=96, seed=3, batch=32, **kw):
    text, where = read_source("cart")
    with Library(str(db)) as lib:
        run_id = run_search(lib, text, where, controllers=n, seconds=1.0, seed=seed, batch=batch, **kw)
        return run_id, [(e.encoding, e.score) for e in lib.top(run_id, 10)], lib.scores(run_id)


def test_a_seeded_search_is_deterministic(tmp_path):
    a_id, a_top, a_scores = search(tmp_path / "a.db")
    b_id, b_top, b_scores = search(tmp_path / "b.db")
    assert a_id != b_id
    assert a_top == b_top and a_scores == b_scores
    _, c_top, _ = search(tmp_path / "c.db", seed=4)
    assert c_top != a_top
    assert len(a_scores) == 96 and max(a_scores) > 0


def test_the_batch_size_does_not_change_the_result(tmp_path):
    _, a_top, a_scores = search(tmp_path / "a.db", batch=32)
    _, b_top, b_scores = search(tmp_path / "b.db", batch=40)
    assert a_top == b_top and a_scores == b_scores


def test_progress_reaches_the_reporter(tmp_path):
    seen = []
    search(tmp_path / "a.db", n=64, reporter=seen.append)
    assert [p.evaluated for p in seen] == [0, 32, 64, 64]
    assert seen[-1].done and seen[-1].best == max(p.best for p in seen)
