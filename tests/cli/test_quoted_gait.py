"""Issue 57, item 11: after ``audit --select`` the gait to quote is the tuning's selection
``RUN#1``, which ``show`` ranks below the chain's best (``RUN/1`` is ``RUN#0``, unvouched when the
selection scores lower). The "next:" hints of ``show`` and ``audit --select`` lead to the
selection, by its permanent id, and the table says which row it is."""

from __future__ import annotations

import shutil

import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.library import Library

runner = CliRunner()


@pytest.fixture(scope="module")
def selected(lib_run, tmp_path_factory):
    """(db, tuning run id): a 2-trial tuning of ``lib_run``'s best, with a selection stored as a
    real one is (``put_selection``), whose gait scores below the chain's best #0 and which no
    audit of #0 vouched for."""
    from sanlab.search.tune import tune

    src, run_id = lib_run
    db = str(tmp_path_factory.mktemp("quoted") / "g.db")
    shutil.copy(src, db)
    with Library(db) as lib:
        [res] = tune(lib, [f"{run_id}/1"], method="sa", trials=2, seed=0, batch=8, ensemble=1)
        best = lib.gait(res.tuned_gait)
        row = {"encoding": best.encoding, "params": best.params, "score": best.score / 2,
               "speed_cm_s": best.speed_cm_s / 2, "fell": False, "nonfinite": False,
               "extra": {"selected": {"trial": 1}}, "parent": best.parent}
        lib.put_selection(res.run_id, 1, {"settings": {}, "candidates": [], "trial": 1}, row)
    return db, res.run_id


def test_show_of_a_selected_tuning_leads_to_the_selection(selected):
    db, run = selected
    r = runner.invoke(app, ["show", run, "--db", db], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    # the selection is rank 2: its row says "quote this", and the line under the table names it
    row2 = next(line for line in lines if f"{run}/2" in line)
    assert "quote this" in row2 and "quote this" not in next(line for line in lines if f"{run}/1" in line)
    said = " ".join(r.output.split())
    assert f"{run}#1 (rank 2) is this tuning's audited selection" in said
    assert f"{run}/1 is the chain's best by score, which no audit vouched for" in said
    hints = next(line for line in lines if line.startswith("next:"))
    assert f"sanlab show {run}#1" in hints and f"sanlab export {run}#1" in hints
    assert f"{run}/1" not in hints and f"{run}#0" not in hints


def test_show_of_the_unvouched_best_points_at_the_selection(selected):
    db, run = selected
    r = runner.invoke(app, ["show", f"{run}/1", "--db", db], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    assert f"run {run}'s audited selection is {run}#1, the tuned gait to quote" in " ".join(r.output.split())
    hints = r.output.splitlines()[-1]
    assert hints.startswith("next:") and f"sanlab render {run}#1" in hints and f"{run}#0" not in hints


def test_a_tuning_without_selection_hints_at_select(lib_run, tmp_path):
    from sanlab.search.tune import tune

    src, run_id = lib_run
    db = str(tmp_path / "g.db")
    shutil.copy(src, db)
    with Library(db) as lib:
        [res] = tune(lib, [f"{run_id}/1"], method="sa", trials=2, seed=0, batch=8, ensemble=1)
    r = runner.invoke(app, ["show", res.run_id, "--db", db], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    hints = r.output.splitlines()[-1]
    assert hints.startswith(f"next: sanlab audit {res.run_id} --select"), hints
    assert "quote this" not in r.output


def test_a_selection_that_found_nothing_says_so(lib_run, tmp_path):
    from sanlab.search.tune import tune

    src, run_id = lib_run
    db = str(tmp_path / "g.db")
    shutil.copy(src, db)
    with Library(db) as lib:
        [res] = tune(lib, [f"{run_id}/1"], method="sa", trials=2, seed=0, batch=8, ensemble=1)
        lib.put_selection(res.run_id, 1, {"settings": {}, "candidates": [], "trial": None})
    r = runner.invoke(app, ["show", res.run_id, "--db", db], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    assert f"no gait of run {res.run_id} is vouched for" in " ".join(r.output.split())
    assert "quote this" not in r.output


def test_audit_select_ends_with_hints_at_the_selection(selected, monkeypatch):
    import sanlab.audit
    from sanlab.audit import Selection

    db, run = selected
    monkeypatch.setattr(sanlab.audit, "select_robust", lambda lib, run_id, **k: Selection(run_id, f"{run_id}#1", None, [], 0.1))
    r = runner.invoke(app, ["audit", run, "--select", "--db", db], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    hints = r.output.splitlines()[-1]
    assert hints == (f"next: sanlab show {run}#1 --db {db}    sanlab render {run}#1 --db {db}    "
                     f"sanlab export {run}#1 --db {db}"), hints


@pytest.mark.parametrize("selection", [None, "chosen"])
def test_audit_of_an_unvouched_tuned_gait_leads_to_the_selection(lib_run, tmp_path, monkeypatch, selection):
    """A tuned gait the audit cannot vouch for: next, the run's selection (``audit RUN
    --select``), or the selection already made (``show RUN#1``)."""
    import sanlab.audit
    from sanlab.audit import Audit, Shift
    from sanlab.search.tune import tune

    src, run_id = lib_run
    db = str(tmp_path / "g.db")
    shutil.copy(src, db)
    with Library(db) as lib:
        [res] = tune(lib, [f"{run_id}/1"], method="sa", trials=2, seed=0, batch=8, ensemble=1)
        if selection:
            best = lib.gait(res.tuned_gait)
            lib.put_selection(res.run_id, 1, {"settings": {}, "candidates": [], "trial": 1},
                              {"encoding": best.encoding, "params": best.params, "score": best.score / 2,
                               "speed_cm_s": best.speed_cm_s / 2, "fell": False, "nonfinite": False})
    dependent = Shift(0.3, 0.2, 0.4, "resolution-dependent")

    def fake(lib, gait_id, **k):
        return Audit(lib.gait(gait_id).gait_id, 10.0, 10.0, 10.0, {"dt/2": 13.0, "dt/4": 13.0},
                     {"dt/2": dependent, "dt/4": dependent}, {"dt/2": False, "dt/4": False}, 0.1, 0.001, 1, 64, 0.95)

    monkeypatch.setattr(sanlab.audit, "audit_and_store", fake)
    r = runner.invoke(app, ["audit", res.tuned_gait, "--db", db], env={"COLUMNS": "200"})
    assert r.exit_code == 0, r.output
    assert "resolution-dependent" in r.output
    hints = r.output.splitlines()[-1]
    want = f"sanlab show {res.run_id}#1" if selection else f"sanlab audit {res.run_id} --select"
    assert hints == f"next: {want} --db {db}", hints
