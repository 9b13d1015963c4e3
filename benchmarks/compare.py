"""This tree's engine against another commit's, on the same machine in the same run.

The engine benchmark's own yardstick (MuJoCo) does not say whether a change made sanlab slower;
this does. It extracts the other commit's ``sanlab`` package with ``git archive`` into a temporary
folder, then times both trees alternately, each in a fresh process that imports its own package
(``PYTHONPATH``) with the persistent compile cache off: the creature under random closed-loop
SANs (``engine_report.random_san_params``, seed 0), ``sim.rollout`` for ``--steps`` steps, the
best of ``--repeats`` calls after the compiling one. Each tree's figure is its best over
``--rounds`` processes, so a burst of load on a shared machine costs a round, not the result.
It also says whether the two engines' final states are bit-identical (a SHA-256 of the final
coordinates): a change meant only to make the step faster should leave them so.

    python benchmarks/compare.py [REV] [--creature bounder] [--batch 2048] [--steps 1000]
                                 [--repeats 5] [--rounds 3]

REV defaults to 46ea8a4, the velocity-form engine before sticking friction and momentum
(issue 10 asks that the engine lose no more than 20 % against it). The last line is
``ratio_vs_<rev>=<this tree's rate / REV's rate>``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

WORKER = """
import json, os, sys, time
os.environ["SANLAB_NO_COMPILE_CACHE"] = "1"
import sanlab
if hasattr(sanlab, "configure"):
    sanlab.configure()
else:  # older trees set JAX up from sanlab._jax
    from sanlab import _jax
    _jax.configure()
import jax
from sanlab import creature, sim
from sanlab.engine_report import random_san_params
name, batch, steps, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
spec = creature.load(name)
model = sim.compile_creature(spec)
san, params = random_san_params(spec, batch, 0)
run = lambda: jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)
import hashlib, numpy as np
digest = hashlib.sha256(np.ascontiguousarray(run()).tobytes()).hexdigest()
best = float("inf")
for _ in range(repeats):
    t0 = time.perf_counter()
    run()
    best = min(best, time.perf_counter() - t0)
print(json.dumps({"rate": batch * steps / best, "where": sanlab.__file__, "digest": digest}))
"""


def extract(rev: str, into: Path) -> Path:
    """REV's tree (its sanlab package) under ``into``; raises CalledProcessError for an unknown rev."""
    archive = into / "tree.tar"
    with open(archive, "wb") as f:
        subprocess.run(["git", "-C", str(ROOT), "archive", rev, "sanlab"], stdout=f, check=True)
    with tarfile.open(archive) as t:
        t.extractall(into / "tree", filter="data")
    return into / "tree"


def rate(tree: Path, a: argparse.Namespace) -> tuple[float, str]:
    """(creature-steps/s, SHA-256 of the final coordinates) of one fresh process on ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", WORKER, a.creature, str(a.batch), str(a.steps), str(a.repeats)],
                         env=env, cwd=tree, capture_output=True, text=True, check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    if not res["where"].startswith(str(tree)):
        raise SystemExit(f"the worker imported {res['where']}, not the tree under {tree}")
    return res["rate"], res["digest"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("rev", nargs="?", default="46ea8a4")
    ap.add_argument("--creature", default="bounder")
    ap.add_argument("--batch", type=int, default=2048)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="sanlab-compare-") as tmp:
        other = extract(a.rev, Path(tmp))
        best = {"this tree": 0.0, a.rev: 0.0}
        digests: dict[str, set] = {"this tree": set(), a.rev: set()}
        for r in range(a.rounds):
            for label, tree in (("this tree", ROOT), (a.rev, other)):
                x, digest = rate(tree, a)
                best[label] = max(best[label], x)
                digests[label].add(digest)
                print(f"round {r + 1}: {label:>10}: {x / 1e6:6.2f} M creature-steps/s", flush=True)
    same = digests["this tree"] == digests[a.rev] and len(digests[a.rev]) == 1
    print("final states of the two engines: " + ("bit-identical" if same else "different (the arithmetic changed)"))
    ratio = best["this tree"] / best[a.rev]
    print(f"{a.creature}, batch {a.batch} x {a.steps} steps, best of {a.rounds} rounds: this tree "
          f"{best['this tree'] / 1e6:.2f} M/s, {a.rev} {best[a.rev] / 1e6:.2f} M/s")
    print(f"ratio_vs_{a.rev}={ratio:.3f}")


if __name__ == "__main__":
    main()
