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


def test_a_search_smaller_than_its_batch_simulates_only_its_controllers(tmp_path, monkeypatch):
    """The evaluator pads every call to its batch, so 24 controllers in the default batch of 256
    simulated 256 (with the default ensemble, 2,048 rollouts for 192); the run's batch is now its
    size, with the same scores."""
    import sanlab.sim as sim

    rows = []
    real = sim.rollout

    def counted(model, controller, cparams, *a, **k):
        rows.append(len(cparams.weights))
        return real(model, controller, cparams, *a, **k)

    monkeypatch.setattr(sim, "rollout", counted)
    run_id, top, scores = search(tmp_path / "a.db", n=24, batch=256, ensemble=4)
    with Library(str(tmp_path / "a.db")) as lib:
        assert lib.get_run(run_id).settings.batch == 24
    assert sum(rows) == 24 * 4  # one rollout per step factor of the ensemble; 256 * 4 before
    monkeypatch.setattr(sim, "rollout", real)
    _, top16, scores16 = search(tmp_path / "b.db", n=24, batch=16, ensemble=4)  # two calls of 16
    assert top == top16 and scores == scores16


def test_progress_reaches_the_reporter(tmp_path):
    seen = []
    search(tmp_path / "a.db", n=64, reporter=seen.append)
    assert [p.evaluated for p in seen] == [0, 32, 64, 64]
    assert seen[-1].done and seen[-1].best == max(p.best for p in seen)


def test_a_run_stopped_by_a_full_disk_reports_the_disk_not_the_status_it_could_not_write(tmp_path, monkeypatch):
    """Issue 48: when the write that stops a run (a full disk) also refuses the status
    "interrupted", the driver raised the second failure instead of the first and left the other
    runs unmarked. Now it tries each run, and the cause is what comes out. No simulation: a
    strategy, evaluator and backend that only count."""
    import pytest

    from sanlab.library import LibraryError
    from sanlab.search import driver
    from tests.library.test_library import new_run

    lib = Library(str(tmp_path / "g.db"))
    runs = [new_run(lib).run_id for _ in range(2)]
    marked: list[str] = []

    class Strategy:
        run_ids, done = tuple(runs), False

        def ask(self, n):
            return ["candidate"]

        def tell(self, cands, scores):
            return type("Told", (), {"evaluations": [], "trace": [], "finished": []})()

        def progress(self):
            return 0, 1, None

    class Backend:
        slots = 1

        def start(self, evaluator): ...
        def submit(self, request): return 0
        def next(self): return 0, None
        def close(self): ...

    def commit(*a, **k):
        raise LibraryError("g.db: database or disk is full")

    def set_status(run_id, status):
        if status == "interrupted":
            marked.append(run_id)
            raise LibraryError("g.db: database or disk is full (the status)")

    monkeypatch.setattr(lib, "commit", commit)
    monkeypatch.setattr(lib, "set_status", set_status)
    monkeypatch.setattr(driver, "_request", lambda cands: None)
    with pytest.raises(LibraryError) as e:
        driver.run(Strategy(), type("Evaluator", (), {"batch": 1})(), lib, backend=Backend())  # type: ignore[arg-type]
    assert str(e.value) == "g.db: database or disk is full" and marked == runs
    lib.close()
