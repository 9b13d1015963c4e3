"""``sanlab tune`` in a fresh process: the JSON it prints, a bad method as one line, and Ctrl-C or
kill -9 resumed (``--resume``) to exactly the uninterrupted result."""

from __future__ import annotations

import json
import signal
import sqlite3
import subprocess
import time

import pytest

from sanlab.library import Library
from tests.helpers import SANLAB, interruptible, rows_in


@pytest.mark.slow  # over 4 s even with a warm compile cache (the pre-commit subset leaves it out)
def test_tune_cli_json(bounder_run):
    db, run_id = bounder_run
    # single samples: the tuned gait's score is then its own best (with an ensemble it is re-scored
    # on held-out draws, which may fall below the start's)
    r = subprocess.run(SANLAB + ["tune", f"{run_id}/1", "--method", "sga", "--trials", "5", "--batch", "64",
                                 "--ensemble", "1", "--db", str(db), "--json"], capture_output=True, text=True, check=True)
    [out] = json.loads(r.stdout)  # always a list, one element per chain
    assert set(out) == {"schema", "gait", "tuned_gait", "run_id", "before", "after", "direction", "trials", "accepted"}
    assert out["schema"] == "sanlab/tuning/1" and out["tuned_gait"] == f"{out['run_id']}#0"
    assert 0 <= out["accepted"] <= out["trials"]
    assert out["trials"] == 5 and out["after"]["score"] >= out["before"]["score"]
    assert set(out["before"]) == {"score", "speed_cm_s"}
    bad = subprocess.run(SANLAB + ["tune", f"{run_id}/1", "--method", "newton", "--db", str(db)],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    lone = subprocess.run(SANLAB + ["tune", f"{run_id}/1", "--threshold", "0.2", "--db", str(db)],
                          capture_output=True, text=True)
    assert lone.returncode == 2 and "--threshold applies to --select" in lone.stderr


@pytest.mark.slow  # about 15 s on 2 cores: a tuning with its selection, an audit and a show, each a process
def test_tune_select_stores_and_reports_the_robust_gait(bounder_run, tmp_path):
    import shutil

    src, run_id = bounder_run
    db = tmp_path / "copy.db"
    shutil.copy(src, db)
    r = subprocess.run(SANLAB + ["tune", f"{run_id}/1", "--method", "sga", "--trials", "6", "--batch", "8",
                                 "--ensemble", "2", "--select", "--threshold", "0.2", "--db", str(db)],
                       capture_output=True, text=True, check=True)
    with Library(str(db)) as lib:
        tuned_run = next(x.run_id for x in lib.runs() if x.kind == "tune")
    # the selection is stored with its threshold: asking again with it answers from the library, as JSON
    again = subprocess.run(SANLAB + ["audit", tuned_run, "--select", "--threshold", "0.2", "--db", str(db), "--json"],
                           capture_output=True, text=True, check=True)
    sel = json.loads(again.stdout)
    assert sel["run_id"] == tuned_run and sel["threshold"] == 0.2
    assert sel["candidates"] and sel["candidates"][0]["trial"] == -1
    with Library(str(db)) as lib:
        assert lib.selection(tuned_run)["settings"]["threshold"] == 0.2
        # the chain's best (#0) is audited with the selection, so that show and exports flag it
        best = lib.audit(f"{tuned_run}#0")
        assert best is not None and best.result["threshold"] == 0.2
        # flagged at the selection's threshold: unless every nudge's interval lies inside +-20 %
        # (robust), an undecided audit too, whose point change may be inside the band
        inside = all(s["lo"] is not None and s["hi"] is not None and -0.2 <= s["lo"] and s["hi"] <= 0.2
                     for s in best.result["shifts"].values())
        assert best.flagged == (best.verdict != "robust") == (not (best.reproduced and inside))
        assert best.flagged or best.worst <= 0.2  # a point change past the band is never vouched for
        if sel["robust_gait"] is None:  # no rung kept its speed: nothing stored, and no rung passed
            assert not any(c["verdict"] == "robust" and c.get("confirmed_verdict") == "robust"
                           for c in sel["candidates"])
            assert 1 not in {e.idx for e in lib.top(tuned_run, None)}
            assert f"{tuned_run}: no rung of its climb" in " ".join(r.stdout.split())
            assert "within 20 %" in " ".join(r.stdout.split())
        else:
            assert f"{tuned_run}: robust tuned gait {tuned_run}#1" in " ".join(r.stdout.split())
            assert sel["robust_gait"] == f"{tuned_run}#1" and sel["worst"] <= 0.2
            assert lib.gait(sel["robust_gait"]).speed_cm_s == sel["speed_cm_s"]
            assert not lib.audit(sel["robust_gait"]).flagged
    # and `sanlab show` carries the chain's best's audit as stored
    shown = json.loads(subprocess.run(SANLAB + ["show", f"{tuned_run}#0", "--db", str(db), "--json"],
                                      capture_output=True, text=True, check=True).stdout)
    assert shown["audit"]["verdict"] == best.verdict and shown["audit"]["flagged"] == best.flagged
    # a tuning's progress is its trials, whatever number of gaits it stored (one, or two with a
    # robust selection), in `runs` and in the studio's run list
    listed = subprocess.run(SANLAB + ["runs", "--db", str(db)], capture_output=True, text=True, check=True).stdout
    row = next(line for line in listed.splitlines() if tuned_run in line)
    assert "6/6 trials" in row and "/1 " not in row, row
    assert f"{run_id}" in listed and "evaluated" in next(line for line in listed.splitlines() if run_id in line)
    rows = json.loads(subprocess.run(SANLAB + ["runs", "--db", str(db), "--json"], capture_output=True, text=True,
                                     check=True).stdout)
    assert next(r for r in rows if r["run_id"] == tuned_run)["trials"] == 6
    from sanlab.studio.service import Service

    studio_row = next(r for r in Service(str(db)).runs() if r["run_id"] == tuned_run)
    assert studio_row["trials"] == 6 and studio_row["progress"] == {"done": 6, "planned": 6, "unit": "trials"}



@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_an_interrupted_tuning_resumes_to_the_uninterrupted_result(bounder_run, tmp_path, sig):
    src, run_id = bounder_run
    db, ref = tmp_path / "gaits.db", tmp_path / "ref.db"
    with sqlite3.connect(src) as s, sqlite3.connect(db) as d, sqlite3.connect(ref) as r:
        s.backup(d)  # two copies of the library: one to interrupt, one to run uninterrupted
        s.backup(r)
    args = ["tune", f"{run_id}/1", "--method", "sa", "--trials", "64", "--batch", "8", "--seed", "4", "--ensemble", "4"]
    base = rows_in(db, "trace")  # the shared library may hold other tests' tuning runs
    proc = subprocess.Popen(SANLAB + args + ["--db", str(db)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=interruptible)
    deadline = time.time() + 300
    while rows_in(db, "trace") - base < 10 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert 10 <= rows_in(db, "trace") - base < 64, "the tuning should have been stopped part-way"
    with Library(str(db)) as lib:
        run = next(r for r in lib.runs() if r.kind == "tune")
        assert lib.count(run.run_id) == 0  # the tuned gait is stored only when the chain ends
    if sig == signal.SIGINT:
        assert proc.returncode == 130
        assert f"--resume {run.run_id}" in err and "Traceback" not in err
        assert run.status == "interrupted"
    # the same chain named twice (in full and by a prefix) is resumed once
    [resumed] = json.loads(subprocess.run(SANLAB + ["tune", "--resume", run.run_id, "--resume", run.run_id[:6], "--db",
                                                    str(db), "--json"], capture_output=True, text=True, check=True).stdout)
    [expected] = json.loads(subprocess.run(SANLAB + args + ["--db", str(ref), "--json"], capture_output=True, text=True,
                                           check=True).stdout)
    assert resumed["before"] == expected["before"] and resumed["after"] == expected["after"]
    assert resumed["trials"] == expected["trials"] == 64
    with Library(str(db)) as a, Library(str(ref)) as b:
        x, y = a.gait(resumed["tuned_gait"]), b.gait(expected["tuned_gait"])
        assert (x.params, x.score, x.extra) == (y.params, y.score, y.extra)
        assert [(t.trial, t.score, t.accepted) for t in a.trace(x.run_id)] == \
               [(t.trial, t.score, t.accepted) for t in b.trace(y.run_id)]
        assert a.get_run(x.run_id).status == "done"
