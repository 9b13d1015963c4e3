"""The artefact audit: does a gait's speed survive a nudge? (issues 10 and 28)

A SAN in closed loop with contacts is chaotic, and a search finds every flaw of its simulator:
a gait whose speed only exists on one exact float32 trajectory, or at one step size, is an
artefact of the integrator, not a result. :func:`audit` re-scores a stored gait under each
*nudge* of :data:`NUDGES` (the step halved and quartered; the kernel computes in float64, so
the float32 engine's third nudge, float64, is the nominal now) and asks whether the nudge moved its speed *distribution*.

The statistic (issue 28, part 1). A chaotic gait's median speed over a few perturbed starts is
itself a sample: the median of 8 moves by +-20 % under any nudge, or none. So the audit draws its
own ensemble of :data:`MEMBERS` members (``members``; the gait's pose, angle and friction
perturbations, on a stream of its own, :func:`~sanlab.evaluate.ensemble.audit_key`), simulates
every member at the gait's own step and under each nudge, and bootstraps the relative change of
the members' mean speed, (mean(nudged) - mean(nominal)) / max(mean(nominal), 1 cm/s), resampling
members jointly (member i starts from the same draw under every nudge, so the pairing is kept
where it helps, a limit cycle, and costs nothing where it does not, chaos). With the percentile
interval of that change at :data:`LEVEL` (Bonferroni-split over the nudges, so that the level
holds for the verdict as a whole), a nudge is

- *robust* when the interval lies inside the band +-``threshold`` (default 10 %),
- *resolution-dependent* when it lies wholly outside it (or a member blew up under the nudge),
- *undecided* otherwise; the audit then says how many members would likely decide it (the
  interval narrows about its estimate as 1/sqrt(members): the side that crosses the band's edge
  says how far, always more than the members it had).

The gait is robust when every nudge is, resolution-dependent when some nudge is, and undecided
otherwise; undecided is not a pass. Why this statistic: it asks the question (did the step move
the speed by more than the band?) with its own uncertainty, and needs no assumption about the
distribution's shape. Why the mean and not the median every score uses: chaotic gaits' speeds
are often bimodal (some starts fall into the gait, some do not), and the median of such a set
jumps between the modes under resampling, so its interval spans both and decides nothing (a
tuned cart: 7.5 cm/s at the step, 0.25 at dt/2, interval -97 % .. +13 %); the mean moves
smoothly with the share of starts in each mode, and its interval narrows as 1/sqrt(members).

It is also flagged *not reproduced* when the gait, re-scored exactly as it was stored (its own
ensemble, draws and step), is more than ``threshold`` from the stored speed: a score stored by
another engine, or edited in an imported file, is not vouched for however well it survives the
nudges. So is a gait scored in float32 by a sanlab older than 0.2.0 (``Run.old_float32``),
whatever its re-scored speed: that float32 was another arithmetic (the XLA engine's, then float64
on float32-rounded numbers), and this sanlab's float32 computes in float32 (issue 58), so its
stored score cannot be re-scored as it was made.

Every nudged evaluation runs the same kernel (``sanlab.evaluate.Evaluator``), only with another
``dt``: there is no second physics.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sanlab.evaluate import Evaluator, Request
from sanlab.evaluate.backends import Backend, evaluate_all
from sanlab.evaluate.ensemble import Ensemble, Key, audit_key, confirm_key, heldout_key, search_key
from sanlab.gait import Gait
from sanlab.library import Library, LibraryError, SearchSettings, TuneSettings
from sanlab.search.space import Space

THRESHOLD = 0.10
FLOOR_CM_S = 1.0
# The audit's own ensemble, and how far an undecided audit looks again. On the kernel a member
# costs a creature's rollout at dt, dt/2 and dt/4 (7 of them), about 6 ms for a 6 s bounder on
# 2 cores: 64 members take ~0.4 s, a last look on 1024 about 6 s (the XLA engine's 32 and 256
# left 15 of Table 1's 50 tuned chain bests undecided).
MEMBERS = 64
MAX_MEMBERS = 1024
LEVEL = 0.95  # confidence of the verdict, over all nudges together
RESAMPLES = 2000  # bootstrap resamples
MAX_MEMBERS_ADVISED = 4096  # the most `sanlab audit --members` takes
MAX_MEMBERS_SAID = 100_000  # beyond this, "how many members would decide it" is not a useful answer

ROBUST, DEPENDENT, UNDECIDED, NOT_REPRODUCED = "robust", "resolution-dependent", "undecided", "not reproduced"

# (name, factor on dt, dtype). Every nudge runs in float64, the audit's reference: a float32
# gait's nudge changes its arithmetic too, which moves a speed distribution far less than the band
# (issue 58: on all ten creatures float32's median score lies inside float64's 95 % interval), so
# precision is not a nudge of its own; the XLA engine's float32 runs were audited against float64
# too, and their stored audits keep that nudge's name and numbers.
NUDGES: tuple[tuple[str, float, str], ...] = (
    ("dt/2", 0.5, "float64"),
    ("dt/4", 0.25, "float64"),
)


@dataclass(frozen=True)
class Shift:
    """How one nudge moved a gait's speed distribution (see the module docstring).

    change: the relative change of the members' mean speed (signed; at least 1 cm/s in the
    denominator); lo, hi: its bootstrap interval; verdict: :data:`ROBUST`, :data:`DEPENDENT` or
    :data:`UNDECIDED`; needed: for an undecided one, about how many members would decide it
    (None: decided, or more than :data:`MAX_MEMBERS_SAID`)."""

    change: float
    lo: float
    hi: float
    verdict: str
    needed: int | None = None

    def to_json(self) -> dict[str, Any]:
        return {"change": _finite(self.change), "lo": _finite(self.lo), "hi": _finite(self.hi),
                "verdict": self.verdict, "needed": self.needed}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Shift:
        num = lambda v, missing: missing if v is None else float(v)
        return cls(num(d.get("change"), math.inf), num(d.get("lo"), -math.inf), num(d.get("hi"), math.inf),
                   str(d["verdict"]), None if d.get("needed") is None else int(d["needed"]))


def shift(nominal, nudged, threshold: float = THRESHOLD, *, level: float = LEVEL, resamples: int = RESAMPLES,
          seed: int = 0) -> Shift:
    """The :class:`Shift` from member speeds ``nominal`` [M] to ``nudged`` [M] (cm/s; member i
    of both started from the same draw), with a ``level`` percentile bootstrap interval of
    ``resamples`` joint resamples of the members (seeded: the same speeds give the same answer).
    Non-finite speeds are an artefact: resolution-dependent. Raises ValueError for arrays of
    different or zero length."""
    a, b = np.asarray(nominal, float).reshape(-1), np.asarray(nudged, float).reshape(-1)
    if len(a) != len(b) or len(a) == 0:
        raise ValueError(f"shift: expected two equal, non-empty sets of member speeds, got {len(a)} and {len(b)}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return Shift(math.inf, math.inf, math.inf, DEPENDENT)
    rel = lambda ma, mb: (mb - ma) / np.maximum(np.abs(ma), FLOOR_CM_S)
    change = float(rel(np.mean(a), np.mean(b)))
    idx = np.random.default_rng(seed).integers(0, len(a), (resamples, len(a)))
    boot = rel(np.mean(a[idx], axis=1), np.mean(b[idx], axis=1))
    alpha = 1.0 - level
    lo, hi = (float(x) for x in np.quantile(boot, [alpha / 2, 1 - alpha / 2]))
    t = threshold
    if -t <= lo and hi <= t:
        return Shift(change, lo, hi, ROBUST)
    if lo > t or hi < -t:
        return Shift(change, lo, hi, DEPENDENT)
    # The interval narrows about its estimate as 1/sqrt(members): it decides once every side that
    # crosses the band's edge no longer does. (The half-width would do for a symmetric interval; a
    # bootstrap one is not, and the half-width named fewer members than the audit had used.)
    if -t < change < t:  # robust, once both ends are inside the band
        ratio = max((hi - change) / (t - change), (change - lo) / (t + change))
    elif change > t:  # resolution-dependent, once its lower end is above the band
        ratio = (change - lo) / (change - t)
    elif change < -t:
        ratio = (hi - change) / (-t - change)
    else:  # on the edge: no number of members decides it
        ratio = math.inf
    needed = max(len(a) + 1, math.ceil(len(a) * ratio**2)) if math.isfinite(ratio) else None
    return Shift(change, lo, hi, UNDECIDED, needed if needed is not None and needed <= MAX_MEMBERS_SAID else None)


def combine(shifts: dict[str, Shift]) -> str:
    """A gait's verdict from its nudges': resolution-dependent if any is, robust if all are,
    else undecided."""
    verdicts = {s.verdict for s in shifts.values()}
    if DEPENDENT in verdicts:
        return DEPENDENT
    return ROBUST if verdicts <= {ROBUST} else UNDECIDED


def needed(shifts: dict[str, Shift]) -> int | None:
    """Members that would likely decide the undecided nudges (None: none undecided, or too many)."""
    und = [s for s in shifts.values() if s.verdict == UNDECIDED]
    if not und or any(s.needed is None for s in und):
        return None
    return max(s.needed for s in und if s.needed is not None)


def audit_ensemble(ensemble: Ensemble, members: int = MEMBERS) -> Ensemble:
    """The audit's ensemble for a gait scored with ``ensemble``: its start and friction
    perturbations, ``members`` members, every member at the one step being audited (no step
    jitter, no members at other steps: the nudge is the only change of step)."""
    return Ensemble(members=int(members), pose=ensemble.pose, angle=ensemble.angle, friction=ensemble.friction)


def level_each(level: float, n: int) -> float:
    """Each of ``n`` nudges' interval level for a verdict at ``level`` over all of them."""
    return 1.0 - (1.0 - level) / max(1, n)


