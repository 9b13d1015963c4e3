"""The kernel that reads the creature as data (sanlab/sim/kernel.py, sanlab/sim/_kernel) against
the XLA engine it replaced (sanlab.sim.dynamics through sanlab.sim.xla.rollout), and its contracts.

Agreement (issue 46): in float64 the final states of 64 random SANs after 1000 steps agree with the
engine to round-off. The two order some sums differently and compute sin, cos and 1/sqrt their own
way, so they differ in the last bits from the first step on; in most runs that stays below 1e-12
after 1000 steps, but where a binary sensor or a contact's stick-slip decision sits on its
threshold the last bit flips it, and from there a chaotic gait's two runs part (as a run at dt and
dt/2 would). The test therefore asks the median controller to agree within 1e-11 and at least 56 of
the 64 within 1e-9, relative to the state's size; measured on the eight vertical creatures and four
grounds: medians 2e-16 to 5e-13, at most 4 of 64 beyond 1e-9 (fish, crawler: 1e-16, none).

On terrain the creatures start lifted by 1 µm: the loader seats each free tree on the ground, so a
contact starts at a depth of 0 give or take the last bit, and the touch sensor (depth > 0) of the
first step is then round-off's choice.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.creature.spec import Terrain
from sanlab.engine_report import random_san_params
from sanlab.sim import dynamics, kernel, xla

VERTICAL = ("cart", "bounder", "twolink", "threelink", "fourlink", "star", "luxo", "walker")
HORIZONTAL = ("fish", "crawler")  # water, point masses, linear springs, eyes, anisotropic friction
DATA = Path(__file__).resolve().parents[1] / "data"
TERRAINS = {
    "flat": None,
    "slope": Terrain(kind="slope", angle=0.087),
    "hill": Terrain(kind="hill", height=0.08, width=1.0, center=0.3),
    "rough": Terrain(kind="rough", height=0.015, wavelength=0.25, seed=1),
}
LIFT = 1e-6  # m
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


def _start(m, lift: float):
    """The start pose with every free tree lifted by ``lift`` (m), as a state."""
    q0 = np.array(m.params.q0)
    for tree in m.structure.trees:
        if tree.free:
            q0[m.structure.links[tree.root].dof_y] += lift
    return dynamics.make_state(m, q0)


def run_both(spec, B: int, steps: int, lift: float = 0.0, seed: int = 0):
    """(engine, kernel) final coordinates q [B, D] of controllers 0..B-1 of a search seeded
    ``seed``, from the start pose lifted by ``lift``, in float64."""
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, B, seed, dtype="float64")
    s0 = _start(m, lift)
    r = xla.rollout(m, san, sp, steps=steps, state0=s0)
    return np.asarray(r.state.q), run_kernel(m, san, sp, s0, steps)["q"]


def run_kernel(m, san, sp, s0, steps: int, articulated: bool | None = None) -> dict:
    B = sp.weights.shape[0]
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    N = san.n_nodes
    return kernel.run_san(kernel.pack(m, san.n_hidden, articulated), np.asarray(sp.weights), np.asarray(sp.k1), np.asarray(sp.k2),
                          tile(s0.q), tile(s0.p), tile(s0.anchor), np.zeros((B, N)), np.zeros((B, N)), steps)


def relative_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(a - b).max(1) / (1 + np.abs(a).max(1))


def assert_round_off(engine, kern) -> None:
    err = relative_error(engine, kern)
    assert np.median(err) < 1e-11, np.sort(err)
    assert np.sum(err < 1e-9) >= 56, np.sort(err)


@pytest.mark.slow
@pytest.mark.parametrize("terrain", list(TERRAINS))
@pytest.mark.parametrize("name", VERTICAL)
def test_the_kernel_agrees_with_the_engine_to_round_off(name, terrain):
    assert_round_off(*run_both(_on(creature.load(name), terrain), 64, 1000, lift=0.0 if terrain == "flat" else LIFT))


@pytest.mark.slow
@pytest.mark.parametrize("source", [*HORIZONTAL, "kitchen_sink", "chain6", "chain12"])
def test_the_kernel_agrees_in_the_horizontal_plane_and_on_chains(source):
    # kitchen_sink: a linear actuator, a length sensor, a follow path, water and point masses in one
    # file; the chains: stops and springs at every joint, 6 and 12 links (the engine's articulated
    # route from 9 dofs on, the kernel's dense one)
    if source.startswith("chain"):
        spec = creature.loads(chain(int(source[5:])), source=source)
    elif source == "kitchen_sink":
        spec = creature.load(str(DATA / "kitchen_sink.toml"))
    else:
        spec = creature.load(source)
    assert_round_off(*run_both(spec, 64, 1000))


def test_the_bounders_first_steps_agree_with_the_engine_to_the_last_bits():
    # before any sensor can flip: 50 steps, every controller
    engine, kern = run_both(creature.load("bounder"), 16, 50)
    assert relative_error(engine, kern).max() < 1e-13


def test_a_controller_steps_bit_for_bit_alike_alone_and_anywhere_in_a_batch():
    spec = creature.load("bounder")
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, 37, 3, dtype="float64")  # 37: tiles of 8 with a ragged last one
    s0 = dynamics.make_state(m)
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
from sanlab.engine_report import random_san_params
from sanlab.sim import dynamics
from tests.sim.test_kernel import run_kernel
spec = creature.load("bounder")
m = sim.compile_creature(spec, dtype="float64")
san, sp = random_san_params(spec, 40, 5, dtype="float64")
np.save(__import__("sys").argv[1], run_kernel(m, san, sp, dynamics.make_state(m), 200)["q"])
"""
    outs = []
    for threads in ("1", "2"):
        path = tmp_path / f"q{threads}.npy"
        env = dict(os.environ, OMP_NUM_THREADS=threads)
        subprocess.run([sys.executable, "-c", code, str(path)], check=True, env=env, cwd=ROOT)
        outs.append(np.load(path))
    assert np.array_equal(outs[0], outs[1])


