"""What crosses the library's boundary, as frozen records.

Read back: :class:`Run`, :class:`Evaluation` and :class:`TracePoint`. Their JSON columns are
kept as stored (``Run.params``, ``Evaluation.params``, ``Evaluation.extra``) and decoded into
typed records in exactly one place each: :attr:`Run.settings` (:class:`SearchSettings` or
:class:`TuneSettings`), :attr:`Evaluation.gait_params` (``GaitParams``) and
:attr:`Evaluation.scores` (``Scores``).

Written: :class:`EvaluationRow` and :class:`TraceRow`, committed together by
``Library.commit``; a run's settings are created from the settings records' ``to_json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sanlab.evaluate.ensemble import Ensemble
from sanlab.evaluate.records import GaitParams, Scores


@dataclass(frozen=True)
class SearchSettings:
    """A phase-1 run's settings (``sanlab search``); the seed is the run's own column."""

    controllers: int  # random SANs to evaluate
    seconds: float | None  # evaluation time (s); None: the creature file's (a foreign run)
    metric: str | None  # None: the creature file's (a foreign run)
    batch: int  # controllers evaluated (and committed) together
    source: str | None  # where the creature file came from (a built-in name or a path)
    ensemble: Ensemble
    delay_on: float  # every node's delays (s): the creature file's
    delay_off: float
    san: dict[str, int] = field(default_factory=dict)  # sensors, hidden, actuators
    imported_from: str | None = None  # set on an imported gait's run: the source gait id
    strategy: str = "random"  # a phase-1 strategy of ``sanlab.search.registry``
    grid: dict | None = None  # map-elites: its archive (``sanlab.search.base.Grid`` as JSON)

    kind = "search"

    def to_json(self) -> dict[str, Any]:
        out = {"controllers": self.controllers, "seconds": self.seconds, "metric": self.metric,
               "batch": self.batch, "source": self.source, "ensemble": self.ensemble.to_json(),
               "delay_on": self.delay_on, "delay_off": self.delay_off, "san": dict(self.san)}
        if self.imported_from is not None:
            out["imported_from"] = self.imported_from
        if self.strategy != "random":  # a random search's settings read as they did before strategies
            out["strategy"] = self.strategy
        if self.grid is not None:
            out["grid"] = self.grid
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SearchSettings:
        seconds, metric = d.get("seconds"), d.get("metric")
        return cls(int(d.get("controllers", 0)), None if seconds is None else float(seconds),
                   None if metric is None else str(metric), int(d.get("batch", 256)),
                   d.get("source"), Ensemble.from_json(d.get("ensemble")), float(d.get("delay_on", 0.1)),
                   float(d.get("delay_off", 0.1)), dict(d.get("san") or {}), d.get("imported_from"),
                   str(d.get("strategy", "random")), d.get("grid") if isinstance(d.get("grid"), dict) else None)


@dataclass(frozen=True)
class TuneSettings:
    """A phase-2 run's settings (``sanlab tune``): one chain, tuning one gait."""

    method: str  # a phase-2 strategy of ``sanlab.search.registry``
    trials: int
    seed: int
    chain: int  # its index among the chains started together (names its random streams)
    morphology: bool
    terrain: str  # a name of ``sanlab.evaluate.TERRAINS``
    seconds: float
    metric: str
    batch: int
    source: str | None
    ensemble: Ensemble
    parameters: tuple[str, ...] = ()  # the tuned vector's names (``Space.names``)
    imported_from: str | None = None

    kind = "tune"

    def to_json(self) -> dict[str, Any]:
        out = {"method": self.method, "trials": self.trials, "seed": self.seed, "chain": self.chain,
               "morphology": self.morphology, "terrain": self.terrain, "seconds": self.seconds,
               "metric": self.metric, "batch": self.batch, "source": self.source,
               "ensemble": self.ensemble.to_json(), "parameters": list(self.parameters)}
        if self.imported_from is not None:
            out["imported_from"] = self.imported_from
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> TuneSettings:
        return cls(str(d["method"]), int(d["trials"]), int(d.get("seed", 0)), int(d.get("chain", 0)),
                   bool(d.get("morphology", False)), str(d.get("terrain", "flat")), float(d["seconds"]),
                   str(d["metric"]), int(d.get("batch", 128)), d.get("source"), Ensemble.from_json(d.get("ensemble")),
                   tuple(d.get("parameters") or ()), d.get("imported_from"))


RunSettings = SearchSettings | TuneSettings

