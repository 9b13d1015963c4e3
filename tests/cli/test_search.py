"""``sanlab search``, ``runs``, ``show``, ``export`` and ``import`` in fresh processes: Ctrl-C and
kill -9 resume to the same result, the JSON shapes, exchange between libraries, and bad
databases or ids as one line and exit 2."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import time

import pytest

from sanlab.library import Library
from tests.helpers import SANLAB, interruptible, rows_in


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_an_interrupted_search_resumes_to_the_same_top_10(tmp_path, sig):
    db = tmp_path / "gaits.db"
    # 30 batches: once the first is stored, the signal lands long before the last could be
    args = ["search", "cart", "-n", "1920", "--batch", "64", "--seconds", "1", "--seed", "9", "--db", str(db)]
    proc = subprocess.Popen(SANLAB + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=interruptible)
    deadline = time.time() + 240
    while rows_in(db) < 64 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    stored = rows_in(db)
    assert 64 <= stored < 1920, "the search should have been stopped part-way"
    assert stored % 64 == 0  # at most the batch in flight is lost
    with Library(str(db)) as lib:
        run = lib.runs()[0]
    if sig == signal.SIGINT:
        assert proc.returncode == 130
        assert f"--resume {run.run_id}" in err and "Traceback" not in err
        assert run.status == "interrupted"
    resumed = subprocess.run(SANLAB + ["search", "--resume", run.run_id, "--db", str(db), "--json"],
                             capture_output=True, text=True, check=True)
    out = json.loads(resumed.stdout)
    ref = subprocess.run(SANLAB + args[:-1] + [str(tmp_path / "ref.db"), "--json"],
                         capture_output=True, text=True, check=True)
    expected = json.loads(ref.stdout)
    assert out["evaluated"] == 1920
    strip = lambda rows: [(r["encoding"], r["score"], r["speed_cm_s"]) for r in rows]
    assert strip(out["top"]) == strip(expected["top"])
    assert [r["gait"].split("/")[1] for r in out["top"]] == [str(i) for i in range(1, 11)]


@pytest.mark.slow
@pytest.mark.parametrize("after", [1.0, 3.0, 5.0])
def test_ctrl_c_early_in_a_search_exits_130_not_a_crash(tmp_path, after):
    """Interrupted in its first seconds: the run is left interrupted with the resume hint, exit
    status 130. (With the XLA engine the interpreter's shutdown used to crash in JAX's native
    threads when the interrupt came late in the first compile: SIGSEGV, exit 139.)"""
    db = tmp_path / "gaits.db"
    args = ["search", "bounder", "-n", "100000", "--batch", "8", "--seconds", "2", "--db", str(db)]  # still running at 5 s
    proc = subprocess.Popen(SANLAB + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=interruptible)
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:  # the run exists: its first batch has begun
        try:
            with sqlite3.connect(db, timeout=5) as c:
                if c.execute("select count(*) from runs").fetchone()[0]:
                    break
        except sqlite3.Error:
            pass
        time.sleep(0.05)
    time.sleep(after)  # somewhere in its batches
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err[-2000:]
    assert "--resume" in err and "Traceback" not in err
    with Library(str(db)) as lib:
        assert lib.runs()[0].status == "interrupted"


@pytest.mark.slow  # several processes (the pre-commit subset leaves it out)
def test_search_json_has_the_documented_shape(tmp_path):
    db = str(tmp_path / "g.db")
    r = subprocess.run(SANLAB + ["search", "cart", "-n", "20", "--seconds", "0.5", "--db", db, "--json"],
                       capture_output=True, text=True, check=True)
    out = json.loads(r.stdout)
    assert set(out) == {"schema", "run_id", "creature", "metric", "score_unit", "evaluated", "tally", "top"}
    assert out["schema"] == "sanlab/search/1" and out["evaluated"] == out["tally"]["evaluated"] == 20
    first = out["top"][0]
    assert {"gait", "score", "speed_cm_s", "fell", "encoding", "dx_m", "direction"} <= set(first)
    for row in out["top"]:  # the signed displacement is stored with every evaluation
        assert row["dx_m"] is not None and row["direction"] == ("+x" if row["dx_m"] > 0 else "-x" if row["dx_m"] < 0 else None)
    assert first["gait"] == f"{out['run_id']}/1"
    runs = json.loads(subprocess.run(SANLAB + ["runs", "--db", db, "--json"], capture_output=True,
                                     text=True, check=True).stdout)
    assert runs[0]["run_id"] == out["run_id"] and runs[0]["status"] == "done"
    assert runs[0]["creature"] == "cart" and runs[0]["evaluated"] == 20
    # a resumed run keeps its stored settings: an option that would change them is refused, not ignored
    for cmd in (["search", "--resume", out["run_id"], "-n", "40", "--seed", "3"],
                ["tune", "--resume", out["run_id"], "--trials", "5"]):
        r = subprocess.run(SANLAB + cmd + ["--db", db], capture_output=True, text=True)
        assert r.returncode == 2 and "Traceback" not in r.stderr
        assert "cannot change a resumed run" in r.stderr and ("--controllers, --seed" in r.stderr or "--trials" in r.stderr)
    with Library(db) as lib:
        assert lib.count(out["run_id"]) == 20 and len(lib.runs()) == 1
    shown = json.loads(subprocess.run(SANLAB + ["show", out["run_id"][:5], "--db", db, "--json"],
                                      capture_output=True, text=True, check=True).stdout)
    assert shown["top"] == out["top"]


@pytest.mark.slow  # several processes (the pre-commit subset leaves it out)
def test_export_then_import_round_trips(tmp_path):
    db, other = str(tmp_path / "g.db"), str(tmp_path / "other.db")
    out = json.loads(subprocess.run(SANLAB + ["search", "cart", "-n", "10", "--seconds", "0.5", "--db", db, "--json"],
                                    capture_output=True, text=True, check=True).stdout)
    gait = out["top"][0]["gait"]
    path = tmp_path / "gait.json"
    subprocess.run(SANLAB + ["export", gait, "--db", db, "-o", str(path)], check=True)
    data = json.loads(path.read_text())
    assert data["encoding"] == out["top"][0]["encoding"] and data["creature"] == "cart"
    new = subprocess.run(SANLAB + ["import", str(path), "--db", other], capture_output=True, text=True,
                         check=True).stdout.strip()
    with Library(other) as lib:
        e = lib.gait(new)
    assert e.encoding == data["encoding"] and e.score == pytest.approx(data["score"])


@pytest.mark.parametrize("content", [b"hello, this is not a database\n", os.urandom(4096)])
def test_a_corrupt_or_foreign_database_is_a_clear_error(tmp_path, content):
    bad = tmp_path / "bad.db"
    bad.write_bytes(content)
    r = subprocess.run(SANLAB + ["runs", "--db", str(bad)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert "bad.db" in r.stderr


def test_a_foreign_sqlite_database_is_refused_and_left_alone(tmp_path):
    path = tmp_path / "other.db"
    with sqlite3.connect(path) as c:
        c.execute("create table recipes (name text)")
    before = path.read_bytes()
    r = subprocess.run(SANLAB + ["search", "cart", "-n", "5", "--db", str(path)], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "other.db" in r.stderr
    assert path.read_bytes() == before


@pytest.mark.slow  # several processes (the pre-commit subset leaves it out)
def test_missing_run_and_bad_gait_ids_are_clear_errors(tmp_path):
    db = str(tmp_path / "g.db")
    for args in (["show", "deadbeef"], ["export", "nonsense"], ["search"]):
        r = subprocess.run(SANLAB + args + ["--db", db], capture_output=True, text=True)
        assert r.returncode == 2, args
        assert "Traceback" not in r.stderr and r.stderr.strip(), args


@pytest.mark.slow  # several processes (the pre-commit subset leaves it out)
def test_search_prints_the_static_check_warnings_once_on_stderr(tmp_path):
    from tests.helpers import DATA

    db = str(tmp_path / "g.db")
    r = subprocess.run(SANLAB + ["search", str(DATA / "radians.toml"), "-n", "8", "--seconds", "0.2", "--db", db,
                                 "--json"], capture_output=True, text=True, check=True)
    assert json.loads(r.stdout)["evaluated"] == 8  # stdout stays JSON
    warnings = [line for line in r.stderr.splitlines() if line.startswith("warning:")]
    assert any("look like radians" in w for w in warnings) and any("stronger than" in w for w in warnings)
    assert len(warnings) == len(set(warnings))  # each once
    quiet = subprocess.run(SANLAB + ["search", "cart", "-n", "8", "--seconds", "0.2", "--db", db, "--json"],
                           capture_output=True, text=True, check=True)
    assert "warning:" not in quiet.stderr
    # simulate scores the same file as search does, with the same warnings; --top bounds its JSON
    # as it bounds its table
    sim = subprocess.run(SANLAB + ["simulate", str(DATA / "radians.toml"), "-n", "8", "--seconds", "0.2", "--top", "3",
                                   "--json"], capture_output=True, text=True, check=True)
    assert len(json.loads(sim.stdout)["top"]) == 3
    assert [line for line in sim.stderr.splitlines() if line.startswith("warning:")] == warnings


@pytest.mark.parametrize("args", [
    ["search", "bounder", "-n", "0"],  # out of range (Typer's check)
    ["search", "bounder", "--frobnicate"],  # unknown option
    ["tune", "x/1", "--trials", "abc"],  # not a number
    ["search", "bounder", "--seconds", "inf"],  # sanlab's own check, before a run exists
    ["search", "bounder", "--ensemble", "100000"],
    ["search", "bounder", "--dt-factors", "1,half"],
    ["search", "bounder", "--dt-factors", "0.5,1"],  # the first factor is the creature's own step
    ["search", "bounder", "--ensemble", "1", "--dt-factors", "1,0.5"],  # two groups need two members
    ["search", "bounder", "--dt-jitter", "0.7"],
    ["simulate", "bounder", "--seconds", "1e9"],
    ["search", "bounder", "--seconds", "nan"],  # once Typer's "should be >= 0.001": now what is expected
])
def test_command_line_mistakes_are_one_line_with_exit_2(tmp_path, args):
    db = tmp_path / "g.db"
    r = subprocess.run(SANLAB + args + (["--db", str(db)] if args[0] != "simulate" else []),
                       capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr and "╭" not in r.stderr, r.stderr
    assert r.stdout == "" and not db.exists()  # nothing started, nothing stored
    if "nan" in args:
        assert "--seconds: expected a number of seconds in (0, 1000]" in r.stderr, r.stderr
