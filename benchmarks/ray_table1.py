"""Table 1 benchmark: the same small ``sanlab reproduce`` on this machine and on a local Ray cluster.

Makes the rows of ``--creatures`` x ``--seeds`` (phase 1 of ``--controllers`` random SANs,
``--trials`` annealing trials over ``--top`` chains, every chain best audited and its climb's
rungs selected; ensemble 8, as Table 1 is made) twice, through ``sanlab.reproduce.reproduce``:
with the local backend and with ``--backend ray`` on a Ray cluster started here with
``--workers`` CPUs. Both must give the same ledger rows, to the last digit. Then it measures what
bounds a cluster run on paper (docs/ray.md): the driver's own rate (asks, tells and library
commits a second, with evaluations that cost nothing) and the Ray round trip of a tiny task.

    python benchmarks/ray_table1.py [--creatures bounder] [--seeds 0] [--controllers 64] [--trials 64] [--workers 2]

The last line is ``local_s=<x> ray_s=<y> ratio=<x/y> driver_batches_s=<b> commit_ms=<c> task_ms=<t>``;
``ratio`` is Ray's speed as a fraction of local (the goal: at least 0.8 on 2 local workers).
It needs Ray (``pip install -e '.[cluster]'``).
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

RUN_ID = re.compile(r"\b[0-9a-f]{8}\b")


def same(x):
    """A ledger row without the random run ids, the wall time and the device."""
    if isinstance(x, dict):
        return {k: same(v) for k, v in x.items() if k not in ("wall", "device", "resumed", "ledger")}
    if isinstance(x, (list, tuple)):
        return [same(v) for v in x]
    return RUN_ID.sub("RUN", x) if isinstance(x, str) else x


def table(tmp: str, args, backend=None, pieces: int = 1) -> tuple[float, dict, list]:
    """(wall seconds, seconds per step kind, the ledger's rows) of one small Table 1."""
    from sanlab.library import Library
    from sanlab.reproduce import Ledger, parse_seeds, reproduce

    steps: dict[str, list[float]] = defaultdict(list)

    def progress(stage: str, p) -> None:
        kind = stage.rsplit(": ", 1)[-1].split(" of chain")[0]
        steps[kind].append(time.perf_counter())

    t0 = time.perf_counter()
    with Library(os.path.join(tmp, "g.db")) as lib:
        reproduce(lib, args.creatures.split(","), seeds=parse_seeds(args.seeds), controllers=args.controllers,
                  trials=args.trials, top=args.top, ensemble=8, log=lambda s: None, progress=progress,
                  ledger=os.path.join(tmp, "rows.jsonl"), backend=backend, pieces=pieces)
    wall = time.perf_counter() - t0
    rows = sorted((str(e.key), same(asdict(e.row))) for e in Ledger(os.path.join(tmp, "rows.jsonl")).entries)
    return wall, {k: max(v) - min(v) for k, v in steps.items() if k != "rows"}, rows


class Instant:
    """A backend whose evaluations cost nothing: every request gets one stored batch's scores, so
    a run measures the driver alone (ask, tell, commit, report)."""

    slots = 1

    def __init__(self, scores):
        self.scores, self.queue, self.n = scores, [], 0

    def start(self, evaluator) -> None:
        pass

    def submit(self, request) -> int:
        self.n += 1
        self.queue.append((self.n, len(request)))
        return self.n

    def next(self):
        ticket, n = self.queue.pop(0)
        return ticket, self.scores.take(slice(0, n))

    def map(self, jobs):
        return [self.scores.take(slice(0, len(r))) for _, r in jobs]

    def describe(self) -> str:
        return "instant"

    def close(self) -> None:
        self.queue.clear()


def driver_rate(tmp: str, batch: int = 256, batches: int = 40) -> tuple[float, float]:
    """(batches a second the driver asks, tells and commits with instant evaluations, ms a
    library commit of one batch takes) for a random search of the bounder, batches of ``batch``."""
    import numpy as np

    from sanlab.creature import load, read_source
    from sanlab.evaluate import Evaluator, Request
    from sanlab.evaluate.ensemble import default_ensemble, search_key
    from sanlab.library import Library
    from sanlab.search import run_search

    spec = load("bounder")
    ens = default_ensemble(8)
    ev = Evaluator(spec, seconds=0.05, ensemble=ens, batch=batch)
    scores = ev.evaluate(Request(np.stack([ev.san.random_weights(0, i) for i in range(batch)]), None,
                                 tuple(search_key(0, i) for i in range(batch))))
    text, where = read_source("bounder")
    commits: list[float] = []
    with Library(os.path.join(tmp, "driver.db")) as lib:
        commit = lib.commit

        def timed(*a, **k):
            t = time.perf_counter()
            out = commit(*a, **k)
            commits.append(time.perf_counter() - t)
            return out

        lib.commit = timed  # type: ignore[method-assign]
        t0 = time.perf_counter()
        run_search(lib, text, where, controllers=batch * batches, seconds=6.0, seed=0, batch=batch, ensemble=ens,
                   backend=Instant(scores))
        wall = time.perf_counter() - t0
    return batches / wall, 1000 * float(np.median(commits))


def task_ms(n: int = 400) -> float:
    """The Ray round trip of a task that does nothing (ms, with ``n`` in flight at once)."""
    import ray

    noop = ray.remote(num_cpus=1)(lambda: None)
    ray.get([noop.remote() for _ in range(20)])  # the workers up
    t0 = time.perf_counter()
    ray.get([noop.remote() for _ in range(n)])
    return 1000 * (time.perf_counter() - t0) / n


def main() -> None:
    ap = argparse.ArgumentParser(description="a small Table 1 locally and on a local Ray cluster")
    ap.add_argument("--creatures", default="bounder")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--controllers", type=int, default=64)
    ap.add_argument("--trials", type=int, default=64)
    ap.add_argument("--top", type=int, default=2)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--pieces", type=int, default=None, help="rows side by side on Ray (default: all)")
    args = ap.parse_args()

    import ray

    from sanlab.evaluate import describe_devices, make_backend

    tmp = tempfile.mkdtemp()
    os.makedirs(os.path.join(tmp, "l"))
    os.makedirs(os.path.join(tmp, "r"))
    local, lsteps, a = table(os.path.join(tmp, "l"), args)
    print(f"local ({describe_devices()}): {local:.1f} s; steps: "
          + ", ".join(f"{k} {v:.1f} s" for k, v in lsteps.items()), flush=True)
    ray.init(address="local", num_cpus=args.workers, include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING)
    try:
        from sanlab.reproduce import parse_seeds

        pieces = args.pieces or len(args.creatures.split(",")) * len(parse_seeds(args.seeds))
        on_ray, rsteps, b = table(os.path.join(tmp, "r"), args, make_backend("ray", workers=args.workers), pieces)
        tms = task_ms()
    finally:
        ray.shutdown()
    print(f"ray ({args.workers} workers on this machine, {pieces} rows side by side): {on_ray:.1f} s; steps: "
          + ", ".join(f"{k} {v:.1f} s" for k, v in rsteps.items()) + f"; identical rows: {a == b}")
    rate, commit = driver_rate(tmp)
    print(f"ratio ray/local speed: {local / on_ray:.3f}")
    print(f"driver alone: {rate:.1f} batches/s of 256 (ask, tell, commit), a commit {commit:.1f} ms; "
          f"a Ray task's round trip {tms:.2f} ms")
    print(f"local_s={local:.1f} ray_s={on_ray:.1f} ratio={local / on_ray:.3f} driver_batches_s={rate:.1f} "
          f"commit_ms={commit:.2f} task_ms={tms:.2f}")
    if a != b:
        raise SystemExit("ray and local rows differ")


if __name__ == "__main__":
    main()
