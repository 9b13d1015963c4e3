"""``sanlab check --simulate`` (sanlab.check, issue 11 item 2): the warnings it gives on three
deliberately broken files, none on the built-ins, and its JSON; a creature no SAN can move
(every sensor off at rest) and what the ground's damping ratio means (issue 33)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from sanlab.check import _ground, at_rest, radian_ranges, simulate, static, strength, warnings
from sanlab.cli import app
from sanlab.creature import builtin_names, load, loads, read_source
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
    ("floating", {"start": "floats 15 cm above the ground", "ground": "far overdamped, a landing is stopped dead",
                  "strength": "times weaker", "sensors": "sensor far_out (angle) never turns on",
                  "at rest": "sensors at rest: none turns on in the drop"}),
])  # fmt: skip
def test_three_broken_files(name, expected):
    found = warned(simulate(load(str(DATA / f"{name}.toml"))))
    assert set(found) == set(expected), found
    for check, needle in expected.items():
        assert any(needle in m for m in found[check]), (check, found[check])


@pytest.mark.parametrize("name", builtin_names())
def test_no_warnings_on_the_built_ins(name):
    findings = simulate(load(name))
    assert not warned(findings), warned(findings)
    assert {f.check for f in findings} >= {"standing", "strength", "radians"}


def test_check_simulate_json():
    r = runner.invoke(app, ["check", str(DATA / "floating.toml"), "--simulate", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["ok"] and out["name"] == "floating" and out["warnings"] == 5
    checks = {c["check"] for c in out["checks"] if c["warning"]}
    assert checks == {"start", "ground", "strength", "sensors", "at rest"}
    assert next(c for c in out["checks"] if c["check"] == "at rest")["on"] == []
    start = next(c for c in out["checks"] if c["check"] == "start")
    assert start["gap_m"] == pytest.approx(0.15) and start["link"] == "leg"


def test_check_json_without_simulating():
    r = runner.invoke(app, ["check", "bounder", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert (out["name"], out["links"], out["dofs"], out["hidden"]) == ("bounder", 5, 7, 8)
    assert out["sensors"] == {"touch": 2, "angle": 6}
    # the checks that need no simulation (no JAX): all clear for a built-in
    assert {c["check"] for c in out["checks"]} == {"strength", "resolution", "radians", "at rest"} and out["warnings"] == 0


def test_check_simulate_prints_one_line_per_finding():
    r = runner.invoke(app, ["check", str(DATA / "radians.toml"), "--simulate"], terminal_width=400)
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert "simulated (two seconds, servos at mid targets, then sweeping): 3 warnings" in lines
    marked = [ln.strip() for ln in lines if ln.startswith("  ok ") or ln.startswith("  warning ")]
    assert len(marked) == 10 and sum(ln.startswith("warning ") for ln in marked) == 3, marked
    assert any(ln.startswith("ok      sensors at rest: foot on in the drop") for ln in marked)
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


# A three-segment snake lying straight, its servos centred on straight, with only "bent" angle
# sensors: every one is off at rest, so every SAN holds it still (issue 33: 200 SANs, all 0.000).
SNAKE = """\
name = "snake"

[[links]]
name = "head"
mass = 0.1
shape = "segment"
points = [[0, 0], [0.2, 0]]

[[links]]
name = "mid"
mass = 0.1
shape = "segment"
points = [[0, 0], [-0.2, 0]]
contacts = [[-0.2, 0]]
parent = "head"

[[links]]
name = "tail"
mass = 0.1
shape = "segment"
points = [[0, 0], [-0.2, 0]]
contacts = [[-0.2, 0]]
parent = "mid"
anchor = [-0.2, 0]

[[sensors]]
name = "mid_left"
type = "angle"
link = "mid"
min_deg = 20
max_deg = 180

[[sensors]]
name = "mid_right"
type = "angle"
link = "mid"
min_deg = -180
max_deg = -20

[[sensors]]
name = "tail_left"
type = "angle"
link = "tail"
min_deg = 20
max_deg = 180

[[actuators]]
type = "angular"
joint = "mid"
min_deg = -40
max_deg = 40
ks = 0.01
kd = 0.001

