"""Reproduce the paper's Table 1: phase 1 and phase 2 on every creature, as a Markdown report.

For each creature: 200 random SANs (6 s each; 30 s for the fish and the crawler, which track a
follow point), then 1000 simulated-annealing trials on the best one (the paper's budget). The
report gives, per creature, the Table 1 counts and speed, sanlab's best speed before and after
tuning, the fraction of random SANs that moved usefully, and the wall time; then the tracking
results of the fish and the crawler (§6), and the robustness of the best bounder gait on a hill
and on rough ground (§6.2).

"Moved usefully" (the paper: "typically 1-5 % of the random SANs result in useful motions"): the
run stayed finite, the creature did not fall, and it travelled at least 10 % of its Table 1 speed
(at least 2 cm/s); for the pursuit creatures, its pursuit score (the distance it closed on the
follow point) is at least 10 % of the distance the follow point travelled.

Every tuned gait is audited (:mod:`sanlab.audit`: dt/2, dt/4, float64) and the report prints the
audit beside its speed, then the audited selection of its tuning run (``sanlab.audit.select_robust``:
the best-scoring rung of the chain's climb that keeps its speed under every nudge), the speed to quote.

The job takes over an hour at the paper's budget, so it resumes: run the same call again on the
same library and every creature whose search, tuning, audit or selection is already stored is
taken from the library, and an interrupted search or tuning run continues where it stopped (the
result is the same as an uninterrupted run's).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from sanlab.creature import load, read_source
from sanlab.creature.spec import Terrain
from sanlab.creature.table1 import TABLE1
from sanlab.evaluate.ensemble import Ensemble, default_ensemble
from sanlab.library import Library, Run, SearchSettings, TuneSettings

SEARCH_BATCH = 256  # controllers per phase-1 batch
TUNE_BATCH = 32  # one chain: a small batch (a speculative window of 32 trials) has the lowest latency per round


@dataclass
class Row:
    creature: str
    counts: tuple
    paper_speed: float | None
    run_id: str
    before: float  # cm/s
    after: float  # cm/s
    tuned_gait: str
    useful: float  # fraction
    wall: float  # seconds spent on this creature by this call
    metric: str
    audit: dict | None = None  # the tuned gait's stored audit (``sanlab.audit.Audit.to_json``) and verdict
    resumed: bool = False  # some of its work was stored by an earlier call
    robust: dict | None = None  # the audited selection (``_select``); None: not made


def useful_fraction(lib, run_id: str, spec, seconds: float) -> float:
    evs = lib.top(run_id, None)
    row = TABLE1.get(spec.name)
    paper = row.speed_cm_s if row else None
    n = 0
    for e in evs:
        if e.nonfinite or e.fell:
            continue
        if spec.evaluation.metric == "pursuit":
            follow = spec.world.follow.speed * seconds
            n += e.score >= 0.1 * follow
        else:
            n += e.speed_cm_s >= max(2.0, 0.1 * (paper or 0.0))
    return n / max(1, len(evs))


def tracking(lib, run_id: str, tuned_gait: str) -> dict:
    """Mean distance to the follow point and pursuit score: best (tuned) vs the median random SAN."""
    import jax

    from sanlab import sim
    from sanlab.gait import Gait

    evs = lib.top(run_id, None)
    median = evs[len(evs) // 2]
    out = {}
    for label, gid in (("best", tuned_gait), ("median random", f"{run_id}#{median.idx}")):
        g = Gait.from_library(lib, gid)
        model = g.model()
        frames = g.replay(fps=10, model=model).frames
        assert frames is not None  # recorded at 10 fps
        com = jax.vmap(lambda q, m=model: sim.poses(m, q)["com"])(frames.q[0])
        target = jax.vmap(lambda t, m=model: jax.numpy.stack(sim.follow_point(m, t)))(jax.numpy.asarray(frames.t, model.dtype))
        dist = np.linalg.norm(np.asarray(com) - np.asarray(target), axis=1)
        out[label] = {"gait": gid, "mean_distance_m": float(dist.mean()), "pursuit": float(lib.gait(gid).score)}
    return out


def robustness(lib, tuned_gait: str) -> dict:
    """Distance the tuned bounder gait covers on flat ground, a hill, and rough ground, each
    scored by the one evaluator over the tuned gait's own ensemble (the draws of its held-out
    score), for its run's evaluation time: {ground: {distance_m, fell, seconds}}."""
    from sanlab.evaluate import Evaluator
    from sanlab.evaluate.ensemble import heldout_key
    from sanlab.gait import Gait
    from sanlab.library import TuneSettings
    from sanlab.search.space import Space

    g = Gait.from_library(lib, tuned_gait)
    s = lib.get_run(tuned_gait.split("/")[0].split("#")[0]).settings
    key = heldout_key(s.seed, s.chain) if isinstance(s, TuneSettings) else heldout_key(0, 0)
    space = Space(g.spec, morphology=g.params.scale is not None)
    theta = space.nominal(g.params)[None]
    grounds = {
        "flat": Terrain(),
        "hill (12 cm, 1.2 m wide, 0.8 m ahead)": Terrain(kind="hill", height=0.12, width=1.2, center=0.8),
        "hill behind (mirror)": Terrain(kind="hill", height=0.12, width=1.2, center=-0.8),
        "rough (RMS 2 cm)": Terrain(kind="rough", height=0.02, wavelength=0.25, seed=7),
    }
    out = {}
    for name, terrain in grounds.items():
        ev = Evaluator(g.spec, metric="distance", seconds=g.seconds, terrain=[terrain], ensemble=g.ensemble,
                       space=space, batch=1)
        r = ev(g.weights[None], theta, [key])
        out[name] = {"distance_m": float(r.distance_m[0]), "fell": bool(r.fell[0]), "seconds": g.seconds}
    return out


