"""The kernel that reads the creature as data (sanlab/sim/kernel.py, sanlab/sim/_kernel): its own
contracts, and the cases and helpers the stored-reference tests share (test_kernel_reference.py,
which holds the XLA engine's numbers, stored before that engine was removed).

A controller steps bit for bit the same alone and anywhere in a batch, on any thread count, run
after run; rows that carry their own numbers step as each would alone; the two routes of the
linear algebra agree; the GPU's form (one creature per thread in plain double) steps bit for bit
as the SIMD tiles.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.creature.spec import Terrain
from sanlab.random_sans import random_san_params
from sanlab.sim import kernel
from tests.helpers import same_on_one_and_two_threads

VERTICAL = ("cart", "bounder", "twolink", "threelink", "fourlink", "star", "luxo", "walker")
HORIZONTAL = ("fish", "crawler")  # water, point masses, linear springs, eyes, anisotropic friction
DATA = Path(__file__).resolve().parents[1] / "data"
TERRAINS = {
    "flat": None,
    "slope": Terrain(kind="slope", angle=0.087),
    "hill": Terrain(kind="hill", height=0.08, width=1.0, center=0.3),
    "rough": Terrain(kind="rough", height=0.015, wavelength=0.25, seed=1),
}
ROOT = Path(__file__).resolve().parents[2]


def chain(n: int) -> str:
    """An n-link chain lying on flat ground: a servo, a passive spring and a stop at every joint,
    anisotropic friction on every other link (a creature file's text)."""
    out = ['name = "chain"', "dt = 0.001", "[world]", 'plane = "vertical"', "[evaluation]", 'metric = "distance"']
    for i in range(n):
        out += ["[[links]]", f'name = "s{i}"', "mass = 0.1", 'shape = "segment"', "points = [[0.0, 0.0], [0.1, 0.0]]",
                "contacts = [[0.1, 0.0]]" if i else "contacts = [[0.0, 0.0], [0.1, 0.0]]"]
        if i:
            out += [f'parent = "s{i - 1}"', "anchor = [0.1, 0.0]", "spring = { stiffness = 0.002, rest_deg = 10 }",
                    "limit = { min_deg = -50, max_deg = 50, stiffness = 0.05 }"]
        else:
            out += ["position = [0.0, 0.0]"]
        if i % 2:
            out += ["friction = { forward = 0.2, backward = 0.9 }"]
    for i in range(1, n):
        out += ["[[sensors]]", f'name = "a{i}"', 'type = "angle"', f'link = "s{i}"', "min_deg = 20", "max_deg = 180",
                "[[actuators]]", f'name = "m{i}"', 'type = "angular"', f'joint = "s{i}"', "min_deg = -45",
                "max_deg = 45", "ks = 0.02", "kd = 0.002"]
    out += ["[[sensors]]", 'name = "t0"', 'type = "touch"', 'link = "s0"', "contact = 0"]
    return "\n".join(out) + "\n"


def _on(spec, terrain: str):
    t = TERRAINS[terrain]
    if t is None:
        return spec
    return dataclasses.replace(spec, world=dataclasses.replace(spec.world, terrain=t))


def run_kernel(m, san, sp, s0, steps: int, articulated: bool | None = None) -> dict:
    B = sp.weights.shape[0]
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    N = san.n_nodes
    return kernel.run_san(kernel.pack(m, san.n_hidden, articulated), np.asarray(sp.weights), np.asarray(sp.k1), np.asarray(sp.k2),
                          tile(s0.q), tile(s0.p), tile(s0.anchor), np.zeros((B, N)), np.zeros((B, N)), steps)


def relative_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(a - b).max(1) / (1 + np.abs(a).max(1))


def test_a_controller_steps_bit_for_bit_alike_alone_and_anywhere_in_a_batch():
    spec = creature.load("bounder")
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, 37, 3, dtype="float64")  # 37: tiles of 8 with a ragged last one
    s0 = sim.make_state(m)
    whole = run_kernel(m, san, sp, s0, 300)
    for i in (0, 7, 8, 36):
        one = type(sp)(*(x[i : i + 1] for x in sp))
        alone = run_kernel(m, san, one, s0, 300)
        for key in ("q", "p", "anchor", "istate", "out"):
            assert np.array_equal(alone[key][0], whole[key][i]), (i, key)
    again = run_kernel(m, san, sp, s0, 300)
    assert all(np.array_equal(again[k], whole[k]) for k in whole)


def test_the_thread_count_changes_no_bit(tmp_path):
    code = """
import numpy as np, sanlab
from sanlab import creature, sim
from sanlab.random_sans import random_san_params
from tests.sim.test_kernel import run_kernel
spec = creature.load("bounder")
m = sim.compile_creature(spec, dtype="float64")
san, sp = random_san_params(spec, 40, 5, dtype="float64")
np.save(__import__("sys").argv[1], run_kernel(m, san, sp, sim.make_state(m), 200)["q"])
"""
    same_on_one_and_two_threads(code, tmp_path)


