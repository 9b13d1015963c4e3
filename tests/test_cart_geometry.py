"""experiments/cart_geometry.py: the cart's shape search (issue 30).

The search runs every candidate shape as one row of a batched model; these tests check that a row
scores as the candidate's own creature file does, that every candidate is a valid creature
resting on the ground, and that a second call resumes instead of scoring again.
"""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def cg():
    spec = importlib.util.spec_from_file_location("cart_geometry", ROOT / "experiments" / "cart_geometry.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_candidates_are_creatures_on_the_ground(cg):
    from sanlab.creature.loader import loads
    from sanlab.sim import poses
    from sanlab.sim.compiler import compile_creature

    for v in cg.uniform(np.random.default_rng(3), 4):
        spec = loads(cg.toml_text(cg.as_dict(v)))
        assert [len(l.contacts) for l in spec.links] == [4, 4]
        m = compile_creature(spec, "float64")
        low = float(np.asarray(poses(m, m.params.q0)["contacts"])[:, 1].min())
        assert abs(low) < 1e-6  # lowered onto the ground, not above it or inside it


def test_a_batched_row_scores_as_its_own_file(cg):
    """The shape rows of one program against each candidate compiled alone (float64, 0.4 s: short
    enough that the two routes' round-off cannot grow into a different trajectory)."""
    from sanlab.creature.loader import loads
    from sanlab.evaluate.ensemble import default_ensemble, search_key
    from sanlab.evaluate.evaluator import Evaluator

    texts = [cg.toml_text(cg.as_dict(v)) for v in cg.uniform(np.random.default_rng(5), 2)]
    kw = dict(ensemble=default_ensemble(4), batch=8, dtype="float64", seconds=0.4)
    ev = Evaluator(loads(texts[0]), **kw)
    ev.space = cg.Shapes(cg.compile_all(texts, ev.model))
    W = np.stack([ev.san.random_weights(0, i) for i in range(3)])
    keys = [search_key(0, i) for i in range(3)]
    for g, text in enumerate(texts):
        a = ev(W, np.full((3, 1), float(g)), keys)
        b = Evaluator(loads(text), **kw)(W, None, keys)
        assert np.abs(a.member_score - b.member_score).max() < 1e-9
    # and the rows differ between shapes: the shape reaches the physics
    a0, a1 = ev(W, np.zeros((3, 1)), keys), ev(W, np.ones((3, 1)), keys)
    assert np.abs(a0.member_score - a1.member_score).max() > 1e-4


def test_resumes_without_scoring_again(cg, tmp_path, capsys):
    out = tmp_path / "shapes.jsonl"
    args = ["--out", str(out), "--candidates", "2", "--controllers", "3", "--chunk", "1", "--batch", "8"]
    cg.main(args)
    first = out.read_text()
    assert len(first.splitlines()) == 2
    cg.main(args)
    assert out.read_text() == first  # nothing scored twice
    cg.main([*args, "--write", str(tmp_path / "best.toml")])
    best = max((json.loads(x) for x in first.splitlines()), key=lambda r: r["score_m"])
    from sanlab.creature.loader import loads

    spec = loads((tmp_path / "best.toml").read_text())
    assert spec.name == "cart" and f"candidate {best['index']}" in (tmp_path / "best.toml").read_text()
