"""How much of a search the gait modes group: the share of useful controllers that fall in modes
of at least three gaits (issue 57), on the built-ins and on a caterpillar and a snake of our own
(tests/data/caterpillar.toml, tests/data/snake.toml).

Each creature is searched once (seed 0, ``-n`` random SANs, the creature file's own time and
metric) into ``--db`` (a run already there with the same creature, count and seed is reused),
and its useful controllers (as ``sanlab modes``: not fallen, finite, at least a fifth of the
best score) are grouped by ``sanlab.modes.find``, once for the first 200 controllers (a default
search) and once for all of them. Per creature it prints the useful count, the modes, those of
at least 3 gaits and of one, the share in modes of at least 3, and the silhouette of the
grouping (scikit-learn's, in the six continuous descriptors standardised as
``sanlab.modes.features`` does, the same space for every version; a mode of one gait counts 0:
near 1, each gait much nearer its own mode than the next; 0, no nearer), then the totals (the
silhouette: weighted by useful gaits, and the median over creatures).

    python benchmarks/modes_share.py [--db modes.db] [-n 1000] [--modes-from sanlab/modes.py]

``--modes-from FILE`` groups with another version of ``sanlab/modes.py`` (an older commit's,
``git show REV:sanlab/modes.py > old.py``), on the same runs: the before of a change.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

OWN = [str(ROOT / "tests" / "data" / "caterpillar.toml"), str(ROOT / "tests" / "data" / "snake.toml")]
BUILTINS = ["cart", "bounder", "twolink", "threelink", "fourlink", "star", "luxo", "walker", "fish", "crawler"]


def searched(lib, creature: str, n: int) -> str:
    """The run id of a seed-0 search of ``creature`` with ``n`` controllers, made if not there."""
    from sanlab.creature import read_source
    from sanlab.search import run_search

    text, where = read_source(creature)
    for r in lib.runs():
        if r.kind == "search" and r.creature_text == text and r.seed == 0 and r.count == n and r.status == "done":
            return r.run_id
    print(f"searching {Path(creature).stem} ({n} controllers)...", file=sys.stderr)
    return run_search(lib, text, where, controllers=n, seed=0)


def grouped(modes_mod, lib, run_id: str, first: int):
    """(useful gaits, their modes) of the run's first ``first`` controllers, as ``of_run`` picks them."""
    from sanlab.creature import loads

    run = lib.get_run(run_id)
    evs = [e for e in lib.top(run_id, None) if e.idx < first and not e.fell and not e.nonfinite and math.isfinite(e.score)]
    best = max((e.score for e in evs), default=0.0)
    useful = [e for e in evs if e.score >= modes_mod.MIN_SHARE * best and e.score > 0]
    gaits = [modes_mod.Gait(e.gait_id, e.score, e.speed_cm_s, e.extra["descriptors"]) for e in useful
             if e.extra and isinstance(e.extra.get("descriptors"), dict)]
    spec = loads(run.creature_text, source=run.creature)
    seconds = float(run.params.get("seconds") or spec.evaluation.seconds)
    return gaits, modes_mod.find(gaits, seconds=seconds, water=spec.world.water_drag > 0, plane=spec.world.plane)


def silhouette(gaits, modes) -> float | None:
    from sklearn.metrics import silhouette_score

    from sanlab.modes import FEATURES, features

    label = {g.gait_id: k for k, m in enumerate(modes) for g in m.gaits}
    labels = [label[g.gait_id] for g in gaits]
    if not 1 < len(set(labels)) < len(gaits):
        return None
    return float(silhouette_score(features(gaits)[:, :len(FEATURES)], labels))


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--db", default="modes.db")
    ap.add_argument("-n", type=int, default=1000)
    ap.add_argument("--modes-from", default=None, help="group with this modes.py instead of sanlab's")
    ap.add_argument("creatures", nargs="*", default=OWN + BUILTINS)
    args = ap.parse_args()
    from sanlab.library import Library

    if args.modes_from:
        spec = importlib.util.spec_from_file_location("modes_under_test", args.modes_from)
        assert spec is not None and spec.loader is not None
        modes_mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = modes_mod  # its dataclasses look their module up there
        spec.loader.exec_module(modes_mod)
    else:
        import sanlab.modes as modes_mod
    with Library(args.db) as lib:
        runs = {c: searched(lib, c, args.n) for c in args.creatures}
        for first in sorted({min(200, args.n), args.n}):
            total = big = n_modes = n_single = 0
            sil_sum = sil_w = 0.0
            sils = []
            print(f"first {first} controllers of each search ({args.modes_from or 'sanlab/modes.py'}):")
            print(f"  {'creature':12s} {'useful':>6s} {'modes':>5s} {'>=3':>4s} {'of 1':>4s} {'in >=3':>7s} {'silh.':>6s}")
            for c, run_id in runs.items():
                gaits, modes = grouped(modes_mod, lib, run_id, first)
                n = sum(m.size for m in modes)
                b = sum(m.size for m in modes if m.size >= 3)
                s = silhouette(gaits, modes)
                total, big, n_modes = total + n, big + b, n_modes + len(modes)
                n_single += sum(m.size == 1 for m in modes)
                if s is not None:
                    sil_sum, sil_w = sil_sum + s * n, sil_w + n
                    sils.append(s)
                print(f"  {Path(c).stem:12s} {n:6d} {len(modes):5d} {sum(m.size >= 3 for m in modes):4d} "
                      f"{sum(m.size == 1 for m in modes):4d} {100 * b / max(n, 1):6.0f}% "
                      f"{'-' if s is None else f'{s:.2f}':>6s}")
            print(f"  {'all':12s} {total:6d} {n_modes:5d} {'':4s} {n_single:4d} {100 * big / max(total, 1):6.0f}% "
                  f"{sil_sum / max(sil_w, 1):6.2f} (median {sorted(sils)[len(sils) // 2] if sils else math.nan:.2f})")
            print(f"share_in_3_or_more={big / max(total, 1):.3f} modes={n_modes} single={n_single} (first {first})")


if __name__ == "__main__":
    main()
