"""Does a design's choice survive a fresh seed? The same bodies scored with each phase-1 search
(issue 56: "`sanlab design` scores bodies with the strong search, so its choices stop being
lotteries: its validation seeds should agree in sign with the search's").

For each search of ``--searches`` (``random``: the paper's phase 1; ``rhythm``, ``catcma``,
``reflex``: sanlab's), ``sanlab.design.run_design`` scores the same ``--designs`` bodies (drawn by
the ``random`` body strategy from ``--seed``, so every search sees the same bodies) and the
reference (the file's defaults) on the search's seed, then every body that scored above 0 again
on each of ``--seeds``. A body *agrees* on a validation seed when its robust tuned speed minus the
reference's has the same sign there as on the search's seed (a tie at 0 counts as a sign of its
own). Printed per search: the bodies, how many were validated, the agreement over (body,
validation seed) pairs, the rank correlation (Spearman) between the bodies' speeds on the search's
seed and their mean on the validation seeds, and the wall time.

    python benchmarks/design_search.py [--creature experiments/bounder_design.toml] [--designs 8]
        [--controllers 640] [--trials 64] [--top 1] [--seconds 6] [--seed 0] [--seeds 1,2]
        [--searches random,rhythm] [--db FILE]

The last line is ``agreement_<search>=<x>`` for each search, then ``spearman_<search>=<y>``.
Figures: docs/design.md.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def spearman(x, y) -> float:
    """Spearman's rank correlation: Pearson's over the ranks (``scipy.stats.rankdata``, ties at
    their mean rank); nan for fewer than 3 values or a constant one."""
    from scipy.stats import rankdata

    if len(x) < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return float("nan")
    return float(np.corrcoef(rankdata(x), rankdata(y))[0, 1])


def agreement(result, seed: int, seeds) -> tuple[int, int, list[tuple[float, float]]]:
    """(pairs that agree, pairs, [(speed on the search's seed, mean on ``seeds``)] of the bodies
    scored on every seed) of a finished design."""
    ref = result.reference
    same = n = 0
    pairs = []
    for b in result.bodies:
        if b.round < 0 or any(s not in b.speeds for s in (seed, *seeds)):
            continue
        pairs.append((b.speed(seed), b.mean(seeds)))
        first = np.sign(b.speed(seed) - ref.speed(seed))
        for s in seeds:
            n += 1
            same += int(np.sign(b.speed(s) - ref.speed(s)) == first)
    return same, n, pairs


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--creature", default=str(ROOT / "experiments" / "bounder_design.toml"))
    ap.add_argument("--designs", type=int, default=8)
    ap.add_argument("--controllers", type=int, default=640)
    ap.add_argument("--trials", type=int, default=64)
    ap.add_argument("--top", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--searches", default="random,rhythm")
    ap.add_argument("--db", help="gait library (default: a temporary one); the same command again resumes")
    a = ap.parse_args(argv)
    from sanlab.creature import load_design, read_source
    from sanlab.design import DesignSettings, run_design
    from sanlab.library import Library

    text, where = read_source(a.creature)
    design, _ = load_design(a.creature)
    seeds = tuple(int(x) for x in a.seeds.split(","))
    lib = Library(a.db or os.path.join(tempfile.mkdtemp(), "design.db"))
    last = []
    for search in a.searches.split(","):
        s = DesignSettings(a.designs, a.designs, "random", a.controllers, a.trials, a.top, a.seconds, 8, a.seed,
                           a.designs, seeds, search=search)
        t0 = time.perf_counter()
        r = run_design(lib, design, text, where, s)
        wall = time.perf_counter() - t0
        same, n, pairs = agreement(r, a.seed, seeds)
        rho = spearman(*zip(*pairs)) if pairs else float("nan")
        print(f"{search:>7}: {a.designs} bodies, {len(pairs)} validated on seeds {a.seeds}; agree in sign with the "
              f"search's seed on {same} of {n} (body, seed) pairs; Spearman {rho:+.2f}; reference "
              f"{r.reference.speed(a.seed):.1f} cm/s on the search's seed, {r.reference.mean(seeds):.1f} on the others; "
              f"{wall:.0f} s", flush=True)
        for b in r.bodies:
            print(f"         {b.label:>9}: " + " ".join(f"seed {k} {b.speed(k):6.1f}" for k in sorted(b.speeds)),
                  flush=True)
        last.append((search, same / max(n, 1), rho))
    print(" ".join(f"agreement_{k}={x:.2f}" for k, x, _ in last) + " "
          + " ".join(f"spearman_{k}={r:.2f}" for k, _, r in last))


if __name__ == "__main__":
    main()