@dataclass(frozen=True)
class Audit:
    """One gait's audit (see the module docstring). Speeds in cm/s: ``stored_cm_s`` as stored,
    ``nominal_cm_s`` re-scored exactly as stored (the gait's own ensemble), ``reference_cm_s``
    and ``speeds`` (nudge name -> speed) the means over the audit's ``audit_members`` members
    at the gait's own step and under each nudge; ``shifts`` each nudge's :class:`Shift`."""

    gait_id: str  # "RUN#IDX"
    stored_cm_s: float
    nominal_cm_s: float
    reference_cm_s: float
    speeds: dict[str, float]
    shifts: dict[str, Shift]
    fell: dict[str, bool]  # nudge name -> the audit's ensemble fell (more than half its members)
    threshold: float
    dt: float  # the creature's step (s)
    members: int  # the gait's ensemble members
    audit_members: int
    level: float
    old_float32: bool = False  # scored by an older sanlab's float32, another arithmetic (module docstring)

    @property
    def changes(self) -> dict[str, float]:
        """Each nudge's relative change of the mean speed, as a magnitude."""
        return {k: abs(s.change) for k, s in self.shifts.items()}

    @property
    def worst(self) -> float:
        return max(self.changes.values(), default=0.0)

    @property
    def verdict(self) -> str:
        """:data:`NOT_REPRODUCED`, :data:`DEPENDENT`, :data:`UNDECIDED` or :data:`ROBUST`."""
        return NOT_REPRODUCED if not self.reproduced else combine(self.shifts)

    @property
    def resolution_dependent(self) -> bool:
        """Some nudge moved the speed distribution outside the band (with the interval's confidence)."""
        return combine(self.shifts) == DEPENDENT

    @property
    def needed(self) -> int | None:
        """For an undecided audit, about how many members would decide it."""
        return needed(self.shifts)

    @property
    def stored_change(self) -> float:
        """How far the stored speed is from the one re-scored as stored (relative, as ``changes``)."""
        a, b = self.stored_cm_s, self.nominal_cm_s
        if not (math.isfinite(a) and math.isfinite(b)):
            return 0.0 if (math.isnan(a) and math.isnan(b)) or a == b else math.inf
        return abs(a - b) / max(abs(b), FLOOR_CM_S)

    @property
    def reproduced(self) -> bool:
        """The stored speed is what this sanlab re-scores, within the threshold, in the arithmetic
        it was scored in (not an older sanlab's float32)."""
        return self.stored_change <= self.threshold and not self.old_float32

    @property
    def flagged(self) -> bool:
        """The audit does not vouch for the stored speed: resolution-dependent, undecided or not
        reproduced."""
        return self.verdict != ROBUST

    def summary(self) -> str:
        """One line, e.g. "robust: worst change 3 % (dt/4)"."""
        if not self.shifts:
            return "not audited"
        if self.old_float32:
            return (f"NOT REPRODUCED: stored {self.stored_cm_s:.1f} cm/s by an older sanlab's float32, which did not "
                    f"compute in float32; re-scored {self.nominal_cm_s:.1f} in float32 arithmetic")
        if not self.reproduced:
            return f"NOT REPRODUCED: stored {self.stored_cm_s:.1f} cm/s, re-scored {self.nominal_cm_s:.1f}"
        name = max(self.changes, key=lambda k: self.changes[k])
        v = self.verdict
        what = {DEPENDENT: "RESOLUTION-DEPENDENT", UNDECIDED: "UNDECIDED"}.get(v, v)
        tail = f"; about {self.needed} members would decide it" if v == UNDECIDED and self.needed else ""
        return f"{what}: worst change {100 * self.worst:.0f} % ({name}){tail}"

    def to_json(self) -> dict[str, Any]:
        return {"verdict": self.verdict, "stored_cm_s": _finite(self.stored_cm_s),
                "nominal_cm_s": _finite(self.nominal_cm_s), "reference_cm_s": _finite(self.reference_cm_s),
                "reproduced": self.reproduced, "resolution_dependent": self.resolution_dependent,
                "needed": self.needed, "speeds": {k: _finite(v) for k, v in self.speeds.items()},
                "changes": {k: _finite(v) for k, v in self.changes.items()},
                "shifts": {k: v.to_json() for k, v in self.shifts.items()}, "fell": dict(self.fell),
                "threshold": self.threshold, "level": self.level, "dt": self.dt, "members": self.members,
                "audit_members": self.audit_members}


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


