"""float32 that computes in float32 (issue 58, section 2).

A model compiled with ``dtype="float32"`` is stepped by the kernel's float32 instantiation (the
same template over float lanes, ``_kernel/lanes.h``): every value of the run is a float32, the
clock advances by float32 additions, a controller steps bit for bit alike alone and anywhere in a
batch and on any thread count, and the scalar form (the GPU's) steps as the tiles do. Being chaotic
in general, it is accepted against float64 by distribution: on all ten built-in creatures the
median score of the same 200 random SANs lies inside float64's 95 % bootstrap interval.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from sanlab import creature, descriptors, sim
from sanlab.metrics import Metric
from sanlab.random_sans import random_san_params, simulate_random
from sanlab.sim import kernel
from tests.helpers import same_on_one_and_two_threads
from tests.sim.test_gpu import needs_nvrtc
from tests.sim.test_kernel import HORIZONTAL, VERTICAL, observe_of


def _run(name: str, dtype: str, B: int, steps: int, seed: int = 3, order=None, scalar: bool = False, **kw) -> dict:
    """Random SANs 0..B-1 of ``seed`` (rows in ``order``, default as drawn) on built-in ``name`` in
    ``dtype`` from the creature's start at rest, with the metric's and descriptors' observers."""
    spec = creature.load(name)
    m = sim.compile_creature(spec, dtype)
    san, sp = random_san_params(spec, B, seed, dtype="float64")
    idx = np.arange(B) if order is None else np.asarray(order)
    s0 = sim.make_state(m)
    n, N = len(idx), san.n_nodes
    tile = lambda x: np.tile(np.asarray(x), (n,) + (1,) * np.ndim(x))
    ob = observe_of(Metric.for_creature(spec), descriptors.Descriptors.for_creature(m))
    return kernel.run_san(kernel.pack(m, san.n_hidden), sp.weights[idx], sp.k1[idx], sp.k2[idx], tile(s0.q),
                          tile(s0.p), tile(s0.anchor), np.zeros((n, N)), np.zeros((n, N)), steps, observe=ob,
                          scalar=scalar, **kw)


def _is_float32(x: np.ndarray) -> bool:
    x = np.asarray(x, np.float64)
    return bool(np.array_equal(x, x.astype(np.float32).astype(np.float64), equal_nan=True))


def test_a_float32_model_is_stepped_in_float32_arithmetic():
    # every number a float32 run returns is a float32 (a float64 step would leave most of them
    # between two floats), and its clock is the float32 sum of dt step by step, which parts from
    # the float64 sum within 300 steps of 1 ms
    steps = 300
    r32, r64 = _run("bounder", "float32", 20, steps), _run("bounder", "float64", 20, steps)
    for key in ("q", "p", "anchor", "qd", "t", "acc", "istate", "out"):
        assert _is_float32(r32[key]), key
    assert not _is_float32(r64["q"]) and not _is_float32(r64["p"])
    t32, t64 = np.float32(0.0), 0.0
    dt = float(creature.load("bounder").dt)
    for _ in range(steps):
        t32 = np.float32(t32 + np.float32(dt))
        t64 = t64 + dt
    assert np.all(r32["t"] == np.float64(t32)) and np.all(r64["t"] == t64)
    assert np.float64(t32) != t64


def test_float32_agrees_closely_with_float64_on_a_short_smooth_run():
    # the twolink and the bounder under held activations for a few hundred ms: smooth runs, so
    # float32 stays within its precision's reach of float64 (measured 6e-7 and 8e-7 in q, m and
    # rad, after moving by 2.5 and 1.5), yet is not equal to it
    for name, u, steps in (("twolink", 1.0, 300), ("bounder", 0.0, 100)):
        spec = creature.load(name)
        out = {}
        for dtype in ("float32", "float64"):
            m = sim.compile_creature(spec, dtype)
            out[dtype] = sim.rollout(m, sim.ConstantController(), np.full((1, len(spec.actuators)), u),
                                     steps=steps).state.q[0]
        diff = np.abs(out["float32"] - out["float64"]).max()
        assert 0 < diff < 1e-5, (name, diff)
        assert np.abs(out["float64"] - np.asarray(sim.compile_creature(spec).params.q0)).max() > 1.0  # it moved


def test_a_float32_controller_steps_bit_for_bit_alike_alone_and_anywhere_in_a_batch():
    # 41 rows: tiles of 16 float lanes with a ragged last one; the same rows reversed put each
    # controller in another lane of another tile
    B = 41
    whole = _run("bounder", "float32", B, 300)
    rev = _run("bounder", "float32", B, 300, order=np.arange(B)[::-1])
    keys = ("q", "p", "anchor", "istate", "out", "acc", "qd", "t")
    for i in (0, 15, 16, 31, 40):
        alone = _run("bounder", "float32", B, 300, order=[i])
        for key in keys:
            assert np.array_equal(alone[key][0], whole[key][i]), (i, key)
            assert np.array_equal(rev[key][B - 1 - i], whole[key][i]), (i, key)
    assert np.ptp(whole["q"][:, 0]) > 1e-3  # the controllers differ


def test_the_thread_count_changes_no_bit_of_a_float32_run(tmp_path):
    code = """
import sys
import numpy as np
from tests.sim.test_float32 import _run
np.save(sys.argv[1], _run("bounder", "float32", 40, 200)["q"])
"""
    same_on_one_and_two_threads(code, tmp_path)


