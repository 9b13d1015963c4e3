"""The long jobs on ``--backend ray`` (issue 59): Table 1 (``reproduce``), ``audit``, ``audit
--select`` and ``ceiling`` on a local Ray cluster (the ``cluster`` fixture) give the rows, verdicts
and ledger of a local run to the last digit; a worker that raises ends in one line naming the
piece. The faults (a node killed, the driver killed) are in ``test_cluster_faults.py``."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import asdict

import numpy as np
import pytest

from sanlab.evaluate import Evaluator, Request, make_backend
from sanlab.library import Library
from sanlab.reproduce import Ledger, reproduce
from tests.helpers import SANLAB

# a two-seed table of the two-link chain with two chains each, audited, and its pattern ceiling
TABLE: dict = dict(seeds=[0, 1], controllers=16, trials=8, ensemble=2, top=2, ceiling=32)
RUN_ID = re.compile(r"\b[0-9a-f]{8}\b")  # a library's run ids are random: rows compare without them


def same(x):
    """A ledger row (or part of one) without what differs between two equal runs: the random run
    ids, the wall time, where it ran."""
    if isinstance(x, dict):
        return {k: same(v) for k, v in x.items() if k not in ("wall", "device", "resumed", "ledger")}
    if isinstance(x, (list, tuple)):
        return [same(v) for v in x]
    return RUN_ID.sub("RUN", x) if isinstance(x, str) else x


def table(tmp, backend=None, pieces: int = 1):
    """(the library, the ledger's rows made by a small Table 1 on ``backend``, ``pieces`` rows side
    by side), the rows in the order of their keys (rows made side by side end in any order)."""
    tmp.mkdir(exist_ok=True)
    with Library(str(tmp / "g.db")) as lib:
        reproduce(lib, ["twolink"], log=lambda s: None, ledger=tmp / "rows.jsonl", backend=backend, pieces=pieces,
                  **TABLE)
    rows = [(e.key, same(asdict(e.row))) for e in Ledger(tmp / "rows.jsonl").entries]
    return tmp / "g.db", sorted(rows, key=lambda r: json.dumps(r[0], sort_keys=True))


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    return table(tmp_path_factory.mktemp("local"))


def test_a_local_backend_audits_as_no_backend(tmp_path):
    """``audit`` takes a backend; the local one scores each look's evaluations in turn, exactly as
    before there were backends (the rest of the suite audits with none)."""
    from sanlab.audit import audit
    from sanlab.creature import read_source
    from sanlab.search import run_search

    text, where = read_source("twolink")
    with Library(str(tmp_path / "g.db")) as lib:
        run_id = run_search(lib, text, where, controllers=8, seconds=1.0, seed=3, batch=8, ensemble=2)
        gait = lib.top(run_id, 1)[0].gait_id
        a, b = audit(lib, gait, members=8), audit(lib, gait, members=8, backend=make_backend("local"))
    assert a.to_json() == b.to_json() and set(a.shifts) == {"dt/2", "dt/4"}


@pytest.mark.slow  # a Ray cluster and a small Table 1 twice: about 10 s
def test_table_1_on_ray_has_the_local_rows_and_ledger(cluster, local, tmp_path):
    _, on_ray = table(tmp_path, make_backend("ray", workers=2), pieces=2)  # its two rows side by side
    _, here = local
    assert len(here) == 2 and all(r["audit"] and r["robust"] and r["ceiling"] for _, r in here)
    assert on_ray == here  # every key, speed, audit, selection and ceiling, to the last digit
    assert all(e.row.device.startswith("ray") for e in Ledger(tmp_path / "rows.jsonl").entries)


@pytest.mark.slow  # the small table again, its two rows on two threads
def test_rows_made_side_by_side_are_the_rows_made_in_turn(local, tmp_path):
    _, side_by_side = table(tmp_path, pieces=2)
    assert side_by_side == local[1]


@pytest.mark.slow
def test_audit_and_select_on_ray_give_the_local_verdicts(cluster, local, tmp_path):
    from sanlab.audit import audit, select_robust

    db, _ = local
    for name in ("l.db", "r.db"):
        shutil.copy(db, tmp_path / name)
    made = {}
    for name, backend in (("l.db", None), ("r.db", make_backend("ray", workers=2))):
        with Library(str(tmp_path / name)) as lib:
            tuned = sorted(r.run_id for r in lib.runs() if r.kind == "tune")
            searched = [r.run_id for r in lib.runs() if r.kind == "search" and getattr(r.settings, "strategy", "") == "random"]
            # a phase-1 gait audited on more members than Table 1's, and a selection of other settings
            a = [audit(lib, lib.top(searched[0], 1)[0].gait_id, members=32, backend=backend).to_json()]
            s = [[c.to_json() for c in select_robust(lib, t, top=6, members=16, backend=backend).candidates]
                 for t in tuned]
            made[name] = (same(a), same(s))
    assert made["r.db"] == made["l.db"] and made["l.db"][1][0]


@pytest.mark.slow
def test_reproduce_and_audit_on_an_existing_cluster_from_the_command_line(cluster, tmp_path):
    common = ["reproduce", "--creatures", "twolink", "--controllers", "8", "--trials", "4", "--top", "1",
              "--ensemble", "2"]
    said = {}
    here = cluster.get_runtime_context().gcs_address  # this cluster, not "auto": another may run here
    for tag, extra in (("l", []), ("r", ["--backend", "ray", "--address", here, "--workers", "2"])):
        said[tag] = subprocess.run(SANLAB + common + extra + ["--db", str(tmp_path / f"{tag}.db"), "--out",
                                                              str(tmp_path / f"{tag}.md"), "--ledger",
                                                              str(tmp_path / f"{tag}.jsonl")],
                                   capture_output=True, text=True, check=True).stderr.splitlines()
    # progress in the log (stderr is a pipe): the rows done, and on the cluster its workers alive
    assert "reproduce: rows: 1 of 1 done" in said["r"] and "reproduce: rows: 1 of 1 done" in said["l"]
    tuning = [line for line in said["r"] if line.startswith("reproduce: twolink (seed 0): tune: ")]
    assert tuning and all(", 2 workers alive, " in line for line in tuning), said["r"]
    assert not any("workers alive" in line for line in said["l"])
    assert f"ray ({here}, 2 workers); total wall time" in (tmp_path / "r.md").read_text()  # where it was made
    rows = {t: [same(asdict(e.row)) for e in Ledger(tmp_path / f"{t}.jsonl").entries] for t in "lr"}
    assert rows["r"] == rows["l"] and len(rows["l"]) == 1
    audits = {}
    for tag, extra in (("l", []), ("r", ["--backend", "ray", "--address", here])):
        with Library(str(tmp_path / f"{tag}.db")) as lib:
            run = next(r.run_id for r in lib.runs() if r.kind == "search")
            tuned = next(r.run_id for r in lib.runs() if r.kind == "tune")
        db = ["--json", "--db", str(tmp_path / f"{tag}.db"), *extra]
        out = subprocess.run(SANLAB + ["audit", run, "--top", "2", "--members", "16", *db], capture_output=True,
                             text=True, check=True)
        sel = subprocess.run(SANLAB + ["audit", tuned, "--select", "--top", "4", "--members", "16", *db],
                             capture_output=True, text=True, check=True)
        audits[tag] = same([json.loads(out.stdout), json.loads(sel.stdout)])
    assert audits["r"] == audits["l"] and len(audits["l"][0]) == 2 and audits["l"][1]["candidates"]


@pytest.mark.slow
def test_a_worker_that_raises_ends_in_one_line_naming_the_piece(cluster):
    from sanlab.creature import load
    from sanlab.evaluate.ray_backend import WorkerError

    backend = make_backend("ray", workers=2)
    backend.start(Evaluator(load("twolink"), seconds=0.2))  # no parameter space: a vector cannot be scored
    backend.label = "twolink (seed 3): tune"  # type: ignore[attr-defined]
    san = Evaluator(load("twolink")).san
    backend.submit(Request(np.stack([san.random_weights(0, i) for i in range(2)]), np.zeros((2, 3))))
    with pytest.raises(WorkerError) as e:
        backend.next()
    backend.close()
    said = str(e.value)
    assert "\n" not in said and "Traceback" not in said
    assert said == ("twolink (seed 3): tune: a batch of 2: ValueError: parameter vectors need an evaluator "
                    "with a space")


def test_a_workers_error_ends_a_command_in_its_one_line(capsys):
    import typer

    from sanlab.cli._common import library_call
    from sanlab.evaluate.ray_backend import WorkerError

    def lost():
        raise WorkerError("bounder (seed 3): tune: a batch of 32: ValueError: no")

    with pytest.raises(typer.Exit) as e:
        library_call(lost)
    assert e.value.exit_code == 1
    assert capsys.readouterr().err == "bounder (seed 3): tune: a batch of 32: ValueError: no\n"


@pytest.mark.slow
def test_ceiling_on_an_existing_cluster_from_the_command_line(cluster, tmp_path):
    made = {}
    here = cluster.get_runtime_context().gcs_address
    for tag, extra in (("l", []), ("r", ["--backend", "ray", "--address", here, "--workers", "2"])):
        out = subprocess.run(SANLAB + ["ceiling", "twolink", "-n", "64", "--seed", "2", "--json", "--db",
                                       str(tmp_path / f"{tag}.db"), *extra], capture_output=True, text=True, check=True)
        made[tag] = same({k: v for k, v in json.loads(out.stdout).items() if k != "seconds"})
    assert made["r"] == made["l"] and made["l"]["ceiling"]["speed_cm_s"] > 0
    with Library(str(tmp_path / "r.db")) as lib:
        assert all((r.device or "").startswith("ray") for r in lib.runs())


def test_a_row_stopped_before_its_ceiling_stops_the_creatures_later_ceilings():
    """Rows side by side keep a creature's ceilings in the order of its seeds (a ceiling is the
    best of the pattern searches stored before it): a later row measured after an earlier one
    stopped short would see fewer searches than in turn, so it stops too; after the earlier
    row's ceiling was measured, the later one goes on whatever became of the rest of that row."""
    from sanlab.reproduce import _Turns

    turns = _Turns([(0, "twolink"), (0, "cart"), (1, "twolink"), (2, "twolink")])
    with turns.ceiling(1):  # another creature: no wait
        pass
    turns.fail(0)  # stopped before its ceiling
    with pytest.raises(RuntimeError, match="row 0 of twolink stopped before its ceiling"), turns.ceiling(2):
        pass
    assert turns.failed[2] and turns.done[2].is_set()
    turns = _Turns([(0, "twolink"), (1, "twolink")])
    with turns.ceiling(0):
        pass
    assert not turns.done[0].is_set()  # a later ceiling waits for the whole row, not its ceiling alone
    turns.fail(0)  # its row stopped after the ceiling was measured
    with turns.ceiling(1):
        pass
    assert turns.measured == [True, True]
