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
follow point) is at least 10 % of the distance the follow point travelled; for a creature scored by
tracking, its mean distance to the follow point is at least 10 % below that of the creature
standing still at its start.

Every tuned gait is audited (:mod:`sanlab.audit`: dt/2, dt/4) and the report prints the
audit beside its speed, then the audited selection of its tuning run (``sanlab.audit.select_robust``:
the best-scoring rung of the chain's climb that keeps its speed under every nudge), the speed to quote.

The job takes over an hour at the paper's budget, so it resumes: run the same call again on the
same library and every creature whose search, tuning, audit or selection is already stored is
taken from the library, and an interrupted search or tuning run continues where it stopped (the
result is the same as an uninterrupted run's).

A library holding every evaluation of a five-seed table is hundreds of megabytes, too large to
keep beside the code, and the table takes longer than one sitting on a small machine; so each
finished row (one creature, one seed) can also go to a *ledger* (``ledger=``, ``--ledger``), a
JSON-lines file of a few kilobytes a row, kept under version control. A row the ledger holds for
the same creature file, seed and budget is taken from it without the library, so the table is
made in pieces on any machines and the last piece writes the whole report
(``docs/table1.jsonl``, ``docs/table1.md``).
"""

from __future__ import annotations

import hashlib
import json
import queue
import re
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sanlab.creature import load, loads, read_source
from sanlab.creature.spec import FOLLOW_METRICS, Terrain
from sanlab.creature.table1 import TABLE1
from sanlab.evaluate.ensemble import Ensemble, default_ensemble
from sanlab.library import Library, Run, SearchSettings, TuneSettings

SEARCH_BATCH = 256  # controllers per phase-1 batch
# phase 2's trials spread over the 4 best phase-1 gaits: at seed 0 (the default objective) one
# chain of 1000 kept no robust rung on the bounder and the walker, four chains of 250 kept
# 69.1 and 64.3 cm/s (docs/reproduce.md, "One chain or four")
DEFAULT_TOP = 4
TUNE_BATCH = 32  # one chain: a small batch (a speculative window of 32 trials) has the lowest latency per round
Progress = Callable[[str, Any], None]  # reproduce's progress(stage, driver Progress or a line of text)


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
    seed: int = 0
    tracking: dict | None = None  # the pursuit creatures' ``tracking`` result
    robustness: dict | None = None  # the bounder's §6.2: {"gait", "grounds": ``robustness``}
    ledger: bool = False  # taken from a ledger, not from this call's library
    device: str = ""  # where it was made: "2 x cpu"
    chains: list | None = None  # every chain's best speed before its audit (cm/s); None in rows made before it was kept
    ceiling: dict | None = None  # the creature's pattern ceiling (``sanlab.search.ceiling.Ceiling.to_json``); None: not measured

    @property
    def robust_speed(self) -> float:
        """The speed to quote (cm/s): the audited selection's; 0 where no rung kept its speed
        (no robust gait) or no selection was made."""
        return float((self.robust or {}).get("speed") or 0.0)


def useful_fraction(lib, run_id: str, spec, seconds: float) -> float:
    evs = lib.top(run_id, None)
    row = TABLE1.get(spec.name)
    paper = row.speed_cm_s if row else None
    still = _still_tracking(spec, seconds) if spec.evaluation.metric == "tracking" else None
    n = 0
    for e in evs:
        if e.nonfinite or e.fell:
            continue
        if spec.evaluation.metric == "pursuit":
            follow = spec.world.follow.speed * seconds
            n += e.score >= 0.1 * follow
        elif still is not None:
            n += e.score >= still / 0.9
        else:
            n += e.speed_cm_s >= max(2.0, 0.1 * (paper or 0.0))
    return n / max(1, len(evs))


def _still_tracking(spec, seconds: float) -> float:
    """The tracking score (``sanlab.metrics``) of the creature standing still at its start for
    ``seconds``: its start distance to the follow point over its mean distance."""
    from sanlab import sim

    model = sim.compile_creature(spec)
    com = sim.poses(model, np.asarray(model.params.q0, np.float64)[None])["com"][0]
    t = np.arange(int(round(seconds / spec.dt))) * spec.dt
    gap = np.linalg.norm(sim.follow_point(model, t) - com, axis=1)
    return float(gap[0] / gap.mean())


def tracking(lib, run_id: str, tuned_gait: str) -> dict:
    """Mean distance to the follow point and score (by the run's metric, pursuit or tracking):
    best (tuned) vs the median random SAN."""
    from sanlab import sim
    from sanlab.gait import Gait

    evs = lib.top(run_id, None)
    median = evs[len(evs) // 2]
    metric = lib.get_run(run_id).metric or "pursuit"
    out = {}
    for label, gid in (("best", tuned_gait), ("median random", f"{run_id}#{median.idx}")):
        g = Gait.from_library(lib, gid)
        model = g.model()
        frames = g.replay(fps=10, model=model).frames
        assert frames is not None  # recorded at 10 fps
        com = sim.poses(model, frames.q[0])["com"]
        target = sim.follow_point(model, np.asarray(frames.t, np.float64))
        dist = np.linalg.norm(np.asarray(com) - np.asarray(target), axis=1)
        out[label] = {"gait": gid, "mean_distance_m": float(dist.mean()), metric: float(lib.gait(gid).score)}
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
        r = ev(g.weights[None], theta, [key], patterns=g.patterns())
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
            ens: Ensemble, backend=None, strategy: str = "random", reporter=None) -> tuple[str, bool]:
    """Phase 1 of one creature (``controllers`` evaluations of phase-1 ``strategy``): (run id,
    whether an earlier call had stored some of it). ``reporter``: told the search's progress
    (``run_search``'s)."""
    from sanlab.search import run_search
    from sanlab.search.pattern import POPSIZE

    batch = POPSIZE if strategy in ("rhythm", "reflex") else SEARCH_BATCH  # the rhythm search's batch is its generation

    def wanted(run: Run) -> bool:
        s = run.settings
        return (isinstance(s, SearchSettings) and s.imported_from is None and s.controllers == controllers
                and s.seconds == seconds and s.batch in (batch, min(batch, controllers))
                and s.ensemble == ens and s.strategy == strategy
                and run.dtype == "float64")

    run = _earlier(lib, "search", text, seed, wanted)
    if run is not None and run.status == "done":
        return run.run_id, True
    if run is not None:
        return run_search(lib, text, where, resume=run.run_id, backend=backend, reporter=reporter), True
    return run_search(lib, text, where, controllers=controllers, seconds=seconds, seed=seed, batch=batch,
                      ensemble=ens, backend=backend, strategy=strategy, reporter=reporter), False


def _tune(lib: Library, text: str, parents: list[str], seed: int, trials: int, ens: Ensemble,
          backend=None, reporter=None) -> tuple[list[str], bool]:
    """Phase 2 of one creature: ``trials`` annealing trials on each gait of ``parents`` (the
    search's best first), as parallel chains 0, 1, ...: (the tuned gait id of each chain, whether
    an earlier call had stored some of it). ``reporter``: told the tuning's progress (``tune``'s)."""
    from sanlab.search.tune import tune

    def wanted(i: int):
        def ok(run: Run) -> bool:
            s = run.settings
            return (isinstance(s, TuneSettings) and run.parent_gait == parents[i] and s.method == "sa"
                    and s.trials == trials and s.seed == seed and s.chain == i and not s.morphology
                    and s.terrain == "flat" and s.batch == TUNE_BATCH and s.ensemble == ens
                    and run.dtype == "float64")
        return ok

    found = [_earlier(lib, "tune", text, seed, wanted(i)) for i in range(len(parents))]
    runs = [r for r in found if r is not None]
    todo = [r.run_id for r in runs if r.status != "done"]
    if todo:
        tune(lib, resume=todo, backend=backend, reporter=reporter)
    missing = [i for i, r in enumerate(found) if r is None]
    if missing:  # a chain's trials depend on its number alone, so the stored chains stand beside new ones
        res = tune(lib, [parents[i] for i in missing], method="sa", trials=trials, seed=seed, batch=TUNE_BATCH,
                   ensemble=ens, backend=backend, reporter=reporter, chains=missing)
        for i, r in zip(missing, res, strict=True):
            found[i] = lib.get_run(r.tuned_gait.split("#")[0])
    return [f"{r.run_id}#0" for r in found if r is not None], bool(runs)


def _audit(lib: Library, gait_id: str, run: bool = True, log=None, backend=None) -> tuple[dict | None, bool]:
    """The gait's audit, the stored one if there is one (else a new one when ``run``, telling
    ``log`` its steps): (its record as a dict or None, whether it was stored before)."""
    from sanlab.audit import THRESHOLD, audit_and_store

    rec = lib.audit(gait_id)
    if rec is not None and rec.result.get("threshold") == THRESHOLD and rec.result.get("audit_members") is not None:
        return {**rec.result, "flagged": rec.flagged, "worst": rec.worst}, True
    if not run:
        return None, False
    a = audit_and_store(lib, gait_id, log=log, backend=backend)
    return {**a.to_json(), "flagged": a.flagged, "worst": a.worst}, False


def _select(lib: Library, run_id: str, run: bool = True, log=None, backend=None) -> tuple[dict | None, bool]:
    """The tuning run's audited selection (``sanlab.audit.select_robust``), the stored one if
    there is one (else a new one when ``run``): ({"gait", "speed", "trial", "worst",
    "candidates"} or None, whether it was stored before). "gait" is None when no rung of the
    climb kept its speed. ``log``: told each rung's audit as it is made."""
    from sanlab.audit import LEVEL, MAX_MEMBERS, MEMBERS, SELECT_TOP, THRESHOLD, select_robust

    settings = {"top": SELECT_TOP, "threshold": THRESHOLD, "members": MEMBERS, "max_members": MAX_MEMBERS,
                "level": LEVEL}
    before = (lib.selection(run_id) or {}).get("settings") == settings
    if not before and not run:
        return None, False
    sel = select_robust(lib, run_id, log=log, backend=backend)
    c = sel.chosen
    return {"gait": sel.gait_id, "speed": None if c is None else c.nominal_cm_s, "trial": None if c is None else c.trial,
            "worst": None if c is None else c.worst, "candidates": len(sel.candidates)}, before


def robust_tuned(lib: Library, text: str, where: str, *, seed: int, controllers: int, trials: int, top: int,
                 ens: Ensemble, seconds: float, backend=None, prune_below: float | None = None,
                 strategy: str = "random") -> dict:
    """A creature's robust tuned speed, scored as a Table 1 row is: phase 1 (``controllers``
    evaluations of ``strategy``: random SANs, or ``catcma``'s), phase 2 (``trials`` annealing trials on each of the ``top`` best, as parallel
    chains) and each chain's audited selection; every step taken from the library where an
    earlier call stored it (an interrupted search or tuning continues). Returns {"speed": the
    best selection's speed (cm/s; 0 where no chain kept a robust gait), "gait": its id or None,
    "search": the phase-1 run, "phase1_cm_s": phase 1's best speed, "chains": each chain's
    {"tuned", "tuned_cm_s", "robust", "robust_cm_s"}}. ``backend``: where the search, the tuning
    and the selections evaluate (default: this machine). ``prune_below``: a phase-1 best speed
    (cm/s) below which phase 2 and the selection are skipped and the speed is 0 ("pruned": True).
    Raises as ``run_search`` and ``tune``."""
    run_id, _ = _search(lib, text, where, seconds, seed, controllers, ens, backend, strategy=strategy)
    from sanlab.search.rhythm import starts

    best = starts(lib, run_id, top)
    if prune_below is not None and best[0].speed_cm_s < prune_below:
        return {"speed": 0.0, "gait": None, "search": run_id, "phase1_cm_s": float(best[0].speed_cm_s),
                "chains": [], "pruned": True}
    tuned_ids, _ = _tune(lib, text, [e.gait_id for e in best], seed, trials, ens, backend)
    chains = []
    for tid in tuned_ids:
        sel, _ = _select(lib, tid.split("#")[0], backend=backend)
        assert sel is not None  # _select with run=True always makes one
        chains.append({"tuned": tid, "tuned_cm_s": lib.gait(tid).speed_cm_s, "robust": sel["gait"],
                       "robust_cm_s": float(sel["speed"] or 0.0)})
    pick = max(chains, key=lambda c: c["robust_cm_s"])
    return {"speed": pick["robust_cm_s"], "gait": pick["robust"], "search": run_id,
            "phase1_cm_s": float(best[0].speed_cm_s), "chains": chains}


ENGINE = "kernel"  # the simulator a ledger's rows were made on (sanlab.sim.kernel)


def row_key(name: str, text: str, seed: int, controllers: int, trials: int, ens: Ensemble, top: int,
            audit: bool, strategy: str = "random") -> dict:
    """What makes a row: the creature and the SHA-256 of its file's text (a changed file is
    another creature), the seed, the budget, phase 1's strategy (absent for random search, as in
    the rows made before there were others), where phase 2 starts (``starts``, for the rhythm
    search's runs: rows made before it started one chain on the warm-up are made again) and the
    simulator (:data:`ENGINE`: a row the XLA engine made before issue 46, whose key has no engine,
    is made again)."""
    key = {"creature": name, "creature_sha256": hashlib.sha256(text.encode()).hexdigest(), "seed": seed,
           "controllers": controllers, "trials": trials, "top": top, "ensemble": ens.to_json(), "audit": audit,
           "engine": ENGINE}
    if strategy != "random":
        key["strategy"] = strategy
    from sanlab.search.rhythm import CLOCKS

    if strategy in CLOCKS and top > 1:
        key["starts"] = "warm-up"  # phase 2 from the k - 1 best and the warm-up's best (sanlab.search.rhythm.starts)
    return key


# What a key of the same creature's rows on another file may differ in besides the file: the
# simulator (rows the XLA engine made before issue 46 have no engine in their keys)
_FILE_FIELDS = ("creature_sha256", "engine")


def _budget(key: dict) -> str:
    """``key`` without its file and simulator (:data:`_FILE_FIELDS`): the creature, seed and budget."""
    return json.dumps({k: v for k, v in key.items() if k not in _FILE_FIELDS}, sort_keys=True)


@dataclass(frozen=True)
class LedgerEntry:
    """One line of a ledger: its ``key`` (:func:`row_key`), ``row`` and when it was ``made`` (UTC,
    "YYYY-MM-DDTHH:MM:SSZ"; "" where the line does not say)."""

    key: dict
    row: Row
    made: str


@dataclass(frozen=True)
class FileRows:
    """A ledger's rows of one creature file (:meth:`Ledger.files`): the ``sha256`` of its text,
    its ``rows`` (one a key), and when the ``first`` and the ``last`` of them were made (UTC
    "YYYY-MM-DDTHH:MM:SSZ", "" where not said)."""

    sha256: str
    rows: tuple[Row, ...]
    first: str
    last: str

    @property
    def median_cm_s(self) -> float:
        """The median of the rows' robust tuned speeds (cm/s; a row without a robust gait counts 0)."""
        return float(np.median([r.robust_speed for r in self.rows]))


class Ledger:
    """Finished rows, one JSON object a line: {"key": :func:`row_key`, "row": the :class:`Row`,
    "sanlab": version, "made": UTC time}. Reading raises ValueError naming the file and line of
    a line that is not such an object; a later line for the same key wins (:meth:`get`), and
    every line is kept (``entries``, in file order), so the rows of a creature's earlier files
    can be found (:meth:`files`)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.rows: dict[str, Row] = {}
        self.entries: list[LedgerEntry] = []
        if not self.path.exists():
            return
        fields = set(Row.__dataclass_fields__)
        for n, line in enumerate(self.path.read_text(encoding="utf-8").splitlines(), 1):
            if not line.strip():
                continue
            try:
                entry = json.loads(line)
                key, row = entry["key"], dict(entry["row"])
                if set(row) - fields:
                    raise ValueError(f"unknown row fields {sorted(set(row) - fields)}")
                row["counts"] = tuple(row["counts"])
                made = entry.get("made", "")
                if not isinstance(key, dict) or not isinstance(made, str):
                    raise TypeError("a key that is an object and a made time that is a string")
                self.rows[self._id(key)] = Row(**row)
                self.entries.append(LedgerEntry(key, self.rows[self._id(key)], made))
            except (ValueError, KeyError, TypeError, AttributeError) as e:
                raise ValueError(f"{self.path}: line {n}: expected a ledger entry "
                                 f'{{"key": {{...}}, "row": {{...}}}} ({type(e).__name__}: {e})') from None

    @staticmethod
    def _id(key: dict) -> str:
        return json.dumps(key, sort_keys=True)

    def get(self, key: dict) -> Row | None:
        """The stored row of ``key`` (marked as taken from the ledger), or None."""
        row = self.rows.get(self._id(key))
        if row is None:
            return None
        return Row(**{**asdict(row), "counts": tuple(row.counts), "ledger": True})

    def add(self, key: dict, row: Row) -> None:
        """Append ``row`` under ``key`` (flushed at once: a killed job keeps every finished row)."""
        from datetime import datetime, timezone

        from sanlab import __version__

        self.rows[self._id(key)] = row
        made = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
        self.entries.append(LedgerEntry(key, row, made))
        entry = {"key": key, "row": {**asdict(row), "ledger": False}, "sanlab": __version__, "made": made}
        with self.path.open("a", encoding="utf-8") as f:
            f.write(json.dumps(entry, sort_keys=True) + "\n")

    def files(self, keys: list[dict]) -> list[FileRows]:
        """The rows of one creature's files: for ``keys`` (the creature's rows on one file, e.g. a
        key per seed), every row whose key is one of them but for the creature file
        (``creature_sha256``) and the simulator (``engine``), grouped by file (a later line of
        the same key wins), ordered by when each file's last row was made (the newest last)."""
        wanted = {_budget(k) for k in keys}
        latest: dict[str, LedgerEntry] = {}
        for e in self.entries:
            if _budget(e.key) in wanted:
                latest[self._id(e.key)] = e
        by_file: dict[str, list[LedgerEntry]] = {}
        for e in latest.values():
            by_file.setdefault(str(e.key.get("creature_sha256", "")), []).append(e)
        out = [FileRows(sha, tuple(e.row for e in es), min(e.made for e in es), max(e.made for e in es))
               for sha, es in by_file.items()]
        return sorted(out, key=lambda f: f.last)


@dataclass(frozen=True)
class CreatureFile:
    """One creature of a report and its file: the ``sha256`` of the file's text, its ``history``
    (the creature format's dated lines, oldest first), and ``files``: the ledger's rows of this
    file and of the creature's other files for the report's seeds and budget (:meth:`Ledger.files`,
    the newest last), None where the report had no ledger."""

    creature: str
    sha256: str
    history: tuple[str, ...] = ()
    files: list[FileRows] | None = None

    @property
    def earlier(self) -> list[FileRows]:
        """The rows of the creature's other files (the newest last): it changed since them."""
        return [f for f in self.files or [] if f.sha256 != self.sha256]

    def changed(self) -> str:
        """Whether the file changed, as the ledger tells: "changed: earlier file 71e52259449c (5
        rows, made 2026-12-03, median 61.2 cm/s)" (the newest earlier file), "unchanged since its
        first rows in the ledger (2026-12-04)", "no rows in the ledger yet" or "no ledger"."""
        if self.files is None:
            return "no ledger"
        if self.earlier:
            f, older = self.earlier[-1], len(self.earlier) - 1
            n = len(f.rows)
            return (f"changed: earlier file {f.sha256[:12]} ({n} row{'s' * (n != 1)}, made {f.last[:10] or '?'}, "
                    f"median {f.median_cm_s:.1f} cm/s)" + (f", and {older} older file{'s' * (older != 1)}" if older else ""))
        mine = [f for f in self.files if f.sha256 == self.sha256]
        if not mine:
            return "no rows in the ledger yet"
        return "unchanged since its first rows in the ledger" + (f" ({mine[0].first[:10]})" if mine[0].first else "")

    def why(self) -> list[str]:
        """The history entries that say why: those dated on or after the day the newest earlier
        file's last row was made (an entry has a day, not a time), or all of them where there is
        no earlier file."""
        if not self.earlier or not self.earlier[-1].last:
            return list(self.history)
        since = self.earlier[-1].last[:10]
        return [h for h in self.history if h[:10] >= since]


def creature_files(book: Ledger | None, keys: dict[str, list[dict]], histories: dict[str, tuple[str, ...]]) -> list[CreatureFile]:
    """A :class:`CreatureFile` per creature of ``keys`` (name -> its rows' :func:`row_key`, one per
    seed, in the report's order), with its file's ``histories[name]``, the ledger's rows found in
    ``book`` (None: no ledger)."""
    return [CreatureFile(name, ks[-1]["creature_sha256"], histories.get(name, ()),
                         None if book is None else book.files(ks)) for name, ks in keys.items() if ks]


def _cell(text: str) -> str:
    """One line of text (a history entry) for a Markdown table cell: "|" escaped, which would
    end the cell (inside a code span too)."""
    return text.replace("|", "\\|")


def files_section(files: list[CreatureFile]) -> list[str]:
    """The report's "Creature files" section: per creature its file's SHA-256, whether it changed
    since the ledger's earlier rows of the creature, and why (its history)."""
    lines = ["## Creature files", "", "| creature | file (SHA-256) | changed | why (the file's history) |",
             "|---|---|---|---|"]
    for f in files:
        why = " · ".join(_cell(h) for h in f.why()) or "-"
        lines.append(f"| {f.creature} | `{f.sha256[:12]}` | {f.changed()} | {why} |")
    return lines + [
        "", "*Changed*: whether the ledger holds rows of another file of the creature (the same seeds and "
        "budget, any simulator), which this report's rows replace: the newest such file, its rows, the day "
        "the last of them was made and the median of their robust tuned speeds. *Why*: the file's `history` "
        "(docs/creature-format.md), the entries dated on or after that day, or all of them where no earlier "
        "file has rows.", ""]


def parse_seeds(text: str) -> list[int]:
    """"0-4" -> [0, 1, 2, 3, 4]; "0,2,7" -> [0, 2, 7]; "3" -> [3] (ranges and lists mix: "0-2,9").
    Raises ValueError naming what was expected."""
    seeds: list[int] = []
    for part in text.split(","):
        m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", part, re.ASCII)
        if m is None:
            raise ValueError(f"seeds: expected seeds like 0-4 or 0,2,7, got {text!r}")
        first = int(m[1])
        last = int(m[2]) if m[2] is not None else first
        if last < first or last - first >= 1000:
            raise ValueError(f"seeds: expected a range low-high with low <= high (at most 1000 seeds), got {part!r}")
        seeds += [k for k in range(first, last + 1) if k not in seeds]
    return seeds


def chains(top: int | None, trials: int, controllers: int) -> int:
    """How many phase-2 chains: ``top``, or for None ``DEFAULT_TOP`` (fewer where the trials or
    the controllers are fewer). Raises ValueError unless 1 <= top <= trials and controllers."""
    k = min(DEFAULT_TOP, trials, controllers) if top is None else top
    if k < 1 or k > trials or k > controllers:
        raise ValueError(f"top: expected 1 to {min(trials, controllers)} (at most the trials, {trials}, and the "
                         f"controllers phase 1 keeps, {controllers}), got {k}")
    return k


def reproduce(lib, creatures: list[str], seed: int = 0, controllers: int = 200, trials: int = 1000,
              log=print, ensemble: int | Ensemble = 8, audit: bool = True, seeds: list[int] | None = None,
              top: int | None = None, ledger: str | Path | Ledger | None = None, command: str | None = None,
              strategy: str = "random", ceiling: int = 0, progress: Progress | None = None, backend=None,
              pieces: int = 1, also: tuple[str, int] | None = None) -> str:
    """Run the paper's budget on each creature for each seed of ``seeds`` (default: ``[seed]``),
    every score over an ensemble (``ensemble``: a number of members, scored as searches score by
    default, ``default_ensemble``, or an :class:`Ensemble`), and audit each tuned gait
    (``audit=False``: only a stored audit is shown); returns the Markdown report, which for
    several seeds opens with the median, min and max over seeds of each creature's robust tuned
    speed.

    Phase 2 spends ``trials`` annealing trials per creature: on the best phase-1 gait, or with
    ``top`` K > 1 spread over the K best as parallel chains of ``trials // K`` trials each (§5.3:
    "takes the best SAN controllers found in phase 1"); the row then quotes the chain with the
    best robust speed. ``top`` None: ``DEFAULT_TOP``, or fewer where the trials or controllers
    are fewer.

    Resumable: what ``lib`` already holds from an earlier call with the same arguments (a
    finished search, tuning run or audit) is reused, and an interrupted search or tuning run
    continues (see the module docstring); a row the ``ledger`` file holds for the same creature
    file, seed and budget is taken from it, and every row made is appended to it
    (:class:`Ledger`). Raises LibraryError and ValueError as ``run_search`` and ``tune`` do,
    ValueError for a ``top`` :func:`chains` refuses or a malformed ledger; KeyboardInterrupt
    leaves every stored evaluation in the library and every finished row in the ledger.
    ``command``: the command line that made the report, named at its top. ``strategy``: phase
    1's (``random``, the paper's; ``catcma``: ``controllers`` evaluations of CatCMAwM; ``rhythm``
    and ``reflex``: of the rhythm search, ``sanlab.search.rhythm``). ``ceiling``
    > 0: each row also measures its creature's pattern ceiling with that many patterns
    (``sanlab.search.ceiling``, the row's seed) and quotes it beside the robust speed (not for a
    creature scored by tracking: a pattern ceiling is a speed's). ``also``: a second phase-1
    budget, (strategy, controllers), made for every creature whose score is a speed (not
    tracking) with the same phase 2, seeds and ledger; the report then opens with both budgets
    side by side (:func:`budgets`) and gives each its own tables (issue 56: Table 1 at the
    paper's budget and at sanlab's).
    ``progress``: called as ``progress(stage, p)`` while a row is made, ``stage`` naming the
    creature, the seed and the step ("walker (seed 0): search"), ``p`` the driver's
    :class:`sanlab.search.driver.Progress` during the search and the tuning and a line of text
    during the audits (``sanlab.cli`` draws it as ``tune`` does), and ``progress("rows", "3 of 10
    done")`` as each row is finished. ``backend`` (``sanlab.evaluate.backends``; default: this
    machine): where every evaluation of a row runs (search, tuning, audits, selections and
    ceiling; the tracking and robustness replays, a few rollouts, run here); the rows are the same
    on any backend. ``pieces`` > 1: that many rows (creature x seed) are made side by side, each
    by a thread of this process with its own connection to ``lib`` and its own copy of
    ``backend`` (``twin()``), so that a cluster runs the table's independent rows at once rather
    than one after another; a row's ceiling (the best of the creature's pattern searches stored
    before it) is measured once the creature's rows of earlier seeds are finished, so the rows
    are those of ``pieces=1``. Each row's chains are then audited side by side too. This process
    stays the only writer of ``lib`` and of the ledger. An error (or Ctrl-C) in one row stops the
    others within a second (they stop where they are and resume as after a kill)."""
    seeds = [seed] if seeds is None else list(seeds)
    top = chains(top, trials, controllers)
    book = ledger if isinstance(ledger, Ledger) or ledger is None else Ledger(ledger)
    lib.mark_stale_runs()  # runs of a killed earlier call become "interrupted", so they can continue
    ens = ensemble if isinstance(ensemble, Ensemble) else default_ensemble(int(ensemble))
    keys: dict[tuple[int, str], list[dict]] = {}
    texts = {name: read_source(name) for name in creatures}
    speeds = {name for name in creatures if loads(*texts[name]).evaluation.metric != "tracking"}
    t_all = time.perf_counter()
    plans = [(strategy, controllers)] + ([(also[0], int(also[1]))] if also is not None else [])
    # (budget, seed, creature) of each row: the second budget's only where the score is a speed
    order = [(b, sd, name) for b in range(len(plans)) for sd in seeds for name in creatures if b == 0 or name in speeds]
    for b, sd, name in order:
        keys.setdefault((b, name), []).append(
            row_key(name, texts[name][0], sd, plans[b][1], trials, ens, top, audit, plans[b][0]))
    turns = _Turns([(sd, name) for _, sd, name in order])
    written = threading.Lock()

    def make(k: int, lib: Library, backend) -> Row:
        """Row ``k`` of ``order``, from the ledger or made (and added to it)."""
        b, sd, name = order[k]
        how, many = plans[b]
        key = keys[(b, name)][seeds.index(sd)]
        measure = ceiling if name in speeds else 0
        row = book.get(key) if book is not None else None
        try:
            if row is not None and measure and row.ceiling is None and book is not None:
                # a row made without its ceiling: the ceiling alone is measured, the row kept (a later line wins)
                with turns.ceiling(k):
                    row.ceiling = _ceiling(lib, name, sd, measure, backend)
                with written:
                    book.add(key, row)
            if row is None:
                row = _creature(lib, name, sd, many, trials, ens, audit, top, progress, how, measure,
                                backend, turns.ceiling(k), pieces > 1)
                if name == "bounder":
                    shown = row.robust["gait"] if row.robust and row.robust["gait"] else row.tuned_gait
                    row.robustness = {"gait": shown, "grounds": robustness(lib, shown)}
                if book is not None:
                    with written:
                        book.add(key, row)
        except BaseException:
            turns.fail(k)
            raise
        finally:
            turns.done[k].set()  # finished: the creature's later rows may measure their ceilings
        return row

    made: dict[int, Row] = {}
    for k, row in _side_by_side(make, len(order), lib, backend, pieces):
        made[k] = row
        b, sd, name = order[k]
        if progress is not None:
            progress("rows", f"{len(made)} of {len(order)} done")
        at = f", {_plan(*plans[b])}" if also is not None else ""
        log(f"{name} (seed {sd}{at}): {row.before:.1f} -> {row.after:.1f} cm/s, audit: {_verdict(row.audit)}, "
            f"robust: {_robust(row.robust)} ({row.wall:.0f} s{', from the ledger' if row.ledger else ''})")
    rows = [made[k] for k in range(len(order)) if order[k][0] == 0]
    files = creature_files(book, {name: keys[(0, name)] for name in creatures},
                           {name: loads(*texts[name]).history for name in texts})
    second = None
    if also is not None:
        second = (plans[1][0], plans[1][1], [made[k] for k in range(len(order)) if order[k][0] == 1])
    return markdown(rows, seeds, controllers, trials, time.perf_counter() - t_all, ens, top, command, files, strategy,
                    also=second)


class _Turns:
    """The order a table's ceilings are measured in: row k's once the earlier rows of its creature
    (``order``: (seed, creature) of each row) are finished (in the ledger: a row made again after a
    kill sees the pattern searches it saw in turn), whichever thread makes them."""

    def __init__(self, order: list[tuple[int, str]]):
        self.order = order
        self.done = [threading.Event() for _ in order]
        self.failed = [False] * len(order)
        self.measured = [False] * len(order)

    @contextmanager
    def ceiling(self, k: int):
        name = self.order[k][1]
        try:
            for j in range(k):
                if self.order[j][1] == name:
                    self.done[j].wait()
                    if self.failed[j]:  # measured now, this ceiling would see fewer searches than in turn
                        raise RuntimeError(f"row {j} of {name} stopped before its ceiling")
            yield
            self.measured[k] = True
        except BaseException:
            self.fail(k)
            raise

    def fail(self, k: int) -> None:
        """Row k stopped: if before its ceiling, the creature's later rows stop at theirs."""
        self.failed[k] = not self.measured[k]
        self.done[k].set()


def _side_by_side(make, n: int, lib: Library, backend, pieces: int) -> Iterator[tuple[int, Any]]:
    """Yield (k, ``make(k, lib, backend)``) for k < n as each is made: in order here with
    ``pieces`` <= 1, else on up to ``pieces`` daemon threads, each with its own library
    connection and backend twin. The first error is raised here; the threads still running stop
    with the process (what they stored resumes as after a kill)."""
    if pieces <= 1 or n <= 1:
        for k in range(n):
            yield k, make(k, lib, backend)
        return
    connect = getattr(backend, "connect", None)
    if callable(connect):
        connect()  # here, in the main thread (Ray sets its signal handlers there), once for every twin
    todo: queue.Queue[int] = queue.Queue()
    for k in range(n):
        todo.put(k)
    out: queue.Queue[tuple[int, Any, BaseException | None]] = queue.Queue()
    stop = threading.Event()

    def work() -> None:
        twin = getattr(backend, "twin", None)
        mine = twin() if callable(twin) else backend
        with Library(lib.path, timeout=lib.timeout) as own:
            while not stop.is_set():
                try:
                    k = todo.get_nowait()
                except queue.Empty:
                    return
                try:
                    out.put((k, make(k, own, mine), None))
                except BaseException as e:  # handed to the caller's thread, which raises it
                    out.put((k, None, e))
                    return

    threads = [threading.Thread(target=work, daemon=True) for _ in range(min(pieces, n))]
    for t in threads:
        t.start()
    try:
        for _ in range(n):
            k, row, error = out.get()
            if error is not None:
                raise error
            yield k, row
    except BaseException:  # an error, or Ctrl-C: no thread starts another row, and the cluster's waits end
        stop.set()
        halt = getattr(backend, "stop", None)
        if callable(halt):
            halt()  # every row's driver stops within a second, its runs marked interrupted
            for t in threads:
                t.join(timeout=10)
        raise


def _creature(lib, name: str, seed: int, controllers: int, trials: int, ens: Ensemble, audit: bool,
              top: int, progress: Progress | None = None, strategy: str = "random", ceiling: int = 0,
              backend=None, turn=None, side: bool = False) -> Row:
    """Phase 1, phase 2 (``top`` chains), the audits and selections of one creature and seed
    (``progress``: as :func:`reproduce`'s; with ``ceiling`` its pattern ceiling too, measured
    with that many patterns, in its ``turn``: a context held while it is measured), every
    evaluation on ``backend``; ``side``: the chains' audits and selections side by side, on
    threads of their own)."""
    t0 = time.perf_counter()
    spec = load(name)
    seconds = spec.evaluation.seconds  # 6 s; 30 s for the fish and the crawler (their files say so)
    text, where = read_source(name)

    def told(step: str, say: Progress | None = progress, on=backend):
        if on is not None and hasattr(on, "label"):  # a worker's error names the row and the step
            on.label = f"{name} (seed {seed}): {step}"
        return None if say is None else (lambda p: say(f"{name} (seed {seed}): {step}", p))

    run_id, searched = _search(lib, text, where, seconds, seed, controllers, ens, backend, strategy=strategy,
                               reporter=told("search"))
    from sanlab.search.rhythm import starts

    best = starts(lib, run_id, top)
    tuned_ids, tuned_before = _tune(lib, text, [e.gait_id for e in best], seed, trials // top, ens, backend,
                                    reporter=told("tune"))
    stored = searched or tuned_before

    def chain(k: int, lib: Library, backend):
        """Chain k's best, its audit and its selection (and whether they were stored before)."""
        tid = tuned_ids[k]
        report, audited = _audit(lib, tid, run=audit, log=told(f"audit of chain {k}", on=backend), backend=backend)
        robust, selected = _select(lib, tid.split("#")[0], run=audit, log=told(f"selection of chain {k}", on=backend),
                                   backend=backend)
        return lib.gait(tid), report, robust, audited or selected

    # the chains' audits are independent: side by side too when the rows are (the row's longest step)
    made = dict(_side_by_side(chain, len(tuned_ids), lib, backend, len(tuned_ids) if side else 1))
    chains = [made[k][:3] for k in range(len(tuned_ids))]
    stored = stored or any(made[k][3] for k in made)
    # the row stands on the chain with the best robust speed (the chain best where none has one);
    # under tracking, on the one whose robust gait keeps closest to the point: its score, not a speed
    def rank(c):
        if spec.evaluation.metric == "tracking":
            return (lib.gait(c[2]["gait"]).score if c[2] and c[2]["gait"] else 0.0, c[0].score)
        return ((c[2] or {}).get("speed") or 0.0, c[0].score)

    tuned, report, robust = max(chains, key=rank)
    counts = (len(spec.links), len(spec.sensors), len(spec.actuators), spec.n_hidden)
    paper = TABLE1[name].speed_cm_s if name in TABLE1 else None
    row = Row(name, counts, paper, run_id, best[0].speed_cm_s, tuned.speed_cm_s, tuned.gait_id,
              useful_fraction(lib, run_id, spec, seconds), 0.0, spec.evaluation.metric, report, stored, robust,
              seed=seed, chains=[c[0].speed_cm_s for c in chains])
    if spec.evaluation.metric in FOLLOW_METRICS:
        shown = robust["gait"] if robust and robust["gait"] else tuned.gait_id
        row.tracking = tracking(lib, run_id, shown)
    from sanlab.evaluate.evaluator import describe_devices

    with turn if turn is not None and ceiling else nullcontext():
        if ceiling:
            told("ceiling")
            row.ceiling = _ceiling(lib, name, seed, ceiling, backend)
    row.device = describe_devices() if backend is None else backend.describe()
    row.wall = time.perf_counter() - t0
    return row


def _ceiling(lib, name: str, seed: int, evaluations: int, backend=None) -> dict | None:
    """The creature's pattern ceiling (``sanlab.search.ceiling.measure``: ``evaluations`` patterns
    on ``seed``, the best audited until one is robust; taken from ``lib`` where it holds that
    search) as a row stores it."""
    from sanlab.search.ceiling import measure

    text, where = read_source(name)
    _, c = measure(lib, text, where, evaluations=evaluations, seed=seed, backend=backend)
    return None if c is None else c.to_json()


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
    """"dt/2 41.0 · dt/4 40.2" (cm/s, each nudge of the audit; "-" where the speed was not finite)."""
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


def _table(rows: list[Row], strategy: str = "random") -> list[str]:
    """One seed's table: a row per creature (``strategy``: phase 1's, which names two columns)."""
    found = "random" if strategy == "random" else "phase 1"
    lines = [
        f"| creature | links | sensors | actuators | hidden | Table 1 speed (cm/s) | sanlab best {found} (cm/s) "
        f"| after tuning (cm/s) | tuned gait nudged (cm/s) | audit | robust tuned gait (cm/s) | useful {found} SANs "
        "| tuned gait | wall time |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    ceilings = any(r.ceiling for r in rows)
    if ceilings:  # the pattern ceiling's columns, where a row measured it
        lines[0] += " pattern ceiling (cm/s) | robust / ceiling |"
        lines[1] += "---|---|"
    for r in rows:
        paper = "U" if r.paper_speed is None else f"{r.paper_speed:g}"
        lines.append(
            f"| {r.creature} | {' | '.join(str(c) for c in r.counts)} | {paper} | {r.before:.1f} | {r.after:.1f} "
            f"| {_nudged(r.audit)} | {_verdict(r.audit)} | {_robust(r.robust)} | {100 * r.useful:.1f} % | {_gaits(r)} "
            f"| {r.wall:.0f} s{' (resumed)' if r.resumed else ''} |" + (_ceiling_cells([r]) if ceilings else "")
        )
    return lines


def _vouched(ceiling: dict | None) -> bool:
    """A row's stored ceiling (``Ceiling.to_json``) that its audit found robust, its ensembles standing
    (``Ceiling.robust``)."""
    return bool(ceiling) and ceiling.get("verdict") == "robust" and not ceiling.get("fell")  # type: ignore[union-attr]


def _ceiling_cells(rows: list[Row]) -> str:
    """The pattern ceiling's cells of rows of one creature: the median ceiling (cm/s; "not
    robust" marks one no audit vouched for) and the median of each row's robust speed over its
    own ceiling (the issue 56 goal: at least 0.8)."""
    have = [r for r in rows if r.ceiling and r.ceiling.get("speed_cm_s")]
    if not have:
        return " - | - |"
    c = float(np.median([r.ceiling["speed_cm_s"] for r in have]))  # type: ignore[index]
    vouched = "" if all(_vouched(r.ceiling) for r in have) else " (not vouched for)"
    frac = float(np.median([r.robust_speed / r.ceiling["speed_cm_s"] for r in have]))  # type: ignore[index]
    return f" {c:.1f}{vouched} | {frac:.2f} |"


def _tracking_ratio(r: Row) -> float | None:
    """Mean distance to the follow point of the row's gait over that of the median random SAN."""
    if not r.tracking:
        return None
    return r.tracking["best"]["mean_distance_m"] / max(1e-12, r.tracking["median random"]["mean_distance_m"])


def _by_creature(rows: list[Row], seeds: list[int]):
    """(creature, its rows in the order of ``seeds``), creatures in their first row's order."""
    for name in dict.fromkeys(r.creature for r in rows):
        yield name, sorted((r for r in rows if r.creature == name), key=lambda r: seeds.index(r.seed))


def summary(rows: list[Row], seeds: list[int]) -> list[str]:
    """The table over seeds: per creature, the median, min and max of the robust tuned speed
    (a seed without a robust gait counts 0), each seed's, how many meet Table 1, the verdicts of
    the chain bests' audits, the tracking ratio and the wall time."""
    from sanlab.audit import DEPENDENT, NOT_REPRODUCED, ROBUST, UNDECIDED

    lines = ["| creature | Table 1 speed (cm/s) | robust tuned speed, median (cm/s) | min | max | per seed (cm/s) "
             "| seeds at Table 1 speed | audits of the tuned gaits | tracking: distance ratio, median | wall time |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    ceilings = any(r.ceiling for r in rows)
    if ceilings:
        lines[0] += " pattern ceiling, median (cm/s) | robust / ceiling, median |"
        lines[1] += "---|---|"
    for name, mine in _by_creature(rows, seeds):
        speeds = np.array([r.robust_speed for r in mine])
        paper = mine[0].paper_speed
        met = "-" if paper is None else f"{int((speeds >= paper).sum())} of {len(mine)}"
        verdicts = [(r.audit or {}).get("verdict") or "not audited" for r in mine]
        tally = " · ".join(f"{v} {verdicts.count(v)}" for v in (ROBUST, UNDECIDED, DEPENDENT, NOT_REPRODUCED, "not audited") if verdicts.count(v))
        ratios = [x for x in (_tracking_ratio(r) for r in mine) if x is not None]
        track = f"{float(np.median(ratios)):.2f}" if ratios else "-"
        lines.append(
            f"| {name} | {'U' if paper is None else f'{paper:g}'} | {float(np.median(speeds)):.1f} | {speeds.min():.1f} "
            f"| {speeds.max():.1f} | {' · '.join(f'{x:.1f}' for x in speeds)} | {met} | {tally} | {track} "
            f"| {sum(r.wall for r in mine) / 60:.1f} min{' (resumed)' if any(r.resumed for r in mine) else ''} |"
            + (_ceiling_cells(mine) if ceilings else ""))
    return lines


TRACKING_GOAL = 1 / 3  # §6's tracking, as issue 30 states it: a third of the median random SAN's distance


def shortfalls(rows: list[Row], seeds: list[int]) -> list[str]:
    """Which creatures miss the goal over the seeds, and what the rows say about why: one Markdown
    bullet per creature that misses it (an empty list when every creature meets it).

    The goal (issue 30): the median over seeds of the robust tuned speed at least Table 1's, and,
    for the creatures that follow a point, the median tracking ratio below :data:`TRACKING_GOAL`.
    The cause is read off the rows: whether the quoted chain's best before the audit (*after
    tuning*) already falls short, or reaches the speed and the audit refuses it."""
    out = []
    for name, mine in _by_creature(rows, seeds):
        n, paper = len(mine), mine[0].paper_speed
        why = []
        if paper is not None:
            robust = float(np.median([r.robust_speed for r in mine]))
            if robust < paper:
                after = np.array([r.after for r in mine])
                reached = [r for r in mine if r.after >= paper]
                refused = [r for r in reached if r.robust_speed < paper]
                text = (f"Speed: median {robust:.1f} of {paper:g} cm/s ({sum(r.robust_speed >= paper for r in mine)} of "
                        f"{n} seeds at it). Before the audit, the quoted chains' bests have a median of "
                        f"{float(np.median(after)):.1f} cm/s")
                if all(r.chains for r in mine):
                    every = [x for r in mine for x in (r.chains or [])]
                    text += (f"; of all {len(every)} chains, {sum(x >= paper for x in every)} reached {paper:g} "
                             f"(the fastest {max(every):.1f})")
                if float(np.median(after)) < paper:
                    text += ", so tuning itself falls short (the search and the creature's design, not the audit)"
                else:
                    text += ", so tuning reaches it and the audit refuses it"
                if refused:
                    verdicts = [(r.audit or {}).get("verdict") or "not audited" for r in refused]
                    text += (f"; {len(refused)} quoted chain best{'s' if len(refused) > 1 else ''} at the speed "
                             f"{'were' if len(refused) > 1 else 'was'} refused ({', '.join(verdicts)}), and the "
                             f"robust rungs quoted instead are slower")
                why.append(text + ".")
        ratios = [x for x in (_tracking_ratio(r) for r in mine) if x is not None]
        if ratios and float(np.median(ratios)) >= TRACKING_GOAL:
            why.append(f"Tracking: median ratio {float(np.median(ratios)):.2f} against a goal below "
                       f"{TRACKING_GOAL:.2f} ({sum(x < TRACKING_GOAL for x in ratios)} of {len(ratios)} seeds below it).")
        if why:
            out.append(f"- **{name}**. " + " ".join(why))
    return out


def _plan(strategy: str, controllers: int) -> str:
    """A phase-1 budget in words: "200 random SANs", "3000 SANs of rhythm"."""
    if strategy == "random":
        return f"{controllers} random SANs" + (" (the paper's)" if controllers == 200 else "")
    return f"{controllers} SANs of {strategy}"


def budgets(first: tuple[str, int, list[Row]], second: tuple[str, int, list[Row]], seeds: list[int]) -> list[str]:
    """The two budgets side by side, a row per creature of ``first`` ((strategy, controllers,
    rows) each): Table 1's speed; at each budget the median over ``seeds`` of the robust tuned
    speed (a seed without one counts 0) and how many seeds reach Table 1's; the creature's pattern
    ceiling, the best any of its rows measured (every row's is the best pattern search stored
    when it was made, so the latest is the best of all of them: "not vouched for" where no audit
    found it robust), and each budget's median over it (the issue 56 goal: at least 0.8)."""
    (s1, c1, rows1), (s2, c2, rows2) = first, second
    lines = [f"| creature | Table 1 speed (cm/s) | {_plan(s1, c1)}: robust, median (cm/s) | seeds at Table 1 "
             f"| {_plan(s2, c2)}: robust, median (cm/s) | seeds at Table 1 | pattern ceiling (cm/s) "
             f"| {_plan(s1, c1)} / ceiling | {_plan(s2, c2)} / ceiling |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, mine in _by_creature(rows1, seeds):
        theirs = [r for r in rows2 if r.creature == name]
        paper = mine[0].paper_speed
        cells, medians = [], []
        for rs in (mine, theirs):
            if not rs:
                cells += ["-", "-"]
                medians.append(None)
                continue
            sp = np.array([r.robust_speed for r in rs])
            medians.append(float(np.median(sp)))
            cells += [f"{medians[-1]:.1f}", "-" if paper is None else f"{int((sp >= paper).sum())} of {len(rs)}"]
        known = [r.ceiling for r in (*mine, *theirs) if r.ceiling and r.ceiling.get("speed_cm_s")]
        if known:
            best = max(known, key=lambda c: (_vouched(c), c["speed_cm_s"]))
            top = float(best["speed_cm_s"])
            ceil = f"{top:.1f}" + ("" if _vouched(best) else " (not vouched for)")
            fracs = ["-" if m is None else f"{m / top:.2f}" for m in medians]
        else:
            ceil, fracs = "-", ["-", "-"]
        lines.append(f"| {name} | {'U' if paper is None else f'{paper:g}'} | {' | '.join(cells)} | {ceil} "
                     f"| {' | '.join(fracs)} |")
    return lines


def markdown(rows: list[Row], seeds: list[int] | int, controllers: int, trials: int, total: float,
             ensemble: int | Ensemble = 8, top: int = 1, command: str | None = None,
             files: list[CreatureFile] | None = None, strategy: str = "random",
             also: tuple[str, int, list[Row]] | None = None) -> str:
    """The report: for several seeds the table over seeds first, then the creature files (``files``,
    :func:`creature_files`: which changed since the ledger's earlier rows, and why; none when
    None), then each seed's table, the tracking (§6) and the bounder's robustness (§6.2)
    sections. ``total``: this call's wall time (s); rows taken from a ledger add the wall times
    they were made in. ``also``: a second budget's (strategy, controllers, rows): the report
    opens with :func:`budgets`, and the second budget's table over seeds and its seeds' tables
    follow the first's."""

    from sanlab import __version__

    seeds = [seeds] if isinstance(seeds, int) else list(seeds)
    from sanlab.evaluate.evaluator import describe_devices

    which = f"seed {seeds[0]}" if len(seeds) == 1 else f"seeds {', '.join(map(str, seeds))}"
    every = rows + (also[2] if also else [])  # the rows of both budgets
    phase2 = (f"then {trials} simulated-annealing trials on the best" if top == 1 else
              f"then {trials} simulated-annealing trials spread over the best {top} ({trials // top} each, "
              f"as parallel chains; each row quotes the chain with the best robust speed, or for a creature "
              f"scored by tracking the best robust tracking score)")
    lines = [
        *([f"<!-- made by: {command} -->"] if command else []),
        "# Table 1, reproduced",
        "",
        *([f"Made by `{command}`.", ""] if command else []),
        f"sanlab {__version__}, {which}, "
        + (f"{controllers} random SANs" if strategy == "random" else f"{controllers} SANs of `search --strategy {strategy}`")
        + " per creature (6 s; 30 s for the fish "
        f"and the crawler), {phase2}; "
        + _scoring(ensemble if isinstance(ensemble, Ensemble) else default_ensemble(int(ensemble)))
        + (f"{' and '.join(sorted({r.device for r in every if r.device})) or describe_devices()}; total wall time "
           f"{total / 60:.1f} min." if not any(r.ledger for r in every) else
           f"rows made in pieces (a ledger) on {' and '.join(sorted({r.device or '?' for r in every}))}: their wall times sum "
           f"to {sum(r.wall for r in every) / 60:.1f} min (this call {total / 60:.1f} min)."),
        "",
    ]
    if also:
        lines += [f"The second budget: {_plan(also[0], also[1])} (`search --strategy {also[0]} -n {also[1]}`) per "
                  "creature whose score is a speed, then the same phase 2, audits and selection.", ""]
    missing = [n for n in TABLE1 if n not in {r.creature for r in rows}]
    if missing:
        lines += [f"Not in this report: {', '.join(missing)} (Table 1's other creatures).", ""]
    if also:
        n = f"{len(seeds)} seeds" if len(seeds) > 1 else f"seed {seeds[0]}"
        lines += [f"## Two budgets, over {n}", ""] + budgets((strategy, controllers, rows), also, seeds) + [
            "", "*Robust, median*: the median over seeds of the audited selection's speed (a seed without a robust "
            "gait counts 0 cm/s). *Pattern ceiling*: the fastest open-loop pattern an audit found robust, the "
            "best of the creature's pattern searches (`sanlab ceiling`, one per seed); *not vouched for* where "
            "no audit found one robust. *... / ceiling*: the median over it (the goal: at least 0.8).", ""]
    parts = [(strategy, controllers, rows)] + ([also] if also else [])
    for how, many, mine in parts if len(seeds) > 1 else []:
        title = f"## Over {len(seeds)} seeds" + (f": {_plan(how, many)}" if also else "")
        lines += [title, ""] + summary(mine, seeds) + [
            "", "*Robust tuned speed*: each seed's audited selection (below); a seed where no rung of the "
            "climb kept its speed counts 0 cm/s. *Audits of the tuned gaits*: the verdicts of the chain bests "
            "(before the selection). *Tracking*: the mean distance to the follow point of the quoted gait over "
            "that of the seed's median random SAN (the goal: below 1/3).", ""]
        short = shortfalls(mine, seeds)
        lines += ["### Where the goal is not met", ""] + (short or ["Every creature meets it."]) + [
            "", "The goal: the median of the robust tuned speed at least Table 1's; for the creatures that follow a "
            "point, a median tracking ratio below 1/3. What was tried on the creatures that fall short, and the "
            "evidence, is in docs/reproduce.md.", ""]
    if files is not None:
        lines += files_section(files)
    for sd in seeds:
        if len(seeds) > 1 or files is not None or also:  # one seed's table gets a heading of its own after the files
            lines += [f"## Seed {sd}", ""]
        for how, many, mine in parts:
            if also:
                lines += [f"### {_plan(how, many)}", ""]
            lines += _table([r for r in mine if r.seed == sd], how) + [""]
    from sanlab.audit import LEVEL, MAX_MEMBERS, MEMBERS, NUDGES, THRESHOLD

    nudges = " and ".join(name for name, _, _ in NUDGES)
    lines += ["Speeds are those of the centre of mass: net displacement over the evaluation time.",
              "", f"*Tuned gait nudged*: the mean speed of the audit's own perturbed starts ({MEMBERS}, and up to "
              f"{MAX_MEMBERS} in further looks while it is undecided) with the step at {nudges} (`sanlab audit`); "
              "every run is in float64, the simulator's precision, so precision is no nudge. *Audit*: *robust* when, "
              f"for every nudge, the bootstrap interval ({100 * LEVEL:g} % over the {len(NUDGES)} nudges together) of "
              f"the relative change of the mean speed lies inside ±{100 * THRESHOLD:g} %; "
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
              "travelled at least 10 % of its Table 1 speed (at least 2 cm/s); for a creature scored by pursuit, "
              "when its pursuit score was at least 10 % of the distance the follow point travelled; by "
              "tracking, when its mean distance to the follow point was at least 10 % below that of the creature "
              "standing still at its start."]
    budget = {id(r): (f" ({_plan(how, many)})" if also else "") for how, many, mine in parts for r in mine}
    tracked = [r for r in every if r.tracking]
    if tracked:
        lines += ["", "## Tracking (§6)", "",
                  "| creature | seed | controller | mean distance to the follow point (m) | score |",
                  "|---|---|---|---|---|"]
        for r in tracked:
            for label, v in (r.tracking or {}).items():
                metric = "tracking" if "tracking" in v else "pursuit"
                score = f"{v[metric]:.3f} m (pursuit)" if metric == "pursuit" else f"{v[metric]:.3f} (tracking)"
                lines.append(f"| {r.creature} | {r.seed}{budget[id(r)]} | {label} (`{v['gait']}`) | {v['mean_distance_m']:.3f} "
                             f"| {score} |")
    robust_rows = [r for r in every if r.robustness]
    if robust_rows:
        lines += ["", "## Robustness (§6.2): the tuned flat-ground bounder gait on other ground", "",
                  "| seed | gait | ground | time (s) | distance (m, ensemble median) | fell |", "|---|---|---|---|---|---|"]
        for r in robust_rows:
            sd, gait, res = r.seed, (r.robustness or {})["gait"], (r.robustness or {})["grounds"]
            for name, v in res.items():
                lines.append(f"| {sd}{budget[id(r)]} | `{gait}` | {name} | {v['seconds']:g} | {v['distance_m']:.2f} "
                             f"| {'yes' if v['fell'] else 'no'} |")
    return "\n".join(lines) + "\n"


__all__ = ["TABLE1", "DEFAULT_TOP", "CreatureFile", "Ledger", "creature_files", "reproduce", "markdown", "summary",
           "shortfalls", "parse_seeds", "chains"]
