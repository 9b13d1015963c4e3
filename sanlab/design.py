"""``sanlab design FILE``: search a creature file's free numbers together with its controllers
(paper §6.3, "Evolution"; issue 47, part 2).

A *body* is one vector of the file's free values (``sanlab.creature.free``; couplings applied). A
body's score is what a user will quote: its **robust tuned speed** (cm/s), measured as a Table 1
row is (``sanlab.reproduce.robust_tuned``): phase 1 (``controllers`` random SANs), a short phase
2 (``trials`` annealing trials on each of its ``top`` best SANs) and the audited selection of
each chain (the best rung that keeps its speed at dt/2 and dt/4). Phase 1 only
picks the SANs that phase 2 starts from: it never chooses a body, though it may prune one
(``prune``: a body whose best phase-1 speed falls below a fraction of the reference's skips
phase 2 and scores 0, which saves its tuning and audits). A body whose values make no valid
creature (a range that reaches past valid creatures, which ``sanlab check`` warns of) scores 0
too, unrun, its record saying why ("invalid"); it is never validated. Every run is stored in the gait
library and found there again, keyed by the body's creature file (its text) and the settings,
so a design made again on the same library asks the same bodies (the body strategies are
deterministic given their seed and the scores told) and continues where it stopped; each search
and tuning runs on the one driver. The design itself is stored there too
(``Library.begin_design``): its settings, free numbers and units, each body's score on each seed
as it is made (so an interrupted design shows what it has), and once done the chosen body;
``sanlab studio`` shows it.

The outer search over bodies is a body strategy (``sanlab.search.bodies``: CMA-ES by default,
or random). Then the ``validate`` best bodies of those that scored above 0 (a tie of zeros
spends no validation seed: where none did, nothing is scored again and the reference is kept),
and the reference (the file's defaults, moved onto its ``[[design.total]]``s as every body is:
:func:`reference_name`), are scored again on ``seeds`` (other seeds than the search's: fresh
SANs, fresh ensemble draws), and the chosen body is the one with the best mean robust tuned speed on those seeds: the search's
own scores are biased up (the best of many noisy scores), the validation's are not. The
reference is scored by the same rules beside it and is a contender: where no body beats its mean
there, the chosen body is the reference (the file's defaults are kept). The chosen body's file
keeps the source's ``history`` and adds one entry (:func:`history_entry`: the date, the source
and design, what changed most, the speeds it was chosen by), none when the defaults are kept.

Every candidate shares the reference's structure (links, sensors, actuators), so a body that
adds or drops a link is not possible: free numbers are numbers.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from sanlab import __version__
from sanlab.creature import CreatureError, printable
from sanlab.creature.free import Design
from sanlab.creature.spec import MAX_HISTORY, MAX_HISTORY_ENTRY, METRICS
from sanlab.evaluate.ensemble import default_ensemble
from sanlab.library import Library, LibraryError
from sanlab.search.bodies import BodyProblem, make_bodies

DIGITS = 6  # significant digits of a body's values (its file's text, so its runs' key, is stable)


@dataclass(frozen=True)
class DesignSettings:
    """What a design run does: ``designs`` bodies in all (the reference not counted),
    ``generation`` per round of the ``strategy``; per body ``controllers`` random SANs, ``top``
    chains of ``trials`` trials, scored over ``seconds`` (None: the file's) with an ensemble of
    ``ensemble`` members (``search``: phase 1's strategy, "random", "catcma", "rhythm" or "reflex", see
    ``sanlab.search.catcma`` and ``sanlab.search.rhythm``); ``validate`` best bodies scored again on ``seeds``. ``prune``: a body of
    the search whose phase-1 best speed is below this fraction of the reference's skips phase 2
    and scores 0 (0: none is pruned); the validation never prunes."""

    designs: int = 8
    generation: int = 4
    strategy: str = "cma-es"
    controllers: int = 200
    trials: int = 100
    top: int = 2
    seconds: float | None = None
    ensemble: int = 8
    seed: int = 0
    validate: int = 2
    seeds: tuple[int, ...] = (1,)
    prune: float = 0.0
    search: str = "random"  # each body's phase 1: "random" (§5.2), or "catcma", "rhythm" or "reflex" (``controllers`` evaluations of it)


@dataclass
class Body:
    """One body scored: its ``values`` [D], the robust tuned ``speed`` (cm/s) on each seed
    (``speeds``: seed -> the ``robust_tuned`` record), ``round`` (-1: the reference)."""

    values: list[float]
    round: int
    index: int
    speeds: dict[int, dict] = field(default_factory=dict)

    def speed(self, seed: int) -> float:
        """The robust tuned speed (cm/s) on ``seed`` (0 where no chain kept a robust gait, pruned or invalid)."""
        return float(self.speeds[seed]["speed"])

    def mean(self, seeds) -> float:
        """The mean robust tuned speed (cm/s) over ``seeds``; KeyError for a seed not scored."""
        return float(np.mean([self.speed(s) for s in seeds]))

    @property
    def label(self) -> str:
        """"reference", or "r2b0" (round 2, body 0): a name no one reads as a speed."""
        return "reference" if self.round < 0 else f"r{self.round}b{self.index}"

    def why(self, seed: int) -> str:
        """Why the body scored as it did on ``seed`` where it scored 0 (:func:`why_zero`), else ""."""
        return why_zero(self.speeds[seed])


def why_zero(rec: dict) -> str:
    """Why a ``robust_tuned`` record (a body on one seed) scored 0 cm/s, in a few words: the
    loader's reason for an invalid body; a pruned body's phase-1 best; "no rung survived the audit;
    best tuned 12.0 cm/s" where chains were tuned but none kept its speed at dt/2 and dt/4; "" for
    a body that scored above 0."""
    if rec.get("invalid"):
        return f"invalid: {rec['invalid']}"
    if rec.get("pruned"):
        p1 = rec.get("phase1_cm_s")
        return "pruned: best random SAN " + (f"{p1:.1f} cm/s" if isinstance(p1, int | float) else "unknown") + \
            ", below the --prune line"
    if float(rec.get("speed") or 0.0) > 0:
        return ""
    tuned = [float(c["tuned_cm_s"]) for c in rec.get("chains") or [] if isinstance(c.get("tuned_cm_s"), int | float)]
    if not tuned:
        return "no chain was tuned"
    if max(tuned) <= 0:
        return f"nothing moved: best tuned {max(tuned):.1f} cm/s"
    if any(c.get("robust") for c in rec["chains"]):
        return f"its robust gait moves 0.0 cm/s; best tuned {max(tuned):.1f} cm/s"
    return f"no rung survived the audit; best tuned {max(tuned):.1f} cm/s"


def reference_name(design: Design) -> str:
    """What a design's reference is: "the file's defaults", or where a ``[[design.total]]`` does
    not hold at them (``Design.off_totals``) "the file's defaults moved onto design.total[0]":
    every body of a design keeps its totals, the reference too, so it is then not the file as it
    loads."""
    off = design.off_totals()
    if not off:
        return "the file's defaults"
    return "the file's defaults moved onto " + " and ".join(f"design.total[{k}]" for k, _ in off)


@dataclass
class DesignResult:
    """A finished design: every body scored (``bodies``, the reference first), the ``chosen``
    one and the ``reference``, the chosen body's creature file ``text``, the seconds spent, and
    the design's id in the library (``design_id``)."""

    settings: DesignSettings
    bodies: list[Body]
    reference: Body
    chosen: Body
    text: str
    seconds: float
    design_id: str = ""
    free: list[dict] = field(default_factory=list)  # free_json: the names, units and ranges of ``values``
    validated: bool = True  # False: no body of the search scored above 0, so none was scored again

    def to_json(self) -> dict:
        """The ``sanlab/design/1`` record's fields (``sanlab/schemas/design.json``) but its own."""

        def body(b: Body) -> dict:
            return {"body": b.label, "values": b.values, "round": b.round, "index": b.index,
                    "speeds": {str(k): v for k, v in b.speeds.items()}}

        return {"design": self.design_id, "settings": settings_json(self.settings), "free": self.free,
                "reference": body(self.reference), "chosen": body(self.chosen),
                "bodies": [body(b) for b in self.bodies]}


def settings_json(s: DesignSettings) -> dict:
    """``s`` as a JSON object (the library's key of a design with the file's text); ``search``
    only when it is not random search, so the designs made before it had a choice keep their key."""
    out = {**asdict(s), "seeds": list(s.seeds)}
    if s.search == "random":
        del out["search"]
    return out


def free_json(design: Design) -> list[dict]:
    """Each free number of ``design`` as {name, path, min, max, default, unit} (the file's units)."""
    return [{"name": f.name, "path": f.path, "min": f.min, "max": f.max, "default": f.default, "unit": u}
            for f, u in zip(design.free, design.units, strict=True)]


def rounded(values) -> np.ndarray:
    """``values`` [D] to :data:`DIGITS` significant digits."""
    return np.array([float(f"{float(x):.{DIGITS}g}") for x in values])


Reporter = Callable[[int, int, float, str], None]  # (bodies scored, bodies in all, best speed, what now)


def run_design(lib: Library, design: Design, text: str, where: str, settings: DesignSettings,
               reporter: Reporter | None = None, backend=None) -> DesignResult:
    """Search the free numbers of ``design`` (the parsed ``text``, read from ``where``) as the
    module docstring says; every run goes to ``lib``. Raises ValueError for a file without free
    numbers or bad settings, LibraryError while another process makes the same design, and as
    ``run_search`` and ``tune`` do. ``backend``: where each body's search and tuning evaluate
    (``sanlab.evaluate.backends``; default this machine). The design is stored in ``lib`` as it
    goes (each score as it is made; "interrupted" if anything stops it, Ctrl-C included)."""
    if not design.free:
        raise ValueError(f"{where}: no free numbers to design (write a range, e.g. mass = {{ min = 0.1, max = 0.3 }})")
    s = settings
    if s.seed in s.seeds:
        raise ValueError(f"seeds: expected seeds other than the search's own ({s.seed}), got {list(s.seeds)}")
    if len(set(s.seeds)) < len(s.seeds):
        raise ValueError(f"seeds: expected different seeds, got {list(s.seeds)}")
    if not 0 <= s.prune < 1:
        raise ValueError(f"prune: expected a fraction in [0, 1), got {s.prune}")
    for name in ("designs", "generation", "controllers", "trials", "top", "ensemble"):
        if getattr(s, name) < 1:
            raise ValueError(f"{name}: expected >= 1, got {getattr(s, name)}")
    t0 = time.perf_counter()
    ens = default_ensemble(s.ensemble)
    stated = design.creature()
    if stated.evaluation.metric == "tracking":  # a ratio: the body search compares speeds (cm/s)
        speeds = ", ".join(m for m in METRICS if m != "tracking")
        raise ValueError(f"{where}: evaluation.metric: expected a metric a body can be scored by as a speed "
                         f"({speeds}), got 'tracking'")
    if len(stated.history) >= MAX_HISTORY:  # the chosen body's file could not add its entry
        raise ValueError(f"{where}: history: expected fewer than {MAX_HISTORY} entries (a design adds one), "
                         f"got {len(stated.history)}")
    seconds = s.seconds if s.seconds is not None else stated.evaluation.seconds
    design_id = lib.begin_design(stated.name, where, text, settings_json(s), free_json(design)).design_id
    try:
        result = _run(lib, design, design_id, text, where, s, ens, seconds, reporter, backend)
    except BaseException:
        try:
            lib.end_design(design_id, "interrupted")
        except LibraryError:  # the disk that stopped the design may refuse this too: the cause is
            pass  # what to report; the design reads "interrupted" once this process is gone
        raise
    result.seconds = time.perf_counter() - t0
    lib.end_design(design_id, "done", {"chosen": {"round": result.chosen.round, "index": result.chosen.index},
                                       "seconds": result.seconds, "text": result.text})
    return result


def _run(lib: Library, design: Design, design_id: str, text: str, where: str, s: DesignSettings, ens, seconds: float,
         reporter: Reporter | None, backend) -> DesignResult:
    """The design's search and validation (:func:`run_design`), each score stored as it is made
    (the result's ``seconds`` left 0: the caller's to set)."""
    from sanlab.reproduce import robust_tuned

    report = reporter or (lambda *a: None)
    total = 1 + s.designs + (min(s.validate, s.designs) + 1) * len(s.seeds)  # scores: body x seed
    done = [0]
    bodies: list[Body] = []
    best = [0.0]

    def score(body: Body, seed: int, prune_below: float | None = None) -> None:
        if seed not in body.speeds or (prune_below is None and body.speeds[seed].get("pruned")):
            report(done[0], total, best[0], f"{body.label}, seed {seed}")
            try:
                t = design.text(text, body.values, f"A body of `sanlab design`: {body.values}")
            except CreatureError as e:
                if body.round < 0:  # the file's defaults: the design has nothing to stand on
                    raise
                body.speeds[seed] = _invalid(design, e)
            else:
                body.speeds[seed] = robust_tuned(lib, t, where, seed=seed, controllers=s.controllers,
                                                 trials=s.trials, top=s.top, ens=ens, seconds=seconds,
                                                 backend=backend, prune_below=prune_below, strategy=s.search)
            lib.add_design_score(design_id, body.round, body.index, seed, body.values, body.speeds[seed])
        done[0] += 1
        if seed == s.seed:
            best[0] = max(best[0], body.speed(seed))
        report(done[0], total, best[0], "")

    # the reference keeps the file's totals, as every body does (where the defaults break one,
    # it is not the file as it loads: reference_name says so)
    reference = Body(rounded(design.project(design.defaults)).tolist(), -1, 0)
    score(reference, s.seed)
    below = s.prune * reference.speeds[s.seed]["phase1_cm_s"] if s.prune > 0 else None
    strategy = make_bodies(s.strategy, BodyProblem(design.lo, design.hi, design.defaults, s.designs, s.generation, s.seed))
    rnd = 0
    while not strategy.done:
        asked = strategy.ask()
        batch = [Body(rounded(design.project(x)).tolist(), rnd, k) for k, x in enumerate(asked)]
        for b in batch:
            score(b, s.seed, below)
        strategy.tell(asked, np.array([b.speed(s.seed) for b in batch]))
        bodies += batch
        rnd += 1
    ranked = sorted(bodies, key=lambda b: -b.speed(s.seed))
    picks = []
    for b in ranked:  # distinct bodies: two rounds may ask the same one; an invalid body is no candidate,
        # nor one that scored 0 (a tie of zeros says nothing a validation seed could settle)
        if b.speed(s.seed) > 0 and all(b.values != p.values for p in picks):
            picks.append(b)
    picks = picks[:max(1, s.validate)]
    total = done[0] + (len(picks) + 1) * len(s.seeds) if picks else done[0]
    report(done[0], total, best[0], "validation" if picks else "")
    for seed in s.seeds if picks else ():
        for b in [*picks, reference]:
            score(b, seed)
    # the reference is a contender: a file is changed only for a body that beats its defaults on
    # fresh seeds (ties and a better search score do not count: the defaults stay)
    leader = max(picks, key=lambda b: (b.mean(s.seeds), b.speed(s.seed)), default=reference)
    chosen = leader if picks and leader.mean(s.seeds) > reference.mean(s.seeds) else reference
    note = _note(design, where, s, chosen, reference, len(bodies), bool(picks))
    out = design.text(text, chosen.values, note, history_entry(design, where, design_id, s, chosen, reference))
    return DesignResult(s, [reference, *bodies], reference, chosen, out, 0.0, design_id, free_json(design), bool(picks))


def _invalid(design: Design, error: CreatureError) -> dict:
    """The record of a body whose values make no valid creature (a range that reaches past valid
    creatures: ``sanlab check`` warns of it): it scores 0 cm/s as a pruned body does, nothing is
    run, and "invalid" says why (the loader's message without the file's name)."""
    reason = str(error).removeprefix(f"{design.source}: ")
    return {"speed": 0.0, "gait": None, "search": None, "phase1_cm_s": None, "chains": [], "pruned": True,
            "invalid": reason}


def _count(n: int, word: str) -> str:
    """"1 chain", "2 chains"."""
    return f"{n} {word}{'s' * (n != 1)}"


def _trials(design: Design, s: DesignSettings) -> str:
    """" (2 s trials, the file's 6 s)" when the design evaluated over another time than the file
    states (``--seconds``), else "": its speeds are not the file's evaluation's."""
    stated = design.creature().evaluation.seconds
    if s.seconds is None or s.seconds == stated:
        return ""
    return f" ({s.seconds:g} s trials, the file's {stated:g} s)"


def _note(design: Design, where: str, s: DesignSettings, chosen: Body, reference: Body, n: int,
          validated: bool = True) -> str:
    seeds = ", ".join(str(x) for x in s.seeds)
    ref = reference_name(design)
    which = (f"the body chosen among {n} ({s.strategy}, seed {s.seed}, round {chosen.round}, body {chosen.index})"
             if chosen is not reference else
             f"{ref}: none of {n} {'body' if n == 1 else 'bodies'} searched ({s.strategy}, seed {s.seed}) "
             + ("beat them on the validation seeds" if validated else "scored above 0 cm/s, so none was validated"))
    speeds = (f"Robust tuned speed: {chosen.speed(s.seed):.1f} cm/s on the search's seed, {chosen.mean(s.seeds):.1f} "
              f"mean on seed{'s' * (len(s.seeds) > 1)} {seeds} (validation); the reference ({ref}): "
              f"{reference.speed(s.seed):.1f} and {reference.mean(s.seeds):.1f}." if validated else
              f"Robust tuned speed of the reference ({ref}) on the search's seed: {reference.speed(s.seed):.1f} cm/s"
              + (f" ({why})." if (why := reference.why(s.seed)) else "."))
    lines = [
        f"Written by `sanlab design` (sanlab {__version__}) from {where}: {which}.",
        f"Scored by robust tuned speed{_trials(design, s)}: phase 1 ({_count(s.controllers, 'random SAN')}), "
        f"phase 2 ({_count(s.top, 'chain')} x {_count(s.trials, 'trial')}), the audited selection.",
        speeds,
        *(["What changed (default -> chosen):", *[f"  {line}" for line in design.changes(chosen.values)]]
          if chosen is not reference else []),
    ]
    return "\n".join(lines)


def history_entry(design: Design, where: str, design_id: str, s: DesignSettings, chosen: Body, reference: Body,
                  day: str | None = None) -> str:
    """The line the chosen body's file adds to its ``history`` (docs/creature-format.md, "History"):
    "YYYY-MM-DD: body chosen by `sanlab design` from FILE (design ID): the largest changes; the
    robust tuned speeds (cm/s) of the chosen body and the reference on the search's seed and their
    means on the validation seeds", the trials' length after the first speed when it is not the
    file's ("(2 s trials, the file's 6 s)"). ``day``: the date (default today, UTC). FILE is ``where``
    relative to the working folder, or its name (no machine's folders in a file that travels).
    At most :data:`MAX_HISTORY_ENTRY` characters (cut with "..."); "" when the chosen body is the
    reference: the file's defaults are kept and nothing changed."""
    if chosen is reference:
        return ""
    day = day or datetime.now(timezone.utc).date().isoformat()
    seeds = ", ".join(str(x) for x in s.seeds)
    about = f" (design {design_id})" if design_id else ""
    whose = "the reference's" if design.off_totals() else "the defaults'"  # the defaults break a total: moved
    line = (f"{day}: body chosen by `sanlab design` from {_file(where)}{about}: {_largest(design, chosen.values)}; "
            f"robust tuned speed {chosen.speed(s.seed):.1f} cm/s{_trials(design, s)} on the search's seed {s.seed} and "
            f"{chosen.mean(s.seeds):.1f} mean on validation seed{'s' * (len(s.seeds) > 1)} {seeds}, against {whose} "
            f"{reference.speed(s.seed):.1f} and "
            f"{reference.mean(s.seeds):.1f}")
    return line if len(line) <= MAX_HISTORY_ENTRY else line[:MAX_HISTORY_ENTRY - 3] + "..."


def _file(where: str) -> str:
    """``where`` (a resolved path, or "builtin:NAME") as a history entry names it."""
    if where.startswith("builtin:") or where.startswith("<"):
        return printable(where)
    path = Path(where)
    try:
        shown = str(path.resolve().relative_to(Path.cwd().resolve()))
    except (ValueError, OSError):
        shown = path.name
    return printable(shown)


def _largest(design: Design, values, n: int = 3) -> str:
    """The ``n`` free numbers of ``values`` that moved most from their defaults (``Move.size``:
    the change of magnitude over the default's; over the range's width for a default of 0):
    "largest of 5 changes: shin 0.15 -> 0.18 m (+20 %), ...", or "changes: ..." when they are
    all."""
    moved = [m for m in design.moves(values) if m.moved]
    if not moved:
        return "no free number moved from its default"
    moved.sort(key=lambda m: -round(m.size, 9))  # stable: equal changes (a total's two numbers) in file order
    head = "changes" if len(moved) <= n else f"largest of {len(moved)} changes"
    return f"{head}: " + ", ".join(
        f"{printable(m.name)} {m.default:.4g} -> {m.value:.4g}{f' {m.unit}' if m.unit else ''}{m.percent}" for m in moved[:n])


__all__ = ["Body", "DesignResult", "DesignSettings", "history_entry", "reference_name", "run_design", "why_zero"]
