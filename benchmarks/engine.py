"""Engine benchmark: the bounder under random closed-loop SANs, sanlab vs MuJoCo, same run.

sanlab route: the built-in bounder, dt = 1 ms, random sensor-actuator networks (12 threshold
nodes x 20 integer weights, evaluated every step inside the compiled step), a batch of
``--batch`` creatures sharded over every core, ``--steps`` steps per rollout; the best of
``--repeats`` timed rollouts after a warm-up (compile) call. MuJoCo route: the same creature
converted to MJCF, C stepping, the same SAN in NumPy every step, one worker process per core
(benchmarks/mujoco_route.py).

Also measured: the cold compile time (persistent cache off) and the start-up of a fresh process
with a warm persistent cache (the time to the first result of a short rollout).

Then the latency of a small batch (32 bounders, per step), and the growth table: N-link chains
(benchmarks/chains.py) on both routes of the step's linear algebra (dense, articulated: see
sanlab/sim/articulated.py), each against MuJoCo's own C rollout loop (``mujoco.rollout``, one
thread per core) on the same converted chain. The long chains' cold compiles take minutes.

    python benchmarks/engine.py [--batch 2048] [--steps 2000] [--mujoco-seconds 5]
                                [--growth 2,4,8,16,32] [--dense-up-to 16]

Also the replay: one 6 s bounder replay at batch 1 recorded at 30 fps in a fresh process, cold
and with warm caches (the issue-29 goal: under 1 s warm).

The last line is ``ratio_vs_mujoco=<x> ratio_vs_mujoco_c_loop=<x> sanlab_steps_per_s=<y>
compile_s=<z> replay_warm_s=<w>``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

START = """
import time; t0 = time.perf_counter()
import sanlab; sanlab.configure()
import jax
from sanlab import creature, sim
from sanlab.engine_report import random_san_params
spec = creature.load("bounder")
m = sim.compile_creature(spec)
san, p = random_san_params(spec, {batch}, 0)
r = sim.rollout(m, san, p, steps=10)
jax.block_until_ready(r.state.q)
print(time.perf_counter() - t0)
"""


def sanlab_route(batch: int, steps: int, repeats: int) -> tuple[float, float]:
    """(creature-steps/s, cold compile seconds)."""
    os.environ["SANLAB_NO_COMPILE_CACHE"] = "1"  # this process measures the cold compile
    import sanlab

    sanlab.configure()
    import jax

    from sanlab import creature, sim
    from sanlab.engine_report import random_san_params

    spec = creature.load("bounder")
    model = sim.compile_creature(spec)
    san, params = random_san_params(spec, batch, seed=0)
    t0 = time.perf_counter()
    jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)
    first = time.perf_counter() - t0
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)
        best = min(best, time.perf_counter() - t0)
    rate = batch * steps / best
    compile_s = max(0.0, first - best)
    print(f"sanlab: {rate / 1e6:.2f} M creature-steps/s  (batch {batch} x {steps} steps in {best:.3f} s "
          f"on {len(jax.devices())} x {jax.devices()[0].platform}; cold compile {compile_s:.1f} s)")
    return rate, compile_s


def fresh_processes(code: str, n: int) -> list[float]:
    """The last number printed by ``code`` in ``n`` fresh interpreters in turn, sharing one new
    cache directory (so the first starts cold and the others warm)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, SANLAB_CACHE=cache, PYTHONPATH=str(ROOT))
        env.pop("SANLAB_NO_COMPILE_CACHE", None)
        return [float(subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True,
                                     text=True).stdout.split()[-1]) for _ in range(n)]


def cached_start(batch: int) -> float:
    """Seconds from a fresh interpreter to a first result, with a warm persistent cache."""
    cold, warm = fresh_processes(START.format(batch=batch), 2)
    print(f"start-up to first result: {cold:.1f} s with an empty cache, {warm:.1f} s with a warm one")
    return warm


REPLAY = """
import sanlab; sanlab.configure()
import time
from sanlab import creature, sim
from sanlab.engine_report import random_san_params
t0 = time.perf_counter()
spec = creature.load("{name}")
m = sim.compile_creature(spec)
san, p = random_san_params(spec, 1, 0)
r = sim.rollout(m, san, p, seconds=6.0, record_fps=30)
assert r.frames.q.shape[1] == 181
print(time.perf_counter() - t0)
"""


