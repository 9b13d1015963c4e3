"""Behaviour descriptors (sanlab.descriptors) on hand-made trajectories whose values are known,
then through the evaluator and the library.

The kernel accumulates the descriptors inside its rollout (``sanlab/sim/_kernel``); its inputs
cannot be made by hand, so :class:`Reference` does the same accumulation in NumPy, as the
module docstring of ``sanlab.descriptors`` defines it, on hand-made trajectories, and one test
holds it to the kernel: fed the kernel's own recorded frames, it gives the kernel's accumulators.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sanlab import creature, descriptors, sim
from sanlab.descriptors import EVENTS, Descriptors, cycle, values
from sanlab.evaluate import Evaluator
from sanlab.evaluate.ensemble import default_ensemble, search_key
from sanlab.sim import wrap_angle

G = 9.81


class Reference:
    """The descriptors' accumulation (what the kernel does before each step), in NumPy over rows."""

    def __init__(self, obs: Descriptors, rows: int, dt: float):
        self.obs, self.dt = obs, dt
        z = lambda: np.zeros(rows)
        self.steps, self.height, self.height2, self.turn, self.angle, self.airborne, self.joint_speed = (z() for _ in range(7))
        self.duty = np.zeros((rows, len(obs.touch)))
        self.word, self.candidate, self.changes = (np.full(rows, -1), np.full(rows, -1), np.zeros(rows, int))
        self.since = z()
        self.words, self.times = np.zeros((rows, EVENTS), int), np.zeros((rows, EVENTS))

    def update(self, t, y, air, th, joint_rates, bits) -> None:
        """One step's inputs, each [rows] (joint_rates [rows, J], bits [rows, S]): time (s), the
        COM's height above the ground under it (m), no contact touching, the root's angle (rad)."""
        o = self.obs
        if o.root >= 0:
            self.turn = self.turn + np.where(self.steps > 0, wrap_angle(th - self.angle), 0.0)
            self.angle = th
        if o.joints:
            self.joint_speed = self.joint_speed + np.mean(np.abs(joint_rates), axis=1)
        if o.touch:
            self.duty = self.duty + bits[:, list(o.touch)]
        if 0 < o.n_sensors <= descriptors.MAX_SENSORS:
            w = np.sum(np.where(bits > 0.5, 1 << np.arange(o.n_sensors), 0), axis=1)
            self.since = np.where(w == self.candidate, self.since, t)
            self.candidate = w
            # a word comes into force once it has lasted DEBOUNCE_S
            new = (w != self.word) & (t - self.since + self.dt >= descriptors.DEBOUNCE_S)
            rows, slot = np.flatnonzero(new), self.changes[new] % EVENTS
            self.words[rows, slot], self.times[rows, slot] = w[new], self.since[new]
            self.changes = self.changes + new
            self.word = np.where(new, w, self.word)
        self.steps = self.steps + 1
        self.height, self.height2 = self.height + y, self.height2 + y * y
        self.airborne = self.airborne + air

    def acc(self) -> descriptors.DescriptorAcc:
        return descriptors.DescriptorAcc(self.steps, self.height, self.height2, self.turn, self.angle, self.airborne,
                                         self.duty, self.joint_speed, self.word, self.candidate, self.since, self.words,
                                         self.times, self.changes)


def observe(obs: Descriptors, seconds: float, dt: float, path) -> tuple[dict, str | None]:
    """Run the accumulation over a hand-made trajectory: ``path(t)`` -> (x, y, angle, rate, joint
    rates [J], touching (bool), bits [S]) of one body on flat ground, sampled every ``dt``."""
    ref = Reference(obs, 1, dt)
    n = int(round(seconds / dt))
    x0 = path(0.0)[0]
    for k in range(n):
        t = k * dt
        x, y, th, w, joints, touching, bits = path(t)
        ref.update(np.array([t]), np.array([y]), np.array([not touching]), np.array([th]),
                   np.asarray(joints, float).reshape(1, -1), np.asarray(bits, float).reshape(1, -1))
    d, sig = values(obs, ref.acc(), np.array([path(seconds)[0] - x0]), seconds)
    return {k: v[0] for k, v in d.items()}, sig[0]


