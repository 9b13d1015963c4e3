"""experiments/*_design.toml: the creatures' designs as creature files with free numbers (issue 47).

Each file is what ``sanlab design`` searches for one built-in: at its defaults it is the built-in
(in every loaded and compiled number), the built-in's numbers lie within its ranges, every body
of it keeps the paper's constraints, and ``sanlab check`` lists its free numbers. For the four
built-ins a design search made (issue 30; the record: docs/design-history/), the file's defaults
are that search's chosen design and its ranges are the ranges the search's script had, where a
free number can say them (``times * x + plus`` of one number: not a product, not trigonometry).
"""

import dataclasses
import json
import re
import tomllib

import numpy as np
import pytest

from tests.helpers import ROOT

DESIGN_FILES = ["bounder", "walker", "fish", "crawler", "fourlink", "cart", "luxo"]
HISTORY = ROOT / "docs" / "design-history"


def _file(name: str) -> str:
    return str(ROOT / "experiments" / f"{name}_design.toml")


def _close(a, b, rel: float = 1e-12, where: str = "") -> None:
    """``a == b`` for loaded creatures' parts, floats to ``rel`` (a free number's ``times * x +
    plus`` may differ from the written number in the last bit)."""
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            if not f.compare:  # e.g. the creature's design (its free numbers): not part of its physics
                continue
            _close(getattr(a, f.name), getattr(b, f.name), rel, f"{where}.{f.name}")
    elif isinstance(a, tuple | list):
        assert isinstance(b, tuple | list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, rel, f"{where}[{i}]")
    elif isinstance(a, float) and not isinstance(b, bool):
        assert b == pytest.approx(a, rel=rel, abs=1e-15), where
    else:
        assert a == b, where


@pytest.mark.parametrize("name", DESIGN_FILES)
def test_a_design_file_at_its_defaults_loads_as_the_built_in(name):
    """At its defaults the file is the built-in, in every field of the loaded creature and every
    compiled number (to the last bits: kd = ks / 10 and a start height thigh + a constant are
    computed, not written)."""
    from sanlab.creature import read_source
    from sanlab.creature.loader import loads
    from sanlab.sim.compiler import compile_creature

    a, b = loads(read_source(name)[0]), loads((ROOT / "experiments" / f"{name}_design.toml").read_text())
    if name == "crawler":  # the built-in is scored by tracking, which a design cannot be (the file says why)
        assert (a.evaluation.metric, b.evaluation.metric) == ("tracking", "pursuit")
        b = dataclasses.replace(b, evaluation=dataclasses.replace(b.evaluation, metric="tracking"))
    _close(a, b, where=name)
    ma, mb = compile_creature(a, "float64"), compile_creature(b, "float64")
    assert ma.structure == mb.structure
    for f in dataclasses.fields(ma.params):
        x, y = getattr(ma.params, f.name), getattr(mb.params, f.name)
        np.testing.assert_allclose(np.asarray(x, float), np.asarray(y, float), rtol=1e-12, atol=1e-15, err_msg=f.name)


def _at(data, path: str):
    """The value at a free number's path (``links[1].points[1][0]``) in a parsed creature file."""
    for key, i in re.findall(r"\.?([A-Za-z_]\w*)|\[(\d+)\]", path):
        data = data[key] if key else data[int(i)]
    return data


@pytest.mark.parametrize("name", DESIGN_FILES)
def test_the_built_ins_numbers_are_the_files_defaults_within_its_ranges(name):
    """Where the file writes a free number or a use of one, the built-in's file writes the
    default's value there (``times * default + plus``), and each default lies in its range: the
    search starts from the built-in and can stay there."""
    from sanlab.creature import load_design, read_source

    design, _ = load_design(_file(name))
    builtin = tomllib.loads(read_source(name)[0])
    slots = design.slots()
    assert {p for f in design.free for p in f.uses} == set(slots)
    for path, slot in slots.items():
        f = design.free[slot.index]
        assert f.min <= f.default <= f.max, f.name
        assert _at(builtin, path) == pytest.approx(slot.times * f.default + slot.plus, rel=1e-12, abs=1e-15), path


