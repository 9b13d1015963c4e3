"""Tune benchmark: what `sanlab tune --batch` costs, by batch size and chain count (issue 49).

A tuning chain is sequential; each round proposes the next ``batch / chains`` trials of every
chain at once and keeps those up to the first accepted one (``sanlab.search.chain``), and every
round is padded to ``batch`` controllers. On a few CPU cores a large batch buys no throughput
and wastes most of each round, so the default batch is chosen per platform and chain count
(``sanlab.search.tune.default_batch``); this benchmark is where that choice is measured.

It searches ``--controllers`` random SANs of a small creature (twolink, ``--seconds`` s) for a
start, then tunes its best gait (1 chain) and its best ``--chains`` gaits (one chain each) for
``--trials`` trials at each batch of ``--batches`` and at the default. Each time is measured
from the first committed batch (the start's score, which compiles) to the end, so compilation is
left out; every tuning of one chain count must decide the same trials (the batch only changes
wall time), which is checked.

    python benchmarks/tune_batch.py [--trials 48] [--chains 4] [--batches 8,32,128]

Prints each time and, per chain count, its ratio to the default's; the last line is
``default_1=<b> default_<C>=<b> ratio128_1=<t128/t_default> ratio128_<C>=<...>``.
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


def timed_tune(lib, gaits: list[str], trials: int, batch: int) -> tuple[float, list]:
    """(seconds from the first committed batch to the end, each chain's (accepted, after score))."""
    from sanlab.search.tune import tune

    marks: list[float] = []
    results = tune(lib, gaits, trials=trials, seed=0, batch=batch, reporter=lambda p: marks.append(time.perf_counter()))
    outcome = [(r.accepted, round(r.after["score"], 6)) for r in results]
    return marks[-1] - marks[1], outcome


def main() -> None:
    ap = argparse.ArgumentParser(description="tune wall time by --batch, for one chain and several")
    ap.add_argument("--creature", default="twolink")
    ap.add_argument("--controllers", type=int, default=32)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--trials", type=int, default=48)
    ap.add_argument("--chains", type=int, default=4)
    ap.add_argument("--batches", default="8,32,128")
    args = ap.parse_args()

    from sanlab.creature import read_source
    from sanlab.evaluate import describe_devices
    from sanlab.library import Library
    from sanlab.search import run_search
    from sanlab.search.tune import default_batch

    text, where = read_source(args.creature)
    lib = Library(os.path.join(tempfile.mkdtemp(), "bench.db"))
    run_id = run_search(lib, text, where, controllers=args.controllers, seconds=args.seconds, seed=0, batch=args.controllers)
    print(f"{args.creature}, {args.trials} trials of {args.seconds:g} s, ensemble 8, on {describe_devices()}", flush=True)
    last = []
    for chains in (1, args.chains):
        gaits = [f"{run_id}/{k}" for k in range(1, chains + 1)]
        default = default_batch(chains)
        batches = sorted({*(int(b) for b in args.batches.split(",")), default})
        times, seen = {}, set()
        for b in batches:
            times[b], outcome = timed_tune(lib, gaits, args.trials, b)
            seen.add(tuple(outcome))
            print(f"  {chains} chain(s), --batch {b:>3}: {times[b]:6.1f} s"
                  f"{'  (the default)' if b == default else ''}", flush=True)
        if len(seen) != 1:
            raise SystemExit(f"{chains} chain(s): the batch changed the decided trials: {seen}")
        ratios = ", ".join(f"--batch {b}: {times[b] / times[default]:.2f}" for b in batches if b != default)
        print(f"{chains} chain(s): time / the default's (--batch {default}): {ratios}", flush=True)
        last += [f"default_{chains}={default}", f"ratio128_{chains}={times.get(128, float('nan')) / times[default]:.2f}"]
    print(" ".join(last))


if __name__ == "__main__":
    main()
