"""Free numbers in creature files (issue 47, part 1; paper §6.3): a range in place of a number,
loaded at its default everywhere; named numbers used in several places; the ``[design]``
couplings; one-line errors naming the file and the field."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from sanlab.cli import _schemas, app
from sanlab.creature import CreatureError, load_design, loads
from sanlab.creature.loader import loads_design
from tests.helpers import DATA

HOPPER = DATA / "hopper_free.toml"  # the example of docs/creature-format.md, "Free numbers"
TEXT = HOPPER.read_text()


def _stated(text: str) -> str:
    """The file with each range replaced by its default (the middle, or its default key), and
    each use by its value."""
    values: dict[str, float] = {}

    def free(m: re.Match) -> str:
        body = dict(re.findall(r"(\w+) = (\"?[-\w.]+\"?)", m.group(1)))
        v = float(body.get("default", (float(body["min"]) + float(body["max"])) / 2))
        if "name" in body:
            values[body["name"].strip('"')] = v
        return repr(v)

    text = re.sub(r"\{ (min = [^}]*)\}", free, text)
    return re.sub(r'\{ free = "(\w+)" \}', lambda m: repr(values[m.group(1)]), text).split("[design]")[0]


def test_a_file_with_free_numbers_loads_as_its_defaults_written_out():
    assert loads(TEXT) == loads(_stated(TEXT))
    design, c = loads_design(TEXT)
    assert c.links[1].shape.points[1][1] == pytest.approx(-0.275) and c.links[1].contacts[0][1] == pytest.approx(-0.275)
    assert design.names == ("links[0].mass", "front", "back", "actuators[0].ks")
    assert design.free[1].uses == ("links[1].points[1][1]", "links[1].contacts[0][1]")


def test_a_default_key_is_the_value_loaded():
    text = TEXT.replace("mass = { min = 0.5, max = 1.5 }", "mass = { min = 0.5, max = 1.5, default = 0.6 }")
    assert loads(text).links[0].mass == 0.6


def test_a_use_takes_times_and_plus():
    text = TEXT.replace('contacts = [[0, { free = "front" }]]', 'contacts = [[0, { free = "front", times = 0.5, plus = 0.01 }]]')
    assert loads(text).links[1].contacts[0][1] == pytest.approx(-0.275 * 0.5 + 0.01)


def test_a_creature_at_other_values_follows_the_couplings():
    design, stated = load_design(str(HOPPER))
    v = design.defaults.copy()
    v[1] = -0.35  # the front leg longer by 0.075 m: the total leg length takes 0.075 m back, from
    # each leg in proportion to its room (front 0.15 m to its shortest, back 0.075 m): 2/3 and 1/3
    c = design.creature(v)
    assert c.links[1].contacts[0][1] == pytest.approx(-0.3) and c.links[2].contacts[0][1] == pytest.approx(-0.25)
    assert c.links[1].mass == pytest.approx(0.1 * 0.3 / 0.275)  # density: mass follows length
    assert c.links[2].mass == pytest.approx(0.1 * 0.25 / 0.275)
    v = design.defaults.copy()
    v[3] = 0.03  # a stronger front muscle (0.01 N·m/deg above its default): 2 kg per N·m/deg more
    assert design.creature(v).links[1].mass == pytest.approx(0.1 + 2.0 * 0.01)
    assert design.creature(design.defaults) == stated


def test_total_mass_holds():
    text = TEXT.replace("strength_mass = 2.0", "strength_mass = 2.0\ntotal_mass = true")
    design, stated = loads_design(text)
    for v in (design.lo, design.hi):
        assert sum(k.mass for k in design.creature(v).links) == pytest.approx(sum(k.mass for k in stated.links))
    text = TEXT.replace("strength_mass = 2.0", "total_mass = 2.4")
    assert sum(k.mass for k in loads(text).links) == pytest.approx(2.4)


def test_a_total_moves_its_numbers_within_their_ranges():
    design, _ = load_design(str(HOPPER))
    rng = np.random.default_rng(0)
    for _ in range(20):
        v = design.project(design.lo + (design.hi - design.lo) * rng.random(len(design.free)))
        assert v[1] + v[2] == pytest.approx(-0.55) and np.all(v >= design.lo) and np.all(v <= design.hi)


def test_a_free_number_in_a_repeat_is_one_number_for_every_copy():
    text = """name = "chain"
