"""``sanlab audit``: a score that does not survive a nudge (dt/2, dt/4, float64) is flagged, a
converged one is not; the verdict is stored, shown and exported (issue 10, "Robust scores")."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from sanlab.audit import FLOOR_CM_S, audit_and_store
from sanlab.cli import app
from sanlab.library import Library
from sanlab.search import run_search

runner = CliRunner()


def run_cli(*args):
    return runner.invoke(app, list(args))

# A sled sliding down a 30 deg slope (mu 0.2) under its own weight, waving a flag it cannot push
# with: a motion the step size barely changes (Coulomb sliding, integrated implicitly), 2.8 m/s
# mean over 2 s whatever the SAN does.
SLED = """
name = "sled"
dt = 0.001
[world]
plane = "vertical"
[world.ground]
stiffness = 10000.0
damping = 20.0
friction = 0.2
[world.terrain]
kind = "slope"
angle_deg = -30
[san]
hidden = 1
[evaluation]
metric = "distance"
seconds = 2.0
[[links]]
name = "body"
mass = 1.0
shape = "polygon"
points = [[-0.1, -0.025], [0.1, -0.025], [0.1, 0.025], [-0.1, 0.025]]
contacts = [[-0.1, -0.025], [0.1, -0.025]]
position = [0.0, 0.1]
angle_deg = -30
[[links]]
name = "flag"
mass = 0.001
shape = "segment"
points = [[0.0, 0.0], [0.05, 0.0]]
contacts = []
parent = "body"
anchor = [0.0, 0.025]
[[sensors]]
name = "S1"
type = "angle"
link = "flag"
min_deg = 0
max_deg = 90
[[actuators]]
name = "A1"
type = "angular"
joint = "flag"
min_deg = -45
max_deg = 45
ks = 0.0001
kd = 0.00001
"""


def _coarse_threelink() -> tuple[str, str]:
    """The built-in three-link chain simulated at 10 ms, the coarsest step the format allows: its
    servos, contacts and node delays (70 ms: seven steps) are not resolved, and whatever its best
    random network does at that step is largely an artefact of the step."""
    from sanlab.creature import read_source

    text, where = read_source("threelink")
    return text.replace("dt = 0.001", "dt = 0.01"), where


@pytest.fixture(scope="module")
def audited(tmp_path_factory):
    path = tmp_path_factory.mktemp("audit") / "lib.db"
    lib = Library(path)
    sled = run_search(lib, SLED, "sled.toml", controllers=8, seconds=2.0, seed=0, ensemble=4)
    text, where = _coarse_threelink()
    assert "dt = 0.01 " in text
    coarse = run_search(lib, text, where, controllers=16, seconds=3.0, seed=0, ensemble=4)
    out = {"sled": audit_and_store(lib, f"{sled}/1"), "coarse": audit_and_store(lib, f"{coarse}/1")}
    lib.close()
    return path, out, sled, coarse


def test_a_converged_motion_is_not_flagged(audited):
    _, out, _, _ = audited
    a = out["sled"]
    assert a.nominal_cm_s == pytest.approx(a.stored_cm_s, abs=1e-6)  # re-scored exactly as stored
    assert a.nominal_cm_s > 100 * FLOOR_CM_S  # it really moves
    assert set(a.speeds) == {"dt/2", "dt/4", "float64"}
    assert a.worst < 0.03 and not a.flagged


def test_a_gait_of_an_unresolved_step_is_flagged(audited):
    _, out, _, _ = audited
    a = out["coarse"]
    assert a.nominal_cm_s == pytest.approx(a.stored_cm_s, abs=1e-6)
    assert a.nominal_cm_s > 5.0
    assert a.flagged and a.worst > 0.25, a


def test_the_verdict_is_stored_shown_and_exported(audited):
    path, out, sled, coarse = audited
    with Library(path) as lib:
        assert lib.audit(f"{coarse}/1").flagged and not lib.audit(f"{sled}/1").flagged
        assert lib.audit(f"{coarse}/2") is None  # never audited
        exported = lib.export_gait(f"{coarse}/1")
        assert exported["audit"]["flagged"] is True
        assert exported["audit"]["result"]["speeds"]["dt/2"] == pytest.approx(out["coarse"].speeds["dt/2"])
    shown = json.loads(run_cli("show", coarse, "--top", "2", "--json", "--db", str(path)).stdout)
    assert [r["resolution_dependent"] for r in shown["top"]] == [True, None]
    table = run_cli("show", coarse, "--top", "1", "--db", str(path)).stdout
    assert "resolution-dependent" in table


def test_audit_command_prints_and_stores(audited):
    path, _, sled, _ = audited
    r = run_cli("audit", f"{sled}/1", "--json", "--db", str(path))
    assert r.exit_code == 0, r.output
    [row] = json.loads(r.stdout)
    assert row["flagged"] is False and set(row["speeds"]) == {"dt/2", "dt/4", "float64"}
    bad = run_cli("audit", "nope/1", "--db", str(path))
    assert (bad.exit_code == 2 and "nope" in bad.stderr and bad.exception is None) or isinstance(bad.exception, SystemExit)


def test_a_version_2_library_is_upgraded_with_an_empty_audits_table(tmp_path):
    import sqlite3

    from sanlab.library import _schema

    path = tmp_path / "v2.db"
    con = sqlite3.connect(path)
    for statement in _schema.DDL[:-1]:  # version 2: no audits table
        con.execute(statement)
    con.execute(f"PRAGMA application_id = {_schema.APPLICATION_ID}")
    con.execute("PRAGMA user_version = 2")
    con.commit()
    con.close()
    with Library(path) as lib:
        assert lib.runs() == []
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA user_version").fetchone()[0] == _schema.SCHEMA_VERSION == 3
    assert con.execute("SELECT count(*) FROM audits").fetchone()[0] == 0
