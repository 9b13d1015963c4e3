"""The gait library (sanlab.library): persistence, atomic batches, ranking, ids, exchange, bad
files, and concurrent / crashed writers."""

from __future__ import annotations

import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time

import pytest

from sanlab.library import APPLICATION_ID, SCHEMA_VERSION, Evaluation, Library, LibraryError, Run

CREATURE_TEXT = 'name = "blob"\n[[links]]\nname = "body"\n'


def new_run(lib: Library, total: int = 10, **kw) -> Run:
    args = dict(kind="search", creature="blob", creature_text=CREATURE_TEXT,
                params={"seconds": 10.0, "metric": "distance", "batch": 4}, seed=7, total=total,
                dtype="float32", device="cpu")
    args.update(kw)
    return lib.create_run(**args)


def row(idx: int, score: float, **kw) -> dict:
    r = dict(idx=idx, encoding=f"enc-{idx}", params={"k1": [1.0, 2.0]}, score=score,
             speed_cm_s=score * 10, fell=False, nonfinite=False, extra={"distance": score})
    r.update(kw)
    return r


def real_run(lib: Library) -> tuple[Run, list[str]]:
    """A run of the built-in cart with three real encodings: what an export must hold to be
    imported (the import decodes it against its creature)."""
    from sanlab.creature import load, read_source
    from sanlab.san import San

    san = San.for_creature(load("cart"))
    run = new_run(lib, creature="cart", creature_text=read_source("cart")[0],
                  params={"seconds": 6.0, "metric": "distance", "batch": 4})
    return run, [san.encode(san.random_weights(7, i)) for i in range(3)]


def real_row(idx: int, score: float, enc: list[str], **kw) -> dict:
    return row(idx, score, encoding=enc[idx], params={"delay_on": 0.1, "delay_off": 0.12}, **kw)


def assert_one_line(err: pytest.ExceptionInfo, *needles: str) -> str:
    msg = str(err.value)
    assert "\n" not in msg and msg
    for needle in needles:
        assert needle in msg, msg
    # No sqlite3 exception chained or wrapped.
    assert not isinstance(err.value, sqlite3.Error)
    e = err.value
    assert e.__cause__ is None and (e.__context__ is None or e.__suppress_context__)
    return msg


# -- persistence ---------------------------------------------------------------------------------


def test_create_and_reopen_persists(tmp_path):
    path = tmp_path / "gaits.db"
    with Library(path) as lib:
        run = new_run(lib)
        lib.add_batch(run.run_id, [row(0, 1.5), row(1, 2.5)])
        lib.set_status(run.run_id, "done")
    assert len(run.run_id) == 8 and all(c in "0123456789abcdef" for c in run.run_id)
    with Library(str(path)) as lib:
        again = lib.get_run(run.run_id)
        assert again.status == "done" and again.count == 2 and again.total == 10
        assert again.params == {"seconds": 10.0, "metric": "distance", "batch": 4}
        assert again.creature_text == CREATURE_TEXT and again.seed == 7
        assert len(again.creature_hash) == 64
        assert lib.done_indices(run.run_id) == {0, 1}
        ev = lib.gait(f"{run.run_id}#1")
        assert ev == Evaluation(run.run_id, 1, "enc-1", {"k1": [1.0, 2.0]}, 2.5, 25.0, False,
                                False, {"distance": 2.5}, None, rank=1)
        con = lib._conn
        assert con.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
        assert con.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION


def test_runs_newest_first_with_counts(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        a = new_run(lib)
        b = new_run(lib)
        lib.add_batch(a.run_id, [row(i, i) for i in range(3)])
        assert [(r.run_id, r.count) for r in lib.runs()] == [(b.run_id, 0), (a.run_id, 3)]


def test_tune_run_stores_parent_as_permanent_id(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        a = new_run(lib)
        lib.add_batch(a.run_id, [row(0, 1.0), row(1, 3.0)])
        t = new_run(lib, kind="tune", parent_gait=f"{a.run_id}/1")
        assert t.parent_gait == f"{a.run_id}#1"
        lib.add_batch(t.run_id, [row(0, 4.0, parent=f"{a.run_id}#1")])
        assert lib.gait(f"{t.run_id}/1").parent == f"{a.run_id}#1"
        with pytest.raises(LibraryError, match="no gait"):
            new_run(lib, kind="tune", parent_gait=f"{a.run_id}/3")


def test_bad_arguments_error_clearly(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        with pytest.raises(LibraryError, match="unknown run kind"):
            new_run(lib, kind="walk")
        run = new_run(lib)
        with pytest.raises(LibraryError, match="unknown run status"):
            lib.set_status(run.run_id, "finished")
        with pytest.raises(LibraryError, match="no run"):
            lib.set_status("00000000", "done")
        with pytest.raises(LibraryError, match="missing score"):
            lib.add_batch(run.run_id, [{"idx": 0, "encoding": "x"}])
        with pytest.raises(LibraryError, match="unknown field"):
            lib.add_batch(run.run_id, [row(0, 1.0, speed=3)])
        with pytest.raises(LibraryError, match="no run"):
            lib.add_batch("00000000", [row(0, 1.0)])
        with pytest.raises(LibraryError, match="twice"):
            lib.add_batch(run.run_id, [row(0, 1.0), row(0, 2.0)])
        assert lib.count(run.run_id) == 0
    with pytest.raises(LibraryError, match="closed"):
        lib.count(run.run_id)


# -- batches -------------------------------------------------------------------------------------


def test_add_batch_is_atomic(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        run = new_run(lib)
        lib.add_batch(run.run_id, [row(0, 1.0), row(1, 1.0)])
        # idx 1 is already stored: the database rejects the middle row of this batch.
        with pytest.raises(LibraryError) as err:
            lib.add_batch(run.run_id, [row(2, 1.0), row(1, 9.0), row(3, 1.0)])
        assert_one_line(err, "#1", "replace=True")
        assert lib.done_indices(run.run_id) == {0, 1}
        assert lib.gait(f"{run.run_id}#1").score == 1.0
        # A row that cannot be stored, mid-batch.
        with pytest.raises(LibraryError, match="not JSON-serialisable"):
            lib.add_batch(run.run_id, [row(4, 1.0), row(5, 1.0, params={"x": object()})])
        assert lib.count(run.run_id) == 2
        # replace=True overwrites.
        lib.add_batch(run.run_id, [row(1, 9.0), row(2, 0.5)], replace=True)
        assert lib.done_indices(run.run_id) == {0, 1, 2}
        assert lib.gait(f"{run.run_id}#1").score == 9.0


def test_add_batch_rolls_back_a_failure_inside_the_transaction(tmp_path):
    class Boom(Exception):
        pass

    class DiesMidBatch:
        """The real connection, except that executemany dies after storing rows 0..2."""

        def __init__(self, conn):
            self.conn = conn

        def __getattr__(self, name):
            return getattr(self.conn, name)

        def executemany(self, sql, values):
            def rows():
                for v in values:
                    if v[1] == 3:
                        raise Boom
                    yield v
            return self.conn.executemany(sql, rows())

    with Library(tmp_path / "g.db") as lib:
        run = new_run(lib)
        rows = [row(i, float(i)) for i in range(6)]
        conn = lib._conn
        lib._conn = DiesMidBatch(conn)
        with pytest.raises(Boom):
            lib.add_batch(run.run_id, rows)
        lib._conn = conn
        assert not conn.in_transaction
        assert lib.count(run.run_id) == 0
        lib.add_batch(run.run_id, rows)
        assert lib.count(run.run_id) == 6


# -- ranking -------------------------------------------------------------------------------------


def test_top_orders_by_score_then_idx_nonfinite_last(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        run = new_run(lib)
        lib.add_batch(run.run_id, [
            row(0, 1.0), row(1, 5.0), row(2, math.nan), row(3, 5.0), row(4, 9.0, nonfinite=True),
            row(5, -2.0), row(6, math.inf), row(7, 5.0), row(8, 0.0, fell=True),
        ])
        top = lib.top(run.run_id, n=None)
        assert [e.idx for e in top] == [1, 3, 7, 0, 8, 5, 6, 4, 2]
        assert [e.rank for e in top] == list(range(1, 10))
        assert [e.idx for e in lib.top(run.run_id, 3)] == [1, 3, 7]
        assert all(e.nonfinite for e in top[-3:]) and math.isnan(top[-1].score)
        assert lib.gait(f"{run.run_id}#6").nonfinite  # an infinite score is non-finite
        assert top[4].fell
        s = lib.scores(run.run_id)
        assert len(s) == 9 and s[1] == 5.0 and math.isnan(s[2]) and s[6] == math.inf
        # The rank of an evaluation addressed by index agrees with top().
        for e in top:
            assert lib.gait(e.gait_id).rank == e.rank


# -- ids -----------------------------------------------------------------------------------------


def test_gait_ids(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        run = new_run(lib)
        lib.add_batch(run.run_id, [row(0, 1.0), row(1, 3.0), row(2, 2.0)])
        rid = run.run_id
        assert lib.gait(f"{rid}/1").idx == 1
        assert lib.gait(f"{rid}/3").idx == 0
        assert lib.gait(f"{rid}#2").idx == 2 and lib.gait(f"{rid}#2").rank == 2
        assert lib.gait(f" {rid.upper()}/2 ").idx == 2
        assert lib.gait(f"{rid[:4]}/1").idx == 1
        for bad in ["", rid, f"{rid}/", f"{rid}/x", f"{rid}#-1", f"{rid}/1/2", "/1",
                    f"{rid}:1", "zz/1", None, 5]:
            with pytest.raises(LibraryError) as err:
                lib.gait(bad)
            assert_one_line(err, "malformed gait id")
        with pytest.raises(LibraryError) as err:
            lib.gait(f"{rid}/0")
        assert_one_line(err, "ranks start at 1")
        with pytest.raises(LibraryError) as err:
            lib.gait(f"{rid}/4")
        assert_one_line(err, "has 3 evaluations")
        with pytest.raises(LibraryError) as err:
            lib.gait(f"{rid}#3")
        assert_one_line(err, "no evaluation #3")
        # past SQLite's integers (2^63 - 1): not found, like any other, never an OverflowError
        for huge, what in ((f"{rid}/{2**63}", "has 3 evaluations"), (f"{rid}/{10**23}", "has 3 evaluations"),
                           (f"{rid}#{2**63}", f"no evaluation #{2**63}"), (f"{rid}#{2**63 - 1}", "no evaluation #")):
            with pytest.raises(LibraryError) as err:
                lib.gait(huge)
            assert_one_line(err, what)
        with pytest.raises(LibraryError) as err:
            lib.gait("ffffffff/1" if not rid.startswith("f") else "00000000/1")
        assert_one_line(err, "no run")


def test_run_id_prefixes(tmp_path, monkeypatch):
    import sanlab.library.store as library

    ids = iter(["3fa1c2d0", "3fa19e77", "8b000000"])
    monkeypatch.setattr(library.secrets, "token_hex", lambda n: next(ids))
    path = tmp_path / "gaits.db"
    with Library(path) as lib:
        for _ in range(3):
            new_run(lib)
        assert lib.get_run("3fa1c2d0").run_id == "3fa1c2d0"
        assert lib.get_run("3fa1c").run_id == "3fa1c2d0"
        assert lib.get_run("3FA19").run_id == "3fa19e77"
        assert lib.get_run("8").run_id == "8b000000"
        with pytest.raises(LibraryError) as err:
            lib.get_run("3fa1")
        assert_one_line(err, "ambiguous", "3fa19e77", "3fa1c2d0")
        with pytest.raises(LibraryError) as err:
            lib.get_run("xyz")
        assert str(err.value) == f"no run 'xyz' in {path}"
        with pytest.raises(LibraryError, match="no run '3fa1c2d01'"):
            lib.count("3fa1c2d01")


def test_run_id_collision_draws_again(tmp_path, monkeypatch):
    import sanlab.library.store as library

    ids = iter(["aaaaaaaa", "aaaaaaaa", "bbbbbbbb"])
    monkeypatch.setattr(library.secrets, "token_hex", lambda n: next(ids))
    with Library(tmp_path / "g.db") as lib:
        assert new_run(lib).run_id == "aaaaaaaa"
        assert new_run(lib).run_id == "bbbbbbbb"


# -- exchange ------------------------------------------------------------------------------------


def test_export_import_round_trip(tmp_path):
    with Library(tmp_path / "a.db") as a:
        run, enc = real_run(a)
        a.add_batch(run.run_id, [real_row(0, 1.0, enc), real_row(1, 4.25, enc, fell=True), real_row(2, 2.0, enc)])
        exported = a.export_gait(f"{run.run_id}/1")
    text = json.dumps(exported, allow_nan=False)  # strict JSON
    assert exported["format"] == "sanlab-gait" and exported["source"] == f"{run.run_id}#1"
    with Library(tmp_path / "b.db") as b:
        gid = b.import_gait(json.loads(text))
        ev = b.gait(gid)
        assert (ev.encoding, ev.params, ev.score, ev.fell) == (enc[1], {"delay_on": 0.1, "delay_off": 0.12}, 4.25,
                                                               True)
        imported = b.get_run(gid.split("/")[0])
        assert imported.kind == "import" and imported.status == "done"
        assert imported.creature_text == run.creature_text and imported.creature == "cart"
        assert imported.params["seconds"] == 6.0
        assert imported.params["imported_from"] == f"{run.run_id}#1"
        again = b.export_gait(gid)
        for key in ("encoding", "params", "score", "speed_cm_s", "fell", "creature_text",
                    "creature_hash", "extra"):
            assert again[key] == exported[key]


def test_export_of_nonfinite_gait_is_strict_json(tmp_path):
    with Library(tmp_path / "a.db") as lib:
        run, enc = real_run(lib)
        lib.add_batch(run.run_id, [real_row(0, math.nan, enc, speed_cm_s=math.inf)])
        exported = lib.export_gait(f"{run.run_id}#0")
        json.dumps(exported, allow_nan=False)
        ev = lib.gait(lib.import_gait(exported))
        assert ev.nonfinite and math.isnan(ev.score)


@pytest.mark.parametrize("change, needle", [
    (lambda d: d.pop("encoding"), "missing field 'encoding'"),
    (lambda d: d.update(format="other"), "not a sanlab gait"),
    (lambda d: d.update(version=99), "newer"),
    (lambda d: d.update(version="1"), "'version'"),
    (lambda d: d.update(score="fast"), "'score' has the wrong type"),
    (lambda d: d.update(fell=1), "'fell' has the wrong type"),
    (lambda d: d.update(params=[1, 2]), "'params' has the wrong type"),
    (lambda d: d.update(creature_text="edited"), "creature_hash"),
    (lambda d: d.update(encoding="  "), "empty"),
])
def test_import_rejects_bad_gaits(tmp_path, change, needle):
    with Library(tmp_path / "a.db") as lib:
        run, enc = real_run(lib)
        lib.add_batch(run.run_id, [real_row(0, 1.0, enc)])
        data = lib.export_gait(f"{run.run_id}/1")
        change(data)
        with pytest.raises(LibraryError) as err:
            lib.import_gait(data)
        assert_one_line(err, needle)
        assert len(lib.runs()) == 1
        with pytest.raises(LibraryError, match="JSON object"):
            lib.import_gait([data])


# -- files that are not libraries ----------------------------------------------------------------


def test_random_bytes_file(tmp_path):
    path = tmp_path / "gaits.db"
    path.write_bytes(os.urandom(8192).replace(b"S", b"s"))
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path), "not a database file")


def test_text_file(tmp_path):
    path = tmp_path / "gaits.db"
    path.write_text("name = 'bounder'\n" * 50)
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path), "not a database file", "text file")


def test_damaged_sqlite_file(tmp_path):
    path = tmp_path / "gaits.db"
    path.write_bytes(b"SQLite format 3\x00" + os.urandom(4096))
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path))