# The first sanlab whose float32 runs compute in float32 (issue 58). Before it a float32 run was
# another arithmetic: the XLA engine's float32 (until issue 46), then float64 arithmetic on the
# creature's numbers rounded to float32; its scores are not what this sanlab's float32 gives.
FLOAT32_ARITHMETIC_SINCE = (0, 2, 0)


def _version(text: str | None) -> tuple[int, ...] | None:
    """"0.2.0" -> (0, 2, 0); None for a version that does not read as dotted numbers."""
    try:
        return tuple(int(x) for x in str(text).split("+")[0].split("."))
    except ValueError:
        return None


def settings_from_json(d: dict[str, Any]) -> RunSettings:
    """The settings record of a run's ``params`` (a tuning run's have a ``method``)."""
    return TuneSettings.from_json(d) if "method" in d else SearchSettings.from_json(d)


@dataclass(frozen=True)
class Run:
    """One search or tuning run (or one imported gait)."""

    run_id: str  # 8 lowercase hex characters
    kind: str  # "search", "tune" or "import"
    created: str  # ISO 8601 UTC
    creature: str  # creature name
    creature_text: str = field(repr=False)  # the creature file, verbatim
    creature_hash: str = field(repr=False)  # sha256 hex of creature_text
    params: dict = field(repr=False)  # the run's settings as stored (JSON); see ``settings``
    seed: int | None
    sanlab_version: str
    device: str | None
    dtype: str | None
    status: str  # "running", "done" or "interrupted"
    parent_gait: str | None  # "RUN#IDX" a tuning run starts from
    total: int  # evaluations planned
    count: int  # evaluations stored
    trials: int = 0  # tuning trials stored (a tune run's progress; 0 for other kinds)

    @property
    def old_float32(self) -> bool:
        """Scored in float32 (or with no dtype, as the XLA engine's runs were) by a sanlab older
        than :data:`FLOAT32_ARITHMETIC_SINCE`, whose float32 did not compute in float32: this
        sanlab cannot re-score it as it was scored (``sanlab.audit`` says so)."""
        v = _version(self.sanlab_version)
        return (self.dtype or "float32") == "float32" and (v is None or v < FLOAT32_ARITHMETIC_SINCE)

    @property
    def progress(self) -> tuple[int, int | None, str]:
        """(done, planned, unit) for listings: a search's evaluations, a tuning's trials (its
        stored gaits, the tuned one and a robust selection, are not its progress)."""
        if self.kind == "tune":
            planned = self.params.get("trials")
            return self.trials, planned if isinstance(planned, int) else None, "trials"
        return self.count, self.total, "evaluated"

    @property
    def settings(self) -> RunSettings:
        """``params`` decoded (KeyError, TypeError or ValueError if they are not a sanlab run's)."""
        return settings_from_json(self.params)

    @property
    def metric(self) -> str | None:
        """The settings' metric; None when the run has none (or its params are not sanlab's)."""
        try:
            return self.settings.metric
        except (KeyError, TypeError, ValueError):
            return None


@dataclass(frozen=True)
class Evaluation:
    """One evaluated controller of a run."""

    run_id: str
    idx: int  # index within the run, 0..N-1
    encoding: str  # printable controller encoding
    params: dict  # how it is evaluated, as stored (JSON); see ``gait_params``
    score: float  # NaN when the score was not a number
    speed_cm_s: float  # NaN when unknown
    fell: bool
    nonfinite: bool  # the simulation or the score went non-finite; ranked last
    extra: dict | None  # the ensemble's spread, distance, a strategy's details, as stored (JSON)
    parent: str | None  # "RUN#IDX" of the gait this one was tuned from
    rank: int | None = None  # 1-based place in the run's ranking, when looked up by rank

    @property
    def gait_id(self) -> str:
        """The permanent address of this evaluation, ``RUN#IDX``."""
        return f"{self.run_id}#{self.idx}"

    @property
    def gait_params(self) -> GaitParams:
        return GaitParams.from_json(self.params)

    @property
    def scores(self) -> Scores:
        """The row's scores, with the ensemble's spread when it was stored."""
        return Scores.from_json({**(self.extra or {}), "score": self.score, "speed_cm_s": self.speed_cm_s,
                                 "fell": self.fell, "nonfinite": self.nonfinite})


