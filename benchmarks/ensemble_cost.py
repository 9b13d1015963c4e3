"""What robust scores cost: the same bounder search with single samples, with the plain
ensemble of K members, and with the default objective (K members at dt and dt/2, issue 28).

Runs ``--controllers`` random SANs (6 s each, batches of ``--batch``) locally three times, in
turn, in one process: ``--ensemble 1``; ``--ensemble K --dt-factors 1`` (every member at the
creature's step: the default before issue 28); and ``--ensemble K`` (today's default,
``sanlab.evaluate.ensemble.DEFAULT_DT_FACTORS``). Each rate is measured from the first committed
batch to the last (compilation left out). It prints evaluations/s of each and the cost of the
default against the other two.

    python benchmarks/ensemble_cost.py [--controllers 1024] [--members 8]

The last line is ``k1_eval_s=<x> plain_eval_s=<y> default_eval_s=<z> default_vs_plain=<y/z>
default_vs_k1=<x/z>``.
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
    ap = argparse.ArgumentParser(description="bounder search rate: single samples, a plain ensemble, the default")
    ap.add_argument("--controllers", type=int, default=1024)
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--members", type=int, default=8)
    args = ap.parse_args()

    from search_backends import timed_search

    from sanlab.evaluate import describe_devices
    from sanlab.evaluate.ensemble import DEFAULT_DT_FACTORS, Ensemble, default_ensemble

    tmp = tempfile.mkdtemp()
    K = args.members
    cases = {"k1": Ensemble(1), "plain": Ensemble(K), "default": default_ensemble(K)}
    rates = {}
    for name, ens in cases.items():
        args.ensemble = ens
        rates[name], _ = timed_search(os.path.join(tmp, f"{name}.db"), args)
        print(f"{name} (members {ens.members}, dt factors {list(ens.dt_factors)}): {rates[name]:.1f} evaluations/s "
              f"on {describe_devices()}", flush=True)
    vs_plain, vs_k1 = rates["plain"] / rates["default"], rates["k1"] / rates["default"]
    print(f"the default (K = {K}, dt factors {list(DEFAULT_DT_FACTORS)}) costs {vs_plain:.2f} x the plain ensemble "
          f"of {K} and {vs_k1:.2f} x a single sample per evaluation")
    print(f"k1_eval_s={rates['k1']:.2f} plain_eval_s={rates['plain']:.2f} default_eval_s={rates['default']:.2f} "
          f"default_vs_plain={vs_plain:.2f} default_vs_k1={vs_k1:.2f}")


if __name__ == "__main__":
    main()
