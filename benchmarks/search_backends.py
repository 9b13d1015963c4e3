"""Search benchmark: the same bounder search on this machine and on a local 2-worker Ray cluster.

Runs ``--controllers`` random SANs (default 20,000, 6 s each, batches of ``--batch``, an
ensemble of ``--ensemble`` members per controller) twice through ``sanlab.search.run_search``:
with the local backend (the batch sharded over this machine's cores) and with ``--backend ray``
on a Ray cluster started here with ``--workers`` CPUs (one worker each). Each rate is measured
from the first committed batch to the last, so compilation (once per process: the driver's, or
each worker's) is left out; both runs must store the same scores, bit for bit.

    python benchmarks/search_backends.py [--controllers 20000] [--ensemble 1] [--workers 2]

Prints evaluations/s of each, their ratio (Ray's overhead on one machine), the measured rate per
Ray worker and the projected rate per added worker; the last line is
``local_eval_s=<x> ray_eval_s=<y> ratio=<y/x> per_worker_eval_s=<z>``. It needs Ray
(``pip install -e '.[cluster]'``).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def timed_search(db: str, args, backend=None) -> tuple[float, list]:
    """(evaluations/s from the first committed batch to the end, the stored scores by idx)."""
    from sanlab.creature import read_source
    from sanlab.library import Library
    from sanlab.search import run_search

    marks: list[tuple[float, int]] = []
    text, where = read_source("bounder")
    with Library(db) as lib:
        run_id = run_search(lib, text, where, controllers=args.controllers, seconds=args.seconds, seed=0,
                            batch=args.batch, ensemble=args.ensemble, backend=backend,
                            reporter=lambda p: marks.append((time.perf_counter(), p.evaluated)))
        scores = [(e.idx, e.score, e.speed_cm_s) for e in sorted(lib.top(run_id, None), key=lambda e: e.idx)]
    first = next(m for m in marks if m[1] > 0)
    last = marks[-1]
    return (last[1] - first[1]) / (last[0] - first[0]), scores


def main() -> None:
    ap = argparse.ArgumentParser(description="the same bounder search locally and on a local Ray cluster")
    ap.add_argument("--controllers", type=int, default=20_000)
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--ensemble", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    import ray

    from sanlab.evaluate import describe_devices, make_backend

    tmp = tempfile.mkdtemp()
    local, a = timed_search(os.path.join(tmp, "local.db"), args)
    print(f"local ({describe_devices()}): {local:.1f} evaluations/s", flush=True)
    ray.init(num_cpus=args.workers, include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING)
    try:
        on_ray, b = timed_search(os.path.join(tmp, "ray.db"), args, make_backend("ray", workers=args.workers))
    finally:
        ray.shutdown()
    per_worker = on_ray / args.workers
    print(f"ray ({args.workers} workers on this machine): {on_ray:.1f} evaluations/s; "
          f"identical scores: {a == b}")
    print(f"ratio ray/local: {on_ray / local:.3f} (overhead {100 * (1 - on_ray / local):.1f} %)")
    print(f"per worker: {per_worker:.1f} evaluations/s; each added worker (a core elsewhere) projects "
          f"+{per_worker:.1f} evaluations/s ({args.controllers} x {args.ensemble} rollouts of {args.seconds:g} s; "
          f"{per_worker * args.ensemble * args.seconds * 1000 / 1e6:.2f} M creature-steps/s per worker)")
    print(f"local_eval_s={local:.2f} ray_eval_s={on_ray:.2f} ratio={on_ray / local:.3f} per_worker_eval_s={per_worker:.2f}")
    if a != b:
        raise SystemExit("ray and local scores differ")


if __name__ == "__main__":
    main()
