"""GPU benchmark: the bounder's closed-loop rollout on a CUDA device, over a sweep of batch sizes.

The same job as ``benchmarks/engine.py`` (the built-in bounder, dt = 1 ms, random sensor-actuator
networks evaluated every step inside the compiled step), on one GPU: for each batch size it
prints creature-steps per second (the best of ``--repeats`` timed rollouts after a compile call),
the first call's seconds (compile included) and the device memory the run peaked at.

    python benchmarks/gpu.py [--batches 1000,10000,100000,1000000] [--steps 2000] [--fence auto]

Needs a JAX with a CUDA backend (``jax[cuda12]``/``jax[cuda13]``); the tests never do. The last
line is ``gpu=<name> best_steps_per_s=<x> at_batch=<n>``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").strip().split("\n")[0])
    ap.add_argument("--batches", default="1000,10000,100000,1000000")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--creature", default="bounder")
    ap.add_argument("--fence", choices=["auto", "on", "off"], default="auto",
                    help="XLA fusion fences (see sim.rollout); auto: the platform's default")
    args = ap.parse_args()

    import sanlab

    sanlab.configure()
    import jax

    from sanlab import creature, sim
    from sanlab.engine_report import random_san_params

    dev = jax.devices()[0]
    if dev.platform != "gpu":
        raise SystemExit(f"no GPU: JAX sees {dev.platform} ({dev.device_kind})")
    spec = creature.load(args.creature)
    model = sim.compile_creature(spec)
    fence = None if args.fence == "auto" else args.fence == "on"
    best_rate, best_batch = 0.0, 0
    print(f"{dev.device_kind}: {spec.name}, {args.steps} steps per rollout, dt = {spec.dt * 1e3:g} ms")
    print(f"{'batch':>9} {'M creature-steps/s':>19} {'first call (s)':>15} {'peak memory (GiB)':>18}")
    for batch in (int(b) for b in args.batches.split(",")):
        san, params = random_san_params(spec, batch, seed=0)
        kw = {} if fence is None else {"fence": fence}
        t0 = time.perf_counter()
        jax.block_until_ready(sim.rollout(model, san, params, steps=args.steps, **kw).state.q)
        first = time.perf_counter() - t0
        best = float("inf")
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(sim.rollout(model, san, params, steps=args.steps, **kw).state.q)
            best = min(best, time.perf_counter() - t0)
        rate = batch * args.steps / best
        stats = dev.memory_stats() or {}
        peak = stats.get("peak_bytes_in_use", 0) / 2**30
        print(f"{batch:>9} {rate / 1e6:>19.1f} {first:>15.1f} {peak:>18.2f}", flush=True)
        if rate > best_rate:
            best_rate, best_batch = rate, batch
    print(f"gpu={dev.device_kind.replace(' ', '_')} best_steps_per_s={best_rate:.3e} at_batch={best_batch}")


if __name__ == "__main__":
    main()
