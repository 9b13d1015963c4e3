"""Gymnasium environments: sanlab's vector environment against Gymnasium's own Hopper-v5 on
MuJoCo, in the same run.

sanlab: ``gymnasium.make_vec("sanlab/Bounder-v0", num_envs=N, vectorization_mode=
"vector_entry_point")``, the built-in bounder (5 links, 4 servos, 8 touch and angle sensors)
in the batched simulator; one environment step is one simulator step, 1 ms. MuJoCo:
``gymnasium.make_vec("Hopper-v5", num_envs=N, vectorization_mode="sync")``, Gymnasium's
SyncVectorEnv over N MuJoCo hoppers (4 links, 3 motors; one environment step is its
frame_skip of 4 MuJoCo steps of 2 ms, 8 ms). Then each side's single environment
(``gymnasium.make``) stepped in a Python loop. After a warm-up (sanlab's compile) the four take
turns ``--rounds`` times, each stepped for ``--seconds / --rounds`` of wall time a turn with
random actions from a pool sampled beforehand, and each keeps its best turn; episodes that end
are reset (autoreset in the vector environments) inside the timed loop.

    python benchmarks/gym_env.py [--num-envs 256] [--seconds 6] [--rounds 3] [--creature bounder]

Environment steps per second count every sub-environment's step. The ratios are sanlab /
MuJoCo, measured in the same process in turns; ``vector_sim_time_ratio`` weighs each
step by the simulated time it covers (1 ms against 8 ms). The last line is
``vector_ratio=<x> single_ratio=<y> vector_sim_time_ratio=<z> sanlab_vector_steps_per_s=<a>
hopper_vector_steps_per_s=<b>``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def timed(env, vector: bool, seconds: float, pool: list) -> tuple[float, int]:
    """(environment steps per second, steps taken) of ``env`` over about ``seconds`` of wall
    time, continuing its episodes; a single ``env`` is reset whenever its episode ends."""
    n = env.num_envs if vector else 1
    steps, k = 0, 0
    t0 = time.perf_counter()
    end = t0 + seconds
    while True:
        for _ in range(16):  # check the clock every 16 calls
            _, _, terminated, truncated, _ = env.step(pool[k % len(pool)])
            k += 1
            steps += n
            if not vector and (terminated or truncated):
                env.reset()
        now = time.perf_counter()
        if now >= end:
            return steps / (now - t0), steps


def pool_of(space, size: int = 64) -> list:
    space.seed(0)
    return [space.sample() for _ in range(size)]


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--num-envs", type=int, default=256, help="sub-environments of each vector environment")
    ap.add_argument("--seconds", type=float, default=6.0, help="wall time each environment is stepped for in all (s)")
    ap.add_argument("--rounds", type=int, default=3, help="turns the environments take (each keeps its best)")
    ap.add_argument("--creature", default="bounder", help="sanlab's built-in creature (default: the bounder)")
    args = ap.parse_args()

    import gymnasium

    import sanlab.gym

    sanlab_id = f"sanlab/{args.creature.capitalize()}-v0"
    if sanlab_id not in sanlab.gym.ENV_IDS:
        raise SystemExit(f"--creature: expected one of {sorted(sanlab.gym.ENV_IDS.values())}, got {args.creature!r}")
    N = args.num_envs
    print(f"{os.cpu_count()} cores; {N} sub-environments; {args.seconds:g} s each in {args.rounds} turns")

    t0 = time.perf_counter()
    vec = gymnasium.make_vec(sanlab_id, num_envs=N, vectorization_mode="vector_entry_point")
    one = gymnasium.make(sanlab_id)
    envs = [("sanlab vector", vec, True), ("Hopper-v5 sync vector", gymnasium.make_vec("Hopper-v5", num_envs=N, vectorization_mode="sync"), True),
            ("sanlab single", one, False), ("Hopper-v5 single", gymnasium.make("Hopper-v5"), False)]
    pools = [pool_of(e.action_space) for _, e, _ in envs]
    for (_, e, _), pool in zip(envs, pools, strict=True):  # first-time costs fall here
        e.reset(seed=0)
        for a in pool[:4]:
            e.step(a)
    mine: Any = vec.unwrapped  # sanlab's vector env: its core and dt are not VectorEnv attributes
    core = mine.core
    print(f"made and warmed up in {time.perf_counter() - t0:.1f} s (sanlab vector: {core.rows} rows)")
    # the four take turns, --rounds times, each keeping its best round: a load that comes and
    # goes on a shared machine then weighs on both sides of a ratio alike
    best, total = [0.0] * len(envs), [0] * len(envs)
    for _ in range(args.rounds):
        for i, ((_, e, vector), pool) in enumerate(zip(envs, pools, strict=True)):
            rate, steps = timed(e, vector, args.seconds / args.rounds, pool)
            best[i], total[i] = max(best[i], rate), total[i] + steps
    unwrapped: list[Any] = [vec.unwrapped, envs[1][1].unwrapped.envs[0].unwrapped, one.unwrapped, envs[3][1].unwrapped]
    dts = [u.dt for u in unwrapped]
    rows = [(name, rate, steps, dt) for (name, _, _), rate, steps, dt in zip(envs, best, total, dts, strict=True)]
    for _, e, _ in envs:
        e.close()

    print(f"{'environment':<24}{'steps/s (best)':>16}{'steps':>12}{'sim s/step':>12}{'sim s/s':>12}")
    for name, rate, steps, dt in rows:
        print(f"{name:<24}{rate:>16,.0f}{steps:>12,}{dt:>12.4g}{rate * dt:>12,.1f}")
    (_, sv, _, sdt), (_, hv, _, hdt), (_, s1, _, _), (_, h1r, _, _) = rows
    print(f"vector_ratio={sv / hv:.2f} single_ratio={s1 / h1r:.2f} vector_sim_time_ratio={sv * sdt / (hv * hdt):.2f} "
          f"sanlab_vector_steps_per_s={sv:.0f} hopper_vector_steps_per_s={hv:.0f}")


if __name__ == "__main__":
    main()
