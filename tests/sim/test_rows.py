"""The stepping API that the layers above use instead of the kernel: ``sim.Rows`` (what a
Gymnasium environment steps) and ``sim.poses(..., params_batched=True)`` (a design batch's bodies)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.metrics import Metric
from sanlab.sim.state import start_states


def test_rows_stepped_in_pieces_are_the_rollout_in_one_call_bit_for_bit():
    spec = creature.load("bounder")
    m = sim.compile_creature(spec)
    metric = Metric.for_creature(spec)
    rng = np.random.default_rng(4)
    u = rng.uniform(0, 1, (3, len(spec.actuators)))
    whole = sim.rollout(m, sim.ConstantController(), u, steps=60, observer=metric)
    rows = sim.Rows(m, 3, observe=metric.observe())
    rows.restart(np.ones(3, bool), np.repeat(np.asarray(m.params.q0, np.float64)[None], 3, 0), np.zeros(3, bool))
    for _ in range(3):
        rows.step(u, 20)
    for a, b in ((rows.q, whole.state.q), (rows.p, whole.state.p), (rows.qd, whole.state.qd),
                 (rows.anchor, whole.state.anchor), (rows.t, whole.state.t)):
        np.testing.assert_array_equal(a, b)
    got = metric.collect(rows.columns())
    for a, b in zip(got, whole.acc, strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    np.testing.assert_array_equal(rows.bits(), sim.sense(m, whole.state.q, whole.state.t))
    np.testing.assert_array_equal(rows.finite(), whole.finite)
    rows.qd[1, 0], rows.p[2, 0] = 2e4, np.nan  # blown up: as a rollout's end judges it
    assert rows.finite().tolist() == [True, False, False]


def test_rows_restart_only_the_masked_rows_and_refuse_columns_without_an_observer():
    m = sim.compile_creature(creature.load("twolink"))
    rows = sim.Rows(m, 2)
    q0 = np.repeat(np.asarray(m.params.q0, np.float64)[None], 2, 0)
    rows.restart(np.ones(2, bool), q0, np.ones(2, bool))
    rows.step(np.full((2, 1), 0.7), 15)
    moved = rows.q.copy()
    rows.restart(np.array([False, True]), q0, np.ones(2, bool))
    np.testing.assert_array_equal(rows.q[0], moved[0])
    assert rows.t.tolist() == [pytest.approx(0.015), 0.0]
    np.testing.assert_array_equal(rows.q[1], start_states(m, q0[:1]).q[0])
    np.testing.assert_array_equal(rows.p[1], 0.0)
    with pytest.raises(ValueError, match="accumulate nothing"):
        rows.columns()
    with pytest.raises(ValueError, match="n: expected a number of rows >= 1"):
        sim.Rows(m, 0)


def test_poses_of_a_batch_of_bodies_place_each_row_on_its_own_body():
    m = sim.compile_creature(creature.load("luxo"))
    p = m.params
    B = 3
    bm = m.with_params(**{f.name: np.broadcast_to(np.asarray(getattr(p, f.name)), (B, *np.shape(getattr(p, f.name))))
                          for f in dataclasses.fields(p)})
    com = np.asarray(p.com) * np.array([1.0, 1.3, 0.7])[:, None, None]
    anchor = np.asarray(p.anchor) * np.array([1.0, 1.2, 0.9])[:, None, None]
    bm = bm.with_params(com=com, anchor=anchor)
    q = np.repeat(np.asarray(p.q0, np.float64)[None], B, 0)
    got = sim.poses(bm, q, params_batched=True)
    for b in range(B):
        one = sim.poses(m.with_params(com=com[b], anchor=anchor[b]), q[b])
        for k in one:
            np.testing.assert_array_equal(got[k][b], one[k])
    assert not np.array_equal(got["contacts"][0], got["contacts"][1])
    with pytest.raises(ValueError, match=r"q: expected shape \(B, "):
        sim.poses(bm, q[0], params_batched=True)