@pytest.mark.parametrize("name", DESIGN_FILES)
def test_a_design_files_bodies_keep_the_papers_constraints(name):
    """Every body of the file (its ranges' corners and random draws) is a valid creature of the
    built-in's structure (one program for all), with the counts of Table 1 and the gains the
    paper gives (the bounder's ks = 0.4 N m/deg, kd = 0.1 ks; the cart's Figure 11: masses,
    sensors, actuator); the mass of a link whose size and strength are the stated ones stays the
    built-in's."""
    import math

    from sanlab.creature import load, load_design
    from sanlab.sim import poses
    from sanlab.sim.compiler import compile_creature

    builtin = load(name)
    structure = compile_creature(builtin, "float64").structure
    design, _ = load_design(_file(name))
    assert design.free
    rng = np.random.default_rng(0)
    bodies = [design.lo, design.hi, *(design.lo + rng.random(len(design.free)) * (design.hi - design.lo) for _ in range(6))]
    for v in bodies:
        c = design.creature(v)
        assert (len(c.links), len(c.sensors), len(c.actuators), c.san.hidden) == (
            len(builtin.links), len(builtin.sensors), len(builtin.actuators), builtin.san.hidden)
        assert compile_creature(c, "float64").structure == structure
        assert 0.07 <= c.san.delay_on == c.san.delay_off <= 0.15  # the paper's node delays
        if name == "bounder":  # §3.3's gains, given by the paper
            for a in c.actuators:
                assert (a.ks, a.kd) == pytest.approx((math.degrees(0.4), math.degrees(0.04)))
            assert c.links[0].mass == 2.4  # the body the gain was sized against
        if name in ("bounder", "walker"):  # stands on its feet (lifted onto the ground where they start in it)
            m = compile_creature(c, "float64")
            y = np.sort(np.asarray(poses(m, m.params.q0)["contacts"])[:, 1])
            if name == "bounder":  # both feet level, on the ground or (a thigh under 0.161 m) 1.1 cm above at most
                assert -2e-4 < y[0] < 0.0112 and y[1] - y[0] < 1e-6 and y[2] > y[0] + 0.1
            else:
                assert abs(y[0]) < 2e-4 and y[1] < 3e-3 and y[2] > 0.1
        if name in ("crawler", "cart", "fourlink"):  # no couplings: the masses stay
            assert [link.mass for link in c.links] == [link.mass for link in builtin.links]
        if name == "crawler":  # point masses: no size to follow, no angular muscle
            assert [(a.ks, a.kd) for a in c.actuators] == [(a.ks, a.kd) for a in builtin.actuators]
        if name == "cart":  # Figure 11 fixes all but the geometry; every vertex a contact
            assert (c.sensors, c.actuators) == (builtin.sensors, builtin.actuators)
            assert [len(link.contacts) for link in c.links] == [4, 4]
            assert all(link.inertia > 0 for link in c.links)
        if name == "fourlink":  # kd = ks / 10
            assert [a.kd for a in c.actuators] == pytest.approx([a.ks / 10 for a in c.actuators])


@pytest.mark.parametrize("name", DESIGN_FILES)
def test_check_lists_a_design_files_free_numbers(name):
    """``sanlab check FILE`` names every free number with the word free, its range and default,
    and passes ``--strict`` (no range reaches past valid creatures)."""
    from typer.testing import CliRunner

    from sanlab.cli import app
    from sanlab.creature import load_design

    design, _ = load_design(_file(name))
    runner = CliRunner()
    r = runner.invoke(app, ["check", _file(name), "--strict"])
    assert r.exit_code == 0, r.stdout
    assert f"free numbers: {len(design.free)} " in r.stdout
    for f in design.free:
        line = f"  {f.name}: free in [{f.min:g}, {f.max:g}], default {f.default:g}"
        assert re.search(re.escape(line) + r"( \(also [^)]*\))?;", r.stdout), f.name
    out = json.loads(runner.invoke(app, ["check", _file(name), "--json"]).stdout)
    assert [(x["name"], x["min"], x["max"], x["default"]) for x in out["free"]] == [
        (f.name, f.min, f.max, f.default) for f in design.free]