[[links]]
name = "s0"
mass = 0.05
shape = "segment"
points = [[0, 0], [-0.1, 0]]
[[repeat]]
count = 3
[[repeat.links]]
name = "s{i}"
parent = "s{i-1}"
mass = { min = 0.02, max = 0.08, default = 0.03 }
shape = "segment"
points = [[0, 0], [-0.1, 0]]
anchor = [-0.1, 0]
"""
    design, c = loads_design(text)
    assert [f.path for f in design.free] == ["repeat[0].links[0].mass"]
    assert [k.mass for k in c.links] == [0.05, 0.03, 0.03, 0.03]
    assert [k.mass for k in design.creature([0.08]).links] == [0.05, 0.08, 0.08, 0.08]


@pytest.mark.parametrize("old, new, message", [
    ("mass = { min = 0.5, max = 1.5 }", "mass = { min = 1.5, max = 0.5 }",
     "links[0].mass.max: expected a number above min = 1.5 (a free number's range), got 0.5"),
    ("mass = { min = 0.5, max = 1.5 }", "mass = { min = 0.5, max = 1.5, default = 2 }",
     "links[0].mass.default: expected a number within [0.5, 1.5] (the range), got 2"),
    ("mass = { min = 0.5, max = 1.5 }", 'mass = { min = "a", max = 1.5 }',
     "links[0].mass.min: expected a finite number (an end of a free number's range), got 'a'"),
    ('{ free = "back" }', '{ free = "bakc" }',
     "links[2].contacts[0][1].free: expected the name of a free number (one of ['back', 'front']), got 'bakc'"),
    ('name = "back" }', 'name = "front" }',
     "links[2].points[1][1].name: expected a name not used by another free number (links[1].points[1][1]), got 'front'"),
    ("strength_mass = 2.0", "strength_mass = -1",
     "design.strength_mass: expected a number >= 0 (kg per N·m/deg of actuator strength), got -1"),
    ("strength_mass = 2.0", "strenght_mass = 2.0", "design.strenght_mass: unknown field"),
    ('density = ["front", "back"]', 'density = ["front", "leg"]',
     "design.density[1]: expected one of the link names ['body', 'front', 'back'], got 'leg'"),
    ("value = -0.55", "value = -0.8",
     "design.total[0].value: expected a number within [-0.7, -0.4] (the sum of the ranges), got -0.8"),
    ('mass = { min = 0.5, max = 1.5 }', "mass = { min = 0.5, max = 1.5, default = 0 }",
     "links[0].mass.default: expected a number within [0.5, 1.5]"),
    # a table meant as a free number, or a use of one, but neither: said so, not "got a table"
    ("mass = { min = 0.5, max = 1.5 }", "mass = { min = 0.5, max = 1.5, defualt = 1 }",
     "links[0].mass.defualt: unknown field of a free number; did you mean 'default'? expected one of "
     "['default', 'max', 'min', 'name']"),
    ("mass = { min = 0.5, max = 1.5 }", "mass = { min = 0.5, default = 1 }",
     "links[0].mass: expected a free number with min and max (e.g. { min = 0.1, max = 0.3 }), got a table "
     "without max"),
    ('{ free = "back" }', '{ free = "back", plsu = 0.1 }',
     "links[2].contacts[0][1].plsu: unknown field of a use of a free number; did you mean 'plus'?"),
    ("mass = { min = 0.5, max = 1.5 }", 'mass = { min = 0.5, max = 1.5, free = "back" }',
     "links[0].mass: expected a free number (min, max, default, name) or a use of one (free, times, plus), got "
     "a table with keys of both (max, min and free)"),
])
def test_bad_free_numbers_and_couplings_are_one_line_errors(old, new, message):
    assert old in TEXT
    with pytest.raises(CreatureError) as e:
        loads(TEXT.replace(old, new, 1), "hopper.toml")
    assert str(e.value).startswith("hopper.toml: ") and message in str(e.value) and "\n" not in str(e.value)


def test_a_default_that_makes_no_creature_is_the_loaders_error():
    text = TEXT.replace("mass = { min = 0.5, max = 1.5 }", "mass = { min = -1, max = 1 }")
    with pytest.raises(CreatureError, match=r"hopper.toml: links\[0\].mass: expected a positive number"):
        loads(text, "hopper.toml")


def test_check_lists_each_free_number_its_range_and_masses_and_the_couplings():
    r = CliRunner().invoke(app, ["check", str(HOPPER)])
    assert r.exit_code == 0, r.output
    out = r.stdout
    assert "free numbers: 4" in out
    assert "front: free in [-0.35, -0.2], default -0.275" in out
    assert "links[0].mass: free in [0.5, 1.5], default 1; total mass 0.7 kg at min, 1.7 kg at max" in out
    assert "density: mass follows size" in out and "total: front + back = -0.55" in out
    r = CliRunner().invoke(app, ["check", str(HOPPER), "--json"])
    obj = json.loads(r.stdout)
    _schemas.validate(obj, "check")
    ks = obj["free"][3]
    assert (ks["min"], ks["max"], ks["default"]) == (0.01, 0.03, 0.02)
    assert ks["mass_at_min"] == pytest.approx(1.2 - 0.02) and ks["mass_at_max"] == pytest.approx(1.2 + 0.02)
    assert obj["couplings"]["strength_mass"] == 2.0


def test_check_of_a_file_without_free_numbers_says_nothing_of_them():
    r = CliRunner().invoke(app, ["check", "cart", "--json"])
    assert "free" not in json.loads(r.stdout)


# -- the cost of free numbers (issue 57, item 6) ---------------------------------------------------


def _many(n: int, couple: bool = True) -> str:
    """A chain of 8 segments, 7 motors and 16 angle sensors: its first ``n`` numbers free (the
    links' masses and ends, the motors' gains, the sensors' ranges)."""
    lines, k = ['name = "many"'], 0

    def num(x: float) -> str:
        nonlocal k
        k += 1
        return f"{{ min = {min(0.9 * x, 1.1 * x):.4f}, max = {max(0.9 * x, 1.1 * x):.4f} }}" if k <= n else repr(x)

    for i in range(8):
        lines += ["[[links]]", f'name = "L{i}"', f"mass = {num(0.1)}", 'shape = "segment"',
                  f"points = [[0, 0], [{num(0.1)}, {num(0.02)}]]"]
        lines += ["position = [0, 0.3]"] if i == 0 else [f'parent = "L{i - 1}"', "anchor = [0.1, 0]"]
    for i in range(1, 8):
        lines.append(f'[[actuators]]\ntype = "angular"\njoint = "L{i}"\nmin_deg = -30\nmax_deg = 30\n'
                     f"ks = {num(0.02)}\nkd = {num(0.002)}")
    for j in range(16):
        lines.append(f'[[sensors]]\ntype = "angle"\nlink = "L{j % 7 + 1}"\nmin_deg = {num(-30.0)}\nmax_deg = {num(30.0)}')
    assert k >= n
    return "\n".join(lines) + ("\n[design]\ndensity = true\nstrength_mass = 1.0\ntotal_mass = true\n" if couple else "")


def _counted(design):
    """``design`` with its creature builds counted (``calls[0]``)."""
    import dataclasses

    calls = [0]

    def build(data):
        calls[0] += 1
        return design.build(data)

    return dataclasses.replace(design, build=build), calls


@pytest.mark.parametrize("couple", [False, True])
def test_the_ends_of_free_numbers_cost_builds_linear_in_their_count(couple):
    """Each end is one creature built (two with couplings: the masses they give are built
    again), and the stated creature the couplings measure against once: 2n (4n + 1) builds for
    n free numbers, whatever n. It was three builds an end, the stated creature built again
    for each: a check of 313 free numbers took 57 s."""
    for n in (4, 16, 31):
        design, _ = loads_design(_many(n, couple), "many.toml")
        assert len(design.free) == n
        design, calls = _counted(design)
        ends = design.ends()
        assert all(e is not None and np.isfinite(e).all() for e in ends)
        assert calls[0] == (4 * n + 1 if couple else 2 * n)


def test_the_stated_creature_is_built_once_however_often_it_is_asked():
    design, _ = _counted(loads_design(_many(6), "many.toml")[0])
    design, calls = _counted(design)
    first = design.creature()
    assert design.creature() is first and design.total_mass() == pytest.approx(sum(k.mass for k in first.links))
    assert calls[0] == 2  # the creature at the defaults, and again with the masses the couplings give


def test_a_budget_of_time_leaves_the_ends_not_reached_unchecked():
    design, calls = _counted(loads_design(_many(6), "many.toml")[0])
    assert design.ends(budget_s=0.0) == [None] * 6 and calls[0] == 0


def test_a_file_of_more_free_numbers_than_the_format_allows_is_refused_naming_the_first_too_many():
    from sanlab.creature.free import MAX_FREE

    assert len(loads_design(_many(MAX_FREE, couple=False))[0].free) == MAX_FREE
    with pytest.raises(CreatureError) as e:
        loads(_many(MAX_FREE + 1, couple=False), "many.toml")
    # the 65th free number: after 8 links x 3 numbers, 7 actuators x 2 and 13 sensors x 2
    assert str(e.value) == ("many.toml: sensors[13].min_deg: expected at most 64 free numbers in a file (a design affords "
                            "tens of bodies; `sanlab check` builds both ends of each), got more")


def test_plain_check_says_which_ends_it_did_not_check_and_strict_checks_them_all(tmp_path, monkeypatch):
    import sanlab.cli.creatures as creatures

    path = tmp_path / "many.toml"
    path.write_text(_many(10))
    monkeypatch.setattr(creatures, "ENDS_BUDGET_S", 0.0)
    r = CliRunner().invoke(app, ["check", str(path)])
    assert r.exit_code == 0, r.output
    assert "links[0].mass: free in [0.09, 0.11], default 0.1; ends not checked" in r.stdout
    assert "the ends of 10 of 10 free numbers were not checked" in r.stdout and "--strict checks every end" in r.stdout
    obj = json.loads(CliRunner().invoke(app, ["check", str(path), "--json"]).stdout)
    _schemas.validate(obj, "check")
    assert [f["ends_checked"] for f in obj["free"]] == [False] * 10 and obj["free"][0]["mass_at_min"] is None
    obj = json.loads(CliRunner().invoke(app, ["check", str(path), "--json", "--strict"]).stdout)
    assert [f["ends_checked"] for f in obj["free"]] == [True] * 10 and obj["free"][0]["mass_at_min"] > 0
