"""MAP-Elites (Mouret & Clune 2015, "Illuminating search spaces by mapping elites"): a repertoire
of gaits, the best one found in each cell of a grid over two behaviour descriptors.

The archive is pyribs' ``GridArchive`` over ``problem.grid`` (``sanlab.descriptors``: signed speed,
airborne fraction, turns per second, ...), its objective the evaluation's score. The search runs
in generations of ``problem.generation`` controllers: those of the first tenth of the budget (at
least one generation) are random SANs, as phase 1's (§5.2), the first of them setting the grid's
open ranges (:func:`resolve`); each later one is an elite of the
archive with a few of its integer weights changed (each by +-1 or redrawn in [-2, 2]), the
elite picked with a chance proportional to 2 ** curiosity / (1 + the filled cells around its
own): the archive's frontier is pushed more often than its crowded middle, and an elite whose
children entered the archive (curiosity + 1 each) more often than not (- 1/2 each) more often
than one whose children did not (the curiosity score of Cully & Demiris 2018, "Quality and
diversity optimization: a unifying modular framework", clipped to +-4). Half of the mutants
are first moved along the line towards a second elite picked the same way (:func:`line`, the
line step of Iso+LineDD), which steps where elites differ rather than anywhere. A generation is
inserted into the archive, in index order, once all its scores are in.

Exact resumption: controller ``idx`` draws its parent and its mutation from a stream of its own
(seed, idx), and a generation only reads the archive (and the curiosity) of the generations
before it, so the archive rebuilt from the stored evaluations (:func:`rebuild`), each mutant
stored with its parent's index (``extra["parent_idx"]``), gives a resumed run the same
candidates, and the same rows, as an uninterrupted one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.records import ScoreBatch
from sanlab.library.records import Evaluation, EvaluationRow, TracePoint
from sanlab.san import WEIGHT_MAX, WEIGHT_MIN
from sanlab.search.base import Candidate, Grid, Problem, Told

if TYPE_CHECKING:
    from sanlab.library import Library

STREAM = 0x4D45  # names MAP-Elites' own random streams ("ME")
MEAN_CHANGES = 2.0  # weights changed per mutation, on average (at least one)
INITIAL_SHARE = 0.1  # of the budget: random SANs before any mutation
LINE_SHARE = 0.5  # of the mutants: first moved along the line to a second elite (Iso+LineDD)
LINE_SIGMA = 0.5  # the line step's spread, in units of the two elites' difference
CURIOSITY_UP, CURIOSITY_DOWN = 1.0, 0.5  # an elite's curiosity: + when its child enters the archive, - when not
CURIOSITY_CAP = 4.0  # a parent's weight is multiplied by 2 ** curiosity, curiosity clipped to +-CAP


class MapElites:
    """MAP-Elites over ``problem.grid`` (see the module docstring); phase 1."""

    phase: ClassVar[int] = 1

    def __init__(self, problem: Problem):
        if problem.grid is None:
            raise ValueError("map-elites needs a grid of two behaviour descriptors")
        self.problem = problem
        self.grid = problem.grid
        self.generation = max(1, int(problem.generation))
        first = max(self.generation, int(math.ceil(INITIAL_SHARE * problem.budget)))
        self.random_until = int(math.ceil(first / self.generation)) * self.generation
        self.archive: Any = None  # made when the first generation is in (its ranges may come from it)
        self._gen = 0  # the generation being asked and told
        self._todo: list[int] = list(self._indices(0))
        self._results: dict[int, tuple[np.ndarray, float, np.ndarray | None, int | None]] = {}
        self._curiosity: dict[int, float] = {}  # elite idx -> how often its children entered the archive
        self._parents: dict[int, int] = {}  # idx -> its parent's, for the candidates in flight
        self._pick: tuple | None = None  # (generation, elites, chances) of the parents' draw
        self._pending = 0
        self._stored = 0
        self._best = 0.0

    def _indices(self, g: int) -> range:
        return range(g * self.generation, min(self.problem.budget, (g + 1) * self.generation))

    @property
    def done(self) -> bool:
        return not self._todo and not self._pending and self._gen * self.generation >= self.problem.budget

    @property
    def run_ids(self) -> tuple[str, ...]:
        return (self.problem.run_id,)

    def resume(self, evaluations: Sequence[Evaluation], trace: Sequence[TracePoint]) -> None:
        by_idx = {e.idx: e for e in evaluations}
        self._stored = len(by_idx)
        self._best = max((e.score for e in evaluations if e.score == e.score), default=0.0)
        san = self.problem.san
        while True:
            idx = self._indices(self._gen)
            if not len(idx):
                self._todo = []
                return
            for i in idx:
                if i in by_idx:
                    e = by_idx[i]
                    extra = e.extra or {}
                    parent = extra.get("parent_idx")
                    self._results[i] = (san.decode(e.encoding), _objective(e.score, e.nonfinite),
                                        measures(self.grid, extra.get("descriptors")),
                                        None if parent is None else int(parent))
            if len(self._results) < len(idx):
                self._todo = [i for i in idx if i not in self._results]
                return
            self._insert()

    def _insert(self) -> None:
        """The finished generation into the archive (in index order), and the next one set up."""
        done = sorted(self._results.items())
        ok = [(i, w, f, m) for i, (w, f, m, _) in done if m is not None]
        if self.archive is None:
            self.grid = resolve(self.grid, [m for _, _, _, m in ok])
            self.archive = archive(self.grid, self.problem.san.n_weights)
        entered = {}
        if ok:
            info = self.archive.add(np.stack([w.reshape(-1) for _, w, _, _ in ok]).astype(np.float64),
                                    np.array([f for _, _, f, _ in ok]), np.stack([m for _, _, _, m in ok]),
                                    idx=np.array([i for i, _, _, _ in ok], np.int64))
            entered = {i: bool(st > 0) for (i, _, _, _), st in zip(ok, info["status"], strict=True)}
        for i, (_, _, _, parent) in done:  # curiosity (Cully & Demiris 2018): did the child enter?
            if parent is not None:
                c = self._curiosity.get(parent, 0.0)
                self._curiosity[parent] = c + CURIOSITY_UP if entered.get(i, False) else c - CURIOSITY_DOWN
        self._results = {}
        self._gen += 1
        self._todo = list(self._indices(self._gen))

    def ask(self, n: int) -> list[Candidate]:
        take, self._todo = self._todo[:n], self._todo[n:]
        self._pending += len(take)
        return [self._candidate(i) for i in take]

    def _candidate(self, idx: int) -> Candidate:
        p = self.problem
        if idx < self.random_until or self.archive is None or self.archive.empty:
            return Candidate(idx, p.san.random_weights(p.seed, idx), None, search_key(p.seed, idx))
        rng = np.random.default_rng([p.seed, idx, STREAM])
        elites, chance = self._choice()
        k = rng.choice(len(chance), p=chance)
        parent = elites["solution"][k].astype(np.int8).reshape(p.san.n_nodes, p.san.n_inputs)
        self._parents[idx] = int(elites["idx"][k])
        if LINE_SHARE > 0 and len(chance) > 1 and rng.random() < LINE_SHARE:
            other = elites["solution"][rng.choice(len(chance), p=chance)].astype(np.int8)
            parent = line(parent, other.reshape(parent.shape), rng)
        return Candidate(idx, mutate(parent, rng), None, search_key(p.seed, idx))

    def _choice(self) -> tuple[dict, np.ndarray]:
        """The archive's elites (ordered by evaluation index: the archive's storage order is not
        part of the result) and each one's chance of being the next parent."""
        if self._pick is not None and self._pick[0] == self._gen:
            return self._pick[1], self._pick[2]
        data = self.archive.data(["solution", "idx", "index"])
        order = np.argsort(data["idx"])
        elites = {k: np.asarray(v)[order] for k, v in data.items()}
        # the frontier first: an elite with fewer filled cells around it is picked more often
        # (measured on the walker, 1000 evaluations: coverage 33 % against 25 % with uniform picks)
        filled = np.zeros(tuple(self.grid.bins), bool)
        cells = np.stack(np.unravel_index(elites["index"].astype(int), tuple(self.grid.bins)), 1)
        filled[tuple(cells.T)] = True
        pad = np.pad(filled, 1)
        n = len(self.grid.bins)
        around = np.zeros(filled.shape, int)
        for shift in np.ndindex(*(3,) * n):
            if any(d != 1 for d in shift):
                around += pad[tuple(slice(d, d + b) for d, b in zip(shift, self.grid.bins, strict=True))]
        # ... and one whose children entered the archive more often than not (its curiosity)
        c = np.array([self._curiosity.get(int(i), 0.0) for i in elites["idx"]])
        w = 1.0 / (1.0 + around[tuple(cells.T)]) * 2.0 ** np.clip(c, -CURIOSITY_CAP, CURIOSITY_CAP)
        chance = w / w.sum()
        self._pick = (self._gen, elites, chance)
        return elites, chance

    def tell(self, candidates: Sequence[Candidate], scores: ScoreBatch) -> Told:
        p = self.problem
        rows = []
        for k, c in enumerate(candidates):
            s = scores.row(k)
            m = measures(self.grid, s.descriptors)
            extra: dict[str, Any] = {}
            if c.idx in self._parents:
                extra["parent_idx"] = self._parents.pop(c.idx)
            rows.append(EvaluationRow(p.run_id, c.idx, p.san.encode(c.weights), p.gait_params, s, extra))
            self._results[c.idx] = (np.asarray(c.weights), _objective(s.score, s.nonfinite), m,
                                    extra.get("parent_idx"))
        self._pending -= len(candidates)
        self._stored += len(candidates)
        if len(scores):
            self._best = max(self._best, float(np.max(scores.score)))
        if not self._todo and not self._pending:
            self._insert()
        return Told(rows, [], [p.run_id] if self.done else [])

    def progress(self) -> tuple[int, int, float]:
        return self._stored, self.problem.budget, self._best

    def stats(self) -> dict[str, float]:
        """The archive now: ``coverage`` (share of cells filled), ``qd_score`` (sum of the elites'
        scores), ``elites``."""
        if self.archive is None:
            return {"coverage": 0.0, "qd_score": 0.0, "elites": 0}
        st = self.archive.stats
        return {"coverage": float(st.coverage), "qd_score": float(st.qd_score), "elites": int(st.num_elites)}


