"""Search strength: what each search finds at the same number of evaluations, beside the pattern ceiling.

For each creature and seed it runs, through sanlab's own API (``run_search``, ``tune``), at a
budget of ``--evaluations`` robust evaluations each (8 perturbed starts, half at dt/2, the lower
group's median: every score's objective):

- ``random+sa``: the paper's protocol in its proportions (200 random SANs then 1000 annealing
  trials): a sixth of the budget on random SANs, the rest on simulated annealing of the best;
- ``catcma``: CatCMAwM over the weights (``search --strategy catcma``) for the whole budget;
- ``catcma+sa``: CatCMAwM for half, annealing of its best for the other half;
- ``rhythm``: SANs built as clocks, CMA-ES over their rhythm (``search --strategy rhythm``);
- ``rhythm+sa``: the rhythm search for half, annealing of its best for the other half;
- ``reflex``: ``search --strategy reflex`` for the whole budget (the rhythm search, its last
  quarter on reflexes);
- ``pattern``: CMA-ES over open-loop square waves (``search --strategy pattern``): the ceiling.

Each strategy's anytime curve is its best search-time score after each tenth of the budget, and
the CPU seconds it took (process time: every core's). Its final gait (the best phase-1 controller,
or the tuned gait) is then re-scored on ``--heldout`` fresh ensembles that no search saw, and
the median of their robust speeds is what the table prints, with each SAN strategy's fraction
of the pattern's (the ceiling) and its ratio to ``random+sa`` (today's search). The same final
gaits, searched on flat ground, are then re-scored on the rough and hilly grounds of §6.2
(``Evaluator``'s terrain sets): where a closed loop holds its gait and an open loop does not.

Results are appended to ``--out`` (JSON lines, one per creature, seed and strategy) as each
finishes, and a run with the same ``--out`` skips what is there: an interrupted benchmark goes
on where it stopped.

    python benchmarks/search_strength.py [--creatures bounder,walker] [--seeds 0] [--evaluations 3000]
        [--strategies random+sa,catcma,catcma+sa,rhythm,rhythm+sa,pattern] [--out search_strength.jsonl]

The last lines give, over the creatures and seeds measured, the median ratios of ``catcma``,
``catcma+sa``, ``rhythm`` and ``rhythm+sa`` to ``random+sa``, and the lowest and the median
share of the pattern's speed that the best SAN strategy, and ``rhythm+sa`` alone, reached:
``catcma_vs_random=.. catcma_sa_vs_random=.. best_san_of_ceiling_min=.. median=..`` and
``rhythm_vs_random=.. rhythm_sa_vs_random=.. rhythm_sa_of_ceiling_min=.. median=..``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SPEED_CREATURES = ("bounder", "walker", "luxo", "fourlink", "threelink", "cart", "twolink", "star", "fish")
STRATEGIES = ("random+sa", "catcma", "catcma+sa", "rhythm", "rhythm+sa", "reflex", "pattern")


def heldout(lib, gait_id: str, n: int, terrain: str = "flat") -> dict:
    """The gait re-scored on n fresh ensembles (keys no search uses) on ``terrain`` (a set of
    ``sanlab.evaluate.evaluator.TERRAINS``: the grounds' mean): median speed and score, and how
    many of the n ensembles fell."""
    from sanlab.evaluate.ensemble import heldout_key
    from sanlab.evaluate.evaluator import Evaluator
    from sanlab.gait import Gait
    from sanlab.search.space import Space

    g = Gait.from_library(lib, gait_id)
    space = Space(g.spec)
    phase1 = g.params.k1 is None
    if terrain != "flat" and g.spec.world.plane != "vertical":
        return {}
    ev = Evaluator(g.spec, metric=g.metric, seconds=g.seconds, ensemble=g.ensemble, space=space, batch=n,
                   terrain=terrain)
    theta = None if phase1 else np.repeat(space.nominal(g.params)[None], n, 0)
    pat = g.patterns()
    s = ev(np.repeat(g.weights[None], n, 0), theta, [heldout_key(90_000 + k, 0) for k in range(n)],
           patterns=None if pat is None else np.repeat(pat, n, 0))
    return {"speed_cm_s": float(np.median(s.speed_cm_s)), "score": float(np.median(s.score)),
            "fell": int(np.sum(s.fell))}


def curve(lib, run_ids: list[str], budget: int) -> list[float]:
    """Best search-time score after each tenth of the budget, over the runs' evaluations in the
    order they were made (a tune run's trials after its search)."""
    scores: list[float] = []
    for r in run_ids:
        run = lib.get_run(r)
        if run.kind == "tune":
            scores += [t.score if t.score == t.score else 0.0 for t in lib.trace(r)]
        else:
            evs = sorted(lib.top(r, None), key=lambda e: e.idx)
            scores += [e.score if e.score == e.score else 0.0 for e in evs]
    best = np.maximum.accumulate(np.asarray(scores or [0.0]))
    return [float(best[min(len(best) - 1, int(round(f * budget / 10)) - 1)]) for f in range(1, 11)]


def one(creature: str, strategy: str, seed: int, budget: int, n_heldout: int) -> dict:
    from sanlab.creature import read_source
    from sanlab.library import Library
    from sanlab.search import run_search
    from sanlab.search.tune import tune

    text, where = read_source(creature)
    with tempfile.TemporaryDirectory() as tmp:
        lib = Library(str(Path(tmp) / "s.db"))
        c0, t0 = time.process_time(), time.perf_counter()
        runs = []
        first = {"random+sa": ("random", budget // 6), "catcma": ("catcma", budget), "catcma+sa": ("catcma", budget // 2),
                 "rhythm": ("rhythm", budget), "rhythm+sa": ("rhythm", budget // 2), "reflex": ("reflex", budget),
                 "pattern": ("pattern", budget)}[strategy]
        run_id = run_search(lib, text, where, controllers=first[1], seed=seed, strategy=first[0],
                            batch=32 if first[0] in ("pattern", "rhythm", "reflex") else 256)
        runs.append(run_id)
        gait = lib.top(run_id, 1)[0].gait_id
        if strategy.endswith("+sa"):
            [res] = tune(lib, [gait], method="sa", trials=budget - first[1], seed=seed)
            runs.append(res.run_id)
            gait = res.tuned_gait
        cpu, wall = time.process_time() - c0, time.perf_counter() - t0
        out = {"creature": creature, "strategy": strategy, "seed": seed, "evaluations": budget,
               "cpu_s": round(cpu, 1), "wall_s": round(wall, 1), "curve": curve(lib, runs, budget),
               "gait": gait, "heldout": heldout(lib, gait, n_heldout),
               "terrains": {t: heldout(lib, gait, n_heldout, t) for t in ("rough", "hill")},
               "controller": {"encoding": lib.gait(gait).encoding, "params": lib.gait(gait).params}}
        lib.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--creatures", default=",".join(SPEED_CREATURES))
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--evaluations", type=int, default=3000)
    ap.add_argument("--strategies", default=",".join(STRATEGIES))
    ap.add_argument("--heldout", type=int, default=4, help="fresh ensembles the final gait is re-scored on")
    ap.add_argument("--out", default="search_strength.jsonl")
    args = ap.parse_args()
    out = Path(args.out)
    have = [json.loads(line) for line in out.read_text().splitlines() if line.strip()] if out.exists() else []
    done = {(r["creature"], r["strategy"], r["seed"], r["evaluations"]) for r in have}
    for creature in args.creatures.split(","):
        for seed in (int(s) for s in args.seeds.split(",")):
            for strategy in args.strategies.split(","):
                if (creature, strategy, seed, args.evaluations) in done:
                    continue
                r = one(creature, strategy, seed, args.evaluations, args.heldout)
                have.append(r)
                with out.open("a") as f:
                    f.write(json.dumps(r) + "\n")
                print(f"{creature:10s} seed {seed} {strategy:10s} held-out {r['heldout']['speed_cm_s']:7.1f} cm/s "
                      f"(score {r['heldout']['score']:.3f}), {r['cpu_s']:.0f} CPU s", flush=True)
    report([r for r in have if r["evaluations"] == args.evaluations])


def report(rows: list[dict]) -> None:
    """The table: per creature and seed, each strategy's held-out speed, its fraction of the
    pattern ceiling, and its ratio to random+sa; then the curves."""
    by = {(r["creature"], r["seed"], r["strategy"]): r for r in rows}
    keys = sorted({(r["creature"], r["seed"]) for r in rows})
    print(f"\n{'creature':10s} {'seed':>4s} " + " ".join(f"{s:>18s}" for s in STRATEGIES) + "   (held-out cm/s; % of pattern)")
    vs_random, sa_vs_random, of_ceiling = [], [], []
    rh_vs_random, rhsa_vs_random, rhsa_of_ceiling = [], [], []
    for c, s in keys:
        ceiling = by.get((c, s, "pattern"), {}).get("heldout", {}).get("speed_cm_s")
        cells = []
        for st in STRATEGIES:
            r = by.get((c, s, st))
            if r is None:
                cells.append(f"{'-':>18s}")
                continue
            v = r["heldout"]["speed_cm_s"]
            frac = f"{100 * v / ceiling:4.0f}%" if ceiling and st != "pattern" else "     "
            cells.append(f"{v:12.1f} {frac}")
        console = f"{c:10s} {s:4d} " + " ".join(cells)
        print(console)
        base = by.get((c, s, "random+sa"))
        cc, cs = by.get((c, s, "catcma")), by.get((c, s, "catcma+sa"))
        if base and cc and base["heldout"]["speed_cm_s"] > 0:
            vs_random.append(cc["heldout"]["speed_cm_s"] / base["heldout"]["speed_cm_s"])
        if base and cs and base["heldout"]["speed_cm_s"] > 0:
            sa_vs_random.append(cs["heldout"]["speed_cm_s"] / base["heldout"]["speed_cm_s"])
        rh, rs = by.get((c, s, "rhythm")), by.get((c, s, "rhythm+sa"))
        if base and rh and base["heldout"]["speed_cm_s"] > 0:
            rh_vs_random.append(rh["heldout"]["speed_cm_s"] / base["heldout"]["speed_cm_s"])
        if base and rs and base["heldout"]["speed_cm_s"] > 0:
            rhsa_vs_random.append(rs["heldout"]["speed_cm_s"] / base["heldout"]["speed_cm_s"])
        if rs and ceiling:
            rhsa_of_ceiling.append(rs["heldout"]["speed_cm_s"] / ceiling)
        sans = [r["heldout"]["speed_cm_s"] for r in (base, cc, cs, rh, rs) if r]
        if sans and ceiling:
            of_ceiling.append(max(sans) / ceiling)
    print("\nanytime curves: best search-time score after each tenth of the budget; CPU s")
    for c, s in keys:
        for st in STRATEGIES:
            r = by.get((c, s, st))
            if r:
                print(f"{c:10s} {s:4d} {st:10s} {r['cpu_s']:7.0f} s  " + " ".join(f"{x:6.2f}" for x in r["curve"]))
    print("\noff the flat (searched on flat ground): held-out cm/s on rough / hill, and the flat's")
    for c, s in keys:
        cells = []
        for st in STRATEGIES:
            r = by.get((c, s, st))
            t = (r or {}).get("terrains") or {}
            if r and t.get("rough"):
                cells.append(f"{st} {t['rough']['speed_cm_s']:.1f} / {t['hill']['speed_cm_s']:.1f} ({r['heldout']['speed_cm_s']:.1f})")
        if cells:
            print(f"{c:10s} {s:4d} " + "; ".join(cells))
    med = lambda x: float(np.median(x)) if x else math.nan
    low = min(of_ceiling) if of_ceiling else math.nan
    print(f"catcma_vs_random={med(vs_random):.2f} catcma_sa_vs_random={med(sa_vs_random):.2f} "
          f"best_san_of_ceiling_min={low:.2f} median={med(of_ceiling):.2f}")
    low = min(rhsa_of_ceiling) if rhsa_of_ceiling else math.nan
    print(f"rhythm_vs_random={med(rh_vs_random):.2f} rhythm_sa_vs_random={med(rhsa_vs_random):.2f} "
          f"rhythm_sa_of_ceiling_min={low:.2f} median={med(rhsa_of_ceiling):.2f}")


if __name__ == "__main__":
    main()
