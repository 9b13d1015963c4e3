"""The kernel against the XLA engine it replaced, through the engine's stored numbers.

The engine (sanlab.sim.dynamics, stepped by sanlab.sim.xla) was removed after issue 46; just before,
it stored what the kernel had been compared against live. The scripts that made the two files are
in the bodies of the commits that added them.

``tests/data/engine_reference.npz`` holds, for every built-in creature on every ground (the
vertical ones on flat, slope, hill and rough ground), the kitchen-sink file and 6- and 12-link
chains with a stop and a spring at every joint, the engine's final state in float64 after 1000
steps of controllers 0..15 of a search seeded 0, each from the start pose. On terrain the
creatures start lifted by 1 µm: the loader seats each free tree on the ground, so a contact
starts at a depth of 0 give or take the last bit, and the touch sensor (depth > 0) of the first
step would then be round-off's choice.

The two compute sin, cos and 1/sqrt their own way and order some sums differently, so a run that
sits on a binary sensor's or a contact's threshold parts by chaos; the test asks the median
controller to agree within 1e-11 (relative to the state's size) and at least 14 of the 16 within
1e-9, as the live comparison asked of 64 (measured there on the eight vertical creatures and four
grounds: medians 2e-16 to 5e-13, at most 4 of 64 beyond 1e-9; fish, crawler: 1e-16, none).

``tests/data/engine_details.npz`` holds the rest, each test below says what: the first steps of
closed-loop runs to the last bits, the metric's and the descriptors' accumulators, recorded frames,
seating, and the float32 engine's scores of 200 random SANs per creature (what searches ran on
until issue 46); the open-loop controllers and the inspectors are in test_kernel_open.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sanlab import creature, descriptors, sim
from sanlab.metrics import Metric, MetricAcc, scores
from sanlab.random_sans import random_san_params
from sanlab.sim import kernel
from tests.sim.test_kernel import HORIZONTAL, TERRAINS, VERTICAL, _on, chain, observe_of, relative_error

DATA = Path(__file__).resolve().parents[1] / "data"
REFERENCE = np.load(DATA / "engine_reference.npz")
DETAILS = np.load(DATA / "engine_details.npz")
CASES = sorted({k.rsplit("/", 1)[0] for k in REFERENCE.files})


# built-ins changed since the XLA engine's numbers were stored (issue 47): their earlier files
EARLIER = {"bounder": "bounder_second.toml", "luxo": "luxo_first.toml", "fish": "fish_first.toml",
           "crawler": "crawler_first.toml"}


def stored(name: str):
    """The built-in ``name`` as the XLA engine's stored numbers were made on it (its earlier file
    in tests/data where :data:`EARLIER` names one)."""
    return creature.load(str(DATA / EARLIER[name])) if name in EARLIER else creature.load(name)


def spec_of(case: str):
    name, terrain = case.split("/")
    if name.startswith("chain"):
        spec = creature.loads(chain(int(name[5:])), source=name)
    elif name == "kitchen_sink":
        spec = creature.load(str(DATA / "kitchen_sink.toml"))
    else:
        spec = stored(name)
    assert terrain in TERRAINS
    return _on(spec, terrain)


def run_san_from(m, san, sp, q0: np.ndarray, steps: int, **kw) -> dict:
    """The kernel's run of SANs ``sp`` from coordinates q0 [D] at rest (anchors at the contacts)."""
    B, N = sp.weights.shape[0], san.n_nodes
    pk = kernel.pack(m, san.n_hidden)
    q, anchor = kernel.start(pk, np.repeat(np.asarray(q0)[None], B, 0), seat=False)
    return kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, np.zeros_like(q), anchor, np.zeros((B, N)),
                          np.zeros((B, N)), steps, **kw)


@pytest.mark.parametrize("case", CASES)
def test_the_kernel_ends_where_the_xla_engine_ended(case):
    spec = spec_of(case)
    m = sim.compile_creature(spec)
    san, sp = random_san_params(spec, 16, 0)
    q0 = REFERENCE[case + "/q0"]
    r = run_san_from(m, san, sp, q0, 1000)
    ref = REFERENCE[case + "/q"]
    err = relative_error(ref, r["q"])
    assert np.median(err) < 1e-11, np.sort(err)
    assert np.sum(err < 1e-9) >= 14, np.sort(err)
    # the run moved: a creature at rest would agree with any engine
    assert np.abs(ref - q0).max() > 1e-3


@pytest.mark.parametrize("name, rows, steps", [("bounder", 16, 50), ("fish", 9, 200)])
def test_the_first_steps_agree_with_the_engine_to_the_last_bits(name, rows, steps):
    # before any sensor can flip, every controller (0..rows-1 of a search seeded 0); the fish:
    # water, a passive spring, eyes on a follow path (a tile's scratch once overran into the
    # state of a creature without contacts, and only this caught it)
    spec = stored(name)
    san, sp = random_san_params(spec, rows, 0)
    k = run_san_from(sim.compile_creature(spec), san, sp, DETAILS[f"first/{name}/q0"], steps)
    assert relative_error(DETAILS[f"first/{name}/q"], k["q"]).max() < 1e-13


