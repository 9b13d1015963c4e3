"""``--backend ray`` on a local Ray cluster started here (the ``cluster`` fixture of conftest) and
stopped at the end: bit-identical results to the local backend, a worker killed mid-run loses
nothing, the command line on the cluster, and a missing Ray said in one line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from sanlab.creature import read_source
from sanlab.evaluate import make_backend
from sanlab.library import Library
from sanlab.search import run_search
from tests.helpers import SANLAB

N, SECONDS, BATCH = 48, 0.5, 8  # six batches of the cart, an ensemble of two


def search(db, backend=None, reporter=None, strategy="random"):
    text, where = read_source("cart")
    with Library(str(db)) as lib:
        run_id = run_search(lib, text, where, controllers=N, seconds=SECONDS, seed=5, batch=BATCH, ensemble=2,
                            backend=backend, reporter=reporter, strategy=strategy)
        rows = sorted((e.idx, e.encoding, e.score, e.speed_cm_s, e.fell, e.nonfinite, str(e.extra))
                      for e in lib.top(run_id, None))
        return run_id, rows, lib.get_run(run_id)


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    return search(tmp_path_factory.mktemp("local") / "g.db")[1]


@pytest.mark.slow
def test_ray_gives_bit_identical_results_to_local(cluster, local, tmp_path):
    _, rows, run = search(tmp_path / "g.db", make_backend("ray", workers=2))
    assert rows == local and len(rows) == N  # every score, speed and ensemble spread, bit for bit
    assert run.status == "done" and (run.device or "").startswith("ray")


@pytest.mark.slow
def test_the_rhythm_search_on_ray_stores_the_local_clocks(cluster, tmp_path):
    """Its evaluator carries the creature's parameter space to the workers: every clock's weights,
    delays and ranges, and its score, as a local run stores them."""
    a, here, _ = search(tmp_path / "l.db", strategy="rhythm")
    b, rows, run = search(tmp_path / "r.db", make_backend("ray", workers=2), strategy="rhythm")
    assert rows == here and len(rows) == N and run.params["strategy"] == "rhythm"
    params = []
    for db, run_id in ((tmp_path / "l.db", a), (tmp_path / "r.db", b)):
        with Library(str(db)) as lib:
            params.append(sorted((e.idx, json.dumps(e.params, sort_keys=True)) for e in lib.top(run_id, None)))
    assert params[0] == params[1] and any('"k1"' in p for _, p in params[0])  # the clocks' own delays


@pytest.mark.slow
def test_a_worker_killed_mid_run_loses_nothing(cluster, local, tmp_path):
    backend = make_backend("ray", workers=2)
    killed = []

    def kill_one(p):
        if p.evaluated >= BATCH and not killed:  # after the first committed batch, more in flight
            pid = backend.pids()[0]  # type: ignore[attr-defined]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    _, rows, run = search(tmp_path / "g.db", backend, kill_one)
    assert killed, "a worker should have been killed part-way"
    assert rows == local and len({r[0] for r in rows}) == N  # nothing lost, nothing twice
    assert run.status == "done"


@pytest.mark.slow
def test_search_on_an_existing_cluster_from_the_command_line(cluster, tmp_path):
    common = ["search", "cart", "-n", "16", "--seconds", "0.5", "--batch", "8", "--ensemble", "2", "--json"]
    address = cluster.get_runtime_context().gcs_address  # this cluster, not "auto": another may run here
    on_ray = subprocess.run(SANLAB + common + ["--backend", "ray", "--address", address, "--db", str(tmp_path / "r.db")],
                            capture_output=True, text=True, check=True)
    here = subprocess.run(SANLAB + common + ["--db", str(tmp_path / "l.db")], capture_output=True, text=True, check=True)
    strip = lambda out: [(r["encoding"], r["score"], r["speed_cm_s"]) for r in json.loads(out)["top"]]
    assert strip(on_ray.stdout) == strip(here.stdout)


def test_without_ray_the_backend_says_how_to_install_it(tmp_path):
    code = ("import sys; sys.modules['ray'] = None\n"
            "from sanlab.cli import app\n"
            "app(['search', 'cart', '-n', '2', '--backend', 'ray', '--db', sys.argv[1]])")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "g.db")], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip() == "--backend ray needs Ray: pip install 'sanlab[cluster]'"
    assert not (tmp_path / "g.db").exists()
