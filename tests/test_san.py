"""The SAN controller: Figure 7's node, topology sizes, encoding."""

from __future__ import annotations

import numpy as np
import pytest

from sanlab import creature
from sanlab.san import San, SanParams

DT = 1e-3


def figure7(weights, k1, k2, sensor_seq, n_hidden):
    """Plain transcription of the paper's Figure 7 (and §4's actuator mapping), float64."""
    N, I = len(weights), len(weights[0])
    istate = [0.0] * N
    out = [0] * N
    us = []
    for bits in sensor_seq:
        inputs = list(bits) + out
        sums = [sum(inputs[i] * weights[j][i] for i in range(I)) for j in range(N)]
        new_out = list(out)
        for j in range(N):
            istate[j] += (k1[j] if sums[j] > 0 else k2[j]) * DT
            istate[j] = min(1.0, max(0.0, istate[j]))
            if new_out[j] == 1 and istate[j] == 0.0:
                new_out[j] = 0
            if new_out[j] == 0 and istate[j] == 1.0:
                new_out[j] = 1
        out = new_out
        us.append([(min(2, max(-2, s)) + 2) / 4 for s in sums[n_hidden:]])
    return np.array(us)


def run_san(san, params, sensor_seq):
    """``San.step`` over a sequence of sensor values from rest: (u [T, A], out [T, N])."""
    istate = out = np.zeros(san.n_nodes)
    us, outs = [], []
    for bits in sensor_seq:
        istate, out, u = san.step(params, istate, out, np.asarray(bits, np.float64), DT)
        us.append(u)
        outs.append(out)
    return np.array(us), np.array(outs)


def single_node(delay_on=0.1, delay_off=0.05):
    """One sensor feeding one actuator node (weight +1), no hidden nodes."""
    san = San(1, 0, 1)
    w = np.array([[1, 0]])
    return san, san.params(w, delay_on, delay_off, "float64")


def test_node_turns_on_after_t_on_and_off_after_t_off():
    san, p = single_node(0.1, 0.05)
    seq = [[1]] * 300 + [[0]] * 300
    _, out = run_san(san, p, seq)
    on = np.flatnonzero(out[:, 0] == 1)
    assert on[0] + 1 == pytest.approx(100, abs=1)  # T_on = 1 / k1 = 0.1 s = 100 steps
    off = np.flatnonzero((out[:, 0] == 0) & (np.arange(600) >= 300))
    assert off[0] + 1 - 300 == pytest.approx(50, abs=1)  # T_off = -1 / k2 = 0.05 s


def test_node_does_not_chatter_under_momentary_contact():
    san, p = single_node(0.1, 0.1)
    # 20 ms touches every 60 ms never accumulate to T_on ...
    blips = ([[1]] * 20 + [[0]] * 40) * 10
    _, out = run_san(san, p, blips)
    assert out.max() == 0
    # ... and once on, 20 ms gaps do not switch it off (hysteresis), though a long one does
    seq = [[1]] * 150 + ([[0]] * 20 + [[1]] * 30) * 6 + [[0]] * 200
    _, out = run_san(san, p, seq)
    assert np.all(out[100:450, 0] == 1)
    assert out[-1, 0] == 0
    assert np.count_nonzero(np.diff(out[:, 0])) == 2  # exactly one on and one off


def test_network_matches_figure_7_transcription():
    spec = creature.load("bounder")
    san = San.for_creature(spec)
    rng = np.random.default_rng(7)
    for trial in range(3):
        w = san.random_weights(seed=trial, index=0)
        k1 = rng.uniform(7, 14, san.n_nodes)
        k2 = -rng.uniform(7, 14, san.n_nodes)
        p = SanParams(np.asarray(w, np.float64), np.asarray(k1), np.asarray(k2))
        seq = rng.integers(0, 2, (400, san.n_sensors))
        seq[100:200] = 1  # held inputs let the delays play out
        u, _ = run_san(san, p, seq.tolist())
        ref = figure7(w.astype(int).tolist(), k1.tolist(), k2.tolist(), seq.tolist(), san.n_hidden)
        np.testing.assert_array_equal(u, ref)
        assert len(np.unique(u)) > 2  # the actuators really move


