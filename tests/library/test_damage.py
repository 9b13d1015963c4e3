"""Issue 12, kinds 4 and 6 at the library's level: imports checked completely before anything is
written, damaged cells, read-only folders, FIFOs, schema 2's owners of running runs."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile

import pytest
import typer
from hypothesis import HealthCheck, given, settings
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.cli._common import open_library
from sanlab.creature import load, read_source
from sanlab.library import SCHEMA_VERSION, Library, LibraryError
from sanlab.san import San
from tests.fuzz import page_damage
from tests.helpers import ROOT, time_limit
from tests.library.test_library import assert_one_line, new_run, real_row, real_run


def export(tmp_path, params: dict | None = None) -> dict:
    with Library(tmp_path / "src.db") as lib:
        run, enc = real_run(lib)
        row = real_row(0, 1.0, enc)
        if params is not None:
            row["params"] = params
        lib.add_batch(run.run_id, [row])
        return lib.export_gait(f"{run.run_id}/1")


BOUNDER = read_source("bounder")[0]
CART_SAN = San.for_creature(load("cart"))


def _set(path, value):
    def change(d):
        target = d
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return change


def _nested(depth: int) -> list:
    v: list = []
    for _ in range(depth):
        v = [v]
    return v


# (id, change to a valid export, what the one-line error says)
BAD_IMPORTS = [
    ("encoding too short", lambda d: d.update(encoding=d["encoding"][:-8]), "encoding: expected"),
    ("encoding of another network", lambda d: d.update(encoding="san1-5-5-1-" + d["encoding"].split("-")[-1]),
     "encoding is for sensors/hidden/actuators (5, 5, 1)"),
    ("encoding not base64", lambda d: d.update(encoding="san1-6-5-1-!!!!"), "encoding"),
    ("creature text of another network",
     lambda d: (d.update(creature_text=BOUNDER, creature="bounder"), d.pop("creature_hash")), "encoding is for"),
    ("creature name not the text's", lambda d: (d.update(creature="walker")), "'creature' is 'walker'"),
    ("creature text no longer valid", lambda d: (d.update(creature_text=d["creature_text"].replace("dt = 0.001", "dt = 1")),
                                                 d.pop("creature_hash")), "creature_text: dt: expected"),
    ("unknown model parameter", _set(["params", "model"], {"gravity_boost": [1.0]}), "params.model.gravity_boost: unknown"),
    ("k1 of the wrong length", _set(["params"], {"k1": [10.0] * 3, "k2": [-10.0] * 3}), "params.k1: expected 6 rates"),
    ("k1 without k2", _set(["params"], {"k1": [10.0] * 6}), "both k1 and k2"),
    ("zero delay", _set(["params"], {"delay_on": 0, "delay_off": 0.1}), "params.delay_on: expected a delay in [0.001, 100]"),
    ("negative rate", _set(["params"], {"k1": [10.0] * 6, "k2": [10.0] * 6}), "params.k2"),
    ("act_min above act_max", _set(["params", "model"], {"act_min": [1.0], "act_max": [0.5]}), "params.model.act_max[0]"),
    ("a gain that is not finite", _set(["params", "model"], {"act_ks": [1e300]}), "params.model.act_ks"),
    ("a model array of the wrong shape", _set(["params", "model"], {"com": [[0, 0]]}), "shape 2x2"),
    ("unknown parameter", _set(["params", "weights"], [1, 2]), "params.weights: unknown parameter"),
    ("seed beyond SQLite", _set(["run_params", "seed"], 2**70), "run_params.seed"),
    ("negative seed", _set(["run_params", "seed"], -1), "run_params.seed"),
    ("unknown metric", _set(["run_params", "metric"], "speed"), "run_params.metric"),
    ("seconds beyond the step limit", _set(["run_params", "seconds"], 1e9), "run_params.seconds"),
    ("zero seconds", _set(["run_params", "seconds"], 0), "run_params.seconds"),
    ("infinite score", _set(["score"], float("inf")), "'score' must be a finite number"),
    ("a lone surrogate", _set(["creature"], "cart\ud800"), "not valid Unicode"),
    ("unknown dtype", _set(["dtype"], "float16"), "'dtype' must be"),
    ("extra nested too deep", _set(["extra"], {"a": _nested(5000)}), "nested too deep"),
    ("a misspelt optional field", lambda d: d.update(non_finite=d.pop("nonfinite")), "unknown field 'non_finite'"),
    ("an audit that is not an object", _set(["audit"], "robust"), "field 'audit' has the wrong type"),
]


@pytest.mark.parametrize("change, needle", [b[1:] for b in BAD_IMPORTS], ids=[b[0] for b in BAD_IMPORTS])
def test_an_import_is_checked_completely_before_anything_is_written(tmp_path, change, needle):
    data = export(tmp_path)
    change(data)
    with Library(tmp_path / "dst.db") as lib:
        with pytest.raises(LibraryError) as err:
            lib.import_gait(data)
        assert_one_line(err, needle)
        assert lib.runs() == []  # nothing written


def test_a_tuned_gait_with_model_overrides_imports(tmp_path):
    params = {"k1": [10.0, 12.0, 9.0, 10.0, 11.0, 10.0], "k2": [-10.0] * 6,
              "model": {"act_min": [-2.0], "act_max": [2.1], "act_ks": [0.2], "act_kd": [0.01],
                        "sens_min": [0, 0, 0, 0, -3.1, 2.1], "sens_max": [0, 0, 0, 0, -2.1, 3.1]},
              "scale": [1.1, 0.9]}
    data = export(tmp_path, params=params)
    with Library(tmp_path / "dst.db") as lib:
        gid = lib.import_gait(data)
        assert lib.gait(gid).params == params


# -- damaged cells ---------------------------------------------------------------------------------


def damaged(tmp_path) -> tuple[str, str, str]:
    """(path, damaged run, intact run) of a library whose first run has a cell of bad UTF-8."""
    path = str(tmp_path / "g.db")
    with Library(path) as lib:
        bad, enc = real_run(lib)
        lib.add_batch(bad.run_id, [real_row(0, 1.0, enc)])
        good, enc = real_run(lib)
        lib.add_batch(good.run_id, [real_row(0, 2.0, enc)])
        for run in (bad, good):
            lib.set_status(run.run_id, "done")
    return path, bad.run_id, good.run_id


@pytest.mark.parametrize("table, column, value, why", [
    ("runs", "creature", "CAST(x'ff' AS TEXT)", "its creature: its text is not valid UTF-8"),
    ("runs", "params", "'{not json'", "its params: it is not valid JSON"),
    ("runs", "params", "'[1, 2]'", "its params: a JSON dict was expected"),
    ("runs", "creature_text", "CAST(x'c3' AS TEXT)", "its creature_text: its text is not valid UTF-8"),
    ("runs", "total", "'many'", "its total"),
])  # fmt: skip
def test_a_damaged_run_is_listed_and_refused_by_name(tmp_path, table, column, value, why):
    path, bad, good = damaged(tmp_path)
    con = sqlite3.connect(path)
    con.execute(f"UPDATE {table} SET {column} = {value} WHERE run_id = ?", (bad,))
    con.commit()
    con.close()
    with Library(path, readonly=True) as lib:
        listed = {r.run_id: r.status for r in lib.runs()}
        assert listed == {bad: "damaged", good: "done"}
        assert why in lib.damage(bad) and lib.damage(good) is None
        with pytest.raises(LibraryError) as err:
            lib.get_run(bad)
        assert_one_line(err, path, f"run {bad} is damaged", why, "restore this file from a backup")
        assert lib.export_gait(f"{good}/1")["score"] == 2.0  # the rest is intact


@pytest.mark.parametrize("column, value, why", [
    ("encoding", "CAST(x'80' AS TEXT)", "its encoding: its text is not valid UTF-8"),
    ("params", "'{'", "its params: it is not valid JSON"),
    ("extra", "'nan'", "its extra"),
    ("score", "'fast'", "its score: a number was expected"),
])
def test_a_damaged_gait_is_refused_by_name(tmp_path, column, value, why):
    path, bad, good = damaged(tmp_path)
    con = sqlite3.connect(path)
    con.execute(f"UPDATE evaluations SET {column} = {value} WHERE run_id = ?", (bad,))
    con.commit()
    con.close()
    with Library(path) as lib:
        assert lib.get_run(bad).status == "done"  # the run itself reads
        for read in (lambda: lib.gait(f"{bad}/1"), lambda: lib.top(bad), lambda: lib.export_gait(f"{bad}#0")):
            with pytest.raises(LibraryError) as err:
                read()
            assert_one_line(err, path, f"gait {bad}#0", why)
        assert lib.gait(f"{good}/1").score == 2.0


def test_a_gait_whose_cells_read_but_do_not_decode_is_neither_exported_nor_audited(tmp_path):
    """Valid text that is not an encoding of its creature's network: every cell reads, so only
    decoding finds it; an export would write a file that import refuses, an audit would end in a
    traceback."""
    from sanlab.audit import audit_and_store

    path, bad, good = damaged(tmp_path)
    con = sqlite3.connect(path)
    con.execute("UPDATE evaluations SET encoding = 'san1-zzz' WHERE run_id = ?", (bad,))
    con.commit()
    con.close()
    with Library(path) as lib:
        with pytest.raises(LibraryError) as err:
            lib.export_gait(f"{bad}/1")
        assert_one_line(err, path, f"gait {bad}#0 cannot be exported", "encoding")
        with pytest.raises(LibraryError) as err:
            audit_and_store(lib, f"{bad}/1")
        assert_one_line(err, path, f"gait {bad}#0 cannot be decoded", "san1-zzz")
        assert lib.audit(f"{bad}#0") is None  # nothing stored
        assert lib.export_gait(f"{good}/1")["score"] == 2.0  # the rest is intact


# -- reading without writing -----------------------------------------------------------------------


def test_readonly_writes_nothing_and_refuses_a_missing_or_empty_file(tmp_path):
    path = tmp_path / "g.db"
    with pytest.raises(LibraryError, match="no such gait library"):
        Library(path, readonly=True)
    assert not path.exists()
    path.touch()
    with pytest.raises(LibraryError, match="an empty file, not yet a gait library"):
        Library(path, readonly=True)
    assert path.stat().st_size == 0
    path.unlink()
    with Library(path) as lib:
        new_run(lib)
    before = path.read_bytes()
    with Library(path, readonly=True) as lib:
        assert len(lib.runs()) == 1
        with pytest.raises(LibraryError):
            new_run(lib)
    assert path.read_bytes() == before


READER = """
import sys
from sanlab.library import Library
lib = Library(sys.argv[1], readonly=True)
print(len(lib.runs()), lib.gait(lib.runs()[0].run_id + "/1").score)
try:
    Library(sys.argv[1])