def test_the_fishs_first_steps_agree_with_the_engine_to_the_last_bits():
    # water, a passive spring, eyes on a follow path; a tile's scratch once overran into the state
    # of a creature without contacts (the fish), and only this caught it
    engine, kern = run_both(creature.load("fish"), 9, 200)
    assert relative_error(engine, kern).max() < 1e-13


def test_rows_that_carry_their_own_numbers_step_as_each_would_alone():
    # mixed batches (tuning, ensembles, designs): masses, friction and the step differ per row
    spec = creature.load("bounder")
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, 12, 7, dtype="float64")
    s0 = dynamics.make_state(m)
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
    out = [run_kernel(m, san, sp, dynamics.make_state(m), 300, articulated=a)["q"] for a in (False, True)]
    assert relative_error(out[0], out[1]).max() < 1e-12
    with pytest.raises(ValueError, match="trees of rigid links"):
        kernel.pack(sim.compile_creature(creature.load("crawler"), dtype="float64"), 10, articulated=True)


def observe_of(metric, desc) -> kernel.Observe:
    """The kernel's observers for the engine's Metric and Descriptors (what the evaluator will pass)."""
    from sanlab.descriptors import MAX_SENSORS

    return kernel.Observe(kind=metric.kind, fell_links=metric.fell_links, fell_angle=metric.fell_angle,
                          fell_com_height=metric.fell_com_height, fell_link_height=metric.fell_link_height,
                          depth=metric.max_depth is not None, root=desc.root,
                          sensors=desc.n_sensors if 0 < desc.n_sensors <= MAX_SENSORS else 0,
                          joints=desc.joints, touch=desc.touch)