@dataclass(frozen=True)
class AuditRecord:
    """The stored artefact audit of one gait (``sanlab audit``, ``sanlab.audit``)."""

    gait_id: str  # "RUN#IDX"
    created: str  # ISO 8601 UTC
    flagged: bool  # the audit does not vouch for the stored speed (resolution-dependent or not reproduced)
    worst: float  # the largest relative change of the speed over the nudges (NaN: unknown)
    result: dict  # every nudge's scores, as ``sanlab.audit.Audit.to_json`` wrote them

    @property
    def reproduced(self) -> bool:
        """The speed re-scored without a nudge matched the stored one (audits stored before this
        check was made did not record it: taken as matched)."""
        return self.result.get("reproduced", True) is not False

    @property
    def resolution_dependent(self) -> bool:
        """A nudge changed the speed by more than the audit's threshold (older audits: flagged
        meant only that)."""
        return self.result.get("resolution_dependent", self.flagged) is True

    @property
    def verdict(self) -> str:
        """"robust", "resolution-dependent", "undecided" or "not reproduced" (``sanlab.audit``);
        an audit stored before verdicts (one median against a line) reads as it was decided."""
        v = self.result.get("verdict")
        if isinstance(v, str):
            return v
        if not self.reproduced:
            return "not reproduced"
        return "resolution-dependent" if self.resolution_dependent else "robust"


@dataclass(frozen=True)
class DesignRecord:
    """One design of a creature file's free numbers (``sanlab design``, ``sanlab.design``): its
    outer record. Its bodies' scores are :class:`DesignScore` rows (``Library.design_scores``);
    its inner searches and tunings are runs."""

    design_id: str  # 8 lowercase hex characters
    created: str  # ISO 8601 UTC
    updated: str  # ISO 8601 UTC: its last score or status change
    creature: str  # creature name
    source: str  # where the file was read
    creature_text: str = field(repr=False)  # the file with free numbers, verbatim
    creature_hash: str = field(repr=False)  # sha256 hex of creature_text
    settings: dict = field(repr=False)  # sanlab.design.DesignSettings as JSON (seconds None: the file's)
    free: tuple[dict, ...] = field(repr=False)  # each free number {name, path, min, max, default, unit}
    status: str  # "running", "done" or "interrupted" ("damaged": listed, not readable)
    result: dict | None  # once done: {"chosen": {"round", "index"}, "seconds" (wall s), "text" (the chosen body's file)}
    sanlab_version: str
    scores: int = 0  # score rows stored (a body on one seed each)

    @property
    def chosen(self) -> tuple[int, int] | None:
        """(round, index) of the chosen body once the design is done, else None."""
        c = (self.result or {}).get("chosen")
        if isinstance(c, dict) and isinstance(c.get("round"), int) and isinstance(c.get("index"), int):
            return c["round"], c["index"]
        return None


@dataclass(frozen=True)
class DesignScore:
    """One body of a design scored on one seed: ``values`` [D] (the free values, in the file's
    units), ``speed_cm_s`` (its robust tuned speed, cm/s; 0 where no chain kept a robust gait or
    it was pruned), ``gait`` (the robust gait, RUN#IDX, or None), ``record`` (everything
    ``sanlab.reproduce.robust_tuned`` returned: the phase-1 run, each chain)."""

    round: int  # the strategy's round; -1: the reference (the file's defaults)
    index: int  # the body's place in its round
    seed: int
    values: tuple[float, ...]
    speed_cm_s: float  # NaN when unknown
    gait: str | None
    pruned: bool
    record: dict


@dataclass(frozen=True)
class TracePoint:
    """One trial of a tuning run."""

    trial: int
    score: float  # NaN when the score was not a number
    accepted: bool


@dataclass(frozen=True)
class EvaluationRow:
    """One evaluated controller to store: its scores (their spread goes into ``extra``) and what
    a strategy keeps beside them (``extra``, JSON)."""

    run_id: str
    idx: int
    encoding: str
    params: GaitParams
    scores: Scores
    extra: dict[str, Any] = field(default_factory=dict)
    parent: str | None = None  # "RUN#IDX"

    def to_json(self) -> dict[str, Any]:
        """The ``Library.add_batch`` row of this record."""
        s = self.scores.to_json()
        extra = {"distance_m": s["distance_m"], "members": s["members"], **self.extra}
        if "dx_m" in s:
            extra["dx_m"] = s["dx_m"]
        if "descriptors" in s:
            extra["descriptors"] = s["descriptors"]
        return {"idx": self.idx, "encoding": self.encoding, "params": self.params.to_json(),
                "score": s["score"], "speed_cm_s": s["speed_cm_s"], "fell": s["fell"],
                "nonfinite": s["nonfinite"], "extra": extra, "parent": self.parent}


@dataclass(frozen=True)
class TraceRow:
    """One decided tuning trial to store."""

    run_id: str
    trial: int
    score: float
    accepted: bool