def replay(name: str = "bounder") -> float:
    """Seconds of one 6 s replay at batch 1 recorded at 30 fps (what render, the studio's playback
    and check --simulate do), in a fresh process after JAX's import, with an empty cache and then a
    warm one (the persistent XLA cache and the traced programs of sanlab.sim.executables)."""
    cold, *warm_runs = fresh_processes(REPLAY.format(name=name), 3)
    warm = min(warm_runs)
    print(f"replay: {name}, 6 s at batch 1, 30 fps: {cold:.1f} s with an empty cache, {warm:.2f} s with a warm one "
          "(compile_creature + rollout, after import)")
    return warm


def latency(batch: int = 32, steps: int = 2000, repeats: int = 3) -> float:
    """Microseconds per step of a small batch of bounders (a tuning chain, the studio's live mode)."""
    import jax

    from sanlab import creature, sim
    from sanlab.engine_report import random_san_params

    spec = creature.load("bounder")
    model = sim.compile_creature(spec)
    san, params = random_san_params(spec, batch, seed=0)
    jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)
        best = min(best, time.perf_counter() - t0)
    us = best / steps * 1e6
    print(f"latency: batch {batch}: {us:.1f} us per step ({best / (batch * steps) * 1e9:.0f} ns per creature-step)")
    return us


def growth(links: list[int], batch: int, steps: int, dense_up_to: int) -> None:
    """The growth table: N-link chains (benchmarks/chains.py) on both routes of the step's linear
    algebra, against MuJoCo's C rollout loop on the same converted chains."""
    import jax
    from chains import chain_creature
    from mujoco_route import mujoco_c_loop_steps_per_s

    from sanlab import sim
    from sanlab.engine_report import random_san_params

    print(f"growth: N-link chains, batch {batch} x {steps} steps; first call = compile + first rollout, "
          "cold cache; cost = ns per creature-step")
    print(f"{'links':>5}  {'route':<12}{'steps/s':>10}{'cost':>8}{'vs 2 links':>11}{'first call':>11}"
          f"{'mujoco C':>10}{'ratio':>7}")
    base: dict[str, float] = {}
    for n in links:
        spec = chain_creature(n)
        mj = mujoco_c_loop_steps_per_s(spec, batch=64, steps=1000)
        for route, art in (("dense", False), ("articulated", True)):
            if not art and n > dense_up_to:
                print(f"{n:>5}  {route:<12}{'(skipped: --dense-up-to)':>30}")
                continue
            model = sim.compile_creature(spec, articulated=art)
            san, params = random_san_params(spec, batch, seed=0)
            t0 = time.perf_counter()
            jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)
            first = time.perf_counter() - t0
            best = float("inf")
            for _ in range(2):
                t0 = time.perf_counter()
                jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)
                best = min(best, time.perf_counter() - t0)
            rate = batch * steps / best
            cost = 1e9 / rate
            base.setdefault(route, cost)
            print(f"{n:>5}  {route:<12}{rate / 1e6:>9.3f}M{cost:>8.0f}{cost / base[route]:>10.1f}x{first:>10.1f}s"
                  f"{mj / 1e6:>9.4f}M{rate / mj:>6.1f}x", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--batch", type=int, default=2048)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--mujoco-seconds", type=float, default=5.0)
    ap.add_argument("--skip-start", action="store_true", help="skip the start-up measurement")
    ap.add_argument("--growth", default="2,4,8,16,32", help="chain lengths of the growth table ('' skips it)")
    ap.add_argument("--growth-steps", type=int, default=200)
    ap.add_argument("--dense-up-to", type=int, default=16, help="longest chain timed on the dense route")
    a = ap.parse_args()
    os.environ["SANLAB_NO_COMPILE_CACHE"] = "1"  # every first call below is a cold compile

    from mujoco_route import mujoco_c_loop_steps_per_s, mujoco_steps_per_s

    mj = mujoco_steps_per_s(seconds_budget=a.mujoco_seconds)
    print(f"mujoco: {mj / 1e6:.3f} M creature-steps/s  (C stepping, SAN in NumPy, one process per core)")
    mjc = mujoco_c_loop_steps_per_s()
    print(f"mujoco C loop: {mjc / 1e6:.3f} M creature-steps/s  (mujoco.rollout, open-loop servo targets, "
          f"one thread per core)")
    rate, compile_s = sanlab_route(a.batch, a.steps, a.repeats)
    if not a.skip_start:
        cached_start(a.batch)
        replay_s = replay()
    else:
        replay_s = float("nan")
    latency()
    if a.growth:
        growth([int(n) for n in a.growth.split(",")], a.batch, a.growth_steps, a.dense_up_to)
    print(f"ratio_vs_mujoco={rate / mj:.1f} ratio_vs_mujoco_c_loop={rate / mjc:.1f} "
          f"sanlab_steps_per_s={rate:.0f} compile_s={compile_s:.1f} replay_warm_s={replay_s:.2f}")


if __name__ == "__main__":
    main()
