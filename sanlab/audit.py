"""The artefact audit: does a gait's speed survive a nudge? (issue 10, "Robust scores")

A SAN in closed loop with contacts is chaotic, and a search finds every flaw of its simulator:
a gait whose speed only exists on one exact float32 trajectory, or at one step size, is an
artefact of the integrator, not a result. :func:`audit` re-scores a stored gait exactly as it
was scored (the same creature, parameters, metric, evaluation time, terrain set, ensemble and
ensemble draws) under each *nudge* of :data:`NUDGES`: the step halved and quartered, and the
arithmetic in float64. It is flagged *resolution-dependent* when a nudge changes its robust
speed by more than ``threshold`` (default 10 %) of the speed re-scored without a nudge; speeds
are compared relative to at least :data:`FLOOR_CM_S`, so a gait that stands still is not flagged
for moving 0.02 instead of 0.01 cm/s. It is flagged *not reproduced* when the speed re-scored
without a nudge is that far from the stored one: a score stored by another engine, or edited in
an imported file, is not vouched for however well it survives the nudges.

Every nudged evaluation replays the same compiled step (``sanlab.evaluate.Evaluator``), only
with another ``dt`` or dtype: there is no second physics.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sanlab.evaluate import Evaluator
from sanlab.evaluate.ensemble import Key, heldout_key, search_key
from sanlab.gait import Gait
from sanlab.library import Library, LibraryError, SearchSettings, TuneSettings
from sanlab.search.space import Space

THRESHOLD = 0.10
FLOOR_CM_S = 1.0

# (name, factor on dt, dtype)
NUDGES: tuple[tuple[str, float, str], ...] = (
    ("dt/2", 0.5, "float32"),
    ("dt/4", 0.25, "float32"),
    ("float64", 1.0, "float64"),
)


@dataclass(frozen=True)
class Audit:
    """One gait's audit. Speeds in cm/s, each the robust (ensemble median) speed of the gait's
    own ensemble; ``changes`` are relative to ``nominal_cm_s`` (at least :data:`FLOOR_CM_S`)."""

    gait_id: str  # "RUN#IDX"
    stored_cm_s: float  # as stored in the library
    nominal_cm_s: float  # re-scored as stored (dt, float32)
    speeds: dict[str, float]  # nudge name -> speed
    changes: dict[str, float]  # nudge name -> relative change
    fell: dict[str, bool]  # nudge name -> the ensemble fell (more than half its members)
    threshold: float
    dt: float  # the creature's step (s)
    members: int  # ensemble members

    @property
    def worst(self) -> float:
        return max(self.changes.values(), default=0.0)

    @property
    def resolution_dependent(self) -> bool:
        """Some nudge changed the speed by more than the threshold."""
        return self.worst > self.threshold

    @property
    def stored_change(self) -> float:
        """How far the stored speed is from the one re-scored without a nudge (relative, as
        ``changes``)."""
        a, b = self.stored_cm_s, self.nominal_cm_s
        if not (math.isfinite(a) and math.isfinite(b)):
            return 0.0 if (math.isnan(a) and math.isnan(b)) or a == b else math.inf
        return abs(a - b) / max(abs(b), FLOOR_CM_S)

    @property
    def reproduced(self) -> bool:
        """The stored speed is what this sanlab re-scores, within the threshold."""
        return self.stored_change <= self.threshold

    @property
    def flagged(self) -> bool:
        """The audit does not vouch for the stored speed: resolution-dependent or not reproduced."""
        return self.resolution_dependent or not self.reproduced

    def summary(self) -> str:
        """One line, e.g. "robust: worst change 3 % (dt/4)"."""
        if not self.changes:
            return "not audited"
        if not self.reproduced:
            return f"NOT REPRODUCED: stored {self.stored_cm_s:.1f} cm/s, re-scored {self.nominal_cm_s:.1f}"
        name = max(self.changes, key=lambda k: self.changes[k])
        what = "RESOLUTION-DEPENDENT" if self.resolution_dependent else "robust"
        return f"{what}: worst change {100 * self.worst:.0f} % ({name})"

    def to_json(self) -> dict[str, Any]:
        return {"stored_cm_s": _finite(self.stored_cm_s), "nominal_cm_s": _finite(self.nominal_cm_s),
                "reproduced": self.reproduced, "resolution_dependent": self.resolution_dependent,
                "speeds": {k: _finite(v) for k, v in self.speeds.items()},
                "changes": {k: _finite(v) for k, v in self.changes.items()}, "fell": dict(self.fell),
                "threshold": self.threshold, "dt": self.dt, "members": self.members}


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def gait_key(lib: Library, gait: Gait) -> Key:
    """The ensemble key a stored gait was scored with: a search's controller ``idx``, a tuning
    run's held-out evaluation (an imported gait: the held-out key of seed 0)."""
    run_id, idx = gait.gait_id.split("#")
    run = lib.get_run(run_id)
    s = run.settings
    if isinstance(s, TuneSettings):
        return heldout_key(s.seed, s.chain)
    if isinstance(s, SearchSettings) and run.kind == "search":
        return search_key(run.seed or 0, int(idx))
    return heldout_key(0, 0)