[[actuators]]
type = "angular"
joint = "tail"
min_deg = -40
max_deg = 40
ks = 0.01
kd = 0.001
"""
STRAIGHT = SNAKE + """
[[sensors]]
name = "tail_straight"
type = "angle"
link = "tail"
min_deg = -10
max_deg = 10
"""


def test_a_creature_whose_sensors_are_all_off_at_rest_is_seen_without_simulating():
    (f,) = at_rest(loads(SNAKE, "snake.toml"))
    assert f.warning and f.check == "at rest" and f.values == {"on": []}
    assert "none is on in the start pose, nor on the way to the servos' mid targets" in f.message
    assert "a SAN has no bias" in f.message and 'a "straight" angle sensor' in f.message
    assert "\n" not in f.message and f.message.isprintable()
    assert any(x.check == "at rest" and x.warning for x in static(loads(SNAKE, "snake.toml")))
    (ok,) = at_rest(loads(STRAIGHT, "snake.toml"))  # the fix the message gives
    assert not ok.warning and ok.values == {"on": ["tail_straight"]}
    # on the way to the mid targets: centred servos on a joint that starts bent at 30 deg
    bent = SNAKE.replace('parent = "mid"\n', 'parent = "mid"\nangle_deg = 30\n', 1)
    assert at_rest(loads(bent, "snake.toml"))[0].values == {"on": ["tail_left"]}
    assert at_rest(loads(SNAKE.split("[[sensors]]")[0] + SNAKE[SNAKE.index("[[actuators]]"):], "s.toml"))[0].message \
        .startswith("sensors at rest: it has no sensors")


def test_a_pose_balanced_on_one_contact_tips_over_onto_the_next():
    """A rod standing at 30 deg on its lower end falls flat, both ends on the ground (the
    static check's settling, ``_tipped``), whichever way it leans; a bent two-link body falls
    onto its hull and stops where its centre of mass is over the contacts it landed on."""
    from sanlab.check import _tipped
    from sanlab.creature import geometry

    for lean in (30, 150):  # leaning right, then left
        rod = loads(f'[[links]]\nname = "r"\nmass = 1\nshape = "segment"\npoints = [[0, 0], [0.5, 0]]\n'
                    f'angle_deg = {lean}\n', "rod.toml")
        t = _tipped(rod, geometry.initial_frames(rod))
        ys = [geometry.transform(t["r"], p)[1] for p in rod.links[0].contacts]
        assert ys == pytest.approx([0.0, 0.0], abs=1e-12)
        assert math.cos(t["r"][2]) == pytest.approx(-1.0 if lean > 90 else 1.0)
    bent = loads(BASE, "bent.toml")  # L1 upright on its end, L2 bent 45 deg off its top
    t = _tipped(bent, geometry.initial_frames(bent))
    pts = [geometry.transform(t[link.name], p) for link in bent.links for p in link.contacts]
    low = min(y for _, y in pts)
    feet = [x for x, y in pts if y < low + 1e-9]
    com = sum(link.mass * geometry.transform(t[link.name], link.com)[0] for link in bent.links) / 0.2
    assert len(feet) == 2 and min(feet) <= com <= max(feet)


@pytest.mark.parametrize("name", builtin_names())
def test_no_built_in_is_still_at_rest_without_simulating(name):
    """Every built-in has a sensor on at rest, or (linear actuators, moving eyes) is not judged."""
    assert not [f.message for f in static(load(name)) if f.warning]


def test_the_simulated_check_says_no_san_can_move_it_and_how_to_fix_it():
    found = {f.check: f for f in simulate(loads(SNAKE, "snake.toml"), seconds=1.0)}
    f = found["at rest"]
    assert f.warning and f.values == {"on": []}
    assert f.message.startswith("sensors at rest: none turns on in the drop with the servos at their mid targets, "
                                "which is what every SAN does while its sensors are off")
    assert "a SAN has no bias" in f.message and "add a sensor that is on at the start" in f.message
    straight = {f.check: f for f in simulate(loads(STRAIGHT, "snake.toml"), seconds=1.0)}["at rest"]
    assert not straight.warning and "tail_straight" in straight.values["on"]


def _ground_line(damping: float, depth=(0.0004, 0.0004, 0.0, 0.0)):
    spec = loads(BASE + f"\n[world.ground]\ndamping = {damping}\n")  # 0.2 kg on two touching contacts
    (f,) = _ground(spec, {"depth": np.asarray(depth, float)[None, None, :]})
    return f


def test_an_overdamped_ground_is_called_fine_and_says_what_it_means():
    f = _ground_line(300.0)  # 300 / (2 sqrt(50000 x 0.1)) = 2.1
    assert not f.warning and f.values["damping_ratio"] == pytest.approx(300 / (2 * (50000 * 0.1) ** 0.5))
    assert "overdamped (beyond critical for the mass on each contact), so landings do not bounce; fine" in f.message
    assert "0.1 kg on each contact" in f.message
    under = _ground_line(20.0)  # 0.14
    assert not under.warning and "underdamped, a landing rings down (each swing 64% of the one before)" in under.message
    mud = _ground_line(10000.0)  # 71
    assert mud.warning and "far overdamped, a landing is stopped dead and a contact takes c/k = 0.2 s" in mud.message
    bouncy = _ground_line(0.5)
    assert bouncy.warning and "it bounces (raise world.ground.damping)" in bouncy.message


def test_the_servos_line_says_which_servos_ring():
    """"or overdamped" left the reader to guess: the line now says whether any servo rings."""
    from sanlab.check import resolution

    (b,) = resolution(load("bounder"))
    assert not b.warning and b.message == "servos: the step resolves every one (every one is overdamped: none rings)"
    (c,) = resolution(load("cart"))
    assert not c.warning and "rad per step of those that ring, at most 1" in c.message


# -- issue 48: springs, stops and linear actuators the step cannot resolve -----------------------

SPRING = 'anchor = [0.2, 0.0]'  # twolink's joint, where a spring or a stop goes


def _stiff(kind: str, damping: float) -> str:
    """A built-in with one element made stiff (1e6 in the file's units) and damped by ``damping``
    (the file's units): twolink's joint spring at a 90 degree rest angle (the issue's case) or
    its stop, the crawler's linear spring or linear actuator."""
    import re

    if kind in ("spring", "limit"):
        text, _ = read_source("twolink")
        extra = (f"spring = {{ stiffness = 1e6, damping = {damping}, rest_deg = 90 }}" if kind == "spring"
                 else f"limit = {{ min_deg = -10, max_deg = 10, stiffness = 1e6, damping = {damping} }}")
        return text.replace(SPRING, SPRING + "\n" + extra, 1)
    text, _ = read_source("crawler")
    if kind == "linear spring":
        return re.sub(r'(name = "rear"\n(?:.*\n)*?)stiffness = 50\.0\ndamping = 1\.0', rf"\1stiffness = 1e6\ndamping = {damping}", text, count=1)
    return text.replace("ks = 8.0             # N/m\nkd = 0.8", f"ks = 1e6\nkd = {damping}", 1)


@pytest.mark.parametrize("kind, what", [("spring", "link L2 spring"), ("limit", "link L2 limit"),
                                        ("linear spring", "spring rear"), ("linear actuator", "actuator A1")])
def test_a_stiff_undamped_spring_stop_or_linear_actuator_is_flagged_like_a_servo(kind, what):
    """Issue 48: the twolink with a 1e6 N m/deg joint spring at a 90 degree rest angle topped the
    search table at 67 cm/s (4x the built-in) unflagged: the step-size flag looked at angular
    servos only. Now each kind of spring is the same check; heavily damped, none rings."""
    from sanlab.check import resolution
    from sanlab.evaluate.resolution import Servos

    spec = loads(_stiff(kind, 0.0), "stiff.toml")
    sv = Servos.of(spec)
    ks, kd = [a.ks for a in spec.actuators], [a.kd for a in spec.actuators]
    assert sv.unresolved(ks, kd, spec.dt) and sv.unresolved(np.array([ks, ks]), np.array([kd, kd]), spec.dt).all()
    warned = [f.message for f in resolution(spec) if f.warning]
    assert len(warned) == 1 and warned[0].startswith(f"{what}: rings at ") and "cannot follow it" in warned[0], warned
    damped = loads(_stiff(kind, 1e5), "damped.toml")
    sv = Servos.of(damped)
    assert not sv.unresolved([a.ks for a in damped.actuators], [a.kd for a in damped.actuators], damped.dt)
    assert not [f for f in resolution(damped) if f.warning]


def test_the_springs_line_says_whether_any_rings():
    from sanlab.check import resolution

    lines = [f.message for f in resolution(load("crawler")) if f.message.startswith("springs and stops")]
    assert lines == ["springs and stops: the step resolves every one (largest omega dt 0.032 rad per step of those that "
                     "ring, at most 1)"]


# -- issue 57: ks = 0, no degrees of freedom, no actuators, "ok" that did not hold ------------------

SWITCHED_OFF = BASE.replace("ks = 0.002", "ks = 0")
NO_ACTUATORS = BASE[: BASE.index("[[actuators]]")]
ALL_FIXED = 'name = "post"\n\n[[links]]\nname = "L1"\nmass = 0.1\nshape = "segment"\npoints = [[0, 0], [0.2, 0]]\nfixed = true\n'


def test_an_actuator_switched_off_with_ks_0_is_a_note_and_all_off_a_warning(tmp_path):
    """Issue 57 item 1: ks = 0 ended `check` and `search` in ZeroDivisionError (1 / ratio)."""
    assert not [f for f in static(loads(BASE, "base.toml")) if f.check == "actuators"]  # a driven servo: nothing said
    off = loads(SWITCHED_OFF, "off.toml")
    (s,) = strength(off)
    assert s.note and not s.warning and s.values["held"] == 0.0
    assert s.message.startswith("actuator A1: actuators[0].ks = 0 (switched off): it drives nothing")
    (a,) = [f for f in static(off) if f.check == "actuators"]
    assert a.warning and "every one has ks = 0" in a.message and a.values == {"actuators": 1, "driven": 0}
    path = tmp_path / "off.toml"
    path.write_text(SWITCHED_OFF)
    r = runner.invoke(app, ["check", str(path)])
    assert r.exit_code == 0 and "Traceback" not in r.output and "ZeroDivisionError" not in r.output, r.output
    r = runner.invoke(app, ["search", str(path), "-n", "4", "--db", str(tmp_path / "l.db")])
    assert r.exit_code == 2 and r.stdout == "" and r.stderr.count("\n") == 1, r.output
    assert "can never move: every actuator has ks = 0" in r.stderr and "--force" in r.stderr


def test_one_motor_switched_off_among_driven_ones_is_not_refused():
    three = SWITCHED_OFF.replace("[[sensors]]", '[[links]]\nname = "L3"\nmass = 0.1\nshape = "segment"\n'
                                 'points = [[0, 0], [0.2, 0]]\nparent = "L2"\nanchor = [0.2, 0]\n\n[[sensors]]', 1)
    three += BASE[BASE.index("[[actuators]]"):].replace('joint = "L2"', 'joint = "L3"')
    spec = loads(three, "three.toml")
    assert not [f for f in static(spec) if f.check == "actuators"]
    assert [f.message.split(":")[0] for f in strength(spec) if "ks = 0" in f.message] == ["actuator A1"]


def test_a_creature_with_every_link_fixed_is_refused_naming_the_field(tmp_path):
    """Issue 57 item 2: 0 degrees of freedom passed `check`; `check --simulate` ended in a
    ValueError traceback and `search` flagged every controller non-finite."""
    from sanlab.creature import CreatureError

    with pytest.raises(CreatureError, match=r"^post\.toml: links\[0\]\.fixed: expected at least one degree of freedom"):
        loads(ALL_FIXED, "post.toml")
    path = tmp_path / "post.toml"
    path.write_text(ALL_FIXED)
    for argv in (["check", str(path)], ["check", str(path), "--simulate"], ["search", str(path), "--db", str(tmp_path / "l.db")]):
        r = runner.invoke(app, argv)
        assert r.exit_code == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.output, (argv, r.output)
        assert r.stderr.startswith(f"{path}: links[0].fixed: expected at least one degree of freedom"), r.stderr
    # a fixed root with a jointed link has a degree of freedom: a rig still loads
    rig = ALL_FIXED + '\n[[links]]\nname = "arm"\nmass = 0.1\nshape = "segment"\npoints = [[0, 0], [0.2, 0]]\nparent = "L1"\n'
    assert loads(rig, "rig.toml").dofs == 1
    # a Creature built in code, past the loader: one clear ValueError, not the simulator's shape error
    from sanlab.creature.spec import Creature, Link, Shape

    post = Creature("post", (Link("L1", 0.1, 0.0, (0.1, 0.0), Shape("segment", ((0.0, 0.0), (0.2, 0.0))), fixed=True),))
    with pytest.raises(ValueError, match=r"^post: expected at least one degree of freedom to simulate, got every link fixed$"):
        simulate(post)


def test_a_creature_without_actuators_is_warned_of_and_refused_by_search(tmp_path):
    """Issue 57 item 3: no actuators passed `check` and `check --strict`, `check --simulate` said
    "ok sensors: each turns on and off while the actuators sweep their ranges", and `search`
    scored 200 zeros."""
    spec = loads(NO_ACTUATORS, "idle.toml")
    (a,) = [f for f in static(spec) if f.check == "actuators"]
    assert a.warning and a.message.startswith("actuators: none, so no SAN can move any part")
    assert not strength(spec)  # nothing said about actuators that do not exist
    found = simulate(spec, seconds=1.0)
    assert not [f for f in found if f.check == "sensors"], [f.message for f in found]
    assert not [f for f in found if not f.warning and "actuator" in f.message and f.check != "standing"]
    assert [f.check for f in found if f.warning] == ["actuators"]
    path = tmp_path / "idle.toml"
    path.write_text(NO_ACTUATORS)
    r = runner.invoke(app, ["check", str(path), "--strict"])
    assert r.exit_code == 1 and "warning actuators: none" in r.stdout, r.output
    db = str(tmp_path / "l.db")
    r = runner.invoke(app, ["search", str(path), "-n", "4", "--db", db])
    assert r.exit_code == 2 and r.stdout == "" and r.stderr.count("\n") == 1, r.output
    assert r.stderr.startswith(f"search: {path} can never move: no actuators, so no SAN can move any part")
    assert r.stderr.rstrip().endswith("(or give --force to search it anyway)")
    r = runner.invoke(app, ["search", str(path), "-n", "4", "--batch", "4", "--db", db, "--force", "--json"])
    assert r.exit_code == 0 and json.loads(r.stdout)["evaluated"] == 4, r.output


def test_no_sensor_line_without_sensors():
    bare = BASE[: BASE.index("[[sensors]]")] + BASE[BASE.index("[[actuators]]"):]
    found = simulate(loads(bare, "bare.toml"), seconds=1.0)
    assert not [f for f in found if f.check == "sensors"], [f.message for f in found]
    assert any(f.check == "at rest" and f.warning and "it has no sensors" in f.message for f in found)


def test_a_creature_that_falls_at_mid_targets_is_not_ok_standing():
    """Issue 57 item 4: "ok standing" for a walker2d whose centre of mass moves 71 cm as it
    falls over. The built-in walker does the same (its torso tilts past its fell_angle_deg of
    60): a note naming the rule it broke, never "ok"."""
    (f,) = [f for f in simulate(load("walker")) if f.check == "standing"]
    assert f.note and not f.warning and f.values["fell"], f
    assert f.message.startswith("standing: falls by the file's fell rule with the servos at mid targets (link torso tilts ")
    assert "past evaluation.fell_angle_deg = 60" in f.message
    (b,) = [f for f in simulate(load("bounder")) if f.check == "standing"]
    assert not b.note and not b.warning and not b.values["fell"]
    assert "it never meets the file's fell rule" in b.message
    (c,) = [f for f in simulate(load("cart")) if f.check == "standing"]
    assert not c.note and "the file has no fell rule to judge a fall by" in c.message


def test_a_servo_below_one_times_its_load_is_a_note_not_ok():
    """Issue 57 item 4: "ok" for luxo's base servo holding 0.37x its gravity load, where §3.3's
    rule asks for 1x: "ok" now only from 1x (to 20x), a note between 1/20x and 1x."""
    luxo = {f.message.split(":")[0]: f for f in strength(load("luxo"))}
    a1 = luxo["actuator A1"]
    assert a1.note and not a1.warning and a1.values["ratio"] == pytest.approx(0.37, abs=0.01)
    assert "(0.37x): below §3.3's sizing at full reach" in a1.message
    walker = {f.message.split(":")[0]: f for f in strength(load("walker"))}
    a3 = walker["actuator A3"]
    assert not a3.note and not a3.warning and a3.values["ratio"] >= 1
    assert a3.message.endswith("holds it even at full reach (§3.3's sizing met)")
    for f in (*strength(load("luxo")), *strength(load("walker"))):
        assert (f.values["ratio"] >= 1) == (not f.note and not f.warning), f.message


def test_check_prints_notes_as_notes_and_counts_them():
    r = runner.invoke(app, ["check", "luxo", "--json"])
    out = json.loads(r.stdout)
    assert out["notes"] == 2 and out["warnings"] == 0
    assert [c["note"] for c in out["checks"] if c["check"] == "strength"] == [True, True]
    r = runner.invoke(app, ["check", "luxo"], terminal_width=400)
    assert "checked without simulating (--simulate says more): 0 warnings, 2 notes" in r.stdout
    assert not [ln for ln in r.stdout.splitlines() if ln.startswith("  ok      actuator A")], r.stdout
    assert len([ln for ln in r.stdout.splitlines() if ln.startswith("  note    actuator A")]) == 2


def test_a_tiny_radian_like_range_is_not_suggested_as_0_0():
    """Issue 57 item 13: [0, 0.001] suggested "[0, 0]" (each end rounded to whole degrees)."""
    spec = loads(BASE.replace("min_deg = -90\nmax_deg = 90\nks", "min_deg = 0\nmax_deg = 0.001\nks"), "tiny.toml")
    (f,) = [f for f in radian_ranges(spec) if f.warning]
    assert "[0, 0]" not in f.message and f.message.endswith("e.g. [0, 0.0573]"), f.message
    (g,) = [f for f in radian_ranges(load(str(DATA / "radians.toml"))) if f.warning and "hip" in f.message]
    assert g.message.endswith("e.g. [-46, 46]")
