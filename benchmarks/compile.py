"""Compile-time benchmark: what recording frames costs a rollout's first call, against the same
rollout without recording, in the same run; and what a second recording of another length and
frame rate costs after it.

Each measurement is a fresh process with the compile caches off (``SANLAB_NO_COMPILE_CACHE=1``):
``compile_creature`` then one rollout of two random SANs for 2 s, timed from before the rollout
to its result (trace, lower, XLA compile, and 2 s of simulation that takes about 0.05 s). The
plain rollout is the reference; a recording one at 30 fps (a frame every 33 steps, 1 ms steps,
steps left over after the last frame) and at 100 fps (every 10 steps, none left over) should
cost little more, since the step is compiled once either way (``sim.rollout._batched``). The
goal: at most 1.3x. Measured 2026-12-03 on 2 cores: 1.06-1.15x (bounder, fish); the loop that
held two or three copies of the step measured 1.56-1.80x in the same way.

In the same process, a second recording then runs 1.5 s at 0.8 times the frame rate: its
duration and rate are inputs of the compiled program, and its frames fit the same buffers
(``sim.frame_capacity``), so it should compile nothing: goal at most 0.1x the plain rollout's
first call (before commit 2cd3ece it compiled the whole program again, about 1x).

    python benchmarks/compile.py [--creatures bounder,fish] [--repeats 2]

The last line is ``recording_compile_ratio=<worst of the creatures' medians>
another_recording_ratio=<worst>``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOAL = 1.3
AGAIN_GOAL = 0.1

CODE = """
import time
import numpy as np
import sanlab
sanlab.configure()
from sanlab.creature import load
from sanlab.san import San
from sanlab.sim import compile_creature, rollout
spec = load({name!r})
model = compile_creature(spec)
san = San.for_creature(spec)
p = san.params(np.stack([san.random_weights(0, i) for i in range(2)]), 0.1, 0.1)
t = time.perf_counter()
rollout(model, san, p, seconds=2.0, record_fps={fps!r})
print(time.perf_counter() - t)
if {fps!r}:
    t = time.perf_counter()
    rollout(model, san, p, seconds=1.5, record_fps=0.8 * {fps!r})
    print(time.perf_counter() - t)
"""


def first_calls(name: str, fps: float | None) -> list[float]:
    """Seconds of a fresh process's first rollout of ``name`` (no compile cache), and with
    ``fps`` of the second recording after it."""
    env = {**os.environ, "SANLAB_NO_COMPILE_CACHE": "1", "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", CODE.format(name=name, fps=fps)], capture_output=True, text=True,
                         env=env, check=True)
    return [float(x) for x in out.stdout.strip().splitlines()[-(2 if fps else 1):]]


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--creatures", default="bounder,fish")
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args()
    worst = worst_again = 0.0
    for name in a.creatures.split(","):
        ratios: dict[float, list[float]] = {30.0: [], 100.0: []}
        again: dict[float, list[float]] = {30.0: [], 100.0: []}
        for _ in range(a.repeats):  # plain and recording alternate, so a busy spell hits both
            for fps in ratios:
                [plain] = first_calls(name, None)
                first, second = first_calls(name, fps)
                ratios[fps].append(first / plain)
                again[fps].append(second / plain)
                print(f"{name}: plain {plain:.2f} s, {fps:g} fps {first:.2f} s ({first / plain:.2f}x), "
                      f"then 1.5 s at {0.8 * fps:g} fps {second:.2f} s ({second / plain:.2f}x)", flush=True)
        for fps, r in ratios.items():
            med, med_again = statistics.median(r), statistics.median(again[fps])
            worst, worst_again = max(worst, med), max(worst_again, med_again)
            print(f"{name} at {fps:g} fps: median {med:.2f}x the plain rollout's first call (goal <= {GOAL:g}x); "
                  f"another length and rate after it {med_again:.2f}x (goal <= {AGAIN_GOAL:g}x)")
    print(f"recording_compile_ratio={worst:.2f} another_recording_ratio={worst_again:.2f}")


if __name__ == "__main__":
    main()