# -- the design searches of issue 30 (docs/design-history/) -------------------------------------
#
# Each search's script (removed; docs/design-history/README.md says where git keeps it) gave a
# design as named numbers. A map for each: the script's numbers -> the design file's free numbers.
# A fraction of another range (a sensor threshold, a bump's place along a link) becomes the number
# itself (degrees, metres), a product; lengths drawn downwards or backwards are negative.


def _cart(g):
    u = g["u"] * g["length2"]
    return {"length1": g["length1"], "top1_x": g["a1"] * g["length1"], "top1": g["top1"],
            "bottom1_x": g["b1"] * g["length1"], "bottom1": -g["bottom1"],
            "near2": -u, "far2": g["length2"] - u, "top2_x": g["a2"] * g["length2"] - u, "top2": g["top2"],
            "bottom2_x": g["b2"] * g["length2"] - u, "bottom2": -g["bottom2"],
            "joint_x": g["s"] * g["length1"], "t": g["t"], "start_deg": g["start_deg"]}


def _bounder(g):
    return {"thigh": -g["thigh"], "shin": -g["shin"], "hip_x": g["hip_x"], "hip_swing": g["hip_swing"],
            "knee_fold": -g["knee_fold"], "hip_sense": g["hip_sense"] * g["hip_swing"],
            "knee_sense": -g["knee_sense"] * g["knee_fold"], "delay": g["delay"]}


def _fourlink(g):
    return {**{k: g[k] for k in ("len1", "len2", "len3", "len4", "ks_end", "ks_mid", "range_end", "range_mid", "delay")},
            "fold_end": g["sense"] * g["range_end"], "fold_mid": g["sense"] * g["range_mid"]}


def _walker(g):
    return {"thigh": -g["thigh"], "shin": -g["shin"], "hip_swing": g["hip_swing"], "knee_fold": -g["knee_fold"],
            "waist_back": -g["waist_back"], "waist_fwd": g["waist_fwd"], "hip_sense": g["hip_sense"] * g["hip_swing"],
            "knee_sense": -g["knee_sense"] * g["knee_fold"], "lean": g["lean"], "waist_sense": g["waist_sense"],
            "delay": g["delay"]}


# name: (its record, the map, the design the built-in is (round, candidate), the script's ranges,
# the script's numbers the file cannot say (the start poses: trigonometry), the file's own numbers)
SEARCHES = {
    "cart": ("cart_geometry", _cart, (2, 13), {
        "length1": (0.10, 0.40), "a1": (0.0, 1.0), "top1": (0.005, 0.15), "b1": (0.0, 1.0), "bottom1": (0.005, 0.15),
        "length2": (0.10, 0.40), "a2": (0.0, 1.0), "top2": (0.005, 0.15), "b2": (0.0, 1.0), "bottom2": (0.005, 0.15),
        "s": (0.0, 1.0), "t": (-0.05, 0.05), "u": (0.0, 1.0), "start_deg": (-90.0, 90.0)}, set(), set()),
    "bounder": ("bounder_design", _bounder, (3, 39), {
        "thigh": (0.15, 0.40), "shin": (0.15, 0.40), "hip_x": (0.10, 0.25), "hip_swing": (30.0, 90.0),
        "knee_fold": (60.0, 150.0), "hip_sense": (0.3, 1.0), "knee_sense": (0.2, 0.9), "start_hip": (0.0, 40.0),
        "delay": (0.07, 0.15)}, {"start_hip"}, set()),
    "fourlink": ("fourlink_design", _fourlink, (2, 41), {
        "len1": (0.10, 0.30), "len2": (0.10, 0.30), "len3": (0.10, 0.30), "len4": (0.10, 0.30),
        "ks_end": (0.005, 0.08), "ks_mid": (0.01, 0.16), "range_end": (60.0, 160.0), "range_mid": (60.0, 160.0),
        "sense": (0.3, 1.0), "delay": (0.07, 0.15)}, set(), set()),
    "walker": ("walker_design", _walker, (1, 56), {
        "thigh": (0.15, 0.35), "shin": (0.15, 0.35), "hip_swing": (30.0, 90.0), "knee_fold": (30.0, 120.0),
        "waist_back": (0.0, 30.0), "waist_fwd": (10.0, 60.0), "hip_sense": (0.2, 1.0), "knee_sense": (0.2, 0.9),
        "lean": (5.0, 40.0), "waist_sense": (5.0, 40.0), "start_hip": (5.0, 40.0), "start_knee": (0.0, 30.0),
        "delay": (0.07, 0.15)}, {"start_hip", "start_knee"}, {"ks_leg", "ks_waist"}),
}