def test_foreign_sqlite_database(tmp_path):
    path = tmp_path / "gaits.db"
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE contacts (name TEXT, phone TEXT)")
    con.execute("INSERT INTO contacts VALUES ('a', '1')")
    con.commit()
    con.close()
    before = path.read_bytes()
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path), "not a sanlab gait library", "another application")
    assert path.read_bytes() == before  # not converted to WAL or otherwise touched


def test_newer_schema_and_other_application_id(tmp_path):
    path = tmp_path / "gaits.db"
    Library(path).close()
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    con.close()
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path), "newer sanlab")
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
    con.execute("PRAGMA application_id = 1234")
    con.close()
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path), "not a sanlab gait library")


def test_missing_directory_and_directory_path(tmp_path):
    path = tmp_path / "nowhere" / "gaits.db"
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path), "does not exist")
    assert not path.parent.exists()
    with pytest.raises(LibraryError) as err:
        Library(tmp_path)
    assert_one_line(err, "directory")


def test_empty_file_becomes_a_library(tmp_path):
    path = tmp_path / "gaits.db"
    path.touch()
    with Library(path) as lib:
        assert lib.runs() == []


# -- concurrency and crashes ---------------------------------------------------------------------


def test_wal_mode(tmp_path):
    path = tmp_path / "g.db"
    with Library(path) as lib:
        assert lib._conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert lib._conn.execute("PRAGMA synchronous").fetchone()[0] == 1  # NORMAL
        assert lib._conn.execute("PRAGMA foreign_keys").fetchone()[0] == 1
    con = sqlite3.connect(path)  # persisted in the file, not only set on our connection
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    con.close()


