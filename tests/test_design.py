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