def test_the_kernels_san_is_this_step_bit_for_bit():
    # the kernel's SAN (kernel.run_san, recorded every step) against San.step fed the sensor
    # values the kernel recorded: the same node states, outputs and activations, bit for bit
    from sanlab import sim
    from sanlab.random_sans import random_san_params
    from sanlab.sim import kernel

    spec = creature.load("bounder")
    m = sim.compile_creature(spec)
    san, sp = random_san_params(spec, 8, 3)
    B, N, T = 8, san.n_nodes, 600
    pk = kernel.pack(m, san.n_hidden)
    q, anchor = kernel.start(pk, np.repeat(np.asarray(m.params.q0)[None], B, 0), seat=False)
    k = kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, np.zeros_like(q), anchor, np.zeros((B, N)), np.zeros((B, N)),
                       T, every=1)
    istate = out = np.zeros((B, N))
    dt = float(spec.dt)
    for n in range(T):  # a frame: the network's state as the step begins, its sensors and its activations
        assert np.array_equal(out, k["frames_out"][:, n]) and np.array_equal(istate, k["frames_istate"][:, n]), n
        istate, out, u = san.step(sp, istate, out, k["frames_bits"][:, n], dt)
        assert np.array_equal(u, k["frames_u"][:, n]), n
    assert np.array_equal(out, k["out"]) and np.array_equal(istate, k["istate"])
    assert len(np.unique(k["frames_u"])) > 2 and np.ptp(k["frames_out"], axis=1).max() == 1  # the networks switched


def test_a_network_of_any_size_sums_its_inputs():
    san = San(20, 10, 3)  # 33 inputs
    w = san.random_weights(0, 0)
    p = san.params(w, 0.1, 0.1, "float64")
    bits = np.random.default_rng(0).integers(0, 2, 20).astype(float)
    _, _, u = san.step(p, np.zeros(13), np.zeros(13), bits, DT)
    x = np.concatenate([bits, np.zeros(13)])
    np.testing.assert_allclose(u, (np.clip(w.astype(float) @ x, -2, 2)[10:] + 2) / 4)


@pytest.mark.parametrize("name", creature.builtin_names())
def test_topology_sizes_of_every_builtin(name):
    spec = creature.load(name)
    san = San.for_creature(spec)
    S, A = len(spec.sensors), len(spec.actuators)
    H = spec.n_hidden
    assert (san.n_sensors, san.n_hidden, san.n_actuators) == (S, H, A)
    assert san.n_weights == (H + A) * (S + H + A)
    assert san.random_weights(0, 0).shape == (H + A, S + H + A)


def test_bounder_has_240_weights_in_70_bytes():
    san = San.for_creature(creature.load("bounder"))
    assert san.n_weights == 240  # 12 nodes x 20 inputs, as the paper says
    assert san.n_bytes == 70
    assert len(san.pack(san.random_weights(0, 0))) == 70


@pytest.mark.parametrize("seed", range(5))
def test_encoding_round_trips(seed):
    san = San.for_creature(creature.load("bounder"))
    w = san.random_weights(seed, 3)
    text = san.encode(w)
    assert text.startswith("san1-8-8-4-") and text.isascii() and " " not in text
    np.testing.assert_array_equal(san.decode(text), w)
    np.testing.assert_array_equal(san.unpack(san.pack(w)), w)
    extremes = np.full_like(w, 2), np.full_like(w, -2)
    for e in extremes:
        np.testing.assert_array_equal(san.decode(san.encode(e)), e)


def test_encoding_rejects_other_topologies_and_garbage():
    bounder = San.for_creature(creature.load("bounder"))
    cart = San.for_creature(creature.load("cart"))
    text = cart.encode(cart.random_weights(0, 0))
    with pytest.raises(ValueError, match="sensors/hidden/actuators"):
        bounder.decode(text)
    with pytest.raises(ValueError, match="expected an encoding"):
        bounder.decode("hello")
    ascii_sizes = bounder.encode(bounder.random_weights(0, 0))
    for odd in (ascii_sizes.replace("san1-8-", "san1-\u0668-", 1),  # an Arabic-Indic eight
                ascii_sizes.replace("san1-8-", "san1-" + "8" * 5000 + "-", 1)):  # past int()'s limit
        with pytest.raises(ValueError, match="expected an encoding"):
            bounder.decode(odd)
    with pytest.raises(ValueError):
        bounder.pack(np.full((12, 20), 3))


def test_random_weights_are_per_index_streams():
    san = San(8, 8, 4)
    a = san.random_weights(1, 5)
    assert np.array_equal(a, san.random_weights(1, 5))
    assert not np.array_equal(a, san.random_weights(1, 6))
    assert not np.array_equal(a, san.random_weights(2, 5))
    allw = np.stack([san.random_weights(0, i) for i in range(200)])
    assert set(np.unique(allw)) == {-2, -1, 0, 1, 2}