@pytest.mark.parametrize("name", ["bounder", "walker", "crawler"])
def test_the_kernel_accumulates_what_the_reference_does(name):
    # the reference fed the kernel's recorded frames (every step) and the inspectors' poses of
    # them: the kernel's descriptor accumulators, the sensor words exactly
    from sanlab.metrics import Metric
    from sanlab.random_sans import random_san_params
    from sanlab.sim import kernel
    from tests.sim.test_kernel import observe_of

    spec = creature.load(name)
    m = sim.compile_creature(spec)
    obs = Descriptors.for_creature(m)
    B, T = 8, 1500
    san, sp = random_san_params(spec, B, 2)
    pk = kernel.pack(m, san.n_hidden)
    q, anchor = kernel.start(pk, np.repeat(np.asarray(m.params.q0)[None], B, 0), seat=False)
    N = san.n_nodes
    k = kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, np.zeros_like(q), anchor, np.zeros((B, N)), np.zeros((B, N)),
                       T, every=1, observe=observe_of(Metric.for_creature(spec), obs))
    dt = float(spec.dt)
    ref, t = Reference(obs, B, dt), np.zeros(B)
    vertical = m.structure.plane == "vertical"
    for n in range(T):
        po = kernel.poses(pk, k["frames_q"][:, n])
        c = po["com"]
        y = c[:, 1] - sim.terrain_height(m, c[:, 0])[0] if vertical else np.zeros(B)
        air = ~np.any(po["depth"] > 0, axis=1) if vertical else np.zeros(B, bool)
        th = po["links"][:, max(obs.root, 0), 2]
        ref.update(t, y, air, th, k["frames_qd"][:, n, list(obs.joints)], k["frames_bits"][:, n])
        t = t + dt
    got = dict(zip(kernel.ACC, k["acc"].T))
    close = lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    for f in ("steps", "height", "height2", "turn", "angle", "airborne", "joint_speed", "since"):
        close(getattr(ref, f), got[f])
    for f in ("word", "candidate", "changes"):
        assert np.array_equal(getattr(ref, f), got[f].astype(int)), f
    nt = len(obs.touch)
    close(ref.duty, k["acc"][:, len(kernel.ACC):len(kernel.ACC) + nt])
    words = k["acc"][:, len(kernel.ACC) + nt:len(kernel.ACC) + nt + EVENTS]
    assert np.array_equal(ref.words, words.astype(int))
    assert ref.changes.max() > 3  # the sensor words changed


def test_a_rolling_disc_turns_once_per_circumference_travelled():
    r, omega, T, dt = 0.1, math.pi, 4.0, 0.005  # half a turn per second, rolling to the right
    obs = Descriptors(root=0, joints=(), touch=(0,), n_sensors=1)
    d, sig = observe(obs, T, dt, lambda t: (r * omega * t, r, -omega * t, -omega, [], True, [1.0]))
    assert d["turns_per_s"] == pytest.approx(-0.5, abs=1e-3)
    assert d["vx_cm_s"] == pytest.approx(100 * r * omega, rel=1e-3)
    assert d["height_m"] == pytest.approx(r) and d["height_sd_m"] == pytest.approx(0.0, abs=1e-9)
    assert d["airborne"] == 0.0 and d["duty"][0] == 1.0
    assert sig == "1" and math.isnan(d["period_s"])  # the sensor never changed: the word it kept


def test_a_hopping_point_mass_is_airborne_between_landings():
    P, stance, T, dt, base = 0.5, 0.1, 5.0, 0.001, 0.05
    flight = P - stance

    def path(t):
        ph = t % P
        up = ph >= stance
        tau = ph - stance
        y = base + (0.5 * G * tau * (flight - tau) if up else 0.0)
        return 0.2 * t, y, 0.0, 0.0, [], not up, [0.0 if up else 1.0]

    d, sig = observe(Descriptors(root=0, joints=(), touch=(0,), n_sensors=1), T, dt, path)
    assert d["airborne"] == pytest.approx(flight / P, abs=2e-3)
    assert d["duty"][0] == pytest.approx(stance / P, abs=2e-3)
    mean = base + (flight / P) * G * flight ** 2 / 12  # the mean of a parabola's arc is 2/3 of its peak
    assert d["height_m"] == pytest.approx(mean, rel=1e-2)
    assert d["height_sd_m"] > 0.05
    assert sig == "0.1" and d["period_s"] == pytest.approx(P, abs=2 * dt)
    assert d["turns_per_s"] == 0.0 and d["vx_cm_s"] == pytest.approx(20.0, rel=1e-3)


