"""This tree's engine against another commit's, on the same machine in the same process.

The engine benchmark's own yardstick (MuJoCo) does not say whether a change made sanlab slower;
this does. It extracts the other commit's ``sanlab`` package with ``git archive`` into a temporary
folder as a package named ``sanlab_rev`` (its own imports renamed), imports both, compiles the
creature under random closed-loop SANs on each (``engine_report.random_san_params``, seed 0) and
then times ``sim.rollout`` for ``--steps`` steps on the two engines in turn, ``--rounds`` times:
each engine's figure is its best call. Alternating call by call in one process, rather than
process by process, keeps a burst of load on a shared machine (they last seconds) from landing on
one engine only: best-of figures from separate processes moved the ratio by 1.5 x run to run.

    python benchmarks/compare.py [REV] [--creature bounder] [--batch 2048] [--steps 1000]
                                 [--rounds 15]

REV defaults to 46ea8a4, the velocity-form engine before sticking friction and momentum
(issue 10 asks that the engine lose no more than 20 % against it). It also says whether the two
engines' final states are bit-identical: a change meant only to make the step faster should
leave them so. The last line is ``ratio_vs_<rev>=<this tree's rate / REV's rate>``.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import os
import re
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

ALIAS = "sanlab_rev"


def extract(rev: str, into: Path) -> Path:
    """REV's ``sanlab`` package as the package ``sanlab_rev`` under ``into`` (returned: the folder
    to put on ``sys.path``). Raises CalledProcessError for an unknown rev."""
    archive = into / "tree.tar"
    with open(archive, "wb") as f:
        subprocess.run(["git", "-C", str(ROOT), "archive", rev, "sanlab"], stdout=f, check=True)
    with tarfile.open(archive) as t:
        t.extractall(into / "tree", filter="data")
    pkg = into / "tree" / ALIAS
    (into / "tree" / "sanlab").rename(pkg)
    for path in pkg.rglob("*.py"):
        text = path.read_text()
        text = re.sub(r"\bimport sanlab\b(?![.\w])", f"import {ALIAS} as sanlab", text)  # keeps its name
        text = re.sub(r"\bfrom sanlab\b", f"from {ALIAS}", text)
        text = re.sub(r"([\"'])sanlab\.", rf"\1{ALIAS}.", text)  # module names in strings
        path.write_text(text)
    return into / "tree"


def _setup(pkg: str, creature: str, batch: int, steps: int):
    """A call that rolls the creature out on package ``pkg``'s engine, returning final coordinates."""
    san_mod = importlib.import_module(pkg)
    if hasattr(san_mod, "configure"):
        san_mod.configure()
    else:  # older trees set JAX up from their _jax module
        importlib.import_module(f"{pkg}._jax").configure()
    import jax

    creature_mod = importlib.import_module(f"{pkg}.creature")
    sim = importlib.import_module(f"{pkg}.sim")
    report = importlib.import_module(f"{pkg}.engine_report")
    spec = creature_mod.load(creature)
    model = sim.compile_creature(spec)
    san, params = report.random_san_params(spec, batch, 0)
    return lambda: jax.block_until_ready(sim.rollout(model, san, params, steps=steps).state.q)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("rev", nargs="?", default="46ea8a4")
    ap.add_argument("--creature", default="bounder")
    ap.add_argument("--batch", type=int, default=2048)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--rounds", type=int, default=15)
    a = ap.parse_args()
    os.environ["SANLAB_NO_COMPILE_CACHE"] = "1"  # both compile here, neither reads the other's cache
    import numpy as np

    with tempfile.TemporaryDirectory(prefix="sanlab-compare-") as tmp:
        try:
            sys.path.insert(0, str(extract(a.rev, Path(tmp))))
        except subprocess.CalledProcessError:
            raise SystemExit(f"compare.py: no sanlab package at {a.rev!r} in {ROOT} (git archive failed)") from None
        runs = {"this tree": _setup("sanlab", a.creature, a.batch, a.steps),
                a.rev: _setup(ALIAS, a.creature, a.batch, a.steps)}
        digest = {k: hashlib.sha256(np.ascontiguousarray(run()).tobytes()).hexdigest() for k, run in runs.items()}
        best = {k: float("inf") for k in runs}
        for _ in range(a.rounds):
            for k, run in runs.items():
                t0 = time.perf_counter()
                run()
                best[k] = min(best[k], time.perf_counter() - t0)
    rate = {k: a.batch * a.steps / v for k, v in best.items()}
    same = digest["this tree"] == digest[a.rev]
    print("final states of the two engines: " + ("bit-identical" if same else "different (the arithmetic changed)"))
    print(f"{a.creature}, batch {a.batch} x {a.steps} steps, best of {a.rounds} alternating calls: this tree "
          f"{rate['this tree'] / 1e6:.2f} M creature-steps/s, {a.rev} {rate[a.rev] / 1e6:.2f} M")
    print(f"ratio_vs_{a.rev}={rate['this tree'] / rate[a.rev]:.3f}")


if __name__ == "__main__":
    main()