class _Reads(dict):
    """A dict that remembers which keys were read."""

    def __init__(self, *a):
        super().__init__(*a)
        self.read: set[str] = set()

    def __getitem__(self, k):
        self.read.add(k)
        return super().__getitem__(k)


def _rows(record: str) -> list[dict]:
    return [json.loads(x) for x in (HISTORY / f"{record}.jsonl").read_text().splitlines() if x.strip()]


# built-ins that `sanlab design` has changed since: name -> its record (`sanlab design --json`)
DESIGNED = {"bounder": "bounder_design_bc4dbc74", "luxo": "luxo_design_60d447c7", "fish": "fish_design_c36d8afc"}


@pytest.mark.parametrize("name", [n for n in SEARCHES if n not in DESIGNED])
def test_a_design_files_defaults_are_its_searchs_chosen_design(name):
    """The file's defaults (so the built-in) are the record's chosen design, to the rounding of
    the built-in's file (a millimetre for the cart; 1e-6 m, 1e-3 deg, 1e-4 s for the others)."""
    from sanlab.creature import load_design

    record, to_file, chosen, _, _, _ = SEARCHES[name]
    row = next(r for r in _rows(record) if (r["round"], r["index"]) == chosen)
    want = to_file(row["geometry"])
    design, _ = load_design(_file(name))
    got = dict(zip(design.names, design.defaults, strict=True))
    for k, x in want.items():
        assert got[k] == pytest.approx(x, rel=1e-3, abs=5e-4), k


@pytest.mark.parametrize("name", list(DESIGNED))
def test_a_design_files_defaults_are_the_body_sanlab_design_chose(name):
    """Where `sanlab design` changed a built-in, the file's defaults are the chosen body of its
    record (docs/design-history/), which beat the file's defaults before (the reference) on the
    validation seeds; the search's file was this one with the earlier defaults, so the ranges
    are the same."""
    from sanlab.creature import load_design

    record = json.loads((HISTORY / f"{DESIGNED[name]}.json").read_text())
    chosen, reference, seeds = record["chosen"], record["reference"], record["settings"]["seeds"]
    assert chosen["round"] >= 0  # a searched body, not the reference kept
    mean = lambda body: sum(body["speeds"][str(sd)]["speed"] for sd in seeds) / len(seeds)
    assert mean(chosen) > mean(reference)
    design, _ = load_design(_file(name))
    assert list(design.defaults) == chosen["values"]
    for f, before in zip(design.free, reference["values"], strict=True):
        assert f.min <= before <= f.max, f.name


@pytest.mark.parametrize("name", list(SEARCHES))
def test_a_design_file_searches_its_scripts_ranges(name):
    """Each of the script's numbers is a free number of the file, or in one (a fraction of a
    range, a product), except the start poses; each range is the span the script's could reach
    (the map's extremes over the corners of the script's box, as the map is linear in each
    number), so every design the search scored is a body of the file."""
    import itertools

    from sanlab.creature import load_design

    record, to_file, _, ranges, unsaid, own = SEARCHES[name]
    design, _ = load_design(_file(name))
    names = list(ranges)
    probe = _Reads({n: (lo + hi) / 2 for n, (lo, hi) in ranges.items()})
    mapped = to_file(probe)
    assert probe.read | unsaid == set(ranges) and not probe.read & unsaid  # every number accounted for
    assert set(design.names) == set(mapped) | own
    corners = [to_file(dict(zip(names, c, strict=True))) for c in itertools.product(*(ranges[n] for n in names))]
    for f in design.free:
        if f.name in own:
            continue
        span = (min(c[f.name] for c in corners), max(c[f.name] for c in corners))
        assert (f.min, f.max) == pytest.approx(span, abs=1e-12), f.name
    for r in _rows(record):
        v = to_file(r["geometry"])
        assert all(design.free[i].min - 1e-12 <= v[n] <= design.free[i].max + 1e-12
                   for i, n in enumerate(design.names) if n in v), (r["round"], r["index"])