DEFAULT_DESCRIPTORS = ("vx_cm_s", "airborne")
DEFAULT_GENERATION = 64  # --batch of a map-elites search
DEFAULT_BINS = 16
FIXED = {"airborne": (0.0, 1.0)}  # descriptors whose range is known: fractions


def parse_grid(text: str | None, bins: int = DEFAULT_BINS) -> Grid:
    """``--grid``: "NAME,NAME" or "NAME:LO:HI,NAME:LO:HI" (a range left out is the fraction's
    [0, 1], else found from the first generation: :func:`resolve`); None: the default, signed
    speed by airborne fraction. ValueError (one line) for a bad one."""
    from sanlab.descriptors import NAMES

    parts = [p.strip() for p in (text or ",".join(DEFAULT_DESCRIPTORS)).split(",") if p.strip()]
    if len(parts) != 2:
        raise ValueError(f"grid: expected two descriptors (NAME,NAME or NAME:LO:HI,NAME:LO:HI), got {text!r}")
    if bins < 2 or bins > 1000:
        raise ValueError(f"grid bins: expected 2 to 1000, got {bins}")
    names: list[str] = []
    ranges: list[tuple[float, float] | None] = []
    for p in parts:
        name, *lim = p.split(":")
        if name not in NAMES:
            raise ValueError(f"grid: expected descriptors among {list(NAMES)}, got {name!r}")
        lo_hi = FIXED.get(name)
        if lim:
            try:
                lo, hi = (float(x) for x in lim)
            except ValueError:
                raise ValueError(f"grid: expected NAME:LO:HI with numbers, got {p!r}") from None
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"grid: expected LO < HI in {p!r}")
            lo_hi = (lo, hi)
        names.append(name)
        ranges.append(lo_hi)
    if len(set(names)) != len(names):
        raise ValueError(f"grid: a descriptor named twice in {text!r}")
    return Grid(tuple(names), tuple(ranges), (int(bins),) * len(names))


