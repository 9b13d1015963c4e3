"""What robust scores cost: the same bounder search with single samples and with an ensemble.

Runs ``--controllers`` random SANs (6 s each, batches of ``--batch``) locally with
``--ensemble 1`` and with ``--ensemble K`` (default 8), each rate measured from the first
committed batch to the last (compilation left out), and prints evaluations/s of both, the cost
factor and the creature-steps/s behind each.

    python benchmarks/ensemble_cost.py [--controllers 1024] [--members 8]

The last line is ``k1_eval_s=<x> k<K>_eval_s=<y> cost=<x/y>``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def main() -> None:
    ap = argparse.ArgumentParser(description="bounder search rate with single samples vs an ensemble")
    ap.add_argument("--controllers", type=int, default=1024)
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--members", type=int, default=8)
    args = ap.parse_args()

    import sanlab

    sanlab.configure()
    from search_backends import timed_search

    from sanlab.evaluate import describe_devices

    tmp = tempfile.mkdtemp()
    rates = {}
    for k in (1, args.members):
        args.ensemble = k
        rates[k], _ = timed_search(os.path.join(tmp, f"k{k}.db"), args)
        steps = rates[k] * k * args.seconds * 1000
        print(f"ensemble {k}: {rates[k]:.1f} evaluations/s ({steps / 1e6:.2f} M creature-steps/s) on {describe_devices()}",
              flush=True)
    cost = rates[1] / rates[args.members]
    print(f"an ensemble of {args.members} costs {cost:.2f} x the single-sample time per evaluation")
    print(f"k1_eval_s={rates[1]:.2f} k{args.members}_eval_s={rates[args.members]:.2f} cost={cost:.2f}")


if __name__ == "__main__":
    main()
