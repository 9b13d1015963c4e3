"""What the library hands back: one frozen record per run, evaluation and tuning trial."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Run:
    """One search or tuning run (or one imported gait)."""

    run_id: str  # 8 lowercase hex characters
    kind: str  # "search", "tune" or "import"
    created: str  # ISO 8601 UTC
    creature: str  # creature name
    creature_text: str = field(repr=False)  # the creature file, verbatim
    creature_hash: str = field(repr=False)  # sha256 hex of creature_text
    params: dict = field(repr=False)  # everything about the run (seconds, metric, batch, ...)
    seed: int | None
    sanlab_version: str
    device: str | None
    dtype: str | None
    status: str  # "running", "done" or "interrupted"
    parent_gait: str | None  # "RUN#IDX" a tuning run starts from
    total: int  # evaluations planned
    count: int  # evaluations stored


@dataclass(frozen=True)
class Evaluation:
    """One evaluated controller of a run."""

    run_id: str
    idx: int  # index within the run, 0..N-1
    encoding: str  # printable controller encoding
    params: dict  # node delays etc.
    score: float  # NaN when the score was not a number
    speed_cm_s: float  # NaN when unknown
    fell: bool
    nonfinite: bool  # the simulation or the score went non-finite; ranked last
    extra: dict | None  # metric details etc.
    parent: str | None  # "RUN#IDX" of the gait this one was tuned from
    rank: int | None = None  # 1-based place in the run's ranking, when looked up by rank

    @property
    def gait_id(self) -> str:
        """The permanent address of this evaluation, ``RUN#IDX``."""
        return f"{self.run_id}#{self.idx}"


@dataclass(frozen=True)
class TracePoint:
    """One trial of a tuning run."""

    trial: int
    score: float  # NaN when the score was not a number
    accepted: bool
