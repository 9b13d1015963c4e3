"""Faults on a local multi-node Ray cluster (``ray.cluster_utils.Cluster``: a head and two worker
nodes of one CPU each, issue 59): worker nodes killed in the middle of a small ``reproduce`` (both,
one at a time) and of an ``audit`` (and its selection) end with the rows and verdicts of an
uninterrupted run, nothing lost and nothing stored twice; the driver killed outright and the
command run again resumes."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from dataclasses import asdict
from typing import ClassVar

import pytest

from sanlab.library import Library
from sanlab.reproduce import Ledger
from tests.helpers import ROOT, SANLAB
from tests.test_cluster_jobs import TABLE, same, table

pytestmark = pytest.mark.slow  # a three-node cluster and small tables: about a minute


@pytest.fixture(scope="module")
def nodes():
    """(the cluster, a function that kills one of its worker nodes now); each test starts with
    two worker nodes (one killed by the test before is replaced first)."""
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    # a dead node is noticed within about a second (Ray's default: 15 s)
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "_system_config": {
        "health_check_initial_delay_ms": 0, "health_check_period_ms": 250, "health_check_failure_threshold": 4}})
    workers = []

    def ensure_two() -> None:
        while len(workers) < 2:
            workers.append(c.add_node(num_cpus=1))
        c.wait_for_nodes()

    def kill() -> None:
        c.remove_node(workers.pop(0), allow_graceful=False)

    ensure_two()
    ray.init(address=c.address, include_dashboard=False, log_to_driver=False)
    try:
        yield c, ensure_two, kill
    finally:
        ray.shutdown()
        c.shutdown()


def killing(kill, *after: int):
    """A Ray backend of 3 workers that kills a worker node as each ``after``-th batch comes back
    while others are in flight (on the killed node among them)."""
    from sanlab.evaluate.ray_backend import RayBackend

    class Killing(RayBackend):
        done = 0
        killed_with: ClassVar[list[int]] = []  # chunks in flight when the node was killed

        def next(self):
            out = super().next()
            Killing.done += 1
            due = [n for n in after if n <= Killing.done]
            if len(due) > len(Killing.killed_with) and self._refs:
                Killing.killed_with.append(len(self._refs))
                kill()
            return out

    return Killing(workers=3)


def counts(db) -> dict:
    """Per run kind, what every run stored: (evaluations, distinct indices, trace trials) each."""
    out: dict = {}
    with Library(str(db)) as lib:
        for r in lib.runs():
            n, idx, trials = lib.count(r.run_id), len(lib.done_indices(r.run_id)), len(lib.trace(r.run_id))
            out.setdefault(r.kind, []).append((n, idx, trials, r.status))
    return {k: sorted(v) for k, v in out.items()}


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    """The rows, and the stored counts, of the uninterrupted table, made here without Ray."""
    db, rows = table(tmp_path_factory.mktemp("local"))
    return db, sorted(map(str, rows)), counts(db)


def test_nodes_killed_mid_reproduce_lose_and_change_no_row(nodes, local, tmp_path):
    c, ensure_two, kill = nodes
    ensure_two()
    # both worker nodes, one in phase 2 of the first row (phase 1 is one batch of 16), one in its
    # audits: the second row is made on the head alone
    backend = killing(kill, 3, 20)
    db, rows = table(tmp_path, backend)
    assert len(type(backend).killed_with) == 2, "two nodes should have been killed with chunks in flight"
    assert sorted(map(str, rows)) == local[1]  # every row, to the last digit
    assert counts(db) == local[2]  # every run stored its whole budget once, and is done
    assert backend.alive() == 1  # the workers alive: the head's


def test_a_node_killed_mid_audit_and_selection_changes_no_verdict(nodes, local, tmp_path):
    from sanlab.audit import audit, select_robust

    c, ensure_two, kill = nodes
    ensure_two()
    db = local[0]
    made = {}
    for name in ("here", "ray"):
        shutil.copy(db, tmp_path / f"{name}.db")
        backend = killing(kill, 2) if name == "ray" else None
        with Library(str(tmp_path / f"{name}.db")) as lib:
            tuned = sorted(r.run_id for r in lib.runs() if r.kind == "tune")
            a = audit(lib, f"{tuned[0]}#0", members=48, backend=backend).to_json()
            s = select_robust(lib, tuned[1], top=5, members=24, backend=backend)
            made[name] = same([a, [x.to_json() for x in s.candidates], s.gait_id])
            if backend is not None:
                assert type(backend).killed_with, "a node should have been killed mid-audit"
        with Library(str(tmp_path / f"{name}.db")) as lib:
            made[name].append(same({k: v for k, v in (lib.selection(tuned[1]) or {}).items() if k != "created"}))
    assert made["ray"] == made["here"]


def command(c, tmp_path) -> list[str]:
    """The small table of the ``local`` fixture as a command on the cluster (rows side by side)."""
    return SANLAB + ["reproduce", "--creatures", "twolink", "--seeds", "0-1", "--controllers", str(TABLE["controllers"]),
                    "--trials", str(TABLE["trials"]), "--top", str(TABLE["top"]), "--ensemble", str(TABLE["ensemble"]),
                    "--ceiling", str(TABLE["ceiling"]), "--db", str(tmp_path / "g.db"), "--out", str(tmp_path / "r.md"),
                    "--ledger", str(tmp_path / "rows.jsonl"), "--backend", "ray", "--address", c.address]


def stopped(cmd, how: int, at: str = ": tune: ") -> tuple[subprocess.Popen, list[str]]:
    """``cmd`` sent the signal ``how`` at its first progress line holding ``at`` (default: once a
    row's tuning is under way): (the process, ended, and what it wrote on stderr)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    assert p.stderr is not None
    said = []
    for line in p.stderr:  # progress on a pipe: a line a tenth of each step, both rows side by side
        said.append(line)
        if at in line:  # e.g. ": tune: ": a row's search is stored, its tuning under way
            break
    p.send_signal(how)
    said += p.stderr.read().splitlines(keepends=True)
    p.wait(timeout=60)
    return p, said


def test_a_killed_driver_resumes_on_the_cluster_with_the_same_rows(nodes, local, tmp_path):
    c, ensure_two, _ = nodes
    ensure_two()
    cmd = command(c, tmp_path)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p, said = stopped(cmd, signal.SIGKILL)
    assert any(": tune: " in line for line in said), "".join(said)
    assert not Ledger(tmp_path / "rows.jsonl").entries
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    book = Ledger(tmp_path / "rows.jsonl")
    assert len(book.entries) == 2 and len({json.dumps(e.key, sort_keys=True) for e in book.entries}) == 2
    assert any(e.row.resumed for e in book.entries)  # what the killed call stored is taken up
    rows = sorted(str((e.key, same(asdict(e.row)))) for e in sorted(book.entries, key=lambda e: e.key["seed"]))
    assert rows == local[1]
    assert counts(tmp_path / "g.db") == local[2]


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))


def test_ctrl_c_stops_every_row_in_one_line_and_the_command_resumes(nodes, local, tmp_path):
    c, ensure_two, _ = nodes
    ensure_two()
    cmd = command(c, tmp_path)
    # at the search's first progress: the rest of the table still to do, so that a loaded machine
    # reading the child's progress late still signals it mid-table (at the tuning, the small
    # table had once ended first)
    p, said = stopped(cmd, signal.SIGINT, at=": search: ")
    assert p.returncode == 130, "".join(said)
    assert said[-1] == "interrupted; every stored evaluation is kept: run the same command again to continue\n"
    assert not any("Traceback" in line or "Error" in line for line in said), "".join(said)
    with Library(str(tmp_path / "g.db")) as lib:  # each row's driver stopped and said so
        assert lib.runs() and all(r.status in ("done", "interrupted") for r in lib.runs())
    r = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr
    rows = sorted(str((e.key, same(asdict(e.row)))) for e in Ledger(tmp_path / "rows.jsonl").entries)
    assert rows == local[1] and counts(tmp_path / "g.db") == local[2]
