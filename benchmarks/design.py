"""Design benchmark: the default body strategy (CMA-ES) against random bodies at the same budget,
same run (issue 47).

It runs ``sanlab.design.run_design`` twice on one creature file with free numbers, with the same
settings, seed and library, once with ``--strategy cma-es`` and once with ``random``: each scores
``--designs`` bodies by robust tuned speed (phase 1, a short phase 2, the audited selection),
then scores its ``--validate`` best and the reference (the file's defaults; scored once, as the
library is shared) again on ``--seeds``. For each it prints the best robust tuned speed of the
search (biased up: the best of many noisy scores), the chosen body's mean speed on the validation
seeds (not biased: the figure a user quotes) and the reference's, then the ratios CMA-ES / random.

    python benchmarks/design.py [--creature tests/data/hopper_free.toml] [--designs 8] [--generation 4]
                                [--controllers 16] [--trials 8] [--top 1] [--seconds 2] [--seeds 1,2]

The default run is small (about 2 minutes on 2 CPU cores, a minute of it the first compile): at
this budget a body's robust tuned speed is a noisy figure and a ratio near 1 says only that
neither strategy is broken; a real comparison takes a larger --designs and --controllers
(figures: docs/design.md). The last line is ``validated_ratio=<x> search_ratio=<y>`` (CMA-ES over random).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--creature", default=str(ROOT / "tests" / "data" / "hopper_free.toml"))
    ap.add_argument("--designs", type=int, default=8)
    ap.add_argument("--generation", type=int, default=4)
    ap.add_argument("--controllers", type=int, default=16)
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--top", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--validate", type=int, default=1)
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--db", help="gait library (default: a temporary one)")
    a = ap.parse_args(argv)
    from sanlab.creature import load_design, read_source
    from sanlab.design import DesignSettings, run_design
    from sanlab.library import Library

    text, where = read_source(a.creature)
    design, _ = load_design(a.creature)
    seeds = tuple(int(x) for x in a.seeds.split(","))
    db = a.db or os.path.join(tempfile.mkdtemp(), "design.db")
    lib = Library(db)
    out = {}
    for strategy in ("cma-es", "random"):
        s = DesignSettings(a.designs, a.generation, strategy, a.controllers, a.trials, a.top, a.seconds, 8, a.seed,
                           a.validate, seeds)
        t0 = time.perf_counter()
        r = run_design(lib, design, text, where, s)
        wall = time.perf_counter() - t0
        best = max(b.speed(a.seed) for b in r.bodies if b.round >= 0)
        out[strategy] = (best, r.chosen.mean(seeds))
        print(f"{strategy:>7}: {a.designs} bodies in {wall:.0f} s; best robust tuned speed in the search "
              f"{best:.1f} cm/s; chosen body {r.chosen.mean(seeds):.1f} cm/s on seeds {a.seeds} "
              f"(reference {r.reference.mean(seeds):.1f})", flush=True)
    (cb, cv), (rb, rv) = out["cma-es"], out["random"]
    print(f"validated_ratio={cv / max(rv, 1e-9):.2f} search_ratio={cb / max(rb, 1e-9):.2f}")


if __name__ == "__main__":
    main()