def nudged_evaluator(spec, factor: float, dtype: str, *, batch: int, metric, seconds, terrain, ensemble,
                     morphology: bool) -> Evaluator:
    """The evaluator of ``spec`` with its step scaled by ``factor`` and in ``dtype``, otherwise
    as the gait was scored: every nudge replays the same compiled step, only with another ``dt``
    or dtype."""
    spec = dataclasses.replace(spec, dt=spec.dt * factor)
    return Evaluator(spec, metric=metric, seconds=seconds, dtype=dtype, batch=batch, terrain=terrain,
                     ensemble=ensemble, space=Space(spec, morphology=morphology))


def audit(lib: Library, gait_id: str, *, nudges: tuple[tuple[str, float, str], ...] = NUDGES,
          threshold: float = THRESHOLD, log=None) -> Audit:
    """Audit the gait ``gait_id`` ("RUN/RANK" or "RUN#IDX") of ``lib`` (see the module
    docstring); store nothing. Raises LibraryError for an unknown gait."""
    g = _stored_gait(lib, gait_id)
    run = lib.get_run(g.gait_id.split("#")[0])
    s = run.settings
    terrain = s.terrain if isinstance(s, TuneSettings) else "flat"
    key = gait_key(lib, g)
    morphology = g.params.scale is not None
    # A phase-1 gait is scored as its search scored it, with the creature file's own parameters
    # (a parameter vector takes another compiled path, equal only to the last bits, and a chaotic
    # gait would already differ there); a tuned or imported one with its parameter vector.
    theta = None if run.kind == "search" else Space(g.spec, morphology=morphology).nominal(g.params)[None]

    def speed(factor: float, dtype: str) -> tuple[float, bool]:
        ev = nudged_evaluator(g.spec, factor, dtype, batch=1, metric=g.metric, seconds=g.seconds, terrain=terrain,
                              ensemble=g.ensemble, morphology=morphology)
        r = ev(g.weights[None], theta, [key])
        return float(r.speed_cm_s[0]), bool(r.fell[0])

    nominal, _ = speed(1.0, run.dtype or "float32")  # as it was scored
    if log:
        log(f"{g.gait_id}: {nominal:.1f} cm/s re-scored as it was scored (stored {g.speed_cm_s:.1f})")
    speeds, changes, fell = {}, {}, {}
    for name, factor, dtype in nudges:
        v, f = speed(factor, dtype)
        speeds[name], fell[name] = v, f
        changes[name] = abs(v - nominal) / max(abs(nominal), FLOOR_CM_S) if np.isfinite(v) else math.inf
        if log:
            log(f"{g.gait_id}: {v:.1f} cm/s at {name} (changed {100 * changes[name]:.0f} %)")
    return Audit(g.gait_id, g.speed_cm_s, nominal, speeds, changes, fell, threshold, g.spec.dt, g.ensemble.members)


def audit_and_store(lib: Library, gait_id: str, **kw) -> Audit:
    """:func:`audit`, then the result stored in the library (replacing an earlier audit)."""
    a = audit(lib, gait_id, **kw)
    lib.add_audit(a.gait_id, a.to_json(), flagged=a.flagged, worst=a.worst)
    return a