def resolve(grid: Grid, first: Sequence[np.ndarray]) -> Grid:
    """``grid`` with every range left open set from the first generation's coordinates
    ``first``: [lo - w, hi + w] around their extent [lo, hi], w its width (at least the
    descriptor's resolution times the bins: ``sanlab.modes.RESOLUTION``), so the mutants, which
    leave the random SANs' region, still find cells. The first generation is stored, so a resumed
    run and :func:`rebuild` find the same ranges."""
    from sanlab.modes import RESOLUTION

    ranges = []
    for j, (name, r) in enumerate(zip(grid.names, grid.ranges, strict=True)):
        if r is None:
            v = np.array([m[j] for m in first], float)
            v = v[np.isfinite(v)]
            lo, hi = (float(v.min()), float(v.max())) if len(v) else (0.0, 0.0)
            w = max(hi - lo, RESOLUTION.get(name, 0.01) * grid.bins[j])
            r = (lo - w, hi + w)
        ranges.append(r)
    return Grid(grid.names, tuple(ranges), grid.bins)


QD_EXTRA = "pip install 'sanlab[qd]'"  # pyribs (numba, llvmlite and pandas with it: about 300 MB)


class MissingExtra(ImportError):
    """An optional dependency is not installed; the message is one line naming the extra."""