def _earlier(lib: Library, kind: str, text: str, seed: int, wanted) -> Run | None:
    """The newest run of ``kind`` on this creature text and seed for which ``wanted(run)``."""
    for run in lib.runs():
        if run.kind == kind and run.creature_text == text and run.seed == seed and run.status != "damaged":
            try:
                if wanted(run):
                    return run
            except (KeyError, TypeError, ValueError):  # settings that are not a sanlab run's
                continue
    return None


def _search(lib: Library, text: str, where: str, seconds: float, seed: int, controllers: int,
            ens: Ensemble) -> tuple[str, bool]:
    """Phase 1 of one creature: (run id, whether an earlier call had stored some of it)."""
    from sanlab.search import run_search

    def wanted(run: Run) -> bool:
        s = run.settings
        return (isinstance(s, SearchSettings) and s.imported_from is None and s.controllers == controllers
                and s.seconds == seconds and s.batch == SEARCH_BATCH and s.ensemble == ens
                and (run.dtype or "float32") == "float32")

    run = _earlier(lib, "search", text, seed, wanted)
    if run is not None and run.status == "done":
        return run.run_id, True
    if run is not None:
        return run_search(lib, text, where, resume=run.run_id), True
    return run_search(lib, text, where, controllers=controllers, seconds=seconds, seed=seed, batch=SEARCH_BATCH,
                      ensemble=ens), False


def _tune(lib: Library, text: str, parent: str, seed: int, trials: int, ens: Ensemble) -> tuple[str, bool]:
    """Phase 2 of one creature's best gait: (tuned gait id, whether an earlier call had stored some of it)."""
    from sanlab.search.tune import tune

    def wanted(run: Run) -> bool:
        s = run.settings
        return (isinstance(s, TuneSettings) and run.parent_gait == parent and s.method == "sa" and s.trials == trials
                and s.seed == seed and s.chain == 0 and not s.morphology and s.terrain == "flat"
                and s.batch == TUNE_BATCH and s.ensemble == ens and (run.dtype or "float32") == "float32")

    run = _earlier(lib, "tune", text, seed, wanted)
    if run is not None and run.status == "done":
        return f"{run.run_id}#0", True
    if run is not None:
        [res] = tune(lib, resume=[run.run_id])
        return res.tuned_gait, True
    [res] = tune(lib, [parent], method="sa", trials=trials, seed=seed, batch=TUNE_BATCH, ensemble=ens)
    return res.tuned_gait, False


def _audit(lib: Library, gait_id: str, run: bool = True) -> tuple[dict | None, bool]:
    """The gait's audit, the stored one if there is one (else a new one when ``run``): (its
    record as a dict or None, whether it was stored before)."""
    from sanlab.audit import THRESHOLD, audit_and_store

    rec = lib.audit(gait_id)
    if rec is not None and rec.result.get("threshold") == THRESHOLD and rec.result.get("audit_members") is not None:
        return {**rec.result, "flagged": rec.flagged, "worst": rec.worst}, True
    if not run:
        return None, False
    a = audit_and_store(lib, gait_id)
    return {**a.to_json(), "flagged": a.flagged, "worst": a.worst}, False


def _select(lib: Library, run_id: str, run: bool = True) -> tuple[dict | None, bool]:
    """The tuning run's audited selection (``sanlab.audit.select_robust``), the stored one if
    there is one (else a new one when ``run``): ({"gait", "speed", "trial", "worst",
    "candidates"} or None, whether it was stored before). "gait" is None when no rung of the
    climb kept its speed."""
    from sanlab.audit import LEVEL, MAX_MEMBERS, MEMBERS, SELECT_TOP, THRESHOLD, select_robust

    settings = {"top": SELECT_TOP, "threshold": THRESHOLD, "members": MEMBERS, "max_members": MAX_MEMBERS,
                "level": LEVEL}
    before = (lib.selection(run_id) or {}).get("settings") == settings
    if not before and not run:
        return None, False
    sel = select_robust(lib, run_id)
    c = sel.chosen
    return {"gait": sel.gait_id, "speed": None if c is None else c.nominal_cm_s, "trial": None if c is None else c.trial,
            "worst": None if c is None else c.worst, "candidates": len(sel.candidates)}, before