def shifts_of(ref, nudged: dict, k: int, threshold: float, level: float
              ) -> tuple[dict[str, float], dict[str, Shift], dict[str, bool]]:
    """Evaluation ``k``'s speeds, shifts and falls under each nudge, from the ScoreBatch ``ref``
    (the audit's members at the gait's own step) and ``nudged`` (nudge name -> ScoreBatch); an
    evaluation with a member that blew up is resolution-dependent."""
    each = level_each(level, len(nudged))
    speeds, shifts, fell = {}, {}, {}
    for name, b in nudged.items():
        speeds[name], fell[name] = float(np.mean(b.member_speed_cm_s[k])), bool(b.fell[k])
        if bool(b.nonfinite[k]) or bool(ref.nonfinite[k]):
            shifts[name] = Shift(math.inf, math.inf, math.inf, DEPENDENT)
        else:
            shifts[name] = shift(ref.member_speed_cm_s[k], b.member_speed_cm_s[k], threshold, level=each)
    return speeds, shifts, fell


@dataclass(frozen=True)
class Look:
    """One evaluation's audit on ``members`` members: their mean speed (``reference``) and
    median score at the gait's own step, and each nudge's mean speed, shift and fall."""

    members: int
    reference: float
    score: float
    speeds: dict[str, float]
    shifts: dict[str, Shift]
    fell: dict[str, bool]