def test_readers_are_not_blocked_by_a_writer(tmp_path):
    path = tmp_path / "g.db"
    with Library(path) as lib:
        run = new_run(lib)
        lib.add_batch(run.run_id, [row(0, 1.0)])
    writer = sqlite3.connect(path, isolation_level=None)
    try:
        writer.execute("BEGIN IMMEDIATE")
        writer.execute("INSERT INTO evaluations (run_id, idx, encoding, params, score, fell, "
                       "nonfinite) VALUES (?, 1, 'x', '{}', 5.0, 0, 0)", (run.run_id,))
        t0 = time.monotonic()
        with Library(path, timeout=2) as reader:  # opening needs no write lock either
            assert reader.count(run.run_id) == 1  # the uncommitted row is not seen
            assert [e.idx for e in reader.top(run.run_id)] == [0]
            assert reader.get_run(run.run_id[:5]).count == 1
            # A second writer waits for the lock, then says so in one line.
            with pytest.raises(LibraryError) as err:
                Library(path, timeout=0.2).add_batch(run.run_id, [row(2, 1.0)])
            assert_one_line(err, "locked")
        assert time.monotonic() - t0 < 1.5
        writer.execute("COMMIT")
        with Library(path) as reader:
            assert reader.count(run.run_id) == 2
    finally:
        writer.close()