@pytest.mark.parametrize("name", ["bounder", "crawler", "fish"])
def test_the_float32_scalar_form_steps_bit_for_bit_as_the_float32_tiles(name):
    # plain float, one creature per thread (the form a GPU thread would run), against tiles of 16
    # float lanes: every constant of the step is a float in both, so the same bits (both routes,
    # water, eyes, observers and frames)
    tiles, scalar = (_run(name, "float32", 11, 400, seed=8, every=50, scalar=s) for s in (False, True))
    assert tiles.keys() == scalar.keys()
    for key in tiles:
        assert np.array_equal(tiles[key], scalar[key], equal_nan=True), key


def test_a_float32_run_continued_over_calls_is_the_run_in_one_call():
    # the state goes back and forth as float64 arrays holding float32 values, exactly: a Gymnasium
    # env or a studio chunk continuing a float32 run runs it as one call would
    spec = creature.load("walker")
    m = sim.compile_creature(spec, "float32")
    san, params = random_san_params(spec, 4, seed=2, dtype="float32")
    whole = sim.rollout(m, san, params, steps=400)
    first = sim.rollout(m, san, params, steps=150)
    rest = sim.rollout(m, san, params, steps=250, state0=first.state, cstate0=first.cstate)
    for field in ("q", "p", "anchor", "t"):
        np.testing.assert_array_equal(getattr(rest.state, field), getattr(whole.state, field))


def test_a_dtype_the_kernel_has_no_arithmetic_for_is_refused():
    spec = creature.load("cart")
    with pytest.raises(ValueError, match=r"^dtype: expected float32 or float64, got 'float16'$"):
        sim.compile_creature(spec, "float16")
    pk = kernel.pack(sim.compile_creature(spec), 0)._replace(dtype="float16")
    with pytest.raises(ValueError, match=r"^tables\.dtype: expected float64 or float32, got 'float16'$"):
        kernel.run_open(pk, "hold", np.zeros((1, 1)), pk.q0[None], np.zeros((1, pk.ndof)), np.zeros((1, 1, 2)), 1)
    with pytest.raises(ValueError, match=r"^dtype: expected float32 or float64, got 'int32'"):
        kernel.lanes("int32")
    assert kernel.lanes("float32") == 2 * kernel.lanes("float64")  # the same 64 bytes a tile


@pytest.mark.slow
@pytest.mark.parametrize("name", VERTICAL + HORIZONTAL)
def test_float32_scores_agree_with_float64_in_distribution(name):
    # chaotic runs part once a last bit flips a sensor or a stick-slip decision, so float32 is
    # held to float64 by distribution: the same 200 random SANs (controllers 0..199 of a search
    # seeded 0, the creature's own episode and metric), float32's median inside float64's 95 %
    # bootstrap interval (2,000 resamples)
    spec = creature.load(name)
    scores = {d: np.array([t["score"] for t in simulate_random(spec, 200, spec.evaluation.seconds, 0, d)["top"]])
              for d in ("float64", "float32")}
    a, b = scores["float64"], scores["float32"]
    boot = np.median(a[np.random.default_rng(0).integers(0, len(a), (2000, len(a)))], axis=1)
    lo, hi = np.quantile(boot, [0.025, 0.975])
    assert lo - 1e-12 <= np.median(b) <= hi + 1e-12, (np.median(a), np.median(b), lo, hi)
    assert not np.array_equal(a, b)  # two arithmetics, not one


@needs_nvrtc
@pytest.mark.slow
def test_the_gpus_float_entry_points_compile_to_sm_90_without_spills_or_float64_arithmetic():
    # gpu.cu's five _f32 entry points under NVRTC (no GCC vectors, no <cmath>: CUDA's sqrtf,
    # floorf, fabsf, atan2f), ptxas run on them (about 40 s): no spills, registers within the
    # float64 entries' budget, and in the PTX float64 only moves (the caller's float64 arrays read
    # and rounded, results widened and stored): every add, multiply, compare... is f32
    from sanlab.sim import gpu, layout
    from tests.sim.test_gpu import REGISTERS, STACK

    report, ptx = gpu.report("sm_90", "float32")
    assert set(report) == set(layout.KINDS)
    for kind, r in report.items():
        assert r["spill_stores"] == 0 and r["spill_loads"] == 0, (kind, r)
        assert 0 < r["registers"] <= REGISTERS and r["stack"] <= STACK, (kind, r)
    for kind in layout.KINDS:
        assert f".entry {gpu.ENTRIES[kind, 'float32']}(" in ptx
    assert ".entry sanlab_gpu_san(" not in ptx  # the float64 entries are built apart
    f64 = {op.split(".")[0] for op in re.findall(r"^\s*([a-z][\w.]*\.f64)\b", ptx, re.M)}
    assert f64 <= {"ld", "st", "cvt"}, f64
    assert len(re.findall(r"\b(?:add|sub|mul|div)\.rn\.f32\b", ptx)) > 1000
    # IEEE division and square root, denormals kept (gpu.OPTIONS), as the CPU's float tiles
    assert re.findall(r"\b(?:div|sqrt)\.rn\.f32\b", ptx) and not re.search(r"\.(?:approx|full|ftz)\b", ptx)