def reproduce(lib, creatures: list[str], seed: int = 0, controllers: int = 200, trials: int = 1000,
              log=print, ensemble: int | Ensemble = 8, audit: bool = True) -> str:
    """Run the paper's budget on each creature, every score over an ensemble (``ensemble``: a
    number of members, scored as searches score by default, ``default_ensemble``, or an
    :class:`Ensemble`), and audit each tuned gait (``audit=False``: only a stored audit is
    shown); returns the Markdown report.

    Resumable: what ``lib`` already holds from an earlier call with the same arguments (a
    finished search, tuning run or audit) is reused, and an interrupted search or tuning run
    continues (see the module docstring). Raises LibraryError and ValueError as ``run_search``
    and ``tune`` do; KeyboardInterrupt leaves every stored evaluation in the library."""
    lib.mark_stale_runs()  # runs of a killed earlier call become "interrupted", so they can continue
    ens = ensemble if isinstance(ensemble, Ensemble) else default_ensemble(int(ensemble))
    rows: list[Row] = []
    extras: dict = {}
    t_all = time.perf_counter()
    for name in creatures:
        t0 = time.perf_counter()
        spec = load(name)
        seconds = spec.evaluation.seconds  # 6 s; 30 s for the fish and the crawler (their files say so)
        text, where = read_source(name)
        run_id, searched = _search(lib, text, where, seconds, seed, controllers, ens)
        best = lib.top(run_id, 1)[0]
        tuned_id, tuned_before = _tune(lib, text, best.gait_id, seed, trials, ens)
        tuned = lib.gait(tuned_id)
        report, audited = _audit(lib, tuned.gait_id, run=audit)
        robust, selected = _select(lib, tuned.gait_id.split("#")[0], run=audit)
        shown = robust["gait"] if robust and robust["gait"] else tuned_id  # the gait the report stands on
        wall = time.perf_counter() - t0
        counts = (len(spec.links), len(spec.sensors), len(spec.actuators), spec.n_hidden)
        paper = TABLE1[name].speed_cm_s if name in TABLE1 else None
        rows.append(Row(name, counts, paper, run_id, best.speed_cm_s, tuned.speed_cm_s, tuned_id,
                        useful_fraction(lib, run_id, spec, seconds), wall, spec.evaluation.metric, report,
                        searched or tuned_before or audited or selected, robust))
        log(f"{name}: {best.speed_cm_s:.1f} -> {tuned.speed_cm_s:.1f} cm/s, audit: {_verdict(report)}, "
            f"robust: {_robust(robust)} ({wall:.0f} s)")
        if spec.evaluation.metric == "pursuit":
            extras.setdefault("tracking", {})[name] = tracking(lib, run_id, shown)
        if name == "bounder":
            extras["robustness"] = robustness(lib, shown)
            extras["robustness_gait"] = shown
    return markdown(rows, extras, seed, controllers, trials, time.perf_counter() - t_all, ens)


def _verdict(audit: dict | None) -> str:
    if not audit:
        return "not audited"
    if audit.get("reproduced") is False:
        return f"not reproduced: stored {audit.get('stored_cm_s')} cm/s, re-scored {audit.get('nominal_cm_s')}"
    changes = {k: (float("inf") if v is None else v) for k, v in (audit.get("changes") or {}).items()}
    what = audit.get("verdict") or ("flagged" if audit.get("flagged") else "robust")
    if not changes:
        return what
    worst = max(changes, key=lambda k: changes[k])
    return f"{what}: {100 * changes[worst]:.0f} % at {worst}"


def _robust(sel: dict | None) -> str:
    """"108.2 (trial 306, worst change 3 %)", "none of 10 rungs" or "not selected"."""
    if not sel:
        return "not selected"
    if not sel.get("gait"):
        return f"none of {sel['candidates']} rungs"
    from sanlab.audit import rung_name

    return f"{sel['speed']:.1f} ({rung_name(sel['trial'])}, worst change {100 * sel['worst']:.0f} %)"


def _gaits(r: Row) -> str:
    """The row's gait ids: the tuned gait, and its robust selection when there is one."""
    robust = (r.robust or {}).get("gait")
    return f"`{r.tuned_gait}`" + (f" · robust `{robust}`" if robust else "")


