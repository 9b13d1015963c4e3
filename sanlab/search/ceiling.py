"""A creature's pattern ceiling: the fastest audited open-loop pattern, and how far a SAN gait reaches it.

:func:`measure` runs the pattern search (``search --strategy pattern``, ``sanlab.search.pattern``)
on a creature file and audits its best patterns (``sanlab.audit``) until one is robust: that
pattern's stored speed, scored by the same robust objective as every SAN (the ensemble's median,
the lower of its dt and dt/2 groups), is the creature's *pattern ceiling*. :func:`find` looks it
up in a library for any gait: the best robust pattern of the same creature file, metric and
evaluation time, so ``show``, the studio and ``reproduce`` can say what fraction of it a SAN gait
reaches (issue 56). It is a reference, not a bound: where the closed loop holds a gait an open
loop cannot (the cart, the fourlink) a SAN passes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sanlab.library import Library, SearchSettings

EVALUATIONS = 2560  # the default budget: 2 restarts of 40 generations of 32 (about 40 s for the bounder on 2 cores)
AUDITED = 3  # best patterns audited, in order, until one is robust


@dataclass(frozen=True)
class Ceiling:
    """A creature's pattern ceiling: the pattern gait (``RUN#IDX``), its stored speed (cm/s) and
    score, its audit's verdict ("robust", or the best unaudited or not robust pattern's verdict,
    None when never audited), whether the audit's ensemble fell under a nudge (more than half
    its members: a pattern whose stored speed was the luck of its draws, as the walker's can be),
    and its run's evaluations."""

    gait: str
    speed_cm_s: float
    score: float
    verdict: str | None
    evaluations: int
    fell: bool = False

    @property
    def robust(self) -> bool:
        """Vouched for: the audit found its speed robust and its ensembles standing."""
        return self.verdict == "robust" and not self.fell

    def fraction(self, speed_cm_s: float) -> float | None:
        """``speed_cm_s`` (a SAN gait's, cm/s) over the ceiling's; None without a ceiling speed."""
        if not (self.speed_cm_s > 0 and math.isfinite(speed_cm_s)):
            return None
        return speed_cm_s / self.speed_cm_s

    def to_json(self) -> dict:
        return {"gait": self.gait, "speed_cm_s": self.speed_cm_s, "score": self.score, "verdict": self.verdict,
                "fell": self.fell, "evaluations": self.evaluations}


def find(lib: Library, creature_text: str, metric: str | None, seconds: float | None) -> Ceiling | None:
    """The pattern ceiling stored in ``lib`` for this creature file (its exact text), metric and
    evaluation time: the fastest pattern gait an audit vouched for (robust, its ensembles
    standing), or, when none was, the fastest pattern (its verdict and ``fell`` say so); None
    when no pattern search of it is stored."""
    best: Ceiling | None = None
    for run in lib.runs():
        s = run.settings
        if run.kind != "search" or not isinstance(s, SearchSettings) or s.strategy != "pattern":
            continue
        if run.creature_text != creature_text or s.metric != metric or not _same(s.seconds, seconds):
            continue
        audits = lib.audits(run.run_id)
        for e in lib.top(run.run_id, None):
            if e.nonfinite or e.fell or not math.isfinite(e.speed_cm_s):
                continue
            a = audits.get(e.idx)
            fell = a is not None and _fell(a)
            c = Ceiling(e.gait_id, e.speed_cm_s, e.score, None if a is None else a.verdict, lib.count(run.run_id), fell)
            if best is None or (c.robust, c.speed_cm_s) > (best.robust, best.speed_cm_s):
                best = c
            if a is None or c.robust:
                break  # this run's best robust, or its best unaudited: nothing below it can beat them
    return best


def _fell(audit) -> bool:
    """The audit's ensemble fell under some nudge (more than half its members; ``sanlab.audit``)."""
    return any(bool(v) for v in dict(audit.result.get("fell") or {}).values())


def _same(a: float | None, b: float | None) -> bool:
    return a is None or b is None or abs(a - b) <= 1e-9 * max(1.0, abs(a))


def measure(lib: Library, creature_text: str, source: str, *, evaluations: int = EVALUATIONS, seed: int = 0,
            reporter=None, log=None, backend=None, resume: str | None = None) -> tuple[str, Ceiling | None]:
    """Search patterns on the creature (``evaluations`` of them; or go on with the pattern run
    ``resume``), then audit its best (up to :data:`AUDITED`, storing each audit) until one is
    robust; returns (the run id, the creature's ceiling from :func:`find`, which may be an earlier
    run's when that one is faster). ``backend``: where the search and the audits evaluate
    (default: this machine). A pattern search of the same file, budget and seed already in
    ``lib`` is taken as it is, or continued where it was interrupted (``sanlab reproduce
    --ceiling`` resumes so)."""
    from sanlab.audit import audit_and_store
    from sanlab.search.pattern import POPSIZE
    from sanlab.search.runner import run_search

    if resume is None:
        for run in lib.runs():
            s = run.settings
            if (run.kind == "search" and isinstance(s, SearchSettings) and s.strategy == "pattern"
                    and run.creature_text == creature_text and s.controllers == evaluations and run.seed == seed
                    and s.batch == POPSIZE and s.imported_from is None):
                resume = run.run_id
                break
    if resume is not None and lib.get_run(resume).status == "done":
        run_id = resume
    else:
        run_id = run_search(lib, creature_text, source, controllers=evaluations, seed=seed, batch=POPSIZE,
                            strategy="pattern", reporter=reporter, backend=backend, resume=resume)
    audits = lib.audits(run_id)
    for e in lib.top(run_id, AUDITED):
        if e.nonfinite or e.fell:
            break
        if e.idx not in audits:
            audit_and_store(lib, e.gait_id, log=log, backend=backend)
        a = lib.audits(run_id)[e.idx]
        if a.verdict == "robust" and not _fell(a):
            break
    run = lib.get_run(run_id)
    s = run.settings
    assert isinstance(s, SearchSettings)
    return run_id, find(lib, run.creature_text, s.metric, s.seconds)
