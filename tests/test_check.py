"""``sanlab check --simulate`` (sanlab.check, issue 11 item 2): the warnings it gives on three
deliberately broken files, none on the built-ins, and its JSON."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from sanlab.check import radian_ranges, simulate, strength, warnings
from sanlab.cli import app
from sanlab.creature import builtin_names, load, loads
from tests.helpers import BASE, DATA

runner = CliRunner()


def warned(findings) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for f in findings:
        if f.warning:
            out.setdefault(f.check, []).append(f.message)
    return out


def test_radians_and_gains_in_the_wrong_unit_are_seen_without_simulating():
    c = load(str(DATA / "radians.toml"))
    r = warned(radian_ranges(c))["radians"]
    assert any("actuator hip: min_deg, max_deg = [-0.8, 0.8] look like radians" in m for m in r)
    assert any("sensor knee_bent (angle): min_deg, max_deg = [0.3, 1.2]" in m for m in r)
    (s,) = warned(strength(c))["strength"]
    assert "stronger than §3.3's sizing" in s
    assert not warned(radian_ranges(loads(BASE))) and not warned(strength(load("bounder")))


def test_a_weak_servo_is_seen():
    (s,) = warned(strength(load(str(DATA / "floating.toml"))))["strength"]
    assert "118 times weaker than §3.3's sizing" in s


@pytest.mark.parametrize("name, expected", [
    ("radians", {"strength": "467 times stronger", "radians": "look like radians"}),
    ("buried", {"start": "contact 1 of link arm starts 26.3 cm below the ground",
                "sinking": "link hub goes"}),
    ("floating", {"start": "floats 15 cm above the ground", "ground": "overdamped",
                  "strength": "times weaker", "sensors": "sensor far_out (angle) never turns on"}),
])  # fmt: skip
def test_three_broken_files(name, expected):
    found = warned(simulate(load(str(DATA / f"{name}.toml"))))
    assert set(found) == set(expected), found
    for check, needle in expected.items():
        assert any(needle in m for m in found[check]), (check, found[check])


@pytest.mark.slow
@pytest.mark.parametrize("name", builtin_names())
def test_no_warnings_on_the_built_ins(name):
    findings = simulate(load(name))
    assert not warned(findings), warned(findings)
    assert {f.check for f in findings} >= {"standing", "strength", "radians"}


def test_check_simulate_json():
    r = runner.invoke(app, ["check", str(DATA / "floating.toml"), "--simulate", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["ok"] and out["name"] == "floating" and out["warnings"] == 4
    checks = {c["check"] for c in out["checks"] if c["warning"]}
    assert checks == {"start", "ground", "strength", "sensors"}
    start = next(c for c in out["checks"] if c["check"] == "start")
    assert start["gap_m"] == pytest.approx(0.15) and start["link"] == "leg"


def test_check_json_without_simulating():
    r = runner.invoke(app, ["check", "bounder", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert (out["name"], out["links"], out["dofs"], out["hidden"]) == ("bounder", 5, 7, 8)
    assert out["sensors"] == {"touch": 2, "angle": 6} and "checks" not in out


def test_check_simulate_prints_one_line_per_finding():
    r = runner.invoke(app, ["check", str(DATA / "radians.toml"), "--simulate"], terminal_width=400)
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert "simulated (two seconds, servos at mid targets, then sweeping): 3 warnings" in lines
    marked = [ln.strip() for ln in lines if ln.startswith("  ok ") or ln.startswith("  warning ")]
    assert len(marked) == 9 and sum(ln.startswith("warning ") for ln in marked) == 3, marked
    assert any(ln.startswith("ok      servos: the step resolves every one") for ln in marked)
    assert any(ln.startswith("warning actuator hip: min_deg, max_deg = [-0.8, 0.8] look like radians") for ln in marked)
    assert any(ln.startswith("ok      start: rests on the ground") for ln in marked)


def test_warnings_are_the_simulations_warning_lines():
    found = warnings(load(str(DATA / "buried.toml")))
    assert len(found) == 2 and all("\n" not in m and m.isprintable() for m in found), found
    assert "contact 1 of link arm starts 26.3 cm below the ground" in found[0]


def test_a_bad_file_is_refused_before_any_simulation(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(BASE.replace('name = "L1"', 'name = ["L1"]'))
    r = runner.invoke(app, ["check", str(bad), "--simulate", "--json"])
    assert r.exit_code == 2 and r.stdout == "", r.output
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"{bad}: links[0].name: expected a name"), r.stderr
