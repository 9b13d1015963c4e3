"""The command line as a whole: every command that reads the gait library refuses a missing
``--db`` (one line, exit 2, no file left behind); only those that start runs create it."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.library import Library

runner = CliRunner()


@pytest.mark.parametrize(
    "args",
    [
        ["runs"],
        ["show", "deadbeef"],
        ["export", "deadbeef/1"],
        ["tune", "deadbeef/1"],
        ["render", "deadbeef/1"],
        ["audit", "deadbeef/1"],
        ["search", "--resume", "deadbeef"],
    ],
)
def test_commands_that_read_the_library_refuse_a_missing_file(tmp_path, args):
    db = tmp_path / "mistyped.db"
    r = runner.invoke(app, [*args, "--db", str(db)])
    assert r.exit_code == 2, r.output
    assert r.stderr == f"{db}: no such gait library (give --db PATH)\n"
    assert not db.exists()


def cart_export(tmp_path) -> dict:
    """A valid export of a (made-up) cart gait: real creature text and encoding, no simulation."""
    from sanlab.creature import load, read_source
    from sanlab.san import San

    san = San.for_creature(load("cart"))
    with Library(tmp_path / "src.db") as lib:
        run = lib.create_run("search", "cart", read_source("cart")[0], {"metric": "distance", "seconds": 6.0}, 0, 1)
        lib.add_batch(run.run_id, [{"idx": 0, "encoding": san.encode(san.random_weights(0, 0)), "score": 1.0,
                                    "params": {"delay_on": 0.1, "delay_off": 0.1}}])
        return lib.export_gait(f"{run.run_id}/1")


def test_import_starts_a_library_where_there_was_none(tmp_path):
    exported = cart_export(tmp_path)
    gait = tmp_path / "gait.json"
    gait.write_text(json.dumps(exported))
    db = tmp_path / "new.db"
    r = runner.invoke(app, ["import", str(gait), "--db", str(db)])
    assert r.exit_code == 0, r.output
    with Library(db) as lib:
        assert lib.gait(r.stdout.strip()).encoding == exported["encoding"]


def test_a_bad_export_starts_no_library(tmp_path):
    exported = cart_export(tmp_path)
    exported["encoding"] = exported["encoding"][:-8]  # checked against the creature: refused
    gait = tmp_path / "gait.json"
    gait.write_text(json.dumps(exported))
    db = tmp_path / "new.db"
    r = runner.invoke(app, ["import", str(gait), "--db", str(db)])
    assert r.exit_code == 2 and r.output.startswith(f"{gait}: bad sanlab gait: encoding"), r.output
    assert not db.exists()  # "a bad file leaves the library as it was": here, no library at all


def test_an_imported_audit_is_named_and_left_behind(tmp_path):
    exported = cart_export(tmp_path)
    exported["audit"] = {"flagged": True, "worst": 0.4, "created": "2026-12-01", "result": {}}
    gait = tmp_path / "gait.json"
    gait.write_text(json.dumps(exported))
    db = tmp_path / "new.db"
    r = runner.invoke(app, ["import", str(gait), "--db", str(db)])
    assert r.exit_code == 0, r.output
    gid = r.stdout.strip()  # stdout stays the gait id alone, for scripts
    assert r.stderr == (f"the file's audit (flagged) is the exporting sanlab's and was not imported: "
                        f"`sanlab audit {gid}` audits the gait here\n")
    with Library(db) as lib:
        assert lib.audits(lib.gait(gid).run_id) == {}


def test_runs_names_the_librarys_designs_in_a_line_and_not_in_its_json(tmp_path):
    db = str(tmp_path / "g.db")
    with Library(db) as lib:
        run = lib.create_run("search", "cart", "name = 'cart'", {"metric": "distance"}, seed=0, total=1)
        assert "design" not in runner.invoke(app, ["runs", "--db", db]).stdout  # none yet: no line
        d = lib.begin_design("hopper", "hopper.toml", 'name = "hopper"\n', {"designs": 3}, [])
        lib.add_design_score(d.design_id, -1, 0, 0, [1.0], {"speed": 20.0, "gait": None})
        lib.end_design(d.design_id, "interrupted")
    r = runner.invoke(app, ["runs", "--db", db])
    assert r.exit_code == 0 and f"1 design: {d.design_id} hopper (interrupted, 1 score)" in r.stdout
    listed = json.loads(runner.invoke(app, ["runs", "--db", db, "--json"]).stdout)
    assert [x["run_id"] for x in listed] == [run.run_id]  # the JSON lists runs only, as before
