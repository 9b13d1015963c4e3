"""Traced programs kept on disk (sanlab.sim.executables): a warm start loads the export instead of
tracing, and nothing about a result depends on where its program came from."""

from __future__ import annotations

import os
import subprocess
import sys
from collections import OrderedDict
from pathlib import Path

import jax
import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.engine_report import random_san_params
from sanlab.sim import executables

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def store(tmp_path, monkeypatch):
    monkeypatch.setattr(executables, "directory", lambda: tmp_path)
    monkeypatch.setattr(executables, "_loaded", OrderedDict())
    monkeypatch.delenv("SANLAB_NO_COMPILE_CACHE", raising=False)
    return tmp_path


@pytest.fixture(scope="module")
def bounder():
    spec = creature.load("bounder")
    return spec, sim.compile_creature(spec)


def test_a_program_is_stored_then_loaded_without_tracing(store, bounder, monkeypatch):
    spec, m = bounder
    san, p = random_san_params(spec, 5, seed=2)
    first = sim.rollout(m, san, p, steps=400)
    files = list(store.glob("*.stablehlo"))
    assert len(files) == 1
    monkeypatch.setattr(executables, "_loaded", OrderedDict())  # as a fresh process would be

    def no_trace(*a):
        raise AssertionError("traced again")

    monkeypatch.setattr(executables, "_export", no_trace)
    again = sim.rollout(m, san, p, steps=400)
    np.testing.assert_array_equal(again.state.q, first.state.q)
    np.testing.assert_array_equal(again.cstate.istate, first.cstate.istate)
    assert not np.array_equal(first.state.q, np.broadcast_to(m.params.q0, first.state.q.shape))  # it moved


def test_the_stored_program_gives_what_the_traced_one_gives(store, bounder, monkeypatch):
    spec, m = bounder
    san, p = random_san_params(spec, 7, seed=4)  # an odd batch: padding included
    cached = sim.rollout(m, san, p, steps=500)
    monkeypatch.setenv("SANLAB_NO_COMPILE_CACHE", "1")  # straight through jax.jit
    direct = sim.rollout(m, san, p, steps=500)
    np.testing.assert_array_equal(cached.state.q, direct.state.q)
    np.testing.assert_array_equal(cached.cstate.istate, direct.cstate.istate)


def test_different_inputs_or_creatures_get_different_keys(bounder):
    spec, m = bounder
    other = sim.compile_creature(creature.load("cart"))
    a = (m, np.zeros((8, 3), np.float32))
    base = executables.key(("x",), a)
    assert base is not None and base == executables.key(("x",), a)
    assert executables.key(("y",), a) != base  # configuration
    assert executables.key(("x",), (m, np.zeros((16, 3), np.float32))) != base  # shape
    assert executables.key(("x",), (m, np.zeros((8, 3), np.float64))) != base  # dtype
    assert executables.key(("x",), (other, np.zeros((8, 3), np.float32))) != base  # creature


def test_a_configuration_without_a_stable_repr_is_not_stored(store, bounder):
    class Opaque:  # the default repr names a memory address
        pass

    assert executables.key((Opaque(),), (np.zeros(3),)) is None
    f = jax.jit(lambda x: x + 1)
    out = executables.call((Opaque(),), f, (np.zeros(3, np.float32),))
    np.testing.assert_array_equal(out, np.ones(3))
    assert not list(store.iterdir())


def test_a_damaged_file_is_replaced(store):
    f = jax.jit(lambda x: x * 2)
    args = (np.arange(4, dtype=np.float32),)
    np.testing.assert_array_equal(executables.call(("double",), f, args), 2 * args[0])
    (path,) = store.glob("*.stablehlo")
    path.write_bytes(b"not a program")
    executables._loaded.clear()
    np.testing.assert_array_equal(executables.call(("double",), f, args), 2 * args[0])
    assert path.read_bytes() != b"not a program"


def test_the_directory_is_trimmed_oldest_first(store, monkeypatch):
    for i, age in enumerate([30, 20, 10]):
        p = store / f"{i}.stablehlo"
        p.write_bytes(b"x" * 100)
        os.utime(p, (1e9 - age, 1e9 - age))
    monkeypatch.setattr(executables, "MAX_BYTES", 250)
    executables._trim(store)
    assert sorted(p.name for p in store.iterdir()) == ["1.stablehlo", "2.stablehlo"]


@pytest.mark.slow
def test_a_second_process_loads_the_program(tmp_path):
    code = (
        "import sys, time; from sanlab import creature, sim; import jax.numpy as jnp;"
        "from sanlab.sim import executables;"
        "m = sim.compile_creature(creature.load('cart'));"
        "r = sim.rollout(m, sim.ConstantController(), jnp.full((1, 1), 0.7), steps=300);"
        "print(repr(float(r.state.q[0, 0])), sum(1 for _ in executables.directory().glob('*.stablehlo')))"
    )
    env = dict(os.environ, SANLAB_CACHE=str(tmp_path), PYTHONPATH=str(ROOT))
    env.pop("SANLAB_NO_COMPILE_CACHE", None)
    run = lambda: subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=300,
                                 capture_output=True, text=True).stdout.split()
    first, second = run(), run()
    assert first == second  # the same result, and no new program stored by the second process
    assert int(first[1]) >= 2  # the rollout and the seating of the cart on the ground


def test_programs_in_memory_are_bounded_least_recently_used_first(store, monkeypatch):
    monkeypatch.setattr(executables, "MAX_LOADED", 2)
    fs = {k: jax.jit(lambda x, k=k: x + k) for k in (1, 2, 3)}
    x = (np.zeros(2, np.float32),)
    for k in (1, 2, 1, 3):  # 2 is the least recently used when 3 arrives
        np.testing.assert_array_equal(executables.call((f"add{k}",), fs[k], x), np.full(2, k))
    assert [m[0] for m in executables._loaded] == [("add1",), ("add3",)]