def _nudged(audit: dict | None) -> str:
    """"dt/2 41.0 · dt/4 40.2 · float64 38.9" (cm/s; "-" where the speed was not finite)."""
    if not audit:
        return "-"
    speeds = audit.get("speeds") or {}
    return " · ".join(f"{k} {'-' if v is None else f'{v:.1f}'}" for k, v in speeds.items())


def _scoring(ens: Ensemble) -> str:
    """How the report's scores were taken, in words."""
    if ens.members == 1:
        return "every score one unperturbed rollout; "
    if len(ens.dt_factors) == 1:
        return f"every score the median over an ensemble of {ens.members} perturbed starts (the tuned gait's on a held-out ensemble); "
    steps = ", ".join("dt" if f == 1 else f"dt x {f:g}" for f in ens.dt_factors)
    return (f"every score the lowest of the group medians over an ensemble of {ens.members} perturbed starts, the members "
            f"at {steps} in turn (the tuned gait's on a held-out ensemble); ")


def markdown(rows: list[Row], extras: dict, seed: int, controllers: int, trials: int, total: float,
             ensemble: int | Ensemble = 8) -> str:
    import jax

    from sanlab import __version__

    dev = jax.devices()
    lines = [
        "# Table 1, reproduced",
        "",
        f"sanlab {__version__}, seed {seed}, {controllers} random SANs per creature (6 s; 30 s for the fish "
        f"and the crawler), then {trials} simulated-annealing trials on the best; "
        + _scoring(ensemble if isinstance(ensemble, Ensemble) else default_ensemble(int(ensemble)))
        + f"{len(dev)} x {dev[0].platform}; total wall time {total / 60:.1f} min.",
        "",
        "| creature | links | sensors | actuators | hidden | Table 1 speed (cm/s) | sanlab best random (cm/s) "
        "| after tuning (cm/s) | tuned gait nudged (cm/s) | audit | robust tuned gait (cm/s) | useful random SANs "
        "| tuned gait | wall time |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        paper = "U" if r.paper_speed is None else f"{r.paper_speed:g}"
        lines.append(
            f"| {r.creature} | {' | '.join(str(c) for c in r.counts)} | {paper} | {r.before:.1f} | {r.after:.1f} "
            f"| {_nudged(r.audit)} | {_verdict(r.audit)} | {_robust(r.robust)} | {100 * r.useful:.1f} % | {_gaits(r)} "
            f"| {r.wall:.0f} s{' (resumed)' if r.resumed else ''} |"
        )
    lines += ["", "Speeds are those of the centre of mass: net displacement over the evaluation time.",
              "", "*Tuned gait nudged*: the mean speed of the audit's 32 perturbed starts with the step halved "
              "and quartered and in float64 (`sanlab audit`). *Audit*: *robust* when, for every nudge, the bootstrap "
              "interval (95 % over the three) of the relative change of the mean speed lies inside ±10 %; "
              "*resolution-dependent* when one lies wholly outside it (the speed is an artefact of the integrator "
              "rather than a result); *undecided* otherwise (not a pass).",
              "", "*Robust tuned gait*: the audited selection (`sanlab audit RUN --select`): up to 16 rungs of the "
              "tuning chain's climb (its start, its best and the vectors that first reached the scores between) are "
              "audited the same way, and the best-scoring robust one that is robust again on fresh draws is stored "
              "as the run's gait #1, with its held-out speed. This is the tuned speed to quote (it can be the start "
              "itself, when no tuned rung survives); the tracking and robustness sections, where present, use it "
              "(the chain's best where no rung kept its speed).",
              "", "*(resumed)*: an earlier call on the same library had stored some of this creature's work; "
              "the wall time counts this call only.",
              "", "A random SAN *moved usefully* when the run stayed finite, the creature did not fall, and it "
              "travelled at least 10 % of its Table 1 speed (at least 2 cm/s); for the fish and the crawler, when "
              "its pursuit score was at least 10 % of the distance the follow point travelled."]
    if "tracking" in extras:
        lines += ["", "## Tracking (§6)", "",
                  "| creature | controller | mean distance to the follow point (m) | pursuit score (m) |",
                  "|---|---|---|---|"]
        for name, res in extras["tracking"].items():
            for label, v in res.items():
                lines.append(f"| {name} | {label} (`{v['gait']}`) | {v['mean_distance_m']:.3f} | {v['pursuit']:.3f} |")
    if "robustness" in extras:
        lines += ["", "## Robustness (§6.2): the tuned flat-ground bounder gait on other ground", "",
                  f"Gait `{extras.get('robustness_gait', '?')}`.", "",
                  "| ground | time (s) | distance (m, ensemble median) | fell |", "|---|---|---|---|"]
        for name, v in extras["robustness"].items():
            lines.append(f"| {name} | {v['seconds']:g} | {v['distance_m']:.2f} | {'yes' if v['fell'] else 'no'} |")
    return "\n".join(lines) + "\n"


__all__ = ["TABLE1", "reproduce", "markdown"]
