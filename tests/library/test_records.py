"""Typed records at the library's boundary: run settings, stored rows, and ``Library.commit``
storing a driver's batch whole or not at all."""

from __future__ import annotations

import pytest

from sanlab import __version__
from sanlab.evaluate import Ensemble, GaitParams, Scores
from sanlab.library import EvaluationRow, Library, LibraryError, SearchSettings, TraceRow, TuneSettings
from sanlab.library.records import settings_from_json


def test_run_settings_round_trip_and_old_runs_read_as_single_sample():
    s = SearchSettings(200, 6.0, "distance", 256, "bounder", Ensemble(8), 0.1, 0.1, {"sensors": 8})
    assert settings_from_json(s.to_json()) == s
    t = TuneSettings("sa", 1000, 3, 1, False, "hill", 6.0, "distance", 128, "bounder", Ensemble(4), ("H1.T_on",))
    assert settings_from_json(t.to_json()) == t
    old = settings_from_json({"controllers": 10, "seconds": 6.0, "metric": "distance", "batch": 64,
                              "delay_on": 0.1, "delay_off": 0.1})
    assert isinstance(old, SearchSettings) and old.ensemble == Ensemble(members=1)


def _row(run_id, idx, score=1.0):
    return EvaluationRow(run_id, idx, "enc", GaitParams(0.1, 0.1), Scores(score, 10.0, 0.1, False, False, (score,), (10.0,)))


def test_commit_stores_a_batch_of_several_runs_whole_or_not_at_all(tmp_path):
    with Library(str(tmp_path / "g.db")) as lib:
        a = lib.create_run("search", "cart", "t", {}, 0, 3, sanlab_version=__version__).run_id
        b = lib.create_run("tune", "cart", "t", {}, 0, 1, sanlab_version=__version__).run_id
        lib.commit([_row(a, 0), _row(a, 1, 2.0)], [TraceRow(b, 0, 0.5, True)], done=[b])
        assert lib.count(a) == 2 and [t.trial for t in lib.trace(b)] == [0]
        assert lib.get_run(b).status == "done" and lib.get_run(a).status == "running"
        e = lib.gait(f"{a}/1")
        assert e.gait_params == GaitParams(0.1, 0.1) and e.scores == _row(a, 1, 2.0).scores
        with pytest.raises(LibraryError):  # idx 1 is stored already: nothing of this batch is
            lib.commit([_row(a, 2), _row(a, 1)], [TraceRow(b, 1, 0.4, False)], done=[a])
        assert lib.count(a) == 2 and len(lib.trace(b)) == 1 and lib.get_run(a).status == "running"