def test_rows_that_carry_their_own_numbers_step_as_each_would_alone():
    # mixed batches (tuning, ensembles, designs): masses, friction and the step differ per row
    spec = creature.load("bounder")
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, 12, 7, dtype="float64")
    s0 = sim.make_state(m)
    pk = kernel.pack(m, san.n_hidden)
    scale = np.linspace(0.8, 1.25, 12)
    lf = np.repeat(pk.lf[None], 12, 0)
    lf[:, :, kernel.F_MASS] *= scale[:, None]
    lf[:, :, kernel.F_MU] *= scale[::-1, None]
    wf = np.repeat(pk.wf[None], 12, 0)
    wf[:, kernel.W_DT] *= np.where(np.arange(12) % 2, 0.5, 1.0)
    tile = lambda x: np.tile(np.asarray(x), (12,) + (1,) * np.ndim(x))
    N = san.n_nodes
    mixed = kernel.run_san(pk, sp.weights, sp.k1, sp.k2, tile(s0.q), tile(s0.p), tile(s0.anchor), np.zeros((12, N)),
                           np.zeros((12, N)), 400, rows={"lf": lf, "wf": wf})
    for i in (0, 5, 11):
        mi = m.with_params(mass=np.asarray(m.params.mass) * scale[i], mu=np.asarray(m.params.mu) * scale[::-1][i],
                           dt=np.asarray(m.params.dt) * (0.5 if i % 2 else 1.0))
        one = type(sp)(*(x[i : i + 1] for x in sp))
        alone = run_kernel(mi, san, one, s0, 400)
        assert np.array_equal(alone["q"][0], mixed["q"][i]), i
    assert len({mixed["q"][i].tobytes() for i in range(12)}) == 12  # the rows did differ


def test_a_per_row_table_of_the_wrong_shape_or_name_is_refused():
    m = sim.compile_creature(creature.load("twolink"), dtype="float64")
    pk = kernel.pack(m, 5)
    z = np.zeros((2, m.structure.ndof))
    args = (np.zeros((2, 7, 10)), np.ones((2, 7)), -np.ones((2, 7)), z, z, np.zeros((2, 3, 2)), np.zeros((2, 7)),
            np.zeros((2, 7)), 1)
    with pytest.raises(ValueError, match="rows\\['lf'\\]: expected shape"):
        kernel.run_san(pk, *args, rows={"lf": pk.lf})
    with pytest.raises(ValueError, match="follow"):
        kernel.run_san(pk, *args, rows={"follow": pk.follow})


@pytest.mark.parametrize("source", ["walker", "chain6"])
def test_the_two_routes_of_the_kernels_linear_algebra_agree(source):
    # dense L D L^T against the O(n) articulated-body recursion, over the first 300 steps
    spec = creature.loads(chain(6), source="chain6") if source == "chain6" else creature.load(source)
    san, sp = random_san_params(spec, 16, 2, dtype="float64")
    m = sim.compile_creature(spec, dtype="float64")
    out = [run_kernel(m, san, sp, sim.make_state(m), 300, articulated=a)["q"] for a in (False, True)]
    assert relative_error(out[0], out[1]).max() < 1e-12
    with pytest.raises(ValueError, match="trees of rigid links"):
        kernel.pack(sim.compile_creature(creature.load("crawler"), dtype="float64"), 10, articulated=True)
    # compile_creature's choice reaches the kernel; by default it takes the O(n) route where it can
    route = lambda mm: int(kernel.pack(mm, 0).wi[kernel.W_ARTICULATED])
    assert route(m) == 1 and route(sim.compile_creature(spec, articulated=False)) == 0
    assert route(sim.compile_creature(creature.load("crawler"))) == 0  # linear actuators join two bodies
    with pytest.raises(ValueError, match="articulated route"):
        sim.compile_creature(creature.load("crawler"), articulated=True)


def observe_of(metric, desc) -> kernel.Observe:
    """The kernel's observers for the engine's Metric and Descriptors (what the evaluator will pass)."""
    from sanlab.descriptors import MAX_SENSORS

    return kernel.Observe(kind=metric.kind, fell_links=metric.fell_links, fell_angle=metric.fell_angle,
                          fell_com_height=metric.fell_com_height, fell_link_height=metric.fell_link_height,
                          depth=metric.max_depth is not None, root=desc.root,
                          sensors=desc.n_sensors if 0 < desc.n_sensors <= MAX_SENSORS else 0,
                          joints=desc.joints, touch=desc.touch)