@pytest.mark.parametrize("name, kind", [("bounder", None), ("bounder", "hopping"), ("fish", None), ("cart", None)])
def test_the_kernels_observers_accumulate_what_the_engines_do(name, kind):
    # the metric's ingredients and the descriptors over 200 steps (before chaos), in float64
    from sanlab import descriptors
    from sanlab.evaluate.evaluator import Observers
    from sanlab.metrics import Metric

    spec = creature.load(name)
    m = sim.compile_creature(spec, dtype="float64")
    metric, desc = Metric.for_creature(spec, kind), descriptors.Descriptors.for_creature(m)
    san, sp = random_san_params(spec, 16, 4, dtype="float64")
    s0 = dynamics.make_state(m)
    r = xla.rollout(m, san, sp, steps=200, observer=Observers(metric, desc))
    B, N = 16, san.n_nodes
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    ob = observe_of(metric, desc)
    k = kernel.run_san(kernel.pack(m, san.n_hidden), sp.weights, sp.k1, sp.k2, tile(s0.q), tile(s0.p),
                       tile(s0.anchor), np.zeros((B, N)), np.zeros((B, N)), 200, observe=ob)
    acc = dict(zip(kernel.ACC, k["acc"].T))
    ma, da = r.acc
    close = lambda a, b: np.testing.assert_allclose(np.asarray(a, float), b, rtol=1e-9, atol=1e-11)
    close(ma.p0[0], acc["p0x"]), close(ma.p0[1], acc["p0y"]), close(ma.y0, acc["y0"])
    close(ma.p[0], acc["px"]), close(ma.p[1], acc["py"])
    close(ma.hop, acc["hop"]), close(ma.pursuit, acc["pursuit"]), close(ma.deepest, np.maximum(acc["deepest"], 0))
    assert np.array_equal(np.asarray(ma.fell), acc["fell"] > 0)
    for name_ in ("steps", "height", "height2", "turn", "angle", "airborne", "joint_speed", "since"):
        close(getattr(da, name_), acc[name_])
    for name_ in ("word", "candidate", "changes"):
        assert np.array_equal(np.asarray(getattr(da, name_)), acc[name_].astype(int)), name_
    n_touch = len(ob.touch)
    close(da.duty, k["acc"][:, len(kernel.ACC):len(kernel.ACC) + n_touch])
    words = k["acc"][:, len(kernel.ACC) + n_touch:len(kernel.ACC) + n_touch + kernel.EVENTS]
    assert np.array_equal(np.asarray(da.words), words.astype(int))
    np.testing.assert_allclose(np.asarray(r.state.qd), k["qd"], rtol=1e-6, atol=1e-8)  # velocities: more sensitive