def ribs(module: str, what: str) -> Any:
    """pyribs' ``ribs.<module>`` (the optional ``qd`` extra), or :class:`MissingExtra` saying
    that ``what`` needs it and how to install it."""
    import importlib

    try:
        return importlib.import_module(f"ribs.{module}")
    except ImportError as e:
        raise MissingExtra(f"{what} needs pyribs, which is not installed: {QD_EXTRA}") from e


def archive(grid: Grid, solution_dim: int):
    """An empty pyribs ``GridArchive`` for ``grid`` (its ranges set; each elite's evaluation index
    kept beside it). Raises :class:`MissingExtra` without pyribs (``pip install 'sanlab[qd]'``)."""
    GridArchive = ribs("archives", "--strategy map-elites").GridArchive

    ranges = [r for r in grid.ranges if r is not None]
    if len(ranges) != len(grid.ranges):
        raise ValueError("archive: resolve the grid's open ranges first")
    return GridArchive(solution_dim=solution_dim, dims=grid.bins, ranges=ranges, seed=0,
                       extra_fields={"idx": ((), np.int64)})


def measures(grid: Grid, descriptors: dict | None) -> np.ndarray | None:
    """The grid's coordinates [len(grid.names)] of an evaluation's descriptors (None if any is
    missing or not finite: such an evaluation enters no cell)."""
    if not isinstance(descriptors, dict):
        return None
    out = []
    for name in grid.names:
        v = descriptors.get(name)
        if v is None or not isinstance(v, (int, float)) or not math.isfinite(v):
            return None
        out.append(float(v))
    return np.asarray(out)