def second_look(members: int, need: int | None, max_members: int) -> int | None:
    """The members of an undecided audit's next look: about what it said would decide it (a
    quarter more, in multiples of 32, at least twice the first), at most ``max_members``; None
    when it asked for far more than that, or no more can be had."""
    if need is None or max_members <= members or need > 2 * max_members:
        return None
    return min(max_members, max(2 * members, 32 * math.ceil(1.25 * need / 32)))


def decide(evaluate, n: int, members: int, max_members: int, threshold: float, level: float,
           log=None) -> list[Look]:
    """Audit ``n`` evaluations: ``evaluate(M, rows)`` -> (ScoreBatch at the gait's own step,
    {nudge name: ScoreBatch}) of the evaluations ``rows`` (indices into the n) for ``M`` members
    each. Those left undecided are looked at again, all at the size the most demanding of them
    asked for (:func:`second_look`: at least twice the last look), until each is decided, or a
    look on ``max_members`` is made, or one asks for far more; the last look's verdict stands.
    A second look simulates only the evaluations it looks at again. (Each look is a 95 %
    interval: the chance of a false verdict grows with the looks, which the Bonferroni split over
    the nudges more than pays for in practice; at the defaults there are at most five looks, 64
    to 1024 members.)"""
    def looks(M: int, rows: list[int]) -> list[Look]:
        ref, nudged = evaluate(M, rows)
        out = []
        for k in range(len(rows)):
            speeds, shifts, fell = shifts_of(ref, nudged, k, threshold, level)
            ok = np.isfinite(ref.score[k]) and not bool(ref.nonfinite[k])
            out.append(Look(M, float(np.mean(ref.member_speed_cm_s[k])), float(ref.score[k]) if ok else -math.inf,
                            speeds, shifts, fell))
        return out

    result = looks(members, list(range(n)))
    while True:
        again = [k for k, x in enumerate(result) if combine(x.shifts) == UNDECIDED]
        sizes = [second_look(result[k].members, needed(result[k].shifts), max_members) for k in again]
        if all(m is None for m in sizes):  # none undecided, or none another look could decide
            return result
        M = max(m for m in sizes if m is not None)
        rows = [k for k, m in zip(again, sizes, strict=True) if m is not None]
        if log:
            log(f"{len(again)} undecided on {max(result[k].members for k in again)} members: another look on {M}")
        for k, x in zip(rows, looks(M, rows), strict=True):
            result[k] = x