# -- audited selection of a tuning run's gait --------------------------------------------------

SELECT_TOP = 16  # a tuning run's best visited vectors audited by select_robust
SELECTED_IDX = 1  # the evaluation index of a tuning run's audited selection (#0: the chain's best)


@dataclass(frozen=True)
class Candidate:
    """One vector a tuning chain visited (the start, or an accepted trial), as audited."""

    trial: int  # -1: the chain's start (the parent gait's parameters)
    chain_score: float  # the score the chain saw (one ensemble draw of the trial)
    nominal_cm_s: float  # re-scored on the held-out ensemble, as the tuned gait is
    speeds: dict[str, float]  # nudge name -> speed
    changes: dict[str, float]  # nudge name -> relative change (against nominal_cm_s)
    score: float  # the held-out score (what the selection maximises among the robust)

    @property
    def worst(self) -> float:
        return max(self.changes.values(), default=0.0)

    def to_json(self) -> dict[str, Any]:
        return {"trial": self.trial, "chain_score": _finite(self.chain_score), "nominal_cm_s": _finite(self.nominal_cm_s),
                "speeds": {k: _finite(v) for k, v in self.speeds.items()},
                "changes": {k: _finite(v) for k, v in self.changes.items()}, "score": _finite(self.score)}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Candidate:
        num = lambda v, missing: missing if v is None else float(v)
        return cls(int(d["trial"]), num(d.get("chain_score"), math.nan), num(d.get("nominal_cm_s"), math.nan),
                   {k: num(v, math.nan) for k, v in d.get("speeds", {}).items()},
                   {k: num(v, math.inf) for k, v in d.get("changes", {}).items()}, num(d.get("score"), -math.inf))


@dataclass(frozen=True)
class Selection:
    """:func:`select_robust`'s outcome: the audited candidates (best chain score first) and the
    stored gait ("RUN#1"), or None when no candidate kept its speed."""

    run_id: str
    gait_id: str | None
    chosen: Candidate | None
    candidates: list[Candidate]
    threshold: float


def _stored_gait(lib: Library, gait_id: str) -> Gait:
    """``Gait.from_library``, with a stored gait that does not decode (a damaged row, or one this
    sanlab cannot read) as a one-line LibraryError naming it."""
    try:
        return Gait.from_library(lib, gait_id)
    except ValueError as e:
        raise LibraryError(f"{lib.path}: gait {lib.gait(gait_id).gait_id} cannot be decoded ({e})") from None


def rung_name(trial: int) -> str:
    """How a rung is named in reports: "the start" (trial -1) or "trial N"."""
    return "the start" if trial == -1 else f"trial {trial}"


def _tuning_run(lib: Library, run_id: str):
    """The tuning run ``run_id`` and its settings; LibraryError for any other kind of run."""
    run = lib.get_run(run_id)
    s = run.settings
    if run.kind != "tune" or not isinstance(s, TuneSettings) or run.parent_gait is None:
        raise LibraryError(f"run {run.run_id} is {'an' if run.kind[0] in 'aeiou' else 'a'} {run.kind} run, "
                           "not a tuning run")
    return run, s


def visited(lib: Library, run_id: str) -> list[tuple[int, float, np.ndarray]]:
    """The vectors a finished or interrupted tuning run's chain stood on, in order: its start
    (trial -1, the parent gait's parameters, its start score) and every accepted trial, rebuilt
    from the stored trace with the chain's own random choices (so exactly the chain's vectors).
    Raises LibraryError when ``run_id`` is not a tuning run."""
    from sanlab.creature import loads
    from sanlab.search import registry
    from sanlab.search.base import Problem, Start
    from sanlab.search.chain import Chain

    run, s = _tuning_run(lib, run_id)
    assert run.parent_gait is not None
    spec = loads(run.creature_text, source=s.source or run.creature)
    space = Space(spec, morphology=s.morphology)
    parent = _stored_gait(lib, run.parent_gait)
    theta = space.nominal(parent.params)
    chain = registry.make(s.method, Problem(run.run_id, space.san, s.trials, s.seed, s.chain, space,
                                            Start(parent.weights, theta, parent.gait_id), dtype=run.dtype or "float32"))
    assert isinstance(chain, Chain)  # every phase-2 strategy is one
    final = lib.gait(f"{run.run_id}#0").extra if 0 in lib.done_indices(run.run_id) else None
    before = (final or {}).get("before", {}).get("score")
    out = [(-1, float("nan") if before is None else float(before), theta)]
    for p in lib.trace(run.run_id):
        if p.accepted:
            theta = space.perturb(theta, chain.which[p.trial], chain.sign[p.trial])
            out.append((p.trial, p.score, theta))
    return out


