"""The kernel's open-loop and reflex controllers (``kernel.run_open``) and its host inspectors
(``kernel.poses``, ``energy``, ``momenta``, ``velocity``, ``sense``, ``follow_point``,
``centre_of_mass``), against the XLA engine's numbers stored before it was removed
(``tests/data/engine_details.npz``, see test_kernel_reference.py: the engine's
``ConstantController``, ``SineController``, ``ReflexController`` and ``sanlab.sim.dynamics``), all
in float64. The inspectors agree to 1e-12 on every creature and both routes of the linear algebra
(the velocity, a solve with M, to 1e-11).

A rollout agrees to round-off as long as no binary sensor or stick-slip decision sits on its
threshold; where one does, the last bit decides it and the two runs part from there, by a little
where the creature settles again (a bounder held still: 1e-15 before its feet settle, 1e-7 to 1e-5
after) or by chaos (a hopping sine gait), as a run at dt and dt/2 would. Measured over 1000 steps,
16 rows each: crawler, fish and the kitchen sink within 1e-14 on every row; cart within 2e-9 but
one row; the bounder 2 to 3 rows of 16 beyond 1e-9. The tests therefore ask the median row to agree
within 1e-11 and three in four within 1e-9, compare the stored frames of the rows that agree (after
steps 500 and 1000), and every row's frames after steps 50 and 100 (before any landing) to 1e-11.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.sim import kernel
from tests.sim.test_kernel import DATA, chain, relative_error
from tests.sim.test_kernel_reference import DETAILS, stored

B = 16  # rows
STEPS = 1000
EVERY = 10
KINDS = ("hold", "sine", "reflex")


def load(name: str):
    if name == "kitchen_sink":
        return creature.load(str(DATA / "kitchen_sink.toml"))
    if name.startswith("chain"):
        return creature.loads(chain(int(name[5:])), source=name)
    return stored(name)


def model(name: str):
    return sim.compile_creature(load(name))


def random_params(kind: str, m, rows: int = B, seed: int = 1) -> Any:
    """Parameters of ``rows`` controllers of ``kind`` for model ``m`` (the engine's layout)."""
    rng = np.random.default_rng(seed)
    A, S = len(m.structure.actuators), m.structure.n_sensors
    if kind == "hold":
        return rng.uniform(0, 1, (rows, A))
    if kind == "sine":
        return np.concatenate([rng.uniform(-np.pi, np.pi, (rows, A)), rng.uniform(0.5, 3.0, (rows, 1))], 1)
    return rng.uniform(-1, 1, (rows, A, S)), rng.uniform(0, 1, (rows, A))


def at_rest(m, rows: int = B, q0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The state at rest at q0 [D] (default: the start pose of ``m``), repeated over ``rows``:
    (q, p, anchor)."""
    s0 = sim.make_state(m, q0)
    q, p, anchor = (np.repeat(np.asarray(x)[None], rows, 0) for x in (s0.q, s0.p, s0.anchor))
    return q, p, anchor


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", ["bounder", "kitchen_sink", "crawler", "fish", "cart"])
def test_each_controller_kind_agrees_with_the_engines_to_round_off(name, kind):
    # 16 rows of random_params(kind, m) (seed 1), 1000 steps, frames every 10 steps
    m = model(name)
    ref = lambda f: DETAILS[f"open/{name}/{kind}/{f}"]
    par = random_params(kind, m)
    k = kernel.run_open(kernel.pack(m, 0), kind, par, *at_rest(m, q0=ref("q0")), STEPS, every=EVERY)
    err = relative_error(ref("q"), k["q"])
    assert np.median(err) < 1e-11 and np.sum(err < 1e-9) >= 3 * B // 4, np.sort(err)
    ok = err < 1e-9
    early, late = [4, 9], [49, 99]  # the frames after steps 50 and 100, 500 and 1000
    np.testing.assert_allclose(k["frames_q"][:, early], ref("early_q"), rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(k["p"][ok], ref("p")[ok], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(k["qd"][ok], ref("qd")[ok], rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(k["t"], ref("t"), rtol=0, atol=1e-12)
    assert k["frames_q"].shape == (B, int(ref("n_frames")), m.structure.ndof) == (B, STEPS // EVERY, m.structure.ndof)
    np.testing.assert_allclose(k["frames_q"][ok][:, late], ref("late_q")[ok], rtol=1e-7, atol=1e-8)
    np.testing.assert_array_equal(k["frames_bits"][ok][:, late], ref("late_bits")[ok])
    np.testing.assert_allclose(k["frames_u"][ok][:, late], ref("late_u")[ok], rtol=0, atol=1e-12)
    if kind == "hold":
        assert np.array_equal(k["frames_u"], np.repeat(par[:, None], STEPS // EVERY, 1))
    assert set(k) == {"q", "p", "anchor", "t", "dmax", "qd", "frames_q", "frames_qd", "frames_bits", "frames_u"}
    assert np.abs(ref("q") - ref("q0")).max() > 1e-3  # the runs moved


@pytest.mark.parametrize("name", ["bounder", "crawler", "kitchen_sink"])
def test_the_gpus_form_runs_every_kind_bit_for_bit_as_the_simd_tiles(name):
    # the kitchen sink: points off a link's axis, whose rotation GCC's SLP vectorizer once fused
    # in the scalar form only (see kernel.cpp)
    from sanlab import descriptors
    from sanlab.metrics import Metric
    from tests.sim.test_kernel import observe_of

    spec = load(name)
    m = sim.compile_creature(spec, dtype="float64")
    ob = observe_of(Metric.for_creature(spec), descriptors.Descriptors.for_creature(m))
    pk = kernel.pack(m, 0)
    for kind in KINDS:
        par = random_params(kind, m, 11, seed=2)
        out = [kernel.run_open(pk, kind, par, *at_rest(m, 11), 400, t0=0.125, observe=ob, every=50, scalar=s)
               for s in (False, True)]
        assert out[0].keys() == out[1].keys() and "acc" in out[0]
        for key in out[0]:
            assert np.array_equal(out[0][key], out[1][key], equal_nan=True), (kind, key)


def test_a_run_continued_from_its_time_steps_as_one_call():
    # the sine's clock is the rollout's time: two calls (the second from the first's t) are one
    m = model("bounder")
    pk = kernel.pack(m, 0)
    par = random_params("sine", m)
    whole = kernel.run_open(pk, "sine", par, *at_rest(m), 600)
    half = kernel.run_open(pk, "sine", par, *at_rest(m), 250)
    rest = kernel.run_open(pk, "sine", par, half["q"], half["p"], half["anchor"], 350, t0=half["t"])
    for key in ("q", "p", "anchor", "t"):
        assert np.array_equal(rest[key], whole[key]), key
    assert not np.array_equal(half["q"], whole["q"])


def test_the_sine_reads_the_rows_time_from_t0():
    m = model("cart")
    par = random_params("sine", m)
    t0 = np.linspace(0.0, 2.0, B)
    k = kernel.run_open(kernel.pack(m, 0), "sine", par, *at_rest(m), 3, t0=t0, every=1)
    dt = float(m.structure.dt)
    for n in range(3):
        t = t0 + n * dt
        u = 0.5 + 0.5 * np.sin(2 * np.pi * par[:, -1:] * t[:, None] + par[:, :-1])
        np.testing.assert_allclose(k["frames_u"][:, n], u, rtol=0, atol=1e-13)  # 1 ulp of an angle of 40 rad
    np.testing.assert_allclose(k["t"], t0 + 3 * dt, rtol=0, atol=1e-15)


def test_held_activations_move_a_row_as_sim_step_does():
    # the Gymnasium env's use: one step at a time with external actions, row by row
    m = model("twolink")
    pk = kernel.pack(m, 0)
    q, p, anchor = at_rest(m, 2)
    u = np.array([[0.0] * len(m.structure.actuators), [1.0] * len(m.structure.actuators)])
    s = sim.make_state(m)
    for _ in range(5):
        k = kernel.run_open(pk, "hold", u, q, p, anchor, 1)
        q, p, anchor = k["q"], k["p"], k["anchor"]
        s = sim.step(m, s, u[1])
    np.testing.assert_allclose(q[1], s.q, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(p[1], s.p, rtol=1e-12, atol=1e-14)
    assert not np.allclose(q[0], q[1])


def test_rows_with_their_own_numbers_step_under_open_controllers_as_alone():
    m = model("bounder")
    pk = kernel.pack(m, 0)
    par = random_params("hold", m)
    wf = np.repeat(pk.wf[None], B, 0)
    wf[:, kernel.W_DT] *= np.where(np.arange(B) % 2, 0.5, 1.0)
    mixed = kernel.run_open(pk, "hold", par, *at_rest(m), 300, rows={"wf": wf})
    for i in (0, 3, 8):
        alone = kernel.run_open(pk, "hold", par[i:i + 1], *at_rest(m, 1), 300, rows={"wf": wf[i:i + 1]})
        assert np.array_equal(alone["q"][0], mixed["q"][i]) and np.array_equal(alone["t"][0], mixed["t"][i]), i
    assert mixed["t"][1] == pytest.approx(mixed["t"][0] / 2)


def test_bad_arguments_to_run_open_are_refused_by_name():
    m = model("bounder")
    pk = kernel.pack(m, 0)
    A, S = len(m.structure.actuators), m.structure.n_sensors
    q, p, anchor = at_rest(m, 2)
    u = np.full((2, A), 0.5)
    cases = [
        (dict(kind="walk"), "kind"),
        (dict(params=np.full((2, A + 1), 0.5)), "params"),
        (dict(params=np.full((2, A), 1.5)), "params"),
        (dict(params=np.full((2, A), np.nan)), "params"),
        (dict(kind="sine", params=np.zeros((2, A))), "params"),
        (dict(kind="sine", params=np.full((2, A + 1), np.inf)), "params"),
        (dict(kind="reflex", params=np.zeros((2, A, S))), "params"),
        (dict(kind="reflex", params=(np.zeros((2, S, A)), np.zeros((2, A)))), "params\\[0\\]"),
        (dict(kind="reflex", params=(np.zeros((2, A, S)), np.zeros((2, S)))), "params\\[1\\]"),
        (dict(q=q[:, 1:]), "q"),
        (dict(p=p[:1]), "p"),
        (dict(anchor=anchor[:, :, :1]), "anchor"),
        (dict(steps=-1), "steps"),
        (dict(every=-2), "every"),
        (dict(rows={"lf": pk.lf}), "rows\\['lf'\\]"),
        (dict(rows={"follow": pk.follow}), "rows"),
        (dict(t0=np.zeros(3)), "t0"),
    ]
    for change, name in cases:
        args = dict(pk=pk, kind="hold", params=u, q=q, p=p, anchor=anchor, steps=3) | change
        with pytest.raises(ValueError, match=f"^{name}"):
            kernel.run_open(**args)
    assert kernel.run_open(pk, "hold", u, q, p, anchor, 3)["q"].shape == q.shape  # the unchanged call runs


@pytest.mark.parametrize("scalar", [False, True])
def test_a_call_leaves_the_callers_arrays_alone(scalar):
    # the kernel writes its state back in place: into copies (the scalar form's tiles of one lane
    # and a 1-D t0 once were views of the caller's arrays, and came back stepped)
    m = model("bounder")
    q, p, anchor = at_rest(m, 8)
    t0 = np.linspace(0.0, 1.0, 8)
    u = random_params("hold", m, 8)
    before = [x.copy() for x in (q, p, anchor, t0, u)]
    r = kernel.run_open(kernel.pack(m, 0), "hold", u, q, p, anchor, 50, t0=t0, scalar=scalar)
    assert all(np.array_equal(a, b) for a, b in zip((q, p, anchor, t0, u), before))
    assert not np.array_equal(r["q"], q)


# ------------------------------------------------------------------ inspectors


def configurations(m, rows: int = 6, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Random configurations q near the start pose and velocities qd [rows, D]."""
    rng = np.random.default_rng(seed)
    D = m.structure.ndof
    return np.asarray(m.params.q0) + rng.normal(0, 0.15, (rows, D)), rng.normal(0, 1.0, (rows, D))


INSPECTED = [("bounder", False), ("bounder", True), ("kitchen_sink", False), ("fish", False), ("crawler", False),
             ("chain6", False), ("chain6", True), ("bounder@rough", True), ("bounder@hill", False)]


def inspected(source: str):
    from tests.sim.test_kernel import _on

    name, _, terrain = source.partition("@")
    return sim.compile_creature(_on(load(name), terrain or "flat"))


@pytest.mark.parametrize("source, articulated", INSPECTED)
def test_the_inspectors_compute_what_the_engine_did(source, articulated):
    # six random configurations and velocities near the start pose (stored with the engine's values)
    m = inspected(source)
    ref = lambda f: DETAILS[f"inspect/{source}/{int(articulated)}/{f}"]
    pk = kernel.pack(m, 0, articulated=articulated)
    assert pk.wi[kernel.W_ARTICULATED] == int(articulated)
    q, qd = ref("q"), ref("qd")
    close = lambda a, b, tol=1e-12: np.testing.assert_allclose(a, b, rtol=tol, atol=tol)
    # poses: every link frame, contact, depth and the centre of mass
    kp = kernel.poses(pk, q)
    assert kp["links"].shape == (6, len(m.structure.links), 3) and kp["depth"].shape == (6, len(m.structure.contacts))
    for key in ("links", "contacts", "depth", "com"):
        close(kp[key], ref(key))
    if m.structure.plane == "horizontal":
        assert np.all(kp["depth"] == 1.0)
    # momenta (make_state's p = M qd) and back (velocity: M^-1 p, where M's conditioning costs a
    # digit: measured up to 1.2e-12 on the 6-link chain, 3e-14 on the bounder)
    p = kernel.momenta(pk, q, qd)
    close(p, ref("p"))
    close(kernel.velocity(pk, q, ref("p")), ref("velocity"), 1e-11)
    close(kernel.velocity(pk, q, p), qd, 1e-11)
    # energy, term by term
    ke = kernel.energy(pk, q, ref("p"))
    for key in ("kinetic", "gravity", "elastic"):
        close(ke[key], ref(key))
    assert np.all(ke["kinetic"] > 0)
    # the centre of mass and its velocity
    kc, kv = kernel.centre_of_mass(pk, q, ref("p"))
    close(kc, ref("com_x"))
    close(kv, ref("com_v"))
    # sensor values at several times (the eyes' follow point moves)
    t = np.linspace(0.0, 40.0, 6)
    assert np.array_equal(kernel.sense(pk, q, t), ref("bits"))


@pytest.mark.parametrize("name", ["kitchen_sink", "fish"])
def test_the_follow_point_is_the_engines(name):
    # the kitchen sink's path loops; the fish's does not (it stops at the end)
    m = model(name)
    t = np.linspace(-1.0, 120.0, 37)
    kf = kernel.follow_point(kernel.pack(m, 0), t)
    np.testing.assert_allclose(kf, DETAILS[f"follow/{name}"], rtol=1e-12, atol=1e-12)
    assert len({tuple(x) for x in kf.round(9)}) > 10  # it moved


def test_the_inspectors_gpu_form_and_mixed_rows_give_each_rows_own_values():
    m = model("kitchen_sink")
    pk = kernel.pack(m, 0)
    q, qd = configurations(m, 11)
    p = kernel.momenta(pk, q, qd)
    t = np.linspace(0.0, 9.0, 11)
    calls = {
        "poses": lambda **k: kernel.poses(pk, q, **k),
        "energy": lambda **k: kernel.energy(pk, q, p, **k),
        "momenta": lambda **k: kernel.momenta(pk, q, qd, **k),
        "velocity": lambda **k: kernel.velocity(pk, q, p, **k),
        "sense": lambda **k: kernel.sense(pk, q, t, **k),
        "follow_point": lambda **k: kernel.follow_point(pk, t, **k),
        "centre_of_mass": lambda **k: kernel.centre_of_mass(pk, q, p, **k),
    }
    flat = lambda x: np.concatenate([np.ravel(v) for v in (x.values() if isinstance(x, dict) else
                                                              x if isinstance(x, tuple) else [x])])
    for name, call in calls.items():
        assert np.array_equal(flat(call()), flat(call(scalar=True))), name
    # rows with their own masses and springs: each as its own creature would give
    scale = np.linspace(0.5, 2.0, 11)
    lf = np.repeat(pk.lf[None], 11, 0)
    lf[:, :, kernel.F_MASS] *= scale[:, None]
    pf = np.repeat(pk.pf[None], 11, 0)
    pf[:, :, 4] *= scale[:, None]  # linear springs' stiffness
    mixed = kernel.energy(pk, q, p, rows={"lf": lf, "pf": pf})
    for i in (0, 10):
        mi = m.with_params(mass=np.asarray(m.params.mass) * scale[i],
                           spr=np.asarray(m.params.spr) * np.array([scale[i], 1.0, 1.0]))
        alone = kernel.energy(kernel.pack(mi, 0), q[i:i + 1], p[i:i + 1])
        for key in mixed:
            assert mixed[key][i] == alone[key][0], (i, key)
    shared = kernel.energy(pk, q, p)
    assert mixed["kinetic"][0] != shared["kinetic"][0] and mixed["elastic"][10] != shared["elastic"][10]


def test_bad_arguments_to_the_inspectors_are_refused_by_name():
    m = model("bounder")
    pk = kernel.pack(m, 0)
    D = m.structure.ndof
    q = np.zeros((3, D))
    with pytest.raises(ValueError, match=r"^q:"):
        kernel.poses(pk, q[:, 1:])
    with pytest.raises(ValueError, match=r"^q:"):
        kernel.poses(pk, q[0])
    with pytest.raises(ValueError, match=r"^p:"):
        kernel.energy(pk, q, q[:2])
    with pytest.raises(ValueError, match=r"^qd:"):
        kernel.momenta(pk, q, q[:, :2])
    with pytest.raises(ValueError, match=r"^p:"):
        kernel.velocity(pk, q, np.zeros((3, D + 1)))
    with pytest.raises(ValueError, match=r"^p:"):
        kernel.centre_of_mass(pk, q, np.zeros(D))
    with pytest.raises(ValueError, match=r"^t:"):
        kernel.sense(pk, q, np.zeros(2))
    with pytest.raises(ValueError, match=r"^t:"):
        kernel.follow_point(pk, 1.0)
    with pytest.raises(ValueError, match=r"^rows\['lf'\]"):
        kernel.poses(pk, q, rows={"lf": pk.lf})
    assert kernel.sense(pk, q, 0.5).shape == (3, m.structure.n_sensors)  # one time for every row


def pattern_params(m, rows: int = B, seed: int = 2) -> np.ndarray:
    """``rows`` square-wave patterns for model ``m``: per actuator (phase, duty, low, high), then the period (s)."""
    rng = np.random.default_rng(seed)
    A = len(m.structure.actuators)
    per = np.stack([rng.uniform(0, 1, (rows, A)), rng.uniform(0.1, 0.9, (rows, A)), rng.uniform(0, 0.5, (rows, A)),
                    rng.uniform(0.5, 1, (rows, A))], 2).reshape(rows, 4 * A)
    return np.concatenate([per, rng.uniform(0.2, 1.0, (rows, 1))], 1)


def test_a_pattern_switches_each_actuator_on_its_own_clock():
    m = model("bounder")
    par = pattern_params(m)
    A = len(m.structure.actuators)
    t0 = np.linspace(0.0, 2.0, B)
    dt = float(m.structure.dt)
    n = int(1.05 / dt)  # over a whole period of the slowest (1 s)
    k = kernel.run_open(kernel.pack(m, 0), "pattern", par, *at_rest(m), n, t0=t0, every=1)
    phase, duty, low, high = (par[:, :4 * A].reshape(B, A, 4)[:, :, i] for i in range(4))
    period = par[:, -1:]
    t = t0[:, None] + np.arange(n)[None] * dt  # [B, F]
    x = t[:, :, None] / period[:, :, None] - phase[:, None]
    on = (x - np.floor(x)) < duty[:, None]
    u = np.where(on, high[:, None], low[:, None])
    edge = np.abs((x - np.floor(x)) - duty[:, None]) < 1e-9  # on the switching instant the last bit decides
    np.testing.assert_array_equal(np.where(edge, 0, k["frames_u"]), np.where(edge, 0, u))
    assert np.all(k["frames_u"].max(1) == high) and np.all(k["frames_u"].min(1) == low)  # every actuator switched


def test_a_pattern_is_the_same_alone_and_anywhere_in_a_batch():
    m = model("walker")
    par = pattern_params(m, rows=13)
    batch = sim.rollout(m, sim.PatternController(), par, 0.5)
    for i in (0, 7, 12):
        alone = sim.rollout(m, sim.PatternController(), par[i:i + 1], 0.5)
        np.testing.assert_array_equal(alone.state.q[0], batch.state.q[i])


@pytest.mark.parametrize("bad", ["period", "level"])
def test_a_pattern_refuses_a_period_or_level_it_cannot_play(bad):
    m = model("cart")
    par = pattern_params(m, rows=2)
    if bad == "period":
        par[1, -1] = 0.0
    else:
        par[0, 3] = 1.5
    with pytest.raises(ValueError, match="period must be > 0 and its levels lie in"):
        kernel.run_open(kernel.pack(m, 0), "pattern", par, *at_rest(m, 2), 3)