def test_a_block_sliding_at_constant_speed():
    v = 0.3
    obs = Descriptors(root=0, joints=(0,), touch=(0,), n_sensors=1)
    d, sig = observe(obs, 2.0, 0.01, lambda t: (v * t, 0.05, 0.0, 0.0, [0.0], True, [1.0]))
    assert d["vx_cm_s"] == pytest.approx(30.0, rel=1e-6) and d["turns_per_s"] == 0.0
    assert d["airborne"] == 0.0 and d["joint_speed_rad_s"] == 0.0 and d["height_sd_m"] == pytest.approx(0, abs=1e-9)


def _alternating(P):
    """Two touch sensors, the left on for the first half of each cycle, the right from 0.4 to
    0.9 of it: words 10, 11, 01, 00 (one digit per sensor, left first)."""
    def path(t):
        if t < 1.0:  # a transient of another pattern first
            bits = [1.0, 1.0] if (t // 0.13) % 2 else [0.0, 1.0]
        else:
            ph = ((t - 1.0) / P) % 1.0
            bits = [1.0 if ph < 0.5 else 0.0, 1.0 if 0.4 <= ph < 0.9 else 0.0]
        return 0.0, 0.05, 0.0, 0.0, [3.0, -1.0], bits[0] + bits[1] > 0, bits
    return path


def test_a_periodic_contact_pattern_gives_its_cycle_and_period():
    P = 0.8
    obs = Descriptors(root=0, joints=(0, 1), touch=(0, 1), n_sensors=2)
    d, sig = observe(obs, 9.0, 0.002, _alternating(P))
    assert sig == "00.10.11.01"  # rotated to start at the smallest word
    assert d["period_s"] == pytest.approx(P, abs=0.005)
    assert d["joint_speed_rad_s"] == pytest.approx(2.0)
    late = 1.0 / 9.0  # the transient's share of the run
    assert d["duty"][0] == pytest.approx(0.5 * (1 - late) + late * 0.5, abs=0.02)


def test_a_pattern_that_does_not_repeat_has_no_signature():
    rng = np.random.default_rng(3)
    seq = rng.integers(0, 8, EVENTS)
    seq = [int(w) for k, w in enumerate(seq) if k == 0 or w != seq[k - 1]]
    times = np.linspace(0, 10, len(seq))
    ring = np.zeros(EVENTS, np.int32)
    ring[:len(seq)] = seq
    ring_t = np.zeros(EVENTS)
    ring_t[:len(seq)] = times
    sig, period = cycle(ring, ring_t, len(seq), 5.0, 3)
    assert sig is None and math.isnan(period)


def test_the_ring_wraps_and_keeps_the_last_changes():
    words = [1, 2, 3] * 40  # 120 changes, one every 0.1 s: the ring holds the last 64
    ring, ring_t = np.zeros(EVENTS, np.int32), np.zeros(EVENTS)
    for k, w in enumerate(words):
        ring[k % EVENTS], ring_t[k % EVENTS] = w, 0.1 * k
    sig, period = cycle(ring, ring_t, len(words), 6.0, 2)
    assert sig == "01.11.10" and period == pytest.approx(0.3)  # 1 -> "10", 2 -> "01", 3 -> "11"


def test_the_evaluator_stores_ensemble_medians_of_the_descriptors(tmp_path):
    spec = creature.load("bounder")
    ev = Evaluator(spec, seconds=2.0, batch=8, ensemble=default_ensemble(4))
    rng = np.random.default_rng(0)
    W = rng.integers(-2, 3, (8, ev.san.n_nodes, ev.san.n_inputs))
    keys = [search_key(0, i) for i in range(8)]
    sb = ev(W, None, keys)
    assert sb.descriptors is not None and set(descriptors.NAMES) <= set(sb.descriptors)
    n_touch = sum(s.kind == "touch" for s in spec.sensors)
    assert sb.descriptors["duty"].shape == (8, n_touch)
    ok = ~sb.nonfinite
    assert np.allclose(sb.descriptors["vx_cm_s"][ok], sb.dx_m[ok] / 2.0 * 100)
    assert np.all((sb.descriptors["airborne"][ok] >= 0) & (sb.descriptors["airborne"][ok] <= 1))
    again = ev(W[3:5], None, keys[3:5])  # a controller's descriptors depend on itself alone
    for name in descriptors.NAMES:
        np.testing.assert_array_equal(again.descriptors[name], sb.descriptors[name][3:5])
    row = sb.row(3)
    from sanlab.evaluate.records import Scores
    back = Scores.from_json(row.to_json())
    assert back.descriptors == row.descriptors and "signature" in back.descriptors