def ladder(path: list[tuple[int, float, np.ndarray]], n: int) -> list[tuple[int, float, np.ndarray]]:
    """At most ``n`` rungs of a chain's climb: for ``n`` scores evenly spaced from its start's
    score to its best, the first vector on ``path`` (:func:`visited`) that reached it, so the
    start, the best and the steps between are all audited; the chain's many near-copies of its
    best (accepted moves of parameters that barely matter) are not audited over and over."""
    finite = [v for v in path if np.isfinite(v[1])]
    if not finite:
        return path[:1]
    lo, hi = finite[0][1], max(v[1] for v in finite)
    out: list[tuple[int, float, np.ndarray]] = []
    for j in range(n):
        level = lo + (hi - lo) * j / max(1, n - 1)
        first = next(v for v in finite if v[1] >= level - 1e-12 * max(1.0, abs(level)))
        if not any(first is o for o in out):
            out.append(first)
    return out


def select_robust(lib: Library, run_id: str, *, top: int = SELECT_TOP, threshold: float = THRESHOLD,
                  log=None) -> Selection:
    """Audited selection of a finished tuning run's gait: ``top`` vectors of its chain (the
    rungs of its climb, :func:`ladder`: its start, its best and the steps between) are re-scored
    on the tuned gait's held-out ensemble and under every nudge of :data:`NUDGES`, and the one
    with the best held-out score among those whose speed no nudge moves by more than
    ``threshold`` is stored as the run's evaluation #1 with its audit (the start itself, when no
    tuned rung survives). A chain's best is often a vector that only works at its step (issue
    10: annealing learns the integrator); its best *robust* vector is the result to report. The
    chain's best itself (#0) is audited and its audit stored too, unless it has one already.

    The selection's record (every rung's speeds) is stored in the library whatever its outcome,
    and one made with the same ``top`` and ``threshold`` is reused; made again with others, a
    gait chosen before that no rung now earns is removed. Returns the :class:`Selection`
    (``gait_id`` None: no rung kept its speed). Raises ValueError for a threshold that is not a
    finite number >= 0 or ``top`` < 1, LibraryError for a run that is not a finished tuning run."""
    from sanlab import sim
    from sanlab.evaluate.ensemble import heldout_key
    from sanlab.library.records import EvaluationRow

    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold >= 0):
        raise ValueError(f"threshold: expected a finite number >= 0, got {threshold!r}")
    if top < 1:
        raise ValueError(f"top: expected >= 1, got {top}")
    run, s = _tuning_run(lib, run_id)
    assert run.parent_gait is not None
    if 0 not in lib.done_indices(run.run_id):
        raise LibraryError(f"run {run.run_id} has not finished: resume its tuning first")
    settings = {"top": top, "threshold": threshold}
    gait_id = f"{run.run_id}#{SELECTED_IDX}"
    reused = _stored_selection(lib, run.run_id, settings, threshold)
    if reused is not None:
        return reused

    ranked = ladder(visited(lib, run.run_id), top)
    parent = _stored_gait(lib, run.parent_gait)
    spec0 = parent.spec
    thetas = np.stack([v[2] for v in ranked])
    weights = np.repeat(parent.weights[None], len(ranked), axis=0)
    keys = [heldout_key(s.seed, s.chain)] * len(ranked)

    def scores(factor: float, dtype: str):
        ev = nudged_evaluator(spec0, factor, dtype, batch=len(ranked), metric=s.metric, seconds=s.seconds,
                              terrain=s.terrain, ensemble=s.ensemble, morphology=s.morphology)
        return ev(weights, thetas, keys)

    nominal = scores(1.0, run.dtype or "float32")  # as the chain scored it
    nudged = {name: scores(factor, dtype) for name, factor, dtype in NUDGES}
    cands = []
    for k, (trial, chain_score, _) in enumerate(ranked):
        v0 = float(nominal.speed_cm_s[k])
        speeds = {n: float(b.speed_cm_s[k]) for n, b in nudged.items()}
        changes = {n: abs(v - v0) / max(abs(v0), FLOOR_CM_S) if np.isfinite(v) and np.isfinite(v0) else math.inf
                   for n, v in speeds.items()}
        ok = np.isfinite(nominal.score[k]) and not bool(nominal.nonfinite[k])
        cands.append(Candidate(int(trial), float(chain_score), v0, speeds, changes,
                               float(nominal.score[k]) if ok else -math.inf))
        if log:
            log(f"{rung_name(trial)}: {v0:.1f} cm/s held out, worst change {100 * cands[-1].worst:.0f} %")
    robust = [k for k, c in enumerate(cands) if c.worst <= threshold and np.isfinite(c.score)]
    record = {"settings": settings, "candidates": [c.to_json() for c in cands], "trial": None, "fell": {}}
    tuned = f"{run.run_id}#0"  # the chain's best: audited too, so that show and exports flag it
    if lib.audit(tuned) is None:
        audit_and_store(lib, tuned, threshold=threshold)
    if not robust:
        lib.put_selection(run.run_id, SELECTED_IDX, record)
        return Selection(run.run_id, None, None, cands, threshold)
    k = max(robust, key=lambda i: cands[i].score)
    chosen = cands[k]
    record["trial"], record["fell"] = chosen.trial, {n: bool(b.fell[k]) for n, b in nudged.items()}
    space = Space(spec0, morphology=s.morphology)
    model = sim.compile_creature(spec0, run.dtype or "float32")
    row = EvaluationRow(run.run_id, SELECTED_IDX, space.san.encode(parent.weights), space.gait_params(thetas[k], model),
                        nominal.row(k), {"selected": {"trial": chosen.trial}, "theta": thetas[k].tolist()},
                        run.parent_gait)
    a = Audit(gait_id, float(nominal.speed_cm_s[k]), chosen.nominal_cm_s, chosen.speeds, chosen.changes, record["fell"],
              threshold, spec0.dt, s.ensemble.members)
    lib.put_selection(run.run_id, SELECTED_IDX, record, row.to_json(), a.to_json(), flagged=a.flagged, worst=a.worst)
    return Selection(run.run_id, gait_id, chosen, cands, threshold)