WRITER = textwrap.dedent("""
    import sys
    from sanlab.library import Library
    path, batch = sys.argv[1], int(sys.argv[2])
    lib = Library(path)
    run = lib.create_run("search", "blob", "x", {"batch": batch}, seed=1, total=10**9)
    print(run.run_id, flush=True)
    i = 0
    while True:
        lib.add_batch(run.run_id, [
            dict(idx=j, encoding="e" * 200, params={"k": [0.5] * 20}, score=j * 0.5,
                 speed_cm_s=1.0, fell=False, nonfinite=False, extra={"d": j})
            for j in range(i, i + batch)])
        i += batch
        if i == 3 * batch:
            print("started", flush=True)
""")


def test_killed_writer_leaves_complete_batches(tmp_path):
    path = tmp_path / "g.db"
    batch = 997  # odd, so a partly written batch could not pass as whole ones
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(path), str(batch)],
                            stdout=subprocess.PIPE, text=True)
    try:
        run_id = proc.stdout.readline().strip()
        assert proc.stdout.readline().strip() == "started"
        time.sleep(0.3)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    with Library(path) as lib:
        n = lib.count(run_id)
        assert n >= 3 * batch and n % batch == 0
        assert lib.done_indices(run_id) == set(range(n))
        # It was killed before it could say so: its owner process is gone, so it reads as
        # interrupted (and mark_stale_runs stores that), never "running" for ever.
        assert lib.get_run(run_id).status == lib.runs()[0].status == "interrupted"
        assert lib._conn.execute("SELECT status FROM runs").fetchone()[0] == "running"
        assert lib.mark_stale_runs() == [run_id] and lib.mark_stale_runs() == []
        assert lib._conn.execute("SELECT status FROM runs").fetchone()[0] == "interrupted"
        assert lib._conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"