def mutate(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A copy of ``weights`` [N, I] with 1 + Poisson(MEAN_CHANGES - 1) distinct weights changed,
    each by +-1 (half the time; kept in [-2, 2], so a weight at a bound moves inwards) or
    redrawn uniformly in [-2, 2]."""
    w = np.array(weights, np.int8, copy=True)
    flat = w.reshape(-1)
    k = min(flat.size, 1 + int(rng.poisson(MEAN_CHANGES - 1)))
    for j in rng.choice(flat.size, size=k, replace=False):
        if rng.random() < 0.5:
            step = rng.choice((-1, 1))
            v = int(flat[j]) + int(step)
            if v < WEIGHT_MIN or v > WEIGHT_MAX:
                v = int(flat[j]) - int(step)
            flat[j] = v
        else:
            flat[j] = rng.integers(WEIGHT_MIN, WEIGHT_MAX + 1)
    return w


def line(weights: np.ndarray, other: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``weights`` moved along the line to ``other`` (both [N, I] integer weights): w + t (other - w),
    t ~ Normal(0, LINE_SIGMA), rounded and kept in [-2, 2]; the line part of Iso+LineDD
    (Vassiliades & Mouret 2018, "Discovering the elite hypervolume by leveraging interspecies
    correlation"), which steps where two elites differ rather than anywhere."""
    t = rng.normal(0.0, LINE_SIGMA)
    w = np.asarray(weights, np.float64)
    moved = np.rint(w + t * (np.asarray(other, np.float64) - w))
    return np.clip(moved, WEIGHT_MIN, WEIGHT_MAX).astype(np.int8)


def rebuild(grid: Grid, solution_dim: int, evaluations: Sequence[Evaluation], decode, generation: int,
            history: list | None = None) -> Any:
    """The archive a run's stored evaluations make, inserted as the search inserted them: a
    generation (``generation`` consecutive indices) at a time, in index order (``decode``: the
    SAN's ``decode``, encoding -> weights), its open ranges set from the first generation.
    ``history``: if given, (evaluations so far, coverage, QD-score) is appended after each
    generation."""
    rows: list[tuple[int, Evaluation, np.ndarray]] = []
    for e in sorted(evaluations, key=lambda e: e.idx):
        m = measures(grid, (e.extra or {}).get("descriptors"))
        if m is not None:
            rows.append((e.idx, e, m))
    a = archive(resolve(grid, [m for i, _, m in rows if i < generation]), solution_dim)
    for g in sorted({i // generation for i, _, _ in rows}):
        part = [r for r in rows if r[0] // generation == g]
        a.add(np.stack([np.asarray(decode(e.encoding), np.float64).reshape(-1) for _, e, _ in part]),
              np.array([_objective(e.score, e.nonfinite) for _, e, _ in part]), np.stack([m for _, _, m in part]),
              idx=np.array([i for i, _, _ in part], np.int64))
        if history is not None:
            history.append((min(len(evaluations), (g + 1) * generation), float(a.stats.coverage), float(a.stats.qd_score)))
    return a


def _objective(score: float, nonfinite: bool) -> float:
    return 0.0 if nonfinite or not math.isfinite(score) else float(score)


def _of_run(lib: Library, run_id: str, history: list | None = None) -> tuple[Grid, Any]:
    """(the grid, the archive rebuilt) of a stored run: its own MAP-Elites grid, or the default
    one (:func:`parse_grid`) with the run's evaluations binned into it (``history``: see
    :func:`rebuild`)."""
    from sanlab.creature import loads
    from sanlab.library import SearchSettings
    from sanlab.san import San

    run = lib.get_run(run_id)
    s = run.settings
    own = isinstance(s, SearchSettings) and s.grid is not None
    grid = Grid.from_json(s.grid) if own and isinstance(s, SearchSettings) and s.grid is not None else parse_grid(None)
    san = San.for_creature(loads(run.creature_text, source=run.creature))
    generation = int(s.batch) if isinstance(s, SearchSettings) else DEFAULT_GENERATION
    return grid, rebuild(grid, san.n_weights, lib.top(run.run_id, None), san.decode, generation, history)


def view(lib: Library, run_id: str) -> dict[str, Any]:
    """A stored run's archive, rebuilt once from its evaluations (a MAP-Elites run's own grid, any
    other run's evaluations binned into the default grid): {"own": bool, "grid": the Grid with its
    ranges set, "best": each cell's best score [bins_x, bins_y] (NaN: empty), "elites": [{"cell":
    [i, j], "gait": "RUN#IDX", "score", "measures": [x, y]}] by cell, "progress": after each
    generation {"evaluations", "coverage", "qd_score"}, "stats": {"elites", "coverage",
    "qd_score"}}. Raises LibraryError for an unknown run."""
    from sanlab.library import SearchSettings

    s = lib.get_run(run_id).settings
    steps: list = []
    grid, a = _of_run(lib, run_id, steps)
    ranges = tuple((float(lo), float(hi)) for lo, hi in zip(a.lower_bounds, a.upper_bounds, strict=True))
    best = np.full(tuple(grid.bins), np.nan)
    data = a.data(["objective", "index", "idx", "measures"])
    elites = []
    for obj, k, i, m in zip(data["objective"], data["index"], data["idx"], data["measures"], strict=True):
        cell = np.unravel_index(int(k), tuple(grid.bins))
        best[cell] = obj
        elites.append({"cell": [int(c) for c in cell], "gait": f"{run_id}#{int(i)}", "score": float(obj),
                       "measures": [float(x) for x in m]})
    st = a.stats
    return {"own": isinstance(s, SearchSettings) and s.grid is not None, "grid": Grid(grid.names, ranges, grid.bins),
            "best": best, "elites": sorted(elites, key=lambda e: e["cell"]),
            "progress": [{"evaluations": n, "coverage": c, "qd_score": q} for n, c, q in steps],
            "stats": {"elites": int(st.num_elites), "coverage": float(st.coverage), "qd_score": float(st.qd_score)}}


def archive_stats(lib: Library, run_id: str) -> dict | None:
    """A MAP-Elites run's archive (:func:`view`): {"grid" (its ranges set), "elites", "coverage",
    "qd_score"}; None for a run of another strategy. Raises LibraryError for an unknown run."""
    from sanlab.library import SearchSettings

    s = lib.get_run(run_id).settings
    if not isinstance(s, SearchSettings) or s.grid is None:
        return None
    v = view(lib, run_id)
    return {"grid": v["grid"].to_json(), **v["stats"]}


def cells(lib: Library, run_id: str) -> tuple[Grid, list[tuple[float, float]], np.ndarray]:
    """(grid, its ranges, each cell's best score [bins_x, bins_y], NaN where empty): :func:`view`."""
    v = view(lib, run_id)
    return v["grid"], list(v["grid"].ranges), v["best"]


def elites(lib: Library, run_id: str) -> list[dict]:
    """Every filled cell of a stored run's archive, by cell: :func:`view`'s "elites"."""
    return view(lib, run_id)["elites"]


def progress(lib: Library, run_id: str) -> list[dict]:
    """How a stored run's archive grew, after each generation: :func:`view`'s "progress"."""
    return view(lib, run_id)["progress"]
