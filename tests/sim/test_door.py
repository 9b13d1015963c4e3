"""What enters the kernel is checked once, at its door (issue 57, item 5): step counts past its
int64, durations that are not finite, tables that would send it past a buffer."""

from __future__ import annotations

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.creature import CreatureError, loads, read_source
from sanlab.sim import kernel
from sanlab.sim.state import packed


@pytest.fixture(scope="module")
def cart():
    return sim.compile_creature(creature.load("cart"))


# ---------------------------------------------------------------- durations


@pytest.mark.parametrize("steps", [2**64 + 5, 2**63, -1, 2.5, float("nan"), float("inf"), True])
def test_a_step_count_the_kernel_cannot_hold_is_refused_not_wrapped(cart, steps):
    # 2**64 + 5 ran 5 steps: ctypes wrapped it to the kernel's int64
    with pytest.raises(ValueError, match=r"^steps: expected a whole number in \[0, 2\*\*63 - 1\]"):
        sim.rollout(cart, sim.ConstantController(), np.zeros((1, 1)), steps=steps)


@pytest.mark.parametrize("seconds", [1e300, float("inf"), float("nan"), -0.5])
def test_a_duration_beyond_the_kernel_or_not_finite_is_refused(cart, seconds):
    # 1e300 s ran 0 steps and said finite
    with pytest.raises(ValueError, match=r"^seconds: expected a duration >= 0"):
        sim.rollout(cart, sim.ConstantController(), np.zeros((1, 1)), seconds=seconds)


def test_the_kernels_own_entry_points_refuse_counts_past_int64(cart):
    pk = packed(cart)
    q = np.asarray(cart.params.q0, np.float64)[None]
    z = np.zeros_like(q)
    anchor = np.zeros((1, pk.ci.shape[0], 2))
    for kw in ({"steps": 2**63}, {"steps": 1, "every": 2**64 + 1}):
        with pytest.raises(ValueError, match=r"^(steps|every): expected a whole number"):
            kernel.run_open(pk, "hold", np.zeros((1, 1)), q, z, anchor, **kw)


def test_a_file_whose_evaluation_is_shorter_than_one_step_is_refused_naming_it():
    # it stored 0-step gaits scored 0 with no flag, though --seconds refused the same
    text, _ = read_source("cart")
    assert "seconds = 6.0" in text
    with pytest.raises(CreatureError, match=r"^short\.toml: evaluation\.seconds: expected at least one step of "
                                            r"dt = 0\.001 s, got 0\.0004$"):
        loads(text.replace("seconds = 6.0", "seconds = 0.0004", 1), "short.toml")
    assert loads(text.replace("seconds = 6.0", "seconds = 0.001", 1), "ok.toml").evaluation.seconds == 0.001


# ---------------------------------------------------------------- the tables


def _run(pk, scalar=False):
    q = np.asarray(pk.q0)[None]
    anchor = np.zeros((1, pk.ci.shape[0], 2))
    return kernel.run_open(pk, "hold", np.zeros((1, pk.ai.shape[0])), q, np.zeros_like(q), anchor, 3, scalar=scalar)


def test_a_follow_path_of_one_sample_is_refused_before_the_kernel_reads_past_it():
    # the kernel interpolates between a sample and the next: one sample read past the buffer (ASan)
    m = sim.compile_creature(creature.load("crawler"))
    pk = packed(m)._replace(follow=np.zeros((1, 2)))
    for scalar in (False, True):
        with pytest.raises(ValueError, match=r"^tables\.follow: expected a path of at least 2 samples, got 1"):
            _run(pk, scalar)
    with pytest.raises(ValueError, match=r"^tables\.follow"):
        kernel.follow_point(pk, np.zeros(1))
    _run(packed(m))  # the compiled path passes


@pytest.mark.parametrize("change,message", [
    (lambda pk: pk._replace(ci=np.full_like(pk.ci, 99)), r"^tables\.ci: expected indices in \[0, 2\)"),
    (lambda pk: pk._replace(li=np.where(np.arange(pk.li.shape[1]) == kernel.L_PARENT, 5, pk.li).astype(np.int32)),
     r"^tables\.li: expected each link's parent before it"),
    (lambda pk: pk._replace(lf=pk.lf[:, :-1]), r"^tables\.lf: expected float64 of shape \(2, 19\)"),
    (lambda pk: pk._replace(si=np.where(np.arange(4) == 0, 7, pk.si).astype(np.int32)), r"^tables\.si \(kinds\)"),
    (lambda pk: pk._replace(wi=pk.wi + np.array([9, 0, 0, 0, 0, 0], np.int32)), r"^tables\.wi \(terrain\)"),
])
def test_tables_that_would_send_the_kernel_past_a_buffer_are_refused_naming_the_table(cart, change, message):
    pk = change(packed(cart))
    with pytest.raises(ValueError, match=message):
        _run(pk)
    with pytest.raises(ValueError, match=message):
        kernel.poses(pk, np.asarray(pk.q0)[None])


def test_a_san_of_more_nodes_than_the_tables_hold_is_refused(cart):
    # the kernel writes node n's activation to actuator n - hidden: more nodes would write past them
    pk = packed(cart, 5)
    q = np.asarray(pk.q0)[None]
    N = 5 + 1 + 3
    with pytest.raises(ValueError, match=r"^istate: expected 6 nodes per row"):
        kernel.run_san(pk, np.zeros((1, N, pk.si.shape[0] + N)), np.ones((1, N)), -np.ones((1, N)), q,
                       np.zeros_like(q), np.zeros((1, pk.ci.shape[0], 2)), np.zeros((1, N)), np.zeros((1, N)), 2)