# -- schema versions and error classes -----------------------------------------------------------


def test_an_older_schema_is_upgraded_through_the_migration_seam(tmp_path, monkeypatch):
    from sanlab.library import _schema

    path = tmp_path / "g.db"
    with Library(path) as lib:
        run = new_run(lib)
        lib.add_batch(run.run_id, [row(0, 1.5)])
    monkeypatch.setattr(_schema, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    monkeypatch.setattr(_schema, "MIGRATIONS", {})
    with pytest.raises(LibraryError) as err:
        Library(path)
    assert_one_line(err, str(path), f"no upgrade from library schema version {SCHEMA_VERSION}")
    step = lambda conn: conn.execute("ALTER TABLE runs ADD COLUMN note TEXT")
    monkeypatch.setattr(_schema, "MIGRATIONS", {SCHEMA_VERSION: step})
    with Library(path) as lib:
        assert lib._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION + 1
        assert [tuple(r) for r in lib._conn.execute("SELECT note FROM runs")] == [(None,)]
        assert lib.gait(f"{run.run_id}/1").score == 1.5


def test_sqlite_errors_are_told_apart_by_result_code(tmp_path):
    from sanlab.library import errors

    assert errors.is_busy("SQLITE_BUSY") and errors.is_busy("SQLITE_BUSY_SNAPSHOT")
    assert errors.is_busy("SQLITE_LOCKED_SHAREDCACHE") and not errors.is_busy("SQLITE_BUSYX")
    assert errors.is_duplicate("SQLITE_CONSTRAINT_PRIMARYKEY")
    assert not errors.is_duplicate("SQLITE_CONSTRAINT_CHECK") and not errors.is_duplicate(None)
    with Library(tmp_path / "g.db") as lib:
        run = new_run(lib)
        lib.add_trace(run.run_id, [{"trial": 0, "score": 1.0, "accepted": True}])
        with pytest.raises(LibraryError) as err:
            lib.add_trace(run.run_id, [{"trial": 1, "score": 1.0, "accepted": False},
                                       {"trial": 0, "score": 2.0, "accepted": True}])
        assert_one_line(err, "already has one of these trials")
        assert err.value.sqlite_errorname == "SQLITE_CONSTRAINT_PRIMARYKEY"
        assert [t.trial for t in lib.trace(run.run_id)] == [0]
