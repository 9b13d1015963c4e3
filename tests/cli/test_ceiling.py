"""``sanlab ceiling`` and pattern gaits on the command line: stored, audited, shown, rendered and
labelled as patterns, refused where only a SAN makes sense (tune, export), and the ceiling
quoted beside a SAN gait of the same creature."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.cli._schemas import validate
from sanlab.library import Library
from sanlab.search.ceiling import find

runner = CliRunner()
pytestmark = pytest.mark.slow  # a pattern search, its audit, a SAN search: about 20 s on 2 cores


@pytest.fixture(scope="module")
def lib_path(tmp_path_factory):
    db = str(tmp_path_factory.mktemp("ceiling") / "c.db")
    r = runner.invoke(app, ["ceiling", "cart", "-n", "64", "--db", db, "--json"])
    assert r.exit_code == 0, r.output
    rec = json.loads(r.stdout)
    validate(rec, "ceiling")
    return db, rec


def test_the_ceiling_is_an_audited_pattern_of_the_creature(lib_path):
    db, rec = lib_path
    c = rec["ceiling"]
    assert c["evaluations"] == 64 and c["speed_cm_s"] > 0
    with Library(db) as lib:
        run = lib.get_run(rec["run_id"])
        assert run.settings.strategy == "pattern"
        e = lib.gait(c["gait"])
        assert "pattern" in e.params and lib.audit(c["gait"]) is not None  # audited, whatever its verdict
        assert c["verdict"] == lib.audit(c["gait"]).verdict and c["fell"] == any(lib.audit(c["gait"]).result["fell"].values())
        found = find(lib, run.creature_text, run.settings.metric, run.settings.seconds)
        assert found is not None and found.gait == c["gait"]
        assert find(lib, run.creature_text + "\n# another file", run.settings.metric, run.settings.seconds) is None


def test_a_pattern_gait_is_labelled_shown_and_rendered_as_a_pattern(lib_path, tmp_path):
    db, rec = lib_path
    gait = rec["ceiling"]["gait"]
    shown = json.loads(runner.invoke(app, ["show", gait, "--db", db, "--json"]).stdout)
    assert shown["kind"] == "pattern"
    names = {(row["part"], row["name"]) for row in shown["parameters"]["rows"]}
    assert ("pattern", "period") in names and not any(p.startswith("sensor") or p.startswith("san") for p, _ in names)
    top = json.loads(runner.invoke(app, ["show", rec["run_id"], "--db", db, "--json"]).stdout)["top"]
    assert {row["kind"] for row in top} == {"pattern"}
    text = runner.invoke(app, ["show", gait, "--db", db]).output
    assert "pattern (open loop, no SAN)" in text and "sanlab tune" not in text
    r = runner.invoke(app, ["render", gait, "-o", str(tmp_path / "p.png"), "--seconds", "0.5", "--width", "200", "--db", db])
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("args", [["tune", "{g}", "--trials", "2"], ["export", "{g}", "--c", "-o", "{tmp}/x.h"],
                                  ["show", "{g}", "--network"]])
def test_what_needs_a_san_refuses_a_pattern_in_one_line(lib_path, tmp_path, args):
    db, rec = lib_path
    r = runner.invoke(app, [a.format(g=rec["ceiling"]["gait"], tmp=tmp_path) for a in args] + ["--db", db])
    assert r.exit_code == 2
    assert "pattern" in r.output and "Traceback" not in r.output


def test_a_san_gait_is_shown_beside_its_creatures_ceiling(lib_path):
    db, rec = lib_path
    r = runner.invoke(app, ["search", "cart", "-n", "16", "--db", db, "--json"])
    assert r.exit_code == 0, r.output
    best = json.loads(r.stdout)["top"][0]
    assert best["kind"] == "san"
    shown = json.loads(runner.invoke(app, ["show", best["gait"], "--db", db, "--json"]).stdout)
    ceiling = shown["ceiling"]
    assert ceiling["gait"] == rec["ceiling"]["gait"]
    assert ceiling["fraction"] == pytest.approx(best["speed_cm_s"] / rec["ceiling"]["speed_cm_s"])
    assert "of its pattern ceiling" in runner.invoke(app, ["show", best["gait"], "--db", db]).output


def test_search_and_tune_quote_their_best_against_the_ceiling(lib_path):
    db, rec = lib_path
    r = runner.invoke(app, ["search", "cart", "-n", "8", "--seed", "3", "--db", db])
    assert r.exit_code == 0, r.output
    assert "of the creature's pattern ceiling" in r.output and rec["ceiling"]["gait"] in r.output
    with Library(db) as lib:
        run_id = lib.runs()[0].run_id  # the newest
    t = runner.invoke(app, ["tune", f"{run_id}/1", "--trials", "4", "--db", db])
    assert t.exit_code == 0, t.output
    assert "the tuned gait" in t.output and "of the creature's pattern ceiling" in t.output


def test_a_pattern_whose_audit_ensemble_fell_is_not_the_ceiling_a_standing_one_is(tmp_path):
    """The walker's first ceiling: a pattern the audit found robust in speed while more than half
    of its members fell at dt/2 and dt/4 (79 cm/s over the audit's members, 168.7 stored); on
    fresh ensembles it fell. A ceiling is vouched for only when its audit's ensembles stand."""
    from sanlab.creature import read_source
    from sanlab.search import run_search
    from sanlab.search.pattern import POPSIZE

    text, where = read_source("cart")
    with Library(str(tmp_path / "f.db")) as lib:
        run = run_search(lib, text, where, controllers=POPSIZE, seconds=0.5, strategy="pattern", batch=POPSIZE)
        first, second = lib.top(run, 2)
        lib.add_audit(first.gait_id, {"verdict": "robust", "fell": {"dt/2": True, "dt/4": True}}, flagged=False, worst=0.0)
        lib.add_audit(second.gait_id, {"verdict": "robust", "fell": {"dt/2": False, "dt/4": False}}, flagged=False,
                      worst=0.0)
        c = find(lib, text, lib.get_run(run).settings.metric, 0.5)
        assert c is not None and c.gait == second.gait_id and c.robust and not c.fell
        lib.add_audit(second.gait_id, {"verdict": "robust", "fell": {"dt/2": False, "dt/4": True}}, flagged=False,
                      worst=0.0)
        c = find(lib, text, lib.get_run(run).settings.metric, 0.5)
        assert c is not None and c.gait == first.gait_id and c.fell and not c.robust  # none vouched for: the fastest, so marked
