"""A creature file's free numbers in the vector phase 2 tunes (issue 47: one parameter space):
``tune --morphology`` on such a file moves its body numbers within their ranges, couplings
applied, and the tuned gait stores, replays and exports that body."""

from __future__ import annotations

import numpy as np
import pytest

from sanlab.creature import load
from sanlab.evaluate.records import GaitParams
from sanlab.gait import check_params
from sanlab.search.space import Space
from sanlab.sim.compiler import compile_creature
from tests.helpers import DATA

HOPPER = str(DATA / "hopper_free.toml")


@pytest.fixture(scope="module")
def spec():
    return load(HOPPER)


def test_morphology_on_a_file_with_free_numbers_tunes_its_body_numbers(spec):
    names = Space(spec, morphology=True).names
    # the body's mass and the legs are body numbers; the front muscle's ks is the vector's own (A1.ks)
    assert names[-3:] == ["links[0].mass", "front", "back"] and "actuators[0].ks" not in names
    assert not any(n.endswith(".scale") for n in names)
    assert Space(spec).names == names[:-3]  # without --morphology: the controller's numbers only
    assert Space(load("cart"), morphology=True).names[-1].endswith(".scale")  # no free numbers: link scales


def test_a_vector_gives_its_bodys_numbers_couplings_and_all(spec):
    space = Space(spec, morphology=True)
    model = compile_creature(spec, "float64")
    theta = space.nominal()
    assert theta[-3:].tolist() == [1.0, -0.275, -0.275]
    theta[-3] = 0.6  # a lighter body
    theta[-2] = -0.35  # a longer front leg (the total leg length moves both legs)
    _, _, batched = space.batch(theta[None], model)
    body = spec.design.creature(space.free_values(theta))
    assert body.links[1].contacts[0][1] == pytest.approx(-0.3) and body.links[0].mass == 0.6
    np.testing.assert_allclose(np.asarray(batched.params.mass[0]), [k.mass for k in body.links])
    np.testing.assert_allclose(np.asarray(batched.params.contact[0]), compile_creature(body, "float64").params.contact)
    gp = space.gait_params(theta, model)
    assert gp.free == pytest.approx([0.6, -0.3, -0.25, 0.02])
    check_params(spec, gp.to_json())  # a gait's stored parameters, valid for this creature
    assert GaitParams.from_json(gp.to_json()) == gp
    assert space.nominal(gp)[-3:] == pytest.approx([0.6, -0.3, -0.25])


def test_free_values_out_of_range_are_refused(spec):
    with pytest.raises(ValueError, match=r"params.free\[0\]: expected a value of links\[0\].mass within \[0.5, 1.5\]"):
        check_params(spec, {"free": [2.0, -0.275, -0.275, 0.02]})
    with pytest.raises(ValueError, match=r"params\.free: expected no free values"):
        check_params(load("cart"), {"free": [1.0]})


def test_tune_morphology_on_free_numbers_stores_replays_and_exports_the_body(tmp_path):
    import json

    from typer.testing import CliRunner

    from sanlab.cli import app
    from sanlab.creature import loads
    from sanlab.gait import Gait
    from sanlab.library import Library

    db = str(tmp_path / "t.db")
    r = CliRunner()
    out = r.invoke(app, ["search", HOPPER, "--controllers", "8", "--seconds", "1", "--db", db, "--json"])
    assert out.exit_code == 0, out.output
    run = json.loads(out.stdout)["run_id"]
    first = r.invoke(app, ["export", f"{run}/1", "--toml", "--db", db])  # a phase-1 gait: the file at its defaults
    assert first.exit_code == 0, first.output
    assert "min =" not in first.stdout and loads(first.stdout) == load(HOPPER)
    out = r.invoke(app, ["tune", f"{run}/1", "--morphology", "--trials", "6", "--db", db, "--json"])
    assert out.exit_code == 0, out.output
    tuned = json.loads(out.stdout)[0]["tuned_gait"]
    gait = Gait.from_library(Library(db), tuned)
    assert gait.params.free is not None and len(gait.params.free) == 4
    body = gait.spec.design.creature(gait.params.free)
    np.testing.assert_allclose(np.asarray(gait.model("float64").params.mass), [k.mass for k in body.links])
    text = r.invoke(app, ["export", tuned, "--toml", "--db", db])
    assert text.exit_code == 0, text.output
    exported = loads(text.stdout)
    assert [k.mass for k in exported.links] == pytest.approx([k.mass for k in body.links])
    assert [k.shape for k in exported.links] == [k.shape for k in body.links]
