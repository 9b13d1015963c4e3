"""experiments/bounder_design.py, fourlink_design.py and walker_design.py: free sizes and ranges as designs (issue 30).

The search machinery (a design as rows of one batched program, resumable rounds) is
experiments/design.py's, tested through the cart in test_cart_geometry.py; here: each built-in is
its design's chosen values, the bounder search's reference is the bounder it started from, and
every bounder candidate stands on its feet.
"""

import dataclasses
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


def _design(name: str):
    spec = importlib.util.spec_from_file_location(f"{name}_design", ROOT / "experiments" / f"{name}_design.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def bd():
    return _design("bounder")


def _leaves(params) -> list:
    """Every array of a model's ``Params``, in field order."""
    return [getattr(params, f.name) for f in dataclasses.fields(params)]


def _same_physics(text_a: str, text_b: str, atol: float = 0.0) -> None:
    from sanlab.creature.loader import loads
    from sanlab.sim.compiler import compile_creature

    a, b = loads(text_a), loads(text_b)
    assert (a.san, a.evaluation, a.sensors, a.actuators, a.world) == (b.san, b.evaluation, b.sensors, b.actuators, b.world)
    ma, mb = compile_creature(a, "float64"), compile_creature(b, "float64")
    assert ma.structure == mb.structure
    for x, y in zip(_leaves(ma.params), _leaves(mb.params), strict=True):
        np.testing.assert_allclose(np.asarray(x, float), np.asarray(y, float), rtol=0, atol=atol)


@pytest.mark.parametrize("name", ["bounder", "fourlink", "walker"])
def test_the_built_in_is_its_design(name):
    """The built-in's file is the design its search chose, to the file's rounding (1e-6 m, 1e-3 deg)."""
    from sanlab.creature import read_source

    d = _design(name)
    _same_physics(read_source(name)[0], d.toml_text(d.CHOSEN), atol=2e-5)


def test_the_bounder_searchs_reference_is_its_first_version(bd):
    """Round 0's candidate 0 is the bounder as it was before the search (kept in tests/data,
    equal to the built-in file at 29a0af5 in every compiled number), which the file's design note
    quotes."""
    first = (ROOT / "tests" / "data" / "bounder_first.toml").read_text()
    _same_physics(first, bd.toml_text(bd.FIRST), atol=1e-5)  # that file rounded its start height to 0.01 mm


def test_the_walker_searchs_reference_is_its_first_version():
    """Round 0's candidate 0 is the walker as it was before the search (kept in tests/data, the
    built-in file at 7f63d6a), split stance and all: the back hip placed by the design's stance
    rule lands on that file's -20 deg."""
    w = _design("walker")
    assert w.stance(w.FIRST) == pytest.approx((30.0, -20.0, 10.0), abs=1e-9)
    _same_physics((ROOT / "tests" / "data" / "walker_first.toml").read_text(), w.toml_text(w.FIRST), atol=1e-9)


def test_walker_candidates_stand_on_both_feet():
    from sanlab.creature.loader import loads
    from sanlab.sim import poses
    from sanlab.sim.compiler import compile_creature

    w = _design("walker")
    for v in w.DESIGN.uniform(np.random.default_rng(3), 12):  # knees bent more than the hip leans, too
        m = compile_creature(loads(w.toml_text(w.DESIGN.as_dict(v))), "float64")
        y = np.sort(np.asarray(poses(m, m.params.q0)["contacts"])[:, 1])
        assert abs(y[0]) < 1e-6 and abs(y[1]) < 1e-5 and y[2] > 0.01  # two feet down, the rest up


def test_candidates_are_bounders_standing_on_their_feet(bd):
    from sanlab.creature import load
    from sanlab.creature.loader import loads
    from sanlab.sim import poses
    from sanlab.sim.compiler import compile_creature

    builtin = compile_creature(load("bounder"), "float64")  # the same structure, another design
    for v in bd.DESIGN.uniform(np.random.default_rng(7), 6):
        g = bd.DESIGN.as_dict(v)
        spec = loads(bd.toml_text(g))
        m = compile_creature(spec, "float64")
        assert m.structure == builtin.structure  # one program for every candidate
        contacts = np.asarray(poses(m, m.params.q0)["contacts"])
        feet = contacts[np.argsort(contacts[:, 1])[:2]]
        assert np.abs(feet[:, 1]).max() < 1e-6  # both feet on the ground, the rest above it
        assert sorted(feet[:, 0]) == pytest.approx([-g["hip_x"], g["hip_x"]], abs=1e-5)  # each under its hip (angles in 1e-4 deg)
        hip = spec.sensors[2]
        assert math.isclose(hip.min, math.radians(g["hip_sense"] * g["hip_swing"]), rel_tol=1e-3)


def test_validation_rescores_the_best_on_fresh_sans_once_and_picks_by_its_mean(bd, tmp_path, capsys):
    import json

    out = tmp_path / "d.jsonl"
    args = ["--out", str(out), "--candidates", "2", "--controllers", "3", "--chunk", "2", "--batch", "8"]
    bd.main(args)
    bd.main([*args, "--validate", "1", "--seeds", "1"])
    rows = [json.loads(x) for x in out.read_text().splitlines()]
    checks = [r for r in rows if r["round"] == -1]
    best = max((r for r in rows if r["round"] == 0), key=lambda r: r["score_m"])
    # the best design and the reference (candidate 0), each on seed 1's SANs
    assert sorted(tuple(r["of"]) for r in checks) == sorted({(0, best["index"]), (0, 0)})
    assert all(r["seed"] == 1 for r in checks)
    bd.main([*args, "--validate", "1", "--seeds", "1"])
    assert len(out.read_text().splitlines()) == len(rows)  # nothing scored twice
    bd.main([*args, "--write", str(tmp_path / "best.toml")])
    text = (tmp_path / "best.toml").read_text()
    top = max(checks, key=lambda r: r["speed_cm_s"])
    assert f"candidate {top['of'][1]}," in text and "validated on fresh SANs" in text


def test_the_fourlink_design_file_loads_as_the_built_in():
    """experiments/fourlink_design.toml, the script's design as free numbers (issue 47): at its
    defaults it is the built-in fourlink (to the last bits: kd = ks / 10 is computed, not written),
    and its free numbers are the script's, by name and range (the fold thresholds in degrees)."""
    from sanlab.creature import load_design, read_source

    fl = _design("fourlink")
    text = (ROOT / "experiments" / "fourlink_design.toml").read_text()
    from sanlab.creature.loader import loads
    from sanlab.sim.compiler import compile_creature

    a, b = loads(read_source("fourlink")[0]), loads(text)
    assert (a.san, a.evaluation, a.sensors, a.world, a.links) == (b.san, b.evaluation, b.sensors, b.world, b.links)
    ma, mb = compile_creature(a, "float64"), compile_creature(b, "float64")
    assert ma.structure == mb.structure
    for x, y in zip(_leaves(ma.params), _leaves(mb.params), strict=True):
        np.testing.assert_allclose(np.asarray(x, float), np.asarray(y, float), rtol=1e-12, atol=0)
    design, _ = load_design(str(ROOT / "experiments" / "fourlink_design.toml"))
    ranges = {n: (lo, hi) for n, lo, hi in fl.RANGES}
    for f in design.free:
        if f.name in ranges:
            assert (f.min, f.max) == ranges[f.name], f.name
    assert set(design.names) == (set(ranges) - {"sense"}) | {"fold_end", "fold_mid"}


def _close(a, b, rel: float = 1e-12, where: str = "") -> None:
    """``a == b`` for loaded creatures' parts, floats to ``rel`` (a free number's ``times * x +
    plus`` may differ from the written number in the last bit)."""
    import dataclasses

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


DESIGN_FILES = ["bounder", "walker", "fish", "crawler", "fourlink", "cart"]


@pytest.mark.parametrize("name", DESIGN_FILES)
def test_a_design_file_at_its_defaults_loads_as_the_built_in(name):
    """experiments/NAME_design.toml (issue 47, part 3): at its defaults it is the built-in, in
    every field of the loaded creature and every compiled number (to the last bits: kd = ks / 10
    and a start height thigh + a constant are computed, not written)."""
    from sanlab.creature import read_source
    from sanlab.creature.loader import loads
    from sanlab.sim.compiler import compile_creature

    a, b = loads(read_source(name)[0]), loads((ROOT / "experiments" / f"{name}_design.toml").read_text())
    _close(a, b, where=name)
    ma, mb = compile_creature(a, "float64"), compile_creature(b, "float64")
    assert ma.structure == mb.structure
    for f in dataclasses.fields(ma.params):
        x, y = getattr(ma.params, f.name), getattr(mb.params, f.name)
        np.testing.assert_allclose(np.asarray(x, float), np.asarray(y, float), rtol=1e-12, atol=1e-15, err_msg=f.name)


@pytest.mark.parametrize("name", DESIGN_FILES)
def test_a_design_files_bodies_keep_the_papers_constraints(name):
    """Every body of the file (its ranges' corners and random draws) is a valid creature of the
    built-in's structure (one program for all), with the counts of Table 1 and the gains the
    paper gives (the bounder's ks = 0.4 N m/deg, kd = 0.1 ks); the mass of a link whose size
    and strength are the stated ones stays the built-in's."""
    import math

    from sanlab.creature import load, load_design
    from sanlab.sim import poses
    from sanlab.sim.compiler import compile_creature

    builtin = load(name)
    structure = compile_creature(builtin, "float64").structure
    design, _ = load_design(str(ROOT / "experiments" / f"{name}_design.toml"))
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
            assert abs(y[0]) < 2e-4 and y[1] < (1e-6 if name == "bounder" else 3e-3) and y[2] > 0.1
        if name == "crawler":  # point masses: no size to follow, no angular muscle
            assert [link.mass for link in c.links] == [link.mass for link in builtin.links]
            assert [(a.ks, a.kd) for a in c.actuators] == [(a.ks, a.kd) for a in builtin.actuators]


@pytest.mark.parametrize("name", ["bounder", "walker"])
def test_a_design_file_searches_its_scripts_ranges(name):
    """The bounder's and the walker's files free what their scripts searched, over the same
    ranges (lengths written negative: the legs point down; sensor thresholds in degrees, over
    the span the script's fractions could reach), but the start angles, which are trigonometry."""
    from sanlab.creature import load_design

    script = {n: (lo, hi) for n, lo, hi in _design(name).RANGES}
    design, _ = load_design(str(ROOT / "experiments" / f"{name}_design.toml"))
    got = {f.name: (f.min, f.max) for f in design.free}
    for n in ("thigh", "shin"):
        assert got[n] == pytest.approx((-script[n][1], -script[n][0]))
    for n in ("hip_swing", "delay", *(("hip_x",) if name == "bounder" else ("lean", "waist_sense", "waist_fwd"))):
        assert got[n] == pytest.approx(script[n])
    assert got["knee_fold"] == pytest.approx((-script["knee_fold"][1], -script["knee_fold"][0]))
    hs, sw = script["hip_sense"], script["hip_swing"]
    assert got["hip_sense"] == pytest.approx((hs[0] * sw[0], hs[1] * sw[1]))
    ks, kf = script["knee_sense"], script["knee_fold"]
    assert got["knee_sense"] == pytest.approx((-ks[1] * kf[1], -ks[0] * kf[0]))
    assert not {n for n in got} & {"start_hip", "start_knee"}
