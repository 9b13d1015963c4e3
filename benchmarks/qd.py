"""Quality-diversity benchmark: MAP-Elites against random search at the same budget, same run.

For each creature (default the cart, the bounder and the walker) it runs ``--evaluations``
controllers twice through ``sanlab.search.run_search`` with the same seed and ensemble: the
paper's random search (§5.2) and ``--strategy map-elites`` over its default grid (signed speed x
airborne fraction, 16 x 16 cells, generations of ``--batch``). Random search's evaluations are
then binned into the same grid (``map_elites.rebuild`` with MAP-Elites' ranges), and for both it
prints archive coverage (cells filled), QD-score (sum of the cells' best scores), best robust
speed (the highest stored speed of a gait that did not fall: stored speeds are ensemble
medians) and the number of gait modes
(``sanlab.modes.find`` on each run's controllers scoring at least a fifth of random search's
best: one line for both), as MAP-Elites / random ratios; and the share of the grid either
search reached, with MAP-Elites' share of it (the coverage ratio cannot pass the union's size
over random search's without cells neither search found).

    python benchmarks/qd.py [--creatures cart,bounder,walker] [--evaluations 2000] [--seed 0]

Goal (issue 31): coverage ratio >= 2, modes ratio >= 1, best-speed ratio >= 0.9 on every
creature. The last line is ``coverage_ratio=<min> qd_ratio=<min> modes_ratio=<min>
speed_ratio=<min>`` over the creatures.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def run(lib, creature: str, strategy: str, args) -> tuple[str, float]:
    from sanlab.creature import read_source
    from sanlab.search import run_search

    text, where = read_source(creature)
    t0 = time.perf_counter()
    run_id = run_search(lib, text, where, controllers=args.evaluations, seed=args.seed, batch=args.batch,
                        strategy=strategy)
    return run_id, time.perf_counter() - t0


def measure(lib, run_id: str, grid, generation: int, min_score: float) -> dict:
    from sanlab.creature import loads
    from sanlab.modes import of_run
    from sanlab.san import San
    from sanlab.search.map_elites import rebuild

    run = lib.get_run(run_id)
    san = San.for_creature(loads(run.creature_text, source=run.creature))
    evs = lib.top(run_id, None)
    archive = rebuild(grid, san.n_weights, evs, san.decode, generation)
    st = archive.stats
    modes, _, _ = of_run(lib, run_id, min_score)
    ok = [e for e in evs if not e.nonfinite and not e.fell and math.isfinite(e.speed_cm_s)]
    return {"coverage": float(st.coverage), "qd": float(st.qd_score), "modes": len(modes),
            "best_speed": max((e.speed_cm_s for e in ok), default=0.0),
            "cells": set(int(i) for i in archive.data("index"))}


def main() -> None:
    ap = argparse.ArgumentParser(description="MAP-Elites against random search at the same budget")
    ap.add_argument("--creatures", default="cart,bounder,walker")
    ap.add_argument("--evaluations", type=int, default=2000)
    ap.add_argument("--batch", type=int, default=64, help="both searches' batch, MAP-Elites' generation")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    from sanlab.library import Library
    from sanlab.search.base import Grid

    ratios: dict[str, list[float]] = {"coverage": [], "qd": [], "modes": [], "speed": []}
    print(f"{args.evaluations} evaluations each, seed {args.seed}, batch {args.batch}; {os.cpu_count()} cores")
    print(f"{'creature':10s} {'search':11s} {'coverage':>9s} {'QD-score':>9s} {'modes':>6s} {'best cm/s':>10s} {'wall s':>7s}")
    with tempfile.TemporaryDirectory() as tmp, Library(os.path.join(tmp, "qd.db")) as lib:
        for creature in args.creatures.split(","):
            me, t_me = run(lib, creature, "map-elites", args)
            rnd, t_rnd = run(lib, creature, "random", args)
            # random search binned into MAP-Elites' grid, ranges as MAP-Elites found them
            from sanlab.search.map_elites import archive_stats

            stats = archive_stats(lib, me)
            assert stats is not None
            grid = Grid.from_json(stats["grid"])
            # the modes of both above one line: a fifth of random search's best score
            line = 0.2 * max((e.score for e in lib.top(rnd, 1)), default=0.0)
            a, b = measure(lib, me, grid, args.batch, line), measure(lib, rnd, grid, args.batch, line)
            for name, m, t in (("map-elites", a, t_me), ("random", b, t_rnd)):
                print(f"{creature:10s} {name:11s} {m['coverage']:9.1%} {m['qd']:9.3f} {m['modes']:6d} "
                      f"{m['best_speed']:10.1f} {t:7.1f}")
            r = {"coverage": a["coverage"] / max(b["coverage"], 1e-12), "qd": a["qd"] / max(b["qd"], 1e-12),
                 "modes": a["modes"] / max(b["modes"], 1), "speed": a["best_speed"] / max(b["best_speed"], 1e-12)}
            for k, v in r.items():
                ratios[k].append(v)
            print(f"{creature:10s} ratios     coverage {r['coverage']:.2f}x  QD {r['qd']:.2f}x  modes {r['modes']:.2f}x  "
                  f"best speed {r['speed']:.2f}x")
            # how much room the grid left: the cells either search reached, and MAP-Elites' share
            either = a["cells"] | b["cells"]
            print(f"{creature:10s} reached    {len(either) / grid.bins[0] / grid.bins[1]:.1%} of the cells by either search; "
                  f"MAP-Elites holds {len(a['cells']) / max(1, len(either)):.0%} of those, random "
                  f"{len(b['cells']) / max(1, len(either)):.0%} (coverage ratio at most {len(either) / max(1, len(b['cells'])):.2f}x "
                  f"without cells neither found)")
    print(" ".join(f"{k}_ratio={min(v):.3f}" for k, v in ratios.items()))


if __name__ == "__main__":
    main()