def advice(audit_members: int, need: int | None, most: int = MAX_MEMBERS_ADVISED) -> int | None:
    """The ``--members`` to audit an undecided gait with again: what its last look said would
    decide it, a quarter more, in multiples of 32, and more than ``audit_members`` (that look's);
    None when that is more than ``most`` (the command's limit) or it could not say."""
    if need is None:
        return None
    m = max(32 * math.ceil(1.25 * need / 32), 32 * math.ceil((audit_members + 1) / 32))
    return m if m <= most else None


def audit(lib: Library, gait_id: str, *, nudges: tuple[tuple[str, float, str], ...] = NUDGES,
          threshold: float = THRESHOLD, members: int = MEMBERS, max_members: int = MAX_MEMBERS,
          level: float = LEVEL, log=None, backend: Backend | None = None) -> Audit:
    """Audit the gait ``gait_id`` ("RUN/RANK" or "RUN#IDX") of ``lib`` (see the module
    docstring) on an audit ensemble of ``members`` members, and again on more, up to
    ``max_members``, while that leaves it undecided (:func:`decide`); store nothing. ``backend``
    (``sanlab.evaluate.backends``; default: this process): where the evaluations of each look
    (the gait's own step and every nudge, side by side) run; the verdict is the same on any.
    Raises LibraryError for an unknown gait, ValueError for ``members`` < 2."""
    if members < 2:
        raise ValueError(f"members: expected >= 2 (the audit's statistic is over members), got {members}")
    g = _stored_gait(lib, gait_id)
    run = lib.get_run(g.gait_id.split("#")[0])
    s = run.settings
    terrain = s.terrain if isinstance(s, TuneSettings) else "flat"
    key = gait_key(lib, g)
    morphology = g.params.scale is not None
    dtype0 = run.dtype or "float32"
    # A gait is scored as it was scored: a random search's with the creature file's own parameters,
    # any other (tuned, imported, a rhythm search's clock with its own delays and ranges) with its
    # parameter vector.
    own = g.params.k1 is not None or bool(g.params.model) or morphology
    theta = Space(g.spec, morphology=morphology).nominal(g.params)[None] if run.kind != "search" or own else None

    pattern = g.patterns()

    def job(factor: float, dtype: str, ensemble: Ensemble, k: Key) -> tuple[Evaluator, Request]:
        ev = nudged_evaluator(g.spec, factor, dtype, batch=1, metric=g.metric, seconds=g.seconds, terrain=terrain,
                              ensemble=ensemble, morphology=morphology)
        return ev, Request(g.weights[None], theta, (k,), pattern)

    def look(M: int, extra: list[tuple[Evaluator, Request]] = []):  # noqa: B006 (never changed)
        aens = audit_ensemble(g.ensemble, M)
        out = evaluate_all(backend, [*extra, job(1.0, dtype0, aens, audit_key(key)),
                                     *(job(factor, dtype, aens, audit_key(key)) for _, factor, dtype in nudges)])
        return out[:len(extra)], (out[len(extra)], {name: b for (name, _, _), b in zip(nudges, out[len(extra) + 1:],
                                                                                          strict=True)})

    # the re-score as stored (the gait's own ensemble and draws) runs beside the first look
    [as_stored], first = look(members, [job(1.0, dtype0, g.ensemble, key)])
    nominal = float(as_stored.speed_cm_s[0])

    def evaluate(M: int, rows: list[int]):
        assert rows == [0]
        return first if M == members else look(M)[1]

    if log:
        older = ", by an older sanlab's float32, another arithmetic" if run.old_float32 else ""
        log(f"{g.gait_id}: {nominal:.1f} cm/s re-scored as stored (stored {g.speed_cm_s:.1f}{older})")
    [x] = decide(evaluate, 1, members, max_members, threshold, level, log)
    if log:
        log(f"{g.gait_id}: {x.reference:.1f} cm/s mean over the audit's {x.members} members")
        for name, sh in x.shifts.items():
            log(f"{g.gait_id}: {x.speeds[name]:.1f} cm/s at {name} (change {100 * sh.change:+.0f} %, "
                f"interval {100 * sh.lo:+.0f} .. {100 * sh.hi:+.0f} %: {sh.verdict})")
    return Audit(g.gait_id, g.speed_cm_s, nominal, x.reference, x.speeds, x.shifts, x.fell, threshold,
                 g.spec.dt, g.ensemble.members, x.members, level, old_float32=run.old_float32)


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
    """One vector a tuning chain visited (the start, or an accepted trial), as audited: on the
    audit's own members (``shifts``), and, where it was made, again on fresh draws
    (``confirmed``: the confirmation a chosen rung must pass, so that the best of many noisy
    tests is not the lucky one)."""

    trial: int  # -1: the chain's start (the parent gait's parameters)
    chain_score: float  # the score the chain saw (one ensemble draw of the trial)
    nominal_cm_s: float  # re-scored on the held-out ensemble, as the tuned gait is: the speed stored
    score: float  # the audit members' median score at the nominal step (what the selection ranks)
    reference_cm_s: float  # the audit members' mean speed at the nominal step
    speeds: dict[str, float]  # nudge name -> the audit members' mean speed
    shifts: dict[str, Shift]
    confirmed: dict[str, Shift] | None = None  # the same audit on fresh draws (None: not made)
    confirmed_speeds: dict[str, float] | None = None

    @property
    def changes(self) -> dict[str, float]:
        return {k: abs(v.change) for k, v in self.shifts.items()}

    @property
    def worst(self) -> float:
        return max(self.changes.values(), default=0.0)

    @property
    def verdict(self) -> str:
        """The audit's verdict on this rung (:func:`combine`)."""
        return combine(self.shifts)

    @property
    def chosen_ok(self) -> bool:
        """Robust on the audit's members and again on fresh draws."""
        return self.verdict == ROBUST and self.confirmed is not None and combine(self.confirmed) == ROBUST

    def to_json(self) -> dict[str, Any]:
        out = {"trial": self.trial, "chain_score": _finite(self.chain_score), "nominal_cm_s": _finite(self.nominal_cm_s),
               "score": _finite(self.score), "reference_cm_s": _finite(self.reference_cm_s), "verdict": self.verdict,
               "speeds": {k: _finite(v) for k, v in self.speeds.items()},
               "changes": {k: _finite(v) for k, v in self.changes.items()},
               "shifts": {k: v.to_json() for k, v in self.shifts.items()}}
        if self.confirmed is not None:
            out["confirmed"] = {k: v.to_json() for k, v in self.confirmed.items()}
            out["confirmed_verdict"] = combine(self.confirmed)
            out["confirmed_speeds"] = {k: _finite(v) for k, v in (self.confirmed_speeds or {}).items()}
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Candidate:
        num = lambda v, missing: missing if v is None else float(v)
        conf = d.get("confirmed")
        return cls(int(d["trial"]), num(d.get("chain_score"), math.nan), num(d.get("nominal_cm_s"), math.nan),
                   num(d.get("score"), -math.inf), num(d.get("reference_cm_s"), math.nan),
                   {k: num(v, math.nan) for k, v in d["speeds"].items()},
                   {k: Shift.from_json(v) for k, v in d["shifts"].items()},
                   None if conf is None else {k: Shift.from_json(v) for k, v in conf.items()},
                   None if conf is None else {k: num(v, math.nan) for k, v in d.get("confirmed_speeds", {}).items()})


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
                  members: int = MEMBERS, max_members: int = MAX_MEMBERS, level: float = LEVEL,
                  log=None, backend: Backend | None = None) -> Selection:
    """Audited selection of a finished tuning run's gait. ``top`` vectors of its chain (the
    rungs of its climb, :func:`ladder`: its start, its best and the steps between) are audited
    (:func:`audit`'s statistic, ``members`` members of their own and further looks on up to
    ``max_members`` for the undecided, every nudge of :data:`NUDGES`); the robust ones are ranked by the audit members' median score, and the
    first that is robust again on fresh draws (:func:`~sanlab.evaluate.ensemble.confirm_key`: a
    selection among many noisy tests would otherwise report the lucky pass) is stored as the
    run's evaluation #1, scored on the tuned gait's held-out ensemble, with the confirmation as
    its audit. It is the start itself when no tuned rung survives. A chain's best is often a
    vector that only works at its step (issue 10: annealing learns the integrator); its best
    *robust* vector is the result to report. The chain's best itself (#0) is audited and its
    audit stored too, unless it has one already.

    The selection's record (every rung's speeds and shifts) is stored in the library whatever
    its outcome, and one made with the same settings is reused; made again with others, a gait
    chosen before that no rung now earns is removed. Returns the :class:`Selection` (``gait_id``
    None: no rung kept its speed). ``backend``: where the rungs are scored (as :func:`audit`'s;
    the same selection on any). Raises ValueError for a threshold that is not a finite number
    >= 0, ``top`` < 1 or ``members`` < 2, LibraryError for a run that is not a finished tuning run."""
    from sanlab import sim
    from sanlab.library.records import EvaluationRow

    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold >= 0):
        raise ValueError(f"threshold: expected a finite number >= 0, got {threshold!r}")
    if top < 1:
        raise ValueError(f"top: expected >= 1, got {top}")
    if members < 2:
        raise ValueError(f"members: expected >= 2 (the audit's statistic is over members), got {members}")
    run, s = _tuning_run(lib, run_id)
    assert run.parent_gait is not None
    if 0 not in lib.done_indices(run.run_id):
        raise LibraryError(f"run {run.run_id} has not finished: resume its tuning first")
    settings = {"top": top, "threshold": threshold, "members": members, "max_members": max_members, "level": level}
    gait_id = f"{run.run_id}#{SELECTED_IDX}"
    reused = _stored_selection(lib, run.run_id, settings, threshold)
    if reused is not None:
        return reused

    ranked = ladder(visited(lib, run.run_id), top)
    parent = _stored_gait(lib, run.parent_gait)
    spec0 = parent.spec
    dtype0 = run.dtype or "float32"
    thetas = np.stack([v[2] for v in ranked])
    evaluators: dict = {}

    def scores(settings: list[tuple[float, str, Ensemble]], key: Key, rows: Any = None):
        """The rungs ``rows`` (default: all) scored under each (factor, dtype, ensemble) of
        ``settings``, side by side on the backend; a vector the climb visited twice (an accepted
        trial can land where an earlier one did) is simulated once."""
        th = thetas if rows is None else thetas[np.asarray(rows, int)]
        distinct, back = np.unique(th, axis=0, return_inverse=True)
        w = np.repeat(parent.weights[None], len(distinct), axis=0)
        jobs = []
        for ek in settings:  # one evaluator per setting, for both draws
            if ek not in evaluators:
                factor, dtype, ensemble = ek
                evaluators[ek] = nudged_evaluator(spec0, factor, dtype, batch=len(ranked), metric=s.metric,
                                                  seconds=s.seconds, terrain=s.terrain, ensemble=ensemble,
                                                  morphology=s.morphology)
            jobs.append((evaluators[ek], Request(w, distinct, (key,) * len(distinct))))
        return [b.take(back.reshape(-1)) for b in evaluate_all(backend, jobs)]

    def audited(key: Key):
        def evaluate(M: int, rows: list[int]):
            aens = audit_ensemble(s.ensemble, M)
            ref, *nudged = scores([(1.0, dtype0, aens), *((f, d, aens) for _, f, d in NUDGES)], key, rows)
            return ref, {name: b for (name, _, _), b in zip(NUDGES, nudged, strict=True)}
        return decide(evaluate, len(ranked), members, max_members, threshold, level, log)

    [held] = scores([(1.0, dtype0, s.ensemble)], heldout_key(s.seed, s.chain))  # as the chain scored it: what is stored
    cands = []
    for k, ((trial, chain_score, _), x) in enumerate(zip(ranked, audited(audit_key(heldout_key(s.seed, s.chain))),
                                                         strict=True)):
        cands.append(Candidate(int(trial), float(chain_score), float(held.speed_cm_s[k]), x.score, x.reference,
                               x.speeds, x.shifts))
        if log:
            log(f"{rung_name(trial)}: {cands[-1].nominal_cm_s:.1f} cm/s held out, {x.reference:.1f} over "
                f"{x.members} members, worst change {100 * cands[-1].worst:.0f} %: {cands[-1].verdict}")
    robust = [k for k, c in enumerate(cands) if c.verdict == ROBUST and np.isfinite(c.score)]
    cfell: dict = {}
    if robust:  # the confirmation on fresh draws, made for every rung in one batch (one compiled program)
        for k, x in enumerate(audited(confirm_key(s.seed, s.chain))):
            if k not in robust:
                continue
            cands[k] = dataclasses.replace(cands[k], confirmed=x.shifts, confirmed_speeds=x.speeds)
            cfell[k] = (x.reference, x.fell, x.members)
            if log:
                log(f"{rung_name(cands[k].trial)}: on fresh draws {x.reference:.1f} cm/s, {combine(x.shifts)}")
    order = sorted(robust, key=lambda i: -cands[i].score)
    pick = next((k for k in order if cands[k].chosen_ok), None)
    record = {"settings": settings, "candidates": [c.to_json() for c in cands], "trial": None, "fell": {}}
    tuned = f"{run.run_id}#0"  # the chain's best: audited too, so that show and exports flag it
    if lib.audit(tuned) is None:
        audit_and_store(lib, tuned, threshold=threshold, members=members, max_members=max_members, level=level,
                        backend=backend)
    if pick is None:
        lib.put_selection(run.run_id, SELECTED_IDX, record)
        return Selection(run.run_id, None, None, cands, threshold)
    chosen = cands[pick]
    ref_cm_s, fell, used = cfell[pick]
    record["trial"], record["fell"], record["reference_cm_s"], record["audit_members"] = chosen.trial, fell, ref_cm_s, used
    space = Space(spec0, morphology=s.morphology)
    model = sim.compile_creature(spec0, dtype0)
    row = EvaluationRow(run.run_id, SELECTED_IDX, space.san.encode(parent.weights), space.gait_params(thetas[pick], model),
                        held.row(pick), {"selected": {"trial": chosen.trial}, "theta": thetas[pick].tolist()},
                        run.parent_gait)
    assert chosen.confirmed is not None and chosen.confirmed_speeds is not None
    a = Audit(gait_id, chosen.nominal_cm_s, chosen.nominal_cm_s, ref_cm_s, chosen.confirmed_speeds, chosen.confirmed,
              fell, threshold, spec0.dt, s.ensemble.members, used, level)
    lib.put_selection(run.run_id, SELECTED_IDX, record, row.to_json(), a.to_json(), flagged=a.flagged, worst=a.worst)
    return Selection(run.run_id, gait_id, chosen, cands, threshold)


