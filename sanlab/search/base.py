"""The ask/tell interface every search strategy implements, and what crosses it.

A strategy proposes candidates (``ask``) and learns their scores (``tell``); it never simulates
and never stores: ``tell`` returns what to store (:class:`Told`), and the driver
(``sanlab.search.driver``) evaluates what was asked on a backend, commits what was told, and
reports progress. A strategy is built from a :class:`Problem` alone and can be resumed from what
its run stored, so a new optimiser is one new module plus its line in ``registry``; the tests in
``tests/search/test_strategies.py`` check every registered strategy against this contract.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, ClassVar, Protocol

import numpy as np

from sanlab.evaluate.ensemble import Key
from sanlab.evaluate.records import GaitParams, ScoreBatch, Scores
from sanlab.library.records import Evaluation, EvaluationRow, TracePoint, TraceRow
from sanlab.san import San

if TYPE_CHECKING:
    from sanlab.search.space import Space


@dataclass(frozen=True)
class Candidate:
    """One controller to evaluate.

    idx: what it is within its run (a phase-1 controller's index; a tuning trial's number).
    weights: SAN weights [N, I]. theta: a parameter vector [P] of the problem's space (None: the
    creature file's parameters). key: its ensemble key (``sanlab.evaluate.ensemble``). role: what
    the strategy asked it for ("controller", "start", "trial" or "final"). stream: which strategy
    of a :class:`Together` asked it. pattern: an open-loop square wave [4 A + 1] run instead of
    the SAN (``sanlab.search.pattern``; the weights are then all zero and unused).
    """

    idx: int
    weights: np.ndarray
    theta: np.ndarray | None
    key: Key
    role: str = "controller"
    stream: int = 0
    pattern: np.ndarray | None = None


@dataclass(frozen=True)
class Start:
    """Where a phase-2 strategy starts: a gait's weights [N, I], its parameter vector [P], its
    permanent id (the tuned gait's parent), and its scores if already known (else the strategy
    asks for them under its own evaluation conditions)."""

    weights: np.ndarray
    theta: np.ndarray
    parent: str | None = None
    scores: Scores | None = None


@dataclass(frozen=True)
class Grid:
    """The archive of a quality-diversity search: two behaviour descriptors
    (``sanlab.descriptors.NAMES``), each one's range (None: from the search's first generation,
    see ``sanlab.search.map_elites.resolve``) and its number of cells; a value outside a range
    falls into the edge cell (pyribs' ``GridArchive``)."""

    names: tuple[str, ...]
    ranges: tuple[tuple[float, float] | None, ...]
    bins: tuple[int, ...]

    def to_json(self) -> dict:
        return {"names": list(self.names), "ranges": [None if r is None else list(r) for r in self.ranges],
                "bins": list(self.bins)}

    @classmethod
    def from_json(cls, d: dict) -> Grid:
        return cls(tuple(str(n) for n in d["names"]),
                   tuple(None if r is None else (float(r[0]), float(r[1])) for r in d["ranges"]),
                   tuple(int(b) for b in d["bins"]))


@dataclass(frozen=True)
class Problem:
    """Everything a strategy is built from.

    run_id: the run its rows are stored in. san: the network topology. budget: controllers to
    evaluate (phase 1) or trials (phase 2). seed: the run's seed. stream: the chain's index among
    chains started together (phase 2; names its random streams). space: the tuned parameters
    (phase 2). start: where phase 2 starts. gait_params: what every phase-1 controller is stored
    with (the creature file's delays). dtype: of the model that re-seats a reshaped creature.
    grid: a quality-diversity search's archive; generation: how many controllers such a search
    asks before it looks at their scores (its batch).
    """

    run_id: str
    san: San
    budget: int
    seed: int
    stream: int = 0
    space: Space | None = None
    start: Start | None = None
    gait_params: GaitParams = field(default_factory=GaitParams)
    dtype: str = "float64"
    grid: Grid | None = None
    generation: int = 64


@dataclass
class Told:
    """What a ``tell`` gives the driver to commit in one transaction: evaluated controllers,
    decided tuning trials, and the runs that are now finished."""

    evaluations: list[EvaluationRow] = field(default_factory=list)
    trace: list[TraceRow] = field(default_factory=list)
    finished: list[str] = field(default_factory=list)

    def extend(self, other: Told) -> None:
        self.evaluations += other.evaluations
        self.trace += other.trace
        self.finished += other.finished


class Strategy(Protocol):
    """What a driver calls on a search strategy.

    The driver asks while the strategy is not ``done`` (``ask`` may return [] while the strategy
    waits for scores it asked for: a sequential method has one batch in flight at a time), tells
    it the scores of each asked batch (in the order of that batch; batches may come back in any
    order), and commits what ``tell`` returns. ``resume`` restores the state an interrupted run
    left in the library, so the run ends exactly as an uninterrupted one.
    """

    phase: ClassVar[int]  # 1: searches SAN weights from scratch; 2: tunes a start's parameters

    @property
    def done(self) -> bool:
        """Everything is asked, told and returned for storing."""
        ...

    @property
    def run_ids(self) -> tuple[str, ...]:
        """The runs its rows go to."""
        ...

    def ask(self, n: int) -> list[Candidate]:
        """Up to n candidates to evaluate next ([] when none can be asked yet or any more)."""
        ...

    def tell(self, candidates: Sequence[Candidate], scores: ScoreBatch) -> Told:
        """The scores of a batch it asked for (aligned with ``candidates``); what to store."""
        ...

    def resume(self, evaluations: Sequence[Evaluation], trace: Sequence[TracePoint]) -> None:
        """Continue from what its run stored (before the first ``ask``)."""
        ...

    def progress(self) -> tuple[int, int, float]:
        """(units finished, units in all, best score so far): controllers or trials."""
        ...


class StrategyClass(Protocol):
    """What the registry holds: a strategy class, built from a :class:`Problem`."""

    phase: int

    def __call__(self, problem: Problem, /) -> Strategy: ...


class Together:
    """Several strategies driven as one (e.g. one tuning chain per gait): each ``ask`` collects
    a window from every strategy that can ask, ``tell`` routes each candidate back to its own."""

    phase: ClassVar[int] = 2

    def __init__(self, strategies: Sequence[Strategy]):
        self.strategies = list(strategies)

    @property
    def done(self) -> bool:
        return all(s.done for s in self.strategies)

    @property
    def run_ids(self) -> tuple[str, ...]:
        return tuple(r for s in self.strategies for r in s.run_ids)

    def ask(self, n: int) -> list[Candidate]:
        active = [j for j, s in enumerate(self.strategies) if not s.done]
        window = max(1, n // max(1, len(active)))
        out: list[Candidate] = []
        for j in active:
            if len(out) >= n:
                break
            out += [replace(c, stream=j) for c in self.strategies[j].ask(min(window, n - len(out)))]
        return out

    def tell(self, candidates: Sequence[Candidate], scores: ScoreBatch) -> Told:
        told = Told()
        for j, s in enumerate(self.strategies):
            mine = [k for k, c in enumerate(candidates) if c.stream == j]
            if mine:
                told.extend(s.tell([candidates[k] for k in mine], scores.take(np.asarray(mine))))
        return told

    def resume(self, evaluations: Sequence[Evaluation], trace: Sequence[TracePoint]) -> None:
        raise TypeError("resume each strategy of a Together on its own run")

    def progress(self) -> tuple[int, int, float]:
        parts = [s.progress() for s in self.strategies]
        return sum(p[0] for p in parts), sum(p[1] for p in parts), max((p[2] for p in parts), default=0.0)