except Exception as e:
    print(type(e).__name__, e)
"""


def test_a_library_in_a_read_only_folder_can_be_read(tmp_path):
    folder = tempfile.mkdtemp()  # not under pytest's private tmp dir: another user must reach it
    try:
        path = os.path.join(folder, "g.db")
        with Library(path) as lib:
            run, enc = real_run(lib)
            lib.add_batch(run.run_id, [real_row(0, 1.5, enc)])
        os.chmod(path, 0o644)
        os.chmod(folder, 0o555)
        cmd, kw = [sys.executable, "-c", READER, path], {}
        if os.geteuid() == 0:  # root writes anywhere: read as nobody, with an interpreter nobody can run
            python = shutil.which("python3", path="/usr/bin:/bin") or sys.executable
            kw = dict(user=65534, group=65534)
            cmd[0] = python
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd="/", **kw)
        if r.returncode != 0 and ("ModuleNotFoundError" in r.stderr or "Permission denied" in r.stderr):
            pytest.skip(f"no interpreter another user can run here ({r.stderr.strip().splitlines()[-1]})")
        assert r.returncode == 0, r.stderr
        lines = r.stdout.splitlines()
        assert lines[0] == "1 1.5"
        assert lines[1].startswith("LibraryError") and "cannot write" in lines[1] and "read-only" in lines[1]
        assert sorted(os.listdir(folder)) == ["g.db"]  # nothing was made beside it
    finally:
        os.chmod(folder, 0o755)
        shutil.rmtree(folder)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_not_a_library_and_is_never_waited_on(tmp_path):
    fifo = tmp_path / "g.db"
    os.mkfifo(fifo)
    for readonly in (False, True):
        with time_limit(cpu=5, wall=20), pytest.raises(LibraryError) as err:
            Library(fifo, readonly=readonly)
        assert_one_line(err, str(fifo), "is a FIFO (named pipe), not a gait library")


def test_an_empty_path_is_refused():
    with pytest.raises(LibraryError) as err:
        Library("")
    assert_one_line(err, "path is empty")


# -- schema 2: owners of running runs ------------------------------------------------------------


V1_RUNS = """CREATE TABLE runs (run_id TEXT PRIMARY KEY, kind TEXT NOT NULL, created TEXT NOT NULL,
    creature TEXT NOT NULL, creature_text TEXT NOT NULL, creature_hash TEXT NOT NULL, params TEXT NOT NULL,
    seed INTEGER, sanlab_version TEXT NOT NULL, device TEXT, dtype TEXT, status TEXT NOT NULL,
    parent_gait TEXT, total INTEGER NOT NULL)"""


def test_a_version_1_library_is_read_as_it_is_and_upgraded_when_written(tmp_path):
    from sanlab.library import _schema

    path = tmp_path / "v1.db"
    con = sqlite3.connect(path)
    con.execute(V1_RUNS)
    for ddl in _schema.DDL[1:]:  # version 1's rank index had no fell, and it had no audits, selections nor designs
        if ddl in (_schema.AUDITS_DDL, _schema.SELECTIONS_DDL, _schema.DESIGNS_DDL, _schema.DESIGNS_INDEX,
                   _schema.DESIGN_SCORES_DDL):
            continue
        con.execute(ddl.replace("score DESC, fell, idx", "score DESC, idx"))
    con.execute("INSERT INTO runs VALUES ('abcd1234', 'search', '2024-01-01T00:00:00', 'cart', 'x', 'h', '{}', 1, "
                "'0.1.0', NULL, NULL, 'running', NULL, 5)")
    con.execute(f"PRAGMA application_id = {_schema.APPLICATION_ID}")
    con.execute("PRAGMA user_version = 1")
    con.commit()
    con.close()
    with Library(path, readonly=True) as lib:
        assert lib.runs()[0].status == "running"  # no owner recorded: nothing to tell
    assert sqlite3.connect(path).execute("PRAGMA user_version").fetchone()[0] == 1
    with Library(path) as lib:
        assert lib._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 5
        assert lib.audits("abcd1234") == {} and lib.selection("abcd1234") is None and lib.designs() == []
        assert lib.runs()[0].run_id == "abcd1234"
        lib.set_status("abcd1234", "running")
        owner = json.loads(lib._conn.execute("SELECT owner FROM runs").fetchone()[0])
        assert owner["pid"] == os.getpid()
        index = lib._conn.execute("SELECT sql FROM sqlite_schema WHERE name = 'evaluations_by_rank'").fetchone()[0]
        assert "score DESC, fell, idx" in index


def test_only_a_live_owner_writes_a_running_run(tmp_path):
    path = tmp_path / "g.db"
    with Library(path) as lib:
        run = new_run(lib)
        other = {"host": __import__("socket").gethostname(), "pid": os.getppid(), "start": None}
        lib._conn.execute("UPDATE runs SET owner = ?", (json.dumps(other),))
        with pytest.raises(LibraryError) as err:
            lib.set_status(run.run_id, "running")
        assert_one_line(err, f"run {run.run_id} is being written by process {os.getppid()}")
        assert lib.get_run(run.run_id).status == "running"
        lib.set_status(run.run_id, "interrupted")  # anyone may say it stopped
        lib.set_status(run.run_id, "running")  # and then take it over
        assert json.loads(lib._conn.execute("SELECT owner FROM runs").fetchone()[0])["pid"] == os.getpid()


def test_a_run_whose_process_exited_but_is_not_yet_reaped_reads_interrupted(tmp_path):
    """A killed process stays a zombie until its parent reaps it (for a while, under a container's
    init): it no longer runs, so its run is not "running"."""
    import socket
    import time

    from sanlab.library.store import _process_start

    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        owner = {"host": socket.gethostname(), "pid": child.pid, "start": _process_start(child.pid)}
        with Library(tmp_path / "g.db") as lib:
            run = new_run(lib)
            lib._conn.execute("UPDATE runs SET owner = ?", (json.dumps(owner),))
            assert lib.get_run(run.run_id).status == "running"  # alive: its run is running
            child.kill()
            deadline = time.time() + 10
            while open(f"/proc/{child.pid}/stat").read().rsplit(")", 1)[1].split()[0] != "Z" and time.time() < deadline:
                time.sleep(0.01)
            assert lib.get_run(run.run_id).status == "interrupted"  # exited, not yet reaped
    finally:
        child.kill()
        child.wait()


def test_discard_run_removes_only_a_run_without_evaluations(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        empty, full = new_run(lib), new_run(lib)
        lib.add_batch(full.run_id, [{"idx": 0, "encoding": "e", "score": 1.0}])
        lib.discard_run(empty.run_id)
        with pytest.raises(LibraryError) as err:
            lib.discard_run(full.run_id)
        assert_one_line(err, "has 1 stored evaluation; it is kept")
        assert [r.run_id for r in lib.runs()] == [full.run_id]


def test_integers_beyond_sqlite_are_refused_before_writing(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        with pytest.raises(LibraryError) as err:
            new_run(lib, seed=2**70)
        assert_one_line(err, "seed must be an integer in [-2**63, 2**63 - 1]")
        with pytest.raises(LibraryError):
            lib.top(new_run(lib).run_id, 10**30)
        assert len(lib.runs()) == 1


# -- queries the search driver's guidance uses ------------------------------------------------------


def test_at_equal_scores_standing_gaits_rank_before_fallen_ones(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        run = new_run(lib)
        lib.add_batch(run.run_id, [{"idx": i, "encoding": "e", "score": s, "fell": f}
                                   for i, (s, f) in enumerate([(0.0, True), (0.0, True), (0.0, False), (0.5, False),
                                                               (0.0, False)])])
        assert [e.idx for e in lib.top(run.run_id)] == [3, 2, 4, 0, 1]
        assert lib.gait(f"{run.run_id}/2").idx == 2 and lib.gait(f"{run.run_id}#0").rank == 4
        assert lib.tally(run.run_id) == {"evaluated": 5, "fell": 2, "nonfinite": 0}


def test_ranked_lookups_use_the_rank_index_without_sorting(tmp_path):
    from sanlab.library import store

    with Library(tmp_path / "g.db") as lib:
        for query in (f"SELECT * FROM evaluations WHERE run_id = ? ORDER BY {store._RANK_ORDER} LIMIT 10",
                      f"SELECT * FROM evaluations WHERE run_id = ? ORDER BY {store._RANK_ORDER} LIMIT 1 OFFSET 5"):
            plan = " / ".join(r[-1] for r in lib._conn.execute("EXPLAIN QUERY PLAN " + query, ("x",)))
            assert "evaluations_by_rank" in plan and "TEMP B-TREE" not in plan, plan


def test_same_runs_finds_earlier_runs_with_the_same_file_settings_and_seed(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        first = new_run(lib, seed=3)
        new_run(lib, seed=4)
        new_run(lib, seed=3, params={"seconds": 11.0, "metric": "distance", "batch": 4})
        same = lib.same_runs("search", first.creature_text, first.params, 3)
        assert [r.run_id for r in same] == [first.run_id]
        assert lib.same_runs("tune", first.creature_text, first.params, 3) == []


def test_no_nan_or_infinity_is_ever_stored_as_json(tmp_path):
    with Library(tmp_path / "g.db") as lib:
        with pytest.raises(LibraryError) as err:
            new_run(lib, params={"seconds": float("inf")})
        assert_one_line(err, "run params hold a number that is not finite")
        run = new_run(lib)
        lib.add_batch(run.run_id, [{"idx": 0, "encoding": "e", "score": 1.0, "extra": {"d": float("nan"), "v": [float("inf")]}}])
        raw = lib._conn.execute("SELECT extra FROM evaluations").fetchone()[0]
        assert json.loads(raw, parse_constant=lambda c: pytest.fail(c)) == {"d": None, "v": [None]}


# -- damaged pages (issue 48) ----------------------------------------------------------------------


def _library_of_pages(path) -> int:
    """A library of about 80 pages at ``path`` (one run, 2,000 evaluations); its page count."""
    with Library(path) as lib:
        run = new_run(lib, total=2000)
        lib.add_batch(run.run_id, [real_row_free(i) for i in range(2000)])
    con = sqlite3.connect(path)
    con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    pages = con.execute("PRAGMA page_count").fetchone()[0]
    con.close()
    return pages


def real_row_free(i: int) -> dict:
    from tests.library.test_library import row

    return row(i, float(i % 97))


def _quick_check(path) -> bool:
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        return con.execute("PRAGMA quick_check(1)").fetchone()[0] == "ok"
    except sqlite3.DatabaseError:
        return False
    finally:
        con.close()


def _digest(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    path = tmp_path_factory.mktemp("pages") / "lib.db"
    return str(path), _library_of_pages(path)


DAMAGED_SEEN: list = []


@settings(database=None, deadline=None, derandomize=True, max_examples=60,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=page_damage(pages=40))
def test_a_library_failing_the_quick_check_is_refused_for_writing_and_left_as_it_is(pristine, tmp_path, data):
    source, pages = pristine
    assert pages > 40
    path = str(tmp_path / "lib.db")
    shutil.copy(source, path)
    with open(path, "r+b") as f:
        for at, byte, count in data:
            f.seek(at)
            f.write(bytes([byte]) * count)
    intact, before = _quick_check(path), _digest(path)
    if intact:
        open_library(path).close()
        return
    with pytest.raises(typer.Exit) as e:  # fail(): its line goes to stderr
        open_library(path).close()
    assert e.value.exit_code == 2
    DAMAGED_SEEN.append(data)
    with pytest.raises(LibraryError) as err:
        Library(path).check_intact()
    # the quick check's line, or, where a page of the schema (past the first since schema 5) is
    # what was overwritten, the open's
    assert_one_line(err, f"{path}: damaged: ", "sqlite3 ", " .recover")
    assert "SQLite's quick check fails (" in str(err.value) or "SQLite cannot read its schema (" in str(err.value)
    assert _digest(path) == before  # nothing written: not a page, not a -wal to fold back in later


def test_most_generated_damage_fails_the_quick_check():
    """The generator above is worth its examples: most of them damage what SQLite checks."""
    if not DAMAGED_SEEN:
        pytest.skip("run with the test above")
    assert len(DAMAGED_SEEN) >= 30, len(DAMAGED_SEEN)


runner = CliRunner()


@pytest.mark.parametrize("args", [
    ["search", "twolink", "-n", "1", "--seconds", "0.05"],
    ["tune", "xx/1", "--trials", "1"],
    ["audit", "xx/1"],
    ["import", "{export}"],
])  # fmt: skip
def test_every_command_that_writes_refuses_a_damaged_library_before_doing_work(pristine, tmp_path, args):
    source, _ = pristine
    path = str(tmp_path / "lib.db")
    shutil.copy(source, path)
    with open(path, "r+b") as f:
        for page in (5, 17, 30):
            f.seek(page * 4096)
            f.write(b"\xaa" * 4096)
    before = _digest(path)
    exported = tmp_path / "gait.json"
    exported.write_text(json.dumps(export(tmp_path)))
    r = runner.invoke(app, [a.replace("{export}", str(exported)) for a in args] + ["--db", path])
    assert r.exit_code == 2, r.output
    assert r.stderr.startswith(f"{path}: damaged: SQLite's quick check fails (") and r.stderr.count("\n") == 1, r.stderr
    assert _digest(path) == before
    assert not os.path.exists(path + "-wal") or os.path.getsize(path + "-wal") == 0


class _FullAtCommit:
    """A connection whose next COMMIT fails as SQLite's does on a full disk (SQLITE_FULL), with
    the transaction left open, as SQLite may leave it."""

    def __init__(self, conn: sqlite3.Connection):
        self._conn, self.fail_next = conn, True

    def execute(self, sql: str, *args):
        if sql == "COMMIT" and self.fail_next:
            self.fail_next = False
            raise sqlite3.OperationalError("database or disk is full")
        return self._conn.execute(sql, *args)

    def __getattr__(self, name: str):
        return getattr(self._conn, name)


def test_a_commit_that_fails_on_a_full_disk_leaves_the_library_writable(tmp_path):
    """Issue 48: a tuning stopped by a full disk was once left "running": a COMMIT that fails
    can leave its transaction open, and then the write that marks the run "interrupted" failed
    on BEGIN. The failed transaction is now rolled back: nothing of it is stored, and the next
    write works."""
    from tests.library.test_library import row

    path = str(tmp_path / "g.db")
    with Library(path) as lib:
        run = new_run(lib, total=10)
        lib.set_status(run.run_id, "running")
        lib._conn = _FullAtCommit(lib._conn)  # type: ignore[assignment]
        with pytest.raises(LibraryError) as e:
            lib.add_batch(run.run_id, [row(i, 1.0) for i in range(4)])
        assert_one_line(e, "database or disk is full")
        lib.set_status(run.run_id, "interrupted")
        assert lib.get_run(run.run_id).status == "interrupted" and lib.count(run.run_id) == 0