@pytest.mark.parametrize("name", ["bounder", "crawler", "fish"])
def test_the_gpus_form_steps_every_creature_bit_for_bit_as_the_simd_tiles(name):
    # one creature per thread in plain double (what a GPU thread runs) against tiles of SIMD lanes:
    # the same template, the same bits (both routes, water, eyes, observers and frames)
    from sanlab import descriptors
    from sanlab.metrics import Metric

    spec = creature.load(name)
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, 11, 8, dtype="float64")
    s0 = sim.make_state(m)
    B, N = 11, san.n_nodes
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    ob = observe_of(Metric.for_creature(spec), descriptors.Descriptors.for_creature(m))
    out = [kernel.run_san(kernel.pack(m, san.n_hidden), sp.weights, sp.k1, sp.k2, tile(s0.q), tile(s0.p),
                          tile(s0.anchor), np.zeros((B, N)), np.zeros((B, N)), 400, observe=ob, every=50, scalar=s)
           for s in (False, True)]
    assert out[0].keys() == out[1].keys()
    for key in out[0]:
        assert np.array_equal(out[0][key], out[1][key], equal_nan=True), key


def test_a_kernel_built_from_other_sources_is_refused(tmp_path):
    # after a pull that changed the kernel's sources without a rebuild, the old library would read
    # its arguments by the old layout: native.py (the kernel's loader) compares the build's stamp
    # with its sources
    import shutil
    import sysconfig

    here = ROOT / "sanlab" / "sim"
    from sanlab.sim import native

    assert native._library().sanlab_kernel_source().decode() == native.source_hash(here / "_kernel")
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    shutil.copy(here / "native.py", tmp_path / "native.py")
    shutil.copy(here / f"_kernel_lib{suffix}", tmp_path / f"_kernel_lib{suffix}")
    shutil.copytree(here / "_kernel", tmp_path / "_kernel")
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import native\n"
            "try:\n    native.lanes()\nexcept RuntimeError as e:\n    print(e)\n")
    ok = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0 and ok.stdout == "", ok.stdout + ok.stderr  # the same sources: loads
    with (tmp_path / "_kernel" / "step.h").open("a") as f:
        f.write("\n// changed\n")
    stale = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert "built from other sources" in stale.stdout and "pip install -e ." in stale.stdout, stale.stdout + stale.stderr


def test_indices_and_shapes_the_kernel_would_read_past_are_refused():
    # each of these once crashed the process (a segfault) or returned garbage (a newcomer's run)
    from sanlab.san import San

    spec = creature.load("bounder")
    m = sim.compile_creature(spec)
    pk = kernel.pack(m, 8)
    san = San.for_creature(spec)
    sp = san.params(np.stack([san.random_weights(0, i) for i in range(3)]), 0.1, 0.1)
    q, a = kernel.start(pk, np.repeat(np.asarray(m.params.q0)[None], 3, 0))
    z = np.zeros((3, san.n_nodes))
    run = lambda **kw: kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, np.zeros_like(q), a, z, z, 5, **kw)
    for ob, name in ((kernel.Observe(touch=(10**6,)), "touch"), (kernel.Observe(touch=(8,)), "touch"),
                     (kernel.Observe(fell_links=(5,)), "fell_links"), (kernel.Observe(joints=(7,)), "joints"),
                     (kernel.Observe(root=5), "root"), (kernel.Observe(sensors=31), "sensors")):
        with pytest.raises(ValueError, match=rf"observe\.{name}: expected"):
            run(observe=ob)
    acc = run(observe=kernel.Observe(sensors=6))["acc"]
    acc[:, kernel.ACC.index("changes")] = -63
    with pytest.raises(ValueError, match="acc: expected"):
        run(observe=kernel.Observe(sensors=6), acc=acc)
    for bad in (np.zeros((4, 1)), np.zeros(7), np.zeros((0, 7))):
        with pytest.raises(ValueError, match=r"q: expected shape \(B, 7\)"):
            kernel.start(pk, bad)
    with pytest.raises(ValueError, match=r"q: expected shape \(7,\) or \(B, 7\)"):
        sim.make_state(m, q=np.zeros(3))
    with pytest.raises(ValueError, match="at least one controller"):
        sim.rollout(m, san, sp._replace(weights=sp.weights[:0], k1=sp.k1[:0], k2=sp.k2[:0]), steps=3)
    s0 = sim.make_state(m)
    with pytest.raises(ValueError, match=r"state0\.q: expected shape"):
        sim.rollout(m, san, sp, steps=3, state0=s0._replace(q=s0.q[:3]))
    # a NaN time is NaN out, not an int made of NaN
    fish = sim.compile_creature(creature.load("fish"))
    assert np.isnan(sim.follow_point(fish, np.array([np.nan]))).all()
