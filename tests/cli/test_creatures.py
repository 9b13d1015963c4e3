"""``sanlab check`` and ``sanlab creatures``: summaries, one-line errors, and a start without JAX."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from tests.helpers import BASE, DATA, ROOT

runner = CliRunner()


@pytest.mark.parametrize("name, dofs", [("cart", 4), ("bounder", 7)])
def test_check_builtin(name, dofs):
    r = runner.invoke(app, ["check", name])
    assert r.exit_code == 0, r.output
    assert name in r.stdout and f"{dofs} degrees of freedom" in r.stdout and "angular" in r.stdout


def test_check_file_shows_counts():
    r = runner.invoke(app, ["check", str(DATA / "kitchen_sink.toml")])
    assert r.exit_code == 0, r.output
    assert "horizontal" in r.stdout and "linear 1" in r.stdout and "eye 2" in r.stdout


def test_check_prints_the_files_history(tmp_path):
    from sanlab.cli import _schemas

    lines = ["2026-12-04: shin 2 cm longer; faster on every seed", "2026-12-09: [bold]hip[/bold] x 1.5; robust at dt/4"]
    path = tmp_path / "hist.toml"
    path.write_text("history = [\n" + "".join(f'    "{line}",\n' for line in lines) + "]\n" + BASE)
    r = runner.invoke(app, ["check", str(path)], terminal_width=200)
    assert r.exit_code == 0, r.output
    assert "history: 2 changes to the file, oldest first" in r.stdout
    assert [ln.strip() for ln in r.stdout.splitlines() if ln.startswith("  2026-")] == lines  # markup printed as text
    r = runner.invoke(app, ["check", str(path), "--json"])
    out = json.loads(r.stdout)
    assert out["history"] == lines
    _schemas.validate(out, "check")
    r = runner.invoke(app, ["check", "cart", "--json"])
    assert json.loads(r.stdout)["history"] == []
    assert "history" not in runner.invoke(app, ["check", "cart"]).stdout


def _cli(*args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "sanlab", *args], capture_output=True, text=True, cwd=cwd, env=env
    )


def test_check_bad_file_subprocess(tmp_path):
    (tmp_path / "bad.toml").write_text(BASE.replace('link = "L1"', 'link = "L3"'))
    r = _cli("check", "bad.toml", cwd=tmp_path)
    assert r.returncode == 2
    line = "bad.toml: sensors[0].link: expected one of the link names ['L1', 'L2'], got 'L3'"
    assert r.stderr == line + "\n"
    assert "Traceback" not in r.stderr + r.stdout
    r = _cli("check", "missing.toml", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "missing.toml" in r.stderr
    assert "Traceback" not in r.stderr


def test_creatures_json():
    r = runner.invoke(app, ["creatures", "--json"])
    assert r.exit_code == 0, r.output
    rows = {row["name"]: row for row in json.loads(r.stdout)}
    from sanlab.creature import load

    assert rows["cart"] == {"schema": "sanlab/creature-entry/1", "name": "cart", "links": 2, "sensors": 6, "actuators": 1,
                            "hidden": 5, "description": load("cart").description}
    assert {k: v for k, v in rows["bounder"].items() if k not in ("schema", "description")} == \
        dict(name="bounder", links=5, sensors=8, actuators=4, hidden=8)
    assert all(isinstance(row["description"], str) and row["description"] for row in rows.values())
    r = runner.invoke(app, ["creatures"])
    assert r.exit_code == 0 and "bounder" in r.stdout
