"""Issue 33, part 3: every ``--json`` output is a record of ``sanlab/schemas/`` (JSON Schema,
docs/json.md), validated here; each names its schema, and the same thing has the same name in
every record.

One module library (a copy of the session's cart search, ``lib_run``) takes a short tuning and
an audit of two members, so that every command's real output is validated, not a hand-made one."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import jsonschema
import pytest
from typer.testing import CliRunner

from sanlab.cli import _schemas, app
from sanlab.creature import load
from sanlab.library import Library

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]


def out(*args: str):
    r = runner.invoke(app, list(args))
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout, parse_constant=lambda c: pytest.fail(f"{args}: {c} in --json output"))


def valid(obj, name: str):
    """``obj`` validated as record ``name`` (each element of a list), returned."""
    for item in obj if isinstance(obj, list) else [obj]:
        _schemas.validate(item, name)
        assert item["schema"] == f"sanlab/{name}/1"
    return obj


@pytest.fixture(scope="module")
def lib(lib_run, tmp_path_factory):
    """(db, search run id, tuning run id, audited gait): a copy of ``lib_run`` with one tuning
    (2 trials) and one audit (2 members) added, the tuning's and the audit's --json kept."""
    src, run_id = lib_run
    db = str(tmp_path_factory.mktemp("json") / "g.db")
    shutil.copy(src, db)
    tuned = out("tune", f"{run_id}/1", "--trials", "2", "--batch", "8", "--ensemble", "1", "--db", db, "--json")
    audited = out("audit", f"{run_id}/1", "--members", "2", "--max-members", "2", "--db", db, "--json")
    return db, run_id, tuned, audited


def test_every_schema_is_a_valid_json_schema_and_packaged():
    assert set(_schemas.RECORDS) == {p.stem for p in (ROOT / "sanlab" / "schemas").glob("*.json")}
    for name in _schemas.RECORDS:
        schema = _schemas.load(name)
        jsonschema.Draft202012Validator.check_schema(schema)
        assert schema["title"].startswith(f"sanlab/{name}")
    text = (ROOT / "pyproject.toml").read_text()
    assert '"sanlab" = ["schemas/*.json"]' in text and '"jsonschema>=4"' in text
    with pytest.raises(ValueError, match="no --json record"):
        _schemas.schema_id("nonsense")


def test_a_schema_refuses_what_it_does_not_describe(lib):
    db, run_id, _, _ = lib
    shown = valid(out("show", run_id, "--db", db, "--json"), "run")
    for bad in ({**shown, "schema": "sanlab/run/2"},  # another version
                {**shown, "top": [{**shown["top"][0], "finite": True}]},  # an old name in a gait row
                {k: v for k, v in shown.items() if k != "score_unit"}):
        with pytest.raises(jsonschema.ValidationError):
            _schemas.validate(bad, "run")


def test_search_show_runs_and_modes(lib, tmp_path):
    db, run_id, _, _ = lib
    fresh = str(tmp_path / "s.db")
    found = valid(out("search", "cart", "-n", "16", "--seconds", "1", "--batch", "16", "--ensemble", "1", "--db", fresh,
                      "--json"), "search")
    assert found["tally"]["evaluated"] == found["evaluated"] == 16 and set(found["tally"]) == {"evaluated", "fell", "nonfinite"}
    assert found["score_unit"] == "m" and found["creature"] == "cart"
    shown = valid(out("show", found["run_id"], "--db", fresh, "--json"), "run")
    assert shown["top"] == found["top"]  # one gait row, in both
    listed = valid(out("runs", "--db", db, "--json"), "run-entry")
    assert {r["kind"] for r in listed} >= {"search", "tune"}
    valid(out("modes", run_id, "--db", db, "--json"), "modes")
    assert out("show", run_id, "--modes", "--db", db, "--json") == out("modes", run_id, "--db", db, "--json")


def test_show_a_gait_with_and_without_its_audit(lib):
    db, run_id, _, [audited] = lib
    plain = valid(out("show", f"{run_id}/2", "--db", db, "--json", "--network"), "gait")
    assert plain["audit"] is None and set(plain["network"]) >= {"inputs", "nodes", "weights"}
    seen = valid(out("show", audited["gait"], "--db", db, "--json"), "gait")
    # the audit's words are the same in audit --json, show GAIT --json and show RUN --json's rows
    for key in ("verdict", "flagged", "resolution_dependent", "reproduced"):
        assert seen["audit"][key] == audited[key], key
    row = next(r for r in valid(out("show", run_id, "--db", db, "--json"), "run")["top"] if r["gait"] == f"{run_id}/1")
    assert (row["verdict"], row["flagged"], row["resolution_dependent"], row["reproduced"]) == \
        (audited["verdict"], audited["flagged"], audited["resolution_dependent"], audited["reproduced"])
    assert seen["audit"]["worst"] == pytest.approx(audited["worst"])


def test_audit_and_tune_are_lists_of_records(lib):
    db, run_id, tuned, audited = lib
    valid(audited, "audit")
    [a] = audited
    assert a["flagged"] == (a["verdict"] != "robust") and a["audit_members"] == 2
    [t] = valid(tuned, "tuning")  # one gait: a list of one, as --top K gives K
    assert t["gait"].startswith(run_id) and t["tuned_gait"] == f"{t['run_id']}#0" and t["trials"] == 2
    with Library(db) as lb:
        dx = (lb.gait(t["tuned_gait"]).extra or {}).get("dx_m")
    assert t["direction"] == (None if not dx else "+x" if dx > 0 else "-x")
    two = out("tune", run_id, "--top", "2", "--trials", "1", "--batch", "8", "--ensemble", "1", "--db", db, "--json")
    with Library(db) as lb:
        best = [e.gait_id for e in lb.top(run_id, 2)]
    assert [r["gait"] for r in valid(two, "tuning")] == best  # the parents, by permanent id


def test_the_selection_record(lib, monkeypatch):
    """``audit RUN --select --json`` (and ``tune --select``'s ``selection``): its record, from a
    selection made of the stored audit's own shifts (a real one audits up to 16 rungs)."""
    import sanlab.audit
    from sanlab.audit import Candidate, Selection
    from sanlab.cli.audit import select_and_report

    db, _, [t], [a] = lib
    shifts = {k: sanlab.audit.Shift.from_json(v) for k, v in a["shifts"].items()}
    rung = Candidate(3, 0.5, 1.2, 0.4, 1.1, dict.fromkeys(shifts, 1.0), shifts)
    chosen = Selection(t["run_id"], f"{t['run_id']}#1", rung, [rung], 0.1)
    monkeypatch.setattr(sanlab.audit, "select_robust", lambda *a, **k: chosen)
    with Library(db) as lb:
        sel = valid(select_and_report(lb, t["run_id"], 0.1, quiet=True), "selection")
    assert sel["run_id"] == t["run_id"] and sel["trial"] == 3 and sel["candidates"][0]["trial"] == 3
    valid([{**t, "selection": sel}], "tuning")


def test_simulate_check_creatures_and_render(lib, tmp_path):
    db, run_id, _, _ = lib
    sim = valid(out("simulate", "cart", "-n", "16", "--seconds", "1", "--ensemble", "1", "--top", "4", "--json"), "simulate")
    assert len(sim["top"]) == 4 and sim["tally"]["evaluated"] == 16
    for row in sim["top"]:  # the gait rows' words: dx_m and direction, nonfinite (not distance_m, finite)
        assert row["direction"] == (None if not row["dx_m"] else "+x" if row["dx_m"] > 0 else "-x")
    # simulate scores what search stores, controller for controller
    with Library(db) as lb:
        stored = {e.idx: e for e in lb.top(run_id, None)}
    for row in sim["top"]:
        assert row["score"] == pytest.approx(stored[row["controller"]].score, abs=1e-6)
        assert row["dx_m"] == pytest.approx((stored[row["controller"]].extra or {}).get("dx_m"), abs=1e-6)
    checked = valid(out("check", "cart", "--json"), "check")
    assert checked["metric_direction"] == load("cart").evaluation.direction
    assert "direction" not in checked  # "direction" is a motion's (+x, -x) everywhere
    valid(out("creatures", "--json"), "creature-entry")
    still = valid(out("render", f"{run_id}/1", "--seconds", "0.5", "--width", "160", "-o", str(tmp_path / "a.png"),
                      "--db", db, "--json"), "render")
    assert still["kind"] == "strobe"
    film = valid(out("render", f"{run_id}/1", "--seconds", "0.2", "--width", "96", "-o", str(tmp_path / "a.gif"),
                     "--db", db, "--json"), "render")
    assert film["kind"] == "animation" and film["fps"] == 30
    sheet = valid(out("render", run_id, "--top", "2", "--seconds", "0.2", "--width", "400", "-o", str(tmp_path / "s.png"),
                      "--db", db, "--json"), "render")
    assert sheet["kind"] == "contact sheet" and sheet["gaits"] == 2
    valid(out("render", run_id, "--plot", "scores", "-o", str(tmp_path / "p.png"), "--db", db, "--json"), "render")


def test_the_docs_describe_every_record():
    text = (ROOT / "docs" / "json.md").read_text()
    for name in _schemas.RECORDS:
        assert f"`sanlab/{name}/1`" in text, name
        for field in _schemas.load(name)["properties"]:
            assert f"`{field}`" in text, (name, field)
