"""Designs in the gait library (schema 5, ``sanlab design``'s outer record): stored and read
back, continued when made again, checked on the way in, owned while running, and absent from
an older library file, which still opens (read as it is, or upgraded when written)."""

from __future__ import annotations

import json
import os
import socket
import sqlite3

import pytest

from sanlab.library import SCHEMA_VERSION, Library, LibraryError, _schema
from tests.library.test_library import assert_one_line, new_run

TEXT = 'name = "hopper"\n# free numbers here\n'
SETTINGS = {"designs": 3, "generation": 3, "strategy": "cma-es", "seconds": None, "seeds": [1]}
FREE = [{"name": "mass", "path": "links[0].mass", "min": 0.5, "max": 1.5, "default": 1.0, "unit": "kg"},
        {"name": "front", "path": "links[1].points[1][1]", "min": -0.35, "max": -0.2, "default": -0.275, "unit": "m"}]


def record(speed: float, gait: str | None = "abcd1234#3", **kw) -> dict:
    return {"speed": speed, "gait": gait, "search": "abcd1234", "phase1_cm_s": speed / 2, "chains": [], **kw}


def test_a_design_round_trips_and_is_continued_when_made_again(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        d = lib.begin_design("hopper", "hopper.toml", TEXT, SETTINGS, FREE)
        assert (d.status, d.scores, d.chosen, d.result) == ("running", 0, None, None)
        assert (d.creature, d.source, d.creature_text, d.settings, list(d.free)) == ("hopper", "hopper.toml", TEXT, SETTINGS, FREE)
        lib.add_design_score(d.design_id, 0, 1, 0, [0.7, -0.3], record(12.5, None, pruned=True))
        lib.add_design_score(d.design_id, -1, 0, 0, [1.0, -0.275], record(20.0))
        lib.add_design_score(d.design_id, 0, 0, 0, [0.9, -0.25], record(22.0, "ABCD1234#7"))
        lib.add_design_score(d.design_id, -1, 0, 1, [1.0, -0.275], record(18.0))
        lib.add_design_score(d.design_id, 0, 0, 0, [0.9, -0.25], record(23.0, "abcd1234#8"))  # the same body and seed: replaced
        rows = lib.design_scores(d.design_id[:4])  # an unambiguous prefix
        assert [(r.round, r.index, r.seed) for r in rows] == [(-1, 0, 0), (-1, 0, 1), (0, 0, 0), (0, 1, 0)]  # the reference first
        assert [r.speed_cm_s for r in rows] == [20.0, 18.0, 23.0, 12.5]
        assert [r.gait for r in rows] == ["abcd1234#3", "abcd1234#3", "abcd1234#8", None]
        assert [r.pruned for r in rows] == [False, False, False, True]
        assert rows[3].values == (0.7, -0.3) and rows[3].record["phase1_cm_s"] == 6.25
        lib.end_design(d.design_id, "interrupted")
        assert lib.get_design(d.design_id).status == "interrupted"
        # made again (same file, same settings): the same design, its scores kept
        again = lib.begin_design("hopper", "hopper.toml", TEXT, dict(reversed(SETTINGS.items())), FREE)
        assert (again.design_id, again.status, again.scores) == (d.design_id, "running", 4)
        result = {"chosen": {"round": 0, "index": 0}, "seconds": 61.5, "text": "# chosen\n"}
        lib.end_design(d.design_id, "done", result)
        done = lib.get_design(d.design_id)
        assert (done.status, done.chosen, done.result) == ("done", (0, 0), result)
        lib.end_design(d.design_id, "interrupted")  # a later run of it stopped: the result stays
        assert lib.get_design(d.design_id).chosen == (0, 0)
        # another file or other settings: another design, listed newest first
        other = lib.begin_design("hopper", "hopper.toml", TEXT, {**SETTINGS, "designs": 4}, FREE)
        assert other.design_id != d.design_id
        assert [x.design_id for x in lib.designs()] == [other.design_id, d.design_id]
        assert lib.designs()[1].scores == 4


@pytest.mark.parametrize("call, needle", [
    (lambda lib, d: lib.add_design_score("00000000", 0, 0, 0, [1.0], record(1.0)), "no design '00000000'"),
    (lambda lib, d: lib.add_design_score(d, -2, 0, 0, [1.0], record(1.0)), "round must be >= -1"),
    (lambda lib, d: lib.add_design_score(d, 0, -1, 0, [1.0], record(1.0)), "place must be >= 0"),
    (lambda lib, d: lib.add_design_score(d, 0, 0, 0, [float("nan")], record(1.0)), "values must be finite"),
    (lambda lib, d: lib.add_design_score(d, 0, 0, 0, [1.0], record(1.0, "g0.5")), "gait must be a gait id 'RUN#IDX'"),
    (lambda lib, d: lib.add_design_score(d, 0, 0, 0, [1.0], {**record(1.0), "speed": "fast"}), "speed must be a number"),
    (lambda lib, d: lib.end_design(d, "running"), "a design ends 'done' or 'interrupted'"),
    (lambda lib, d: lib.end_design(d, "done"), "a design done needs its result"),
    (lambda lib, d: lib.get_design("zz"), "no design 'zz'"),
    (lambda lib, d: lib.design_scores("ffffffff"), "no design 'ffffffff'"),
    (lambda lib, d: lib.begin_design("h", "h.toml", TEXT, {"x": float("inf")}, FREE), "not finite"),
])
def test_bad_design_writes_are_one_line_errors_and_store_nothing(tmp_path, call, needle):
    with Library(tmp_path / "g.db") as lib:
        d = lib.begin_design("hopper", "hopper.toml", TEXT, SETTINGS, FREE).design_id
        with pytest.raises(LibraryError) as err:
            call(lib, d)
        assert_one_line(err, needle)
        assert lib.design_scores(d) == [] and lib.get_design(d).status == "running" and len(lib.designs()) == 1


def test_an_ambiguous_design_prefix_is_refused(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        for designs in range(1, 40):  # 39 ids of 8 hex digits: two share a first digit
            lib.begin_design("hopper", "hopper.toml", TEXT, {**SETTINGS, "designs": designs}, FREE)
        ids = [d.design_id for d in lib.designs()]
        first = next(c for c in "0123456789abcdef" if sum(i.startswith(c) for i in ids) > 1)
        with pytest.raises(LibraryError) as err:
            lib.get_design(first)
        assert_one_line(err, f"design id '{first}' is ambiguous")


def test_a_running_design_is_owned_and_reads_interrupted_once_its_process_is_gone(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        d = lib.begin_design("hopper", "hopper.toml", TEXT, SETTINGS, FREE)
        alive = {"host": socket.gethostname(), "pid": os.getppid(), "start": None}  # pytest's parent lives
        lib._conn.execute("UPDATE designs SET owner = ?", (json.dumps(alive),))
        with pytest.raises(LibraryError) as err:
            lib.begin_design("hopper", "hopper.toml", TEXT, SETTINGS, FREE)
        assert_one_line(err, f"design {d.design_id} is being written by process {os.getppid()}")
        assert lib.get_design(d.design_id).status == "running"
        gone = {"host": socket.gethostname(), "pid": 2**22 + 12345, "start": None}  # past pid_max: no such process
        lib._conn.execute("UPDATE designs SET owner = ?", (json.dumps(gone),))
        assert lib.get_design(d.design_id).status == "interrupted" and lib.designs()[0].status == "interrupted"
        assert lib.begin_design("hopper", "hopper.toml", TEXT, SETTINGS, FREE).status == "running"  # taken over


def test_a_damaged_design_is_listed_as_such_and_its_reading_names_it(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        d = lib.begin_design("hopper", "hopper.toml", TEXT, SETTINGS, FREE).design_id
        lib.add_design_score(d, 0, 0, 0, [1.0], record(1.0))
        lib._conn.execute("UPDATE designs SET settings = '{not json'")
        lib._conn.execute("UPDATE design_scores SET body = '[1, \"x\"]'")
        assert [(x.design_id, x.status, x.scores) for x in lib.designs()] == [(d, "damaged", 1)]
        with pytest.raises(LibraryError) as err:
            lib.get_design(d)
        assert_one_line(err, f"design {d} is damaged", "settings")
        with pytest.raises(LibraryError) as err:
            lib.design_scores(d)
        assert_one_line(err, f"design {d}'s score of body 0.0 on seed 0 is damaged")


def _version_4_library(path) -> None:
    """A library as sanlab wrote it before designs (schema 4), with one run."""
    with Library(path) as lib:
        new_run(lib)
    con = sqlite3.connect(path)
    for table in ("design_scores", "designs"):
        con.execute(f"DROP TABLE {table}")
    con.execute("PRAGMA user_version = 4")
    con.commit()
    con.close()


def test_a_version_4_library_opens_without_designs_and_takes_them_once_upgraded(tmp_path):
    path = tmp_path / "v4.db"
    _version_4_library(path)
    with Library(path, readonly=True) as lib:  # read as it is: no designs, nothing written
        assert lib.designs() == [] and len(lib.runs()) == 1
        with pytest.raises(LibraryError) as err:
            lib.get_design("abcd1234")
        assert_one_line(err, "no design 'abcd1234'")
    assert sqlite3.connect(path).execute("PRAGMA user_version").fetchone()[0] == 4
    with Library(path) as lib:  # opened to write: upgraded in place, the run kept
        assert lib._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 5
        assert len(lib.runs()) == 1 and lib.designs() == []
        d = lib.begin_design("hopper", "hopper.toml", TEXT, SETTINGS, FREE).design_id
        lib.add_design_score(d, -1, 0, 0, [1.0, -0.275], record(20.0))
        assert [r.speed_cm_s for r in lib.design_scores(d)] == [20.0]
    tables = {r[0] for r in sqlite3.connect(path).execute("SELECT name FROM sqlite_schema WHERE type = 'table'")}
    assert set(_schema.TABLES) <= tables
