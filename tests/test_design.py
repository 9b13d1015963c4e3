"""experiments/bounder_design.py and fourlink_design.py: free sizes and ranges as designs (issue 30).

The search machinery (a design as rows of one batched program, resumable rounds) is
experiments/design.py's, tested through the cart in test_cart_geometry.py; here: each design's
reference reproduces today's built-in, and every bounder candidate stands on its feet.
"""

import importlib.util
import math
from pathlib import Path

import jax
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


@pytest.mark.parametrize("name", ["bounder", "fourlink"])
def test_the_reference_design_is_the_built_in(name):
    from sanlab.creature import load
    from sanlab.creature.loader import loads
    from sanlab.sim.compiler import compile_creature

    d = _design(name)
    a, b = load(name), loads(d.toml_text(d.BUILTIN))
    assert (a.san, a.evaluation, a.sensors, a.actuators, a.world) == (b.san, b.evaluation, b.sensors, b.actuators, b.world)
    ma, mb = compile_creature(a, "float64"), compile_creature(b, "float64")
    assert ma.structure == mb.structure
    for x, y in zip(jax.tree_util.tree_leaves(ma.params), jax.tree_util.tree_leaves(mb.params), strict=True):
        # the built-in's file rounds its start height to 0.01 mm
        np.testing.assert_allclose(np.asarray(x, float), np.asarray(y, float), rtol=0, atol=1e-5)


def test_candidates_are_bounders_standing_on_their_feet(bd):
    from sanlab.creature import load
    from sanlab.creature.loader import loads
    from sanlab.sim import poses
    from sanlab.sim.compiler import compile_creature

    builtin = compile_creature(load("bounder"), "float64")
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


@pytest.mark.slow  # compiles the bounder's screening and held-out programs
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