@pytest.mark.parametrize("name, kind", [("bounder", None), ("bounder", "hopping"), ("fish", None), ("cart", None)])
def test_the_kernels_observers_accumulate_what_the_engines_did(name, kind):
    # the metric's ingredients and the descriptors over 200 steps (before chaos; the fish, which
    # starts to swim later and is not chaotic: 1000) of controllers 0..15 of a search seeded 4
    spec = stored(name)
    m = sim.compile_creature(spec)
    metric, desc = Metric.for_creature(spec, kind), descriptors.Descriptors.for_creature(m)
    ref = lambda f: DETAILS[f"observe/{name}/{metric.kind}/{f}"]
    san, sp = random_san_params(spec, 16, 4)
    ob = observe_of(metric, desc)
    k = run_san_from(m, san, sp, ref("q0"), 1000 if name == "fish" else 200, observe=ob)
    acc = dict(zip(kernel.ACC, k["acc"].T))
    close = lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-11)
    for f in ("p0x", "p0y", "y0", "px", "py", "hop", "pursuit"):
        close(ref(f), acc[f])
    close(ref("deepest"), np.maximum(acc["deepest"], 0))
    assert np.array_equal(ref("fell"), acc["fell"] > 0)
    for f in ("steps", "height", "height2", "turn", "angle", "airborne", "joint_speed", "since"):
        close(ref(f), acc[f])
    for f in ("word", "candidate", "changes"):
        assert np.array_equal(ref(f), acc[f].astype(int)), f
    n_touch = len(ob.touch)
    close(ref("duty"), k["acc"][:, len(kernel.ACC):len(kernel.ACC) + n_touch])
    words = k["acc"][:, len(kernel.ACC) + n_touch:len(kernel.ACC) + n_touch + kernel.EVENTS]
    assert np.array_equal(ref("words"), words.astype(int))
    np.testing.assert_allclose(ref("qd"), k["qd"], rtol=1e-6, atol=1e-8)  # velocities: more sensitive
    assert np.abs(ref("qd")).max() > 1e-3  # the bodies moved


def test_the_kernel_records_the_frames_the_engine_recorded():
    # controllers 0..15 of a search seeded 6 on the bounder, 305 steps, a frame every 10 steps:
    # 30 whole frames (the engine's of rows 0..5 stored)
    spec = stored("bounder")
    m = sim.compile_creature(spec)
    san, sp = random_san_params(spec, 16, 6)
    k = run_san_from(m, san, sp, DETAILS["frames/q0"], 305, every=10)
    ref = lambda f: DETAILS["frames/" + f]
    assert k["frames_q"].shape == (16, 30, m.structure.ndof) and ref("q").shape == (6, 30, m.structure.ndof)
    np.testing.assert_allclose(k["frames_q"][:6], ref("q"), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(k["frames_qd"][:6], ref("qd"), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(k["frames_u"][:6], ref("u"), atol=1e-12)
    assert np.array_equal(k["frames_bits"][:6], ref("bits"))
    assert np.array_equal(k["frames_out"][:6], ref("out"))
    np.testing.assert_allclose(k["frames_istate"][:6], ref("istate"), atol=1e-12)


@pytest.mark.parametrize("terrain", ["flat", "rough", "hill"])
def test_the_kernel_seats_a_creature_and_anchors_it_as_the_engine_did(terrain):
    from sanlab.sim.model import assemble

    ref = lambda f: DETAILS[f"seat/{terrain}/{f}"]
    raw = assemble(_on(stored("bounder"), terrain), "float64")  # where the file puts it
    np.testing.assert_array_equal(raw.params.q0, ref("raw"))
    q0 = np.asarray(raw.params.q0)[None].repeat(3, 0)
    q0[1, 1] -= 0.05  # started inside the ground
    q, anchor = kernel.start(kernel.pack(raw, 8), q0, seat=np.array([True, True, False]))
    np.testing.assert_allclose(q[0], ref("seated"), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(q[1], ref("seated"), rtol=1e-12, atol=1e-12)  # lifted back out
    np.testing.assert_array_equal(q[2], q0[2])  # not seated: left where it was
    np.testing.assert_allclose(anchor[0], ref("anchor"), rtol=1e-12, atol=1e-12)
    assert not np.array_equal(ref("raw"), ref("seated")) or terrain == "flat"


def kernel_scores(spec, B: int, seed: int) -> np.ndarray:
    """The scores of controllers 0..B-1 of a search seeded ``seed`` (one rollout each, the
    creature's metric and evaluation time) on the kernel, from the creature's start at rest."""
    m = sim.compile_creature(spec)
    metric, desc = Metric.for_creature(spec), descriptors.Descriptors.for_creature(m)
    san, sp = random_san_params(spec, B, seed)
    steps = int(round(spec.evaluation.seconds / spec.dt))
    k = run_san_from(m, san, sp, m.params.q0, steps, observe=observe_of(metric, desc))
    a = dict(zip(kernel.ACC, k["acc"].T))
    acc = MetricAcc((a["p0x"], a["p0y"]), a["y0"], a["hop"], a["pursuit"], a["fell"] > 0, (a["px"], a["py"]),
                    np.maximum(a["deepest"], 0.0))
    finite = np.isfinite(k["q"]).all(1) & (np.abs(k["qd"]) < 1e4).all(1) & np.isfinite(k["p"]).all(1)
    return scores(metric, acc, finite, spec.evaluation.seconds, spec.world.plane)["score"]


@pytest.mark.slow
@pytest.mark.parametrize("name", VERTICAL + HORIZONTAL)
def test_the_kernels_scores_agree_with_the_float32_engines_in_distribution(name):
    # chaotic runs part in the last bits (float64 against float32): the same 200 random SANs
    # (controllers 0..199 of a search seeded 0), each median within the other's 95 % bootstrap
    # interval (2,000 resamples)
    a, b = DETAILS[f"scores32/{name}"], kernel_scores(stored(name), 200, 0)
    rng = np.random.default_rng(0)
    for x, y in ((a, b), (b, a)):
        boot = np.median(x[rng.integers(0, len(x), (2000, len(x)))], axis=1)
        lo, hi = np.quantile(boot, [0.025, 0.975])
        assert lo - 1e-12 <= np.median(y) <= hi + 1e-12, (np.median(a), np.median(b), lo, hi)
