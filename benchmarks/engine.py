"""Engine benchmark: the bounder under random closed-loop SANs, sanlab vs MuJoCo, same run.

sanlab route: the built-in bounder, dt = 1 ms, random sensor-actuator networks (12 threshold
nodes x 20 integer weights, evaluated every step inside the compiled step), a batch of
``--batch`` creatures sharded over every core, ``--steps`` steps per rollout; the best of
``--repeats`` timed rollouts after a warm-up (compile) call. MuJoCo route: the same creature
converted to MJCF, C stepping, the same SAN in NumPy every step, one worker process per core
(benchmarks/mujoco_route.py).

Also measured: the cold compile time (persistent cache off) and the start-up of a fresh process
with a warm persistent cache (the time to the first result of a short rollout).

    python benchmarks/engine.py [--batch 2048] [--steps 2000] [--mujoco-seconds 5]

The last line is ``ratio_vs_mujoco=<x> sanlab_steps_per_s=<y> compile_s=<z>``.
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


def cached_start(batch: int) -> float:
    """Seconds from a fresh interpreter to a first result, with a warm persistent cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, SANLAB_CACHE=cache, PYTHONPATH=str(ROOT))
        env.pop("SANLAB_NO_COMPILE_CACHE", None)
        code = START.format(batch=batch)
        run = lambda: float(subprocess.run([sys.executable, "-c", code], env=env, check=True,
                                           capture_output=True, text=True).stdout.split()[-1])
        cold, warm = run(), run()
    print(f"start-up to first result: {cold:.1f} s with an empty cache, {warm:.1f} s with a warm one")
    return warm


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--batch", type=int, default=2048)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--mujoco-seconds", type=float, default=5.0)
    ap.add_argument("--skip-start", action="store_true", help="skip the start-up measurement")
    a = ap.parse_args()

    from mujoco_route import mujoco_steps_per_s

    mj = mujoco_steps_per_s(seconds_budget=a.mujoco_seconds)
    print(f"mujoco: {mj / 1e6:.3f} M creature-steps/s  (C stepping, SAN in NumPy, one process per core)")
    rate, compile_s = sanlab_route(a.batch, a.steps, a.repeats)
    if not a.skip_start:
        cached_start(a.batch)
    print(f"ratio_vs_mujoco={rate / mj:.1f} sanlab_steps_per_s={rate:.0f} compile_s={compile_s:.1f}")


if __name__ == "__main__":
    main()
