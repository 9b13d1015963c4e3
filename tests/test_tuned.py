"""A tuned gait in the creature file's terms (sanlab.tuned; issue 11 item 5): its parameters in
file units, its network by name, and ``export --toml``, whose file compiles to the gait's own
numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from sanlab import sim
from sanlab.cli import app
from sanlab.creature import load, loads, read_source
from sanlab.gait import Gait
from sanlab.library import Library
from sanlab.san import San
from sanlab.search.space import Space
from sanlab.tuned import apply_to_file, file_values, network_table, node_names, per_node_delays

runner = CliRunner()


def tuned(tmp_path, name: str = "bounder", morphology: bool = True, seed: int = 3) -> tuple[str, str]:
    """(library, gait id) of a made-up tuned gait: a random point of phase 2's space (every
    tunable parameter moved), stored as tune runs store it."""
    spec = load(name)
    space = Space(spec, morphology=morphology)
    rng = np.random.default_rng(seed)
    theta = space.nominal()
    for _ in range(200):
        theta = space.perturb(theta, int(rng.integers(len(space))), float(rng.choice([-1, 1])))
    params = space.gait_params(theta, sim.compile_creature(spec)).to_json()
    san = San.for_creature(spec)
    path = str(tmp_path / "g.db")
    with Library(path) as lib:
        run = lib.create_run("tune", spec.name, read_source(name)[0], {"metric": spec.evaluation.metric}, seed, 1)
        lib.add_batch(run.run_id, [{"idx": 0, "encoding": san.encode(san.random_weights(seed, 0)), "score": 1.0,
                                    "params": params}])
        lib.set_status(run.run_id, "done")
    return path, f"{run.run_id}#0"


def gait(path: str, gid: str) -> Gait:
    with Library(path) as lib:
        return Gait.from_library(lib, gid)


def test_names_of_inputs_and_nodes():
    inputs, nodes = node_names(load("bounder"))
    assert inputs[:8] == [f"S{i}" for i in range(1, 9)] and inputs[8:16] == [f"H{i}" for i in range(1, 9)]
    assert nodes[-4:] == ["A1", "A2", "A3", "A4"] and len(inputs) == 20 and len(nodes) == 12


def test_parameters_in_file_units(tmp_path):
    g = gait(*tuned(tmp_path))
    rows = {(r["part"], r["name"]): r for r in file_values(g)["rows"]}
    model = g.params.model
    assert rows[("actuator A1", "min_deg")]["value"] == pytest.approx(math.degrees(model["act_min"][0]))
    assert rows[("actuator A1", "ks")]["value"] == pytest.approx(model["act_ks"][0] * math.pi / 180)
    assert rows[("actuator A1", "ks")]["file"] == pytest.approx(0.4) and rows[("actuator A1", "ks")]["unit"] == "N m/deg"
    assert rows[("node H1", "T_on")]["value"] == pytest.approx(1 / g.params.k1[0])
    assert rows[("link body", "length scale")]["value"] == g.params.scale[0]
    sensors = {p for p, _ in rows if p.startswith("sensor")}
    assert sensors == {f"sensor S{i}" for i in range(3, 9)}  # the range sensors, not the touch sensors
    net = network_table(g)
    assert np.array_equal(np.asarray(net["weights"]), g.weights)


@pytest.mark.parametrize("name, morphology", [("bounder", True), ("cart", False)])
def test_export_toml_compiles_to_the_gaits_own_numbers(tmp_path, name, morphology):
    path, gid = tuned(tmp_path, name, morphology)
    g = gait(path, gid)
    r = runner.invoke(app, ["export", gid, "--toml", "--db", path])
    assert r.exit_code == 0 and "is not exactly the gait" in r.stderr, r.output  # said, not only in a comment
    text = apply_to_file(g)
    assert text.startswith(f"# Written by `sanlab export {g.gait_id} --toml`")
    assert "# The cart" in text or "# The bouncer" in text  # the file's own comments are kept
    mine = sim.compile_creature(loads(text)).params
    theirs = g.model().params
    keys = ["act_min", "act_max", "act_ks", "act_kd", "sens_min", "sens_max"]
    if morphology:
        keys += ["mass", "inertia", "com", "contact", "anchor"]
    for key in keys:
        assert np.allclose(np.asarray(getattr(mine, key)), np.asarray(getattr(theirs, key)), rtol=1e-6, atol=1e-7), key
    assert "node delays differ between nodes" in text  # tuned per node: written as a comment
    assert "so this file is not exactly the gait" in text and per_node_delays(g)


def test_export_toml_of_a_phase_1_gait_sets_the_san_delays(lib_run, tmp_path):
    db, run_id = lib_run
    out = tmp_path / "cart_tuned.toml"
    r = runner.invoke(app, ["export", f"{run_id}/1", "--toml", "-o", str(out), "--db", db])
    assert r.exit_code == 0, r.output
    assert "warning" not in r.output  # one delay pair for every node: the file is the gait
    c = loads(out.read_text())
    assert (c.san.delay_on, c.san.delay_off) == (load("cart").san.delay_on, load("cart").san.delay_off)
    r = runner.invoke(app, ["check", str(out)])
    assert r.exit_code == 0


def test_a_file_with_repeated_parts_exports_them_written_out(tmp_path):
    from tests.creature.test_repeat import repeated

    path = tmp_path / "chain.toml"
    path.write_text(repeated(3))
    g = gait(*tuned(tmp_path, name=str(path), morphology=True))
    text = apply_to_file(g)
    assert "\n[[repeat" not in text and text.count("[[actuators]]") == 3 and "tables are written out" in text
    again = loads(text, "export.toml")
    assert [a.ks for a in again.actuators] == pytest.approx(list(g.params.model["act_ks"]), rel=1e-6)
    assert [k.mass for k in again.links] == pytest.approx(list(g.params.model["mass"]), rel=1e-6)
