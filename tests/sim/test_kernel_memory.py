"""The kernel under AddressSanitizer: every entry point, on creatures that exercise every table.

Two memory errors reached the kernel's first drafts (a tile's scratch counted apart from its
layout, and aligned vector loads from a caller's array) and only their symptoms caught them. Here
the kernel is built again with ``-fsanitize=address`` and driven, in a process without JAX (its
runtime does not load under the sanitizer), through ``run_san`` and ``run_open`` (every controller
kind; SIMD tiles and the scalar form, observers, frames, per-row tables, a continued run), every
inspector (``poses``, ``energy``, ``momenta``, ``velocity``, ``sense``, ``follow_point``,
``centre_of_mass``, both forms) and ``start``, in float64 and in float32 arithmetic; any out-of-bounds access ends that process with the
sanitizer's report.
"""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

HARNESS = """
import ctypes, pickle, sys
import numpy as np
from sanlab.sim import kernel as K, native
assert native.use(ctypes.CDLL(sys.argv[1])) is native._library()  # every call goes to the sanitizer's build
for c in pickle.load(open(sys.argv[2], "rb")):
    for pk in (c["pk"], c["pk"]._replace(dtype="float32")):  # both arithmetics
        c = {**c, "pk": pk}
        B, N = c["B"], c["N"]
        z = np.zeros((B, N))
        for scalar in (False, True):
            r = K.run_san(c["pk"], c["w"], c["k1"], c["k2"], c["q"], c["p"], c["a"], z, z, 120, observe=c["ob"],
                          every=7, rows=c["rows"], scalar=scalar)
            K.run_san(c["pk"], c["w"], c["k1"], c["k2"], r["q"], r["p"], r["anchor"], r["istate"], r["out"], 30,
                      acc=r["acc"], observe=c["ob"], scalar=scalar)
            for kind, par in c["open"].items():
                r = K.run_open(c["pk"], kind, par, c["q"], c["p"], c["a"], 90, observe=c["ob"], every=11, rows=c["rows"],
                               scalar=scalar)
                K.run_open(c["pk"], kind, par, r["q"], r["p"], r["anchor"], 20, t0=r["t"], acc=r["acc"], observe=c["ob"],
                           scalar=scalar)
            t = np.linspace(0.0, 5.0, B)
            K.poses(c["pk"], c["q"], rows=c["rows"], scalar=scalar)
            K.energy(c["pk"], c["q"], c["p"], rows=c["rows"], scalar=scalar)
            K.momenta(c["pk"], c["q"], c["p"], rows=c["rows"], scalar=scalar)
            K.velocity(c["pk"], c["q"], c["p"], rows=c["rows"], scalar=scalar)
            K.sense(c["pk"], c["q"], t, rows=c["rows"], scalar=scalar)
            K.follow_point(c["pk"], t, rows=c["rows"], scalar=scalar)
            K.centre_of_mass(c["pk"], c["q"], c["p"], rows=c["rows"], scalar=scalar)
        K.start(c["pk"], c["q"], seat=True)
print("clean")
"""


def _libasan() -> str | None:
    path = subprocess.run(["g++", "-print-file-name=libasan.so"], capture_output=True, text=True).stdout.strip()
    return path if path and os.path.isabs(path) and os.path.exists(path) else None


@pytest.mark.slow
def test_the_kernel_reads_and_writes_only_its_own_memory(tmp_path):
    from sanlab import creature, descriptors, sim
    from sanlab.metrics import Metric
    from sanlab.random_sans import random_san_params
    from sanlab.sim import kernel
    from tests.sim.test_kernel import DATA, chain, observe_of

    asan = _libasan()
    if shutil.which("g++") is None or asan is None:
        pytest.skip("needs g++ and its libasan (Debian: apt-get install g++)")
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    src = ROOT / "sanlab" / "sim" / "_kernel" / "kernel.cpp"
    subprocess.run(["g++", "-O1", "-g", "-march=native", "-ffp-contract=off", "-fno-math-errno", "-fopenmp", "-fPIC",
                    "-shared", "-std=c++17", "-fsanitize=address", "-fno-omit-frame-pointer", "-o",
                    str(tmp_path / f"_kernel_lib{suffix}"), str(src)], check=True)
    cases = []
    specs = [creature.load(n) for n in ("bounder", "crawler", "fish", "twolink")]
    specs += [creature.load(str(DATA / "kitchen_sink.toml")), creature.loads(chain(12), source="chain12")]
    for spec in specs:  # a batch of 13: tiles with a ragged last one
        m = sim.compile_creature(spec, dtype="float64")
        san, sp = random_san_params(spec, 13, 1, dtype="float64")
        s0 = sim.make_state(m)
        pk = kernel.pack(m, san.n_hidden)
        rep = lambda x: np.repeat(np.asarray(x)[None], 13, 0)
        A, S = len(m.structure.actuators), m.structure.n_sensors
        rng = np.random.default_rng(0)
        open_params = {"hold": rng.uniform(0, 1, (13, A)), "sine": rng.uniform(0, 2, (13, A + 1)),
                       "reflex": (rng.uniform(-1, 1, (13, A, S)), rng.uniform(0, 1, (13, A)))}
        cases.append(dict(pk=pk, w=np.asarray(sp.weights), k1=np.asarray(sp.k1), k2=np.asarray(sp.k2), q=rep(s0.q),
                          p=rep(s0.p), a=rep(s0.anchor), N=san.n_nodes, B=13, rows={"lf": rep(pk.lf)},
                          ob=observe_of(Metric.for_creature(spec), descriptors.Descriptors.for_creature(m)),
                          open=open_params))
    with open(tmp_path / "cases.pkl", "wb") as f:
        pickle.dump(cases, f)
    env = dict(os.environ, LD_PRELOAD=asan, ASAN_OPTIONS="detect_leaks=0:abort_on_error=0")
    out = subprocess.run([sys.executable, "-c", HARNESS, str(tmp_path / f"_kernel_lib{suffix}"), str(tmp_path / "cases.pkl")],
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and "clean" in out.stdout, out.stderr[-3000:]