def _stored_selection(lib: Library, run_id: str, settings: dict, threshold: float) -> Selection | None:
    """The stored selection made with ``settings``, or None (none, other settings, or a record
    that does not read: it is made again). Its gait's audit is stored again when a plain audit
    with another threshold replaced it (or it went missing)."""
    rec = lib.selection(run_id)
    if rec is None or rec.get("settings") != settings:
        return None
    try:
        cands = [Candidate.from_json(c) for c in rec["candidates"]]
        trial = rec["trial"]
        if trial is None or rec["idx"] is None:
            return Selection(run_id, None, None, cands, threshold)
        chosen = next(c for c in cands if c.trial == trial)
        stored = lib.gait(f"{run_id}#{rec['idx']}")
        fell = {str(k): bool(v) for k, v in dict(rec.get("fell") or {}).items()}
    except (KeyError, TypeError, ValueError, AttributeError, StopIteration, LibraryError):
        return None  # a record that does not read, or its gait is gone: make it again
    gait_id = stored.gait_id
    audit_rec = lib.audit(gait_id)
    if audit_rec is None or audit_rec.result.get("threshold") != threshold:
        g = _stored_gait(lib, gait_id)
        a = Audit(gait_id, stored.speed_cm_s, chosen.nominal_cm_s, chosen.speeds, chosen.changes, fell, threshold,
                  g.spec.dt, g.ensemble.members)
        lib.add_audit(gait_id, a.to_json(), flagged=a.flagged, worst=a.worst)
    return Selection(run_id, gait_id, chosen, cands, threshold)

