"""The engine-as-data spike (issue 46): the bounder's step as one kernel that reads the creature
as data, in three forms, against today's XLA engine, in one run.

The kernel (sanlab/sim/_kernel, ``c++``): C++ over GCC vector types, a tile of
``kernel.lanes()`` creatures per thread (one SIMD register per value), OpenMP over tiles, called
through ctypes; built by the package's install, in float64. The engine runs as the search does
(float32, one XLA device per core), and in float64 for the agreement figure. Two Numba forms
were measured beside it and dropped (commit 6ef5cad has them; docs/engine-history.md the figures).

Printed, each as a ratio to the engine in the same run (these machines vary 2x run to run):
- the first call of a creature no process has compiled (the bounder, and a 9-link chain): the
  engine traces and compiles it (no compile cache), the kernel only packs its tables; and in one
  process a never-seen chain's first simulation against its second (nothing compiled either
  time: the issue's "within 1.5x of its second");
- µs per step at batch 1, 32 and 2048 (random SANs, dt = 1 ms);
- against MuJoCo's own C rollout loop (``mujoco.rollout`` on the converted model, open-loop servo
  targets: benchmarks/mujoco_route.py): the bounder at batch 1 on one thread and at batch 2048 on
  every core, and each chain of the growth table;
- growth: ns per creature-step of N-link chains (benchmarks/chains.py) on the C++ kernel;
- agreement: the final states of 64 random SANs after 1000 steps, kernel against the engine in
  float64 (relative to the state's size): median and worst.

    python benchmarks/kernel_spike.py [--steps 2000] [--growth 2,4,8,16,32]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

FIRST = """
import sys, time; t0 = time.perf_counter()
sys.path.insert(0, {bench!r})
import numpy as np
import sanlab; sanlab.configure()
from sanlab import creature, sim
from sanlab.engine_report import random_san_params
from chains import chain_creature
spec = creature.load("bounder") if {links} == 0 else chain_creature({links})
san, sp = random_san_params(spec, 8, 0)
if {form!r} == "engine":
    import jax
    m = sim.compile_creature(spec)
    jax.block_until_ready(sim.rollout(m, san, sp, steps=1000).state.q)
else:
    import bench_kernels as bk
    bk.run({form!r}, spec, 8, 1000, 0)
print(time.perf_counter() - t0)
"""


def first_call(form: str, links: int) -> float:
    """Seconds from a fresh process's start to its first 1 s rollout of 8 SANs (no caches)."""
    import tempfile

    env = dict(os.environ, SANLAB_NO_COMPILE_CACHE="1")
    with tempfile.TemporaryDirectory() as tmp:
        env["NUMBA_CACHE_DIR"] = tmp  # a cold Numba compile too
        code = FIRST.format(bench=str(ROOT / "benchmarks"), links=links, form=form)
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000, help="steps per timed rollout at batch 1 and 32")
    ap.add_argument("--growth", default="2,4,8,16,32", help="chain lengths for the growth table")
    ap.add_argument("--skip-first", action="store_true", help="leave out the fresh-process first calls")
    args = ap.parse_args()

    import bench_kernels as bk

    import sanlab

    sanlab.configure()
    from sanlab import creature

    spec = creature.load("bounder")
    forms = ("c++",)
    if not args.skip_first:
        print("first call, fresh process, no compile caches (8 SANs, 1 s):")
        for links, label in ((0, "bounder"), (9, "9-link chain")):
            e = first_call("engine", links)
            line = f"  {label}: engine {e:.2f} s"
            for f in forms:
                k = first_call(f, links)
                line += f" | {f} {k:.2f} s ({e / k:.1f}x)"
            print(line, flush=True)
    print("a creature this process has never seen (8 SANs, 1 s), on the kernel, first and second time:")
    from chains import chain_creature

    for links in (9, 16):
        spec9 = chain_creature(links)
        first, second = bk.new_creature(spec9), bk.new_creature(spec9)
        print(f"  {links}-link chain: first {first:.3f} s, second {second:.3f} s (first/second {first / second:.2f})",
              flush=True)
    print("bounder, time per step (best of 3 after a warm-up):")
    ratios = {}
    for B, steps in ((1, args.steps), (32, args.steps), (2048, max(100, args.steps // 8))):
        e = bk.best(bk.prepared("engine", spec, B, steps, 0), 3)
        line = f"  batch {B}: engine (float32) {e / steps * 1e6:.2f} us"
        for f in forms:
            k = bk.best(bk.prepared(f, spec, B, steps, 0), 3)
            ratios[(f, B)] = e / k
            line += f" | {f} {k / steps * 1e6:.2f} us ({e / k:.2f}x)"
        print(line, flush=True)
    from mujoco_route import mujoco_c_loop_steps_per_s

    mj1 = mujoco_c_loop_steps_per_s(spec, batch=1, steps=4000, threads=1)
    mjb = mujoco_c_loop_steps_per_s(spec, batch=2048, steps=200)
    k1 = bk.best(bk.prepared("c++", spec, 1, 4000, 0), 3) / 4000
    kb = bk.best(bk.prepared("c++", spec, 2048, 200, 0), 3) / (2048 * 200)
    print(f"bounder against MuJoCo's C loop: batch 1 (one thread) {1e6 / mj1:.2f} us/step, c++ {k1 * 1e6:.2f} us "
          f"({1 / (k1 * mj1):.2f}x); batch 2048 {mjb / 1e6:.3f} M/s, c++ {1e-6 / kb:.3f} M/s ({1 / (kb * mjb):.1f}x)")
    print("growth, c++ kernel, batch 256, ns per creature-step (MuJoCo's C loop on the same chain, batch 64):")
    cost = {}
    for n in [int(x) for x in args.growth.split(",") if x]:
        steps = 200
        k = bk.best(bk.prepared("c++", chain_creature(n), 256, steps, 0), 2)
        cost[n] = k / (256 * steps) * 1e9
        mj = 1e9 / mujoco_c_loop_steps_per_s(chain_creature(n), batch=64, steps=1000)
        print(f"  {n} links: {cost[n]:.0f} ns, MuJoCo {mj:.0f} ns ({mj / cost[n]:.1f}x)", flush=True)
    if len(cost) > 1:
        lo, hi = min(cost), max(cost)
        print(f"  cost({hi})/cost({lo}) = {cost[hi] / cost[lo]:.1f}")
    err = bk.agreement(spec, 64, 1000)
    print(f"agreement with the engine, float64, 64 SANs x 1000 steps: median {np.median(err):.2g}, "
          f"worst {err.max():.2g} (relative)")
    print(" ".join(f"{f.replace('+', 'p').replace('-', '_')}_b{B}={ratios[(f, B)]:.2f}" for f, B in ratios))


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"({time.perf_counter() - t0:.0f} s)")