def _stored_selection(lib: Library, run_id: str, settings: dict, threshold: float) -> Selection | None:
    """The stored selection made with ``settings``, or None (none, other settings, or a record
    that does not read, such as one made before the audit's statistic: it is made again). Its
    gait's audit is stored again when a plain audit with other settings replaced it (or it went
    missing)."""
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
        if chosen.confirmed is None or chosen.confirmed_speeds is None:
            return None
    except (KeyError, TypeError, ValueError, AttributeError, StopIteration, LibraryError):
        return None  # a record that does not read, or its gait is gone: make it again
    gait_id = stored.gait_id
    audit_rec = lib.audit(gait_id)
    members, level = int(rec.get("audit_members") or settings["members"]), float(settings["level"])
    if (audit_rec is None or audit_rec.result.get("threshold") != threshold
            or audit_rec.result.get("audit_members") != members):
        g = _stored_gait(lib, gait_id)
        ref = rec.get("reference_cm_s")
        a = Audit(gait_id, stored.speed_cm_s, chosen.nominal_cm_s, math.nan if ref is None else float(ref),
                  chosen.confirmed_speeds, chosen.confirmed,
                  fell, threshold, g.spec.dt, g.ensemble.members, members, level)
        lib.add_audit(gait_id, a.to_json(), flagged=a.flagged, worst=a.worst)
    return Selection(run_id, gait_id, chosen, cands, threshold)