def test_the_kernel_records_the_frames_the_engine_records():
    spec = creature.load("bounder")
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, 16, 6, dtype="float64")
    s0 = dynamics.make_state(m)
    r = xla.rollout(m, san, sp, steps=305, record_fps=100)  # a frame every 10 steps: 30 whole frames
    B, N = 16, san.n_nodes
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    k = kernel.run_san(kernel.pack(m, san.n_hidden), sp.weights, sp.k1, sp.k2, tile(s0.q), tile(s0.p),
                       tile(s0.anchor), np.zeros((B, N)), np.zeros((B, N)), 305, every=10)
    fr = r.frames
    assert k["frames_q"].shape == np.asarray(fr.q).shape == (16, 30, m.structure.ndof)
    np.testing.assert_allclose(k["frames_q"], fr.q, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(k["frames_qd"], fr.qd, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(k["frames_u"], fr.u, atol=1e-12)
    assert np.array_equal(k["frames_bits"], fr.bits)
    assert np.array_equal(k["frames_out"], fr.cstate.out)
    np.testing.assert_allclose(k["frames_istate"], fr.cstate.istate, atol=1e-12)


@pytest.mark.parametrize("terrain", ["flat", "rough", "hill"])
def test_the_kernel_seats_a_creature_and_anchors_it_as_the_engine_does(terrain):
    from sanlab.sim.model import assemble

    spec = _on(creature.load("bounder"), terrain)
    raw = assemble(spec, "float64")  # where the file puts it
    seated = raw.with_params(q0=np.asarray(dynamics.seat_on_ground(raw, raw.params.q0)))  # the engine's
    q0 = np.asarray(raw.params.q0)[None].repeat(3, 0)
    q0[1, 1] -= 0.05  # started inside the ground
    q, anchor = kernel.start(kernel.pack(raw, 8), q0, seat=np.array([True, True, False]))
    np.testing.assert_allclose(q[0], seated.params.q0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(q[1], seated.params.q0, rtol=1e-12, atol=1e-12)  # lifted back out
    np.testing.assert_array_equal(q[2], q0[2])  # not seated: left where it was
    np.testing.assert_allclose(anchor[0], dynamics.make_state(seated).anchor, rtol=1e-12, atol=1e-12)


def kernel_scores(spec, B: int, seed: int) -> np.ndarray:
    """The scores of controllers 0..B-1 of a search seeded ``seed`` (one rollout each, the
    creature's metric and evaluation time) on the kernel, from the creature's start at rest."""
    from sanlab import descriptors
    from sanlab.metrics import Metric, MetricAcc, scores

    m = sim.compile_creature(spec, dtype="float64")
    metric, desc = Metric.for_creature(spec), descriptors.Descriptors.for_creature(m)
    san, sp = random_san_params(spec, B, seed, dtype="float64")
    pk = kernel.pack(m, san.n_hidden)
    q, anchor = kernel.start(pk, np.repeat(np.asarray(m.params.q0)[None], B, 0), seat=False)
    N = san.n_nodes
    steps = int(round(spec.evaluation.seconds / spec.dt))
    k = kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, np.zeros_like(q), anchor, np.zeros((B, N)), np.zeros((B, N)),
                       steps, observe=observe_of(metric, desc))
    a = dict(zip(kernel.ACC, k["acc"].T))
    acc = MetricAcc((a["p0x"], a["p0y"]), a["y0"], a["hop"], a["pursuit"], a["fell"] > 0, (a["px"], a["py"]),
                    np.maximum(a["deepest"], 0.0))
    finite = np.isfinite(k["q"]).all(1) & (np.abs(k["qd"]) < 1e4).all(1) & np.isfinite(k["p"]).all(1)
    return scores(metric, acc, finite, spec.evaluation.seconds, spec.world.plane)["score"]


def engine_scores(spec, B: int, seed: int) -> np.ndarray:
    """As :func:`kernel_scores` on the XLA engine in float32, as searches ran until now."""
    from sanlab.metrics import Metric, scores

    m = sim.compile_creature(spec, dtype="float32")
    metric = Metric.for_creature(spec)
    san, sp = random_san_params(spec, B, seed, dtype="float32")
    r = xla.rollout(m, san, sp, spec.evaluation.seconds, observer=metric)
    return scores(metric, r.acc, r.finite, spec.evaluation.seconds, spec.world.plane)["score"]


@pytest.mark.slow
@pytest.mark.parametrize("name", VERTICAL + HORIZONTAL)
def test_the_kernels_scores_agree_with_the_float32_engines_in_distribution(name):
    # chaotic runs part in the last bits (float64 against float32): the same 200 random SANs, each
    # median within the other's 95 % bootstrap interval (2,000 resamples)
    spec = creature.load(name)
    a, b = engine_scores(spec, 200, 0), kernel_scores(spec, 200, 0)
    rng = np.random.default_rng(0)
    for x, y in ((a, b), (b, a)):
        boot = np.median(x[rng.integers(0, len(x), (2000, len(x)))], axis=1)
        lo, hi = np.quantile(boot, [0.025, 0.975])
        assert lo - 1e-12 <= np.median(y) <= hi + 1e-12, (np.median(a), np.median(b), lo, hi)


@pytest.mark.parametrize("name", ["bounder", "crawler", "fish"])
def test_the_gpus_form_steps_every_creature_bit_for_bit_as_the_simd_tiles(name):
    # one creature per thread in plain double (what a GPU thread runs) against tiles of SIMD lanes:
    # the same template, the same bits (both routes, water, eyes, observers and frames)
    from sanlab import descriptors
    from sanlab.metrics import Metric

    spec = creature.load(name)
    m = sim.compile_creature(spec, dtype="float64")
    san, sp = random_san_params(spec, 11, 8, dtype="float64")
    s0 = dynamics.make_state(m)
    B, N = 11, san.n_nodes
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    ob = observe_of(Metric.for_creature(spec), descriptors.Descriptors.for_creature(m))
    out = [kernel.run_san(kernel.pack(m, san.n_hidden), sp.weights, sp.k1, sp.k2, tile(s0.q), tile(s0.p),
                          tile(s0.anchor), np.zeros((B, N)), np.zeros((B, N)), 400, observe=ob, every=50, scalar=s)
           for s in (False, True)]
    assert out[0].keys() == out[1].keys()
    for key in out[0]:
        assert np.array_equal(out[0][key], out[1][key], equal_nan=True), key
