"""Gait modes: a run's useful controllers grouped by how they move (issue 31; §6.1: the cart's
five gaits, "told apart by eye").

Each evaluation carries behaviour descriptors (``sanlab.descriptors``). The useful ones (not
fallen, finite, scoring at least ``min_score``) are grouped in three steps (issue 57):

1. by kind: each gait's own rule name (:func:`name` of its own descriptors: rolling, hopping,
   walking ...) and its direction along x (+, -, or still under 0.5 cm/s). Gaits of two kinds
   are never one mode, so a rare kind (§6.1's cartwheeling cart, among 1000 SANs) stays a mode
   of its own however few gaits have it;
2. within a kind, by density: scikit-learn's HDBSCAN on the standardised continuous descriptors
   (signed speed, COM height and its spread, turns per second, airborne fraction, joint speed,
   and each touch sensor's duty factor, n duty factors weighing as much together as sqrt(n)
   other descriptors), its smallest cluster the larger of
   ``min_cluster`` and half the square root of the kind's count; a gait HDBSCAN calls noise joins
   the cluster of its nearest clustered gait of the kind, and a kind HDBSCAN does not split is
   one mode. A gait of a kind is nearer its own crowd than anything else: left alone as a mode
   of one it made most modes single gaits (the caterpillar's 17 of 19), which the table hid;
3. exactly, by the periodic sensor signature within a kind: two controllers of a kind with the
   same cyclic pattern of sensor words (of at least two words) are the same mode by
   construction. Across kinds a signature joins nothing: a two-word cycle (one sensor
   blinking) is common; it put two of the cart's seven rolling gaits in flipping modes, and
   with stragglers joining their crowd it folded all seven, the cart's best among them, into
   one.

Modes are ranked by their best score and named from their descriptors' medians where a rule
fits (see :func:`name`), else "mode 1", "mode 2" ...; a name that repeats is numbered ("hopping
2"), the modes of more than one gait first, so that the names a table shows (it hides the modes
of one gait) have no gaps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from sanlab.descriptors import NAMES

if TYPE_CHECKING:
    from sanlab.library import Library

MIN_SHARE = 0.2  # useful gaits score at least this share of their run's best (the default)
FEATURES = ("vx_cm_s", "height_m", "height_sd_m", "turns_per_s", "airborne", "joint_speed_rad_s")
# The smallest difference in each feature that tells gaits apart (a feature's scale is at least
# this and a tenth of its median size): a feature that only varies by noise among the gaits
# would otherwise be stretched to the weight of one that separates them.
RESOLUTION = {"vx_cm_s": 0.5, "height_m": 0.005, "height_sd_m": 0.002, "turns_per_s": 0.02, "airborne": 0.02,
              "joint_speed_rad_s": 0.1, "duty": 0.02}
MIN_CLUSTER = 3  # HDBSCAN's smallest group, at least (a kind of many gaits: half the square root of their count)
STILL_CM_S = 0.5  # a gait slower than this along x has no direction (as RESOLUTION["vx_cm_s"])


@dataclass(frozen=True)
class Gait:
    """What :func:`find` needs of one evaluation."""

    gait_id: str  # "RUN#IDX"
    score: float
    speed_cm_s: float
    descriptors: dict[str, Any]  # as stored (``Scores.descriptors``)


@dataclass(frozen=True)
class Mode:
    """One mode: its members (best first), name and descriptor medians."""

    name: str
    gaits: tuple[Gait, ...]  # best score first
    summary: dict[str, float]  # each descriptor's median over the members (NaN-free ones)
    signature: str | None  # the members' most common signature (None: none periodic)
    duty: tuple[float, ...] = field(default=())  # per touch sensor, the members' median duty factor
    seconds: float = math.nan  # the evaluation time (s)

    @property
    def turns(self) -> float:
        """The members' median net turns of the body over the run."""
        return self.summary.get("turns_per_s", math.nan) * self.seconds

    @property
    def best(self) -> Gait:
        return self.gaits[0]

    @property
    def size(self) -> int:
        return len(self.gaits)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "size": self.size, "best": self.best.gait_id, "score": self.best.score,
                "speed_cm_s": self.best.speed_cm_s, "signature": self.signature, "turns": _json(self.turns),
                "descriptors": {k: (v if math.isfinite(v) else None) for k, v in self.summary.items()},
                "duty": list(self.duty), "gaits": [g.gait_id for g in self.gaits]}


def periodic(signature: str | None) -> bool:
    """A signature that names a cycle (two words or more), not a word the sensors kept."""
    return bool(signature) and "." in str(signature)


def find(gaits: Sequence[Gait], *, seconds: float, water: bool = False, min_cluster: int = MIN_CLUSTER,
         plane: str = "vertical") -> list[Mode]:
    """Group ``gaits`` (the useful ones, with descriptors) into modes, best first (see the module
    docstring). ``seconds``: the evaluation time (s; for the rotation rules); ``water``: the
    creature swims (``Structure.water``); ``plane``: its world's ("vertical" or "horizontal",
    for the names: see :func:`name`). Raises ValueError for a gait without descriptors."""
    gaits = list(gaits)
    for g in gaits:
        if not g.descriptors:
            raise ValueError(f"gait {g.gait_id} has no descriptors")
    if not gaits:
        return []
    X = features(gaits)
    kinds = [kind(g, seconds=seconds, water=water, plane=plane) for g in gaits]
    labels = np.full(len(gaits), -1)
    for k in dict.fromkeys(kinds):
        idx = np.flatnonzero([x == k for x in kinds])
        sub = _density(X[idx], min_cluster)
        labels[idx] = np.where(sub >= 0, sub + labels.max() + 1, -1)
    parent = list(range(len(gaits)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def join(i: int, j: int) -> None:
        parent[root(i)] = root(j)

    first: dict[Any, int] = {}
    for i, g in enumerate(gaits):
        keys = []
        if labels[i] >= 0:
            keys.append(("cluster", int(labels[i])))
        sig = g.descriptors.get("signature")
        if periodic(sig):
            keys.append(("signature", kinds[i], sig))
        for k in keys:
            if k in first:
                join(i, first[k])
            else:
                first[k] = i
    groups: dict[int, list[int]] = {}
    for i in range(len(gaits)):
        groups.setdefault(root(i), []).append(i)
    modes = [_mode([gaits[i] for i in sorted(m, key=lambda i: -gaits[i].score)]) for m in groups.values()]
    modes.sort(key=lambda m: -m.best.score)
    names = [name(m.summary, m.duty, seconds=seconds, water=water, plane=plane) or "mode" for m in modes]
    used: dict[str, int] = {}
    numbered: dict[int, str] = {}
    # the modes of more than one gait are numbered first: what the table shows reads "hopping",
    # "hopping 2" without a gap where a mode of one gait it hides took a number
    for i in sorted(range(len(modes)), key=lambda i: (modes[i].size == 1, i)):
        n = names[i]
        used[n] = used.get(n, 0) + 1
        numbered[i] = f"{n} {used[n]}" if used[n] > 1 or n == "mode" else n
    return [Mode(numbered[i], m.gaits, m.summary, m.signature, m.duty, seconds) for i, m in enumerate(modes)]


def kind(g: Gait, *, seconds: float, water: bool = False, plane: str = "vertical") -> tuple[str, int]:
    """A gait's kind, the first split of :func:`find`: (its own rule name, "" where none fits;
    its direction along x: 1, -1, or 0 when slower than :data:`STILL_CM_S`)."""
    d = g.descriptors
    own = name({k: _num(d.get(k)) for k in NAMES}, [_num(x) for x in (d.get("duty") or ())], seconds=seconds,
               water=water, plane=plane)
    vx = _num(d.get("vx_cm_s"))
    return own or "", (0 if not abs(vx) >= STILL_CM_S else 1 if vx > 0 else -1)


def of_run(lib: Library, run_id: str, min_score: float | None = None, min_cluster: int = MIN_CLUSTER,
           rescore: bool = False) -> tuple[list[Mode], float, int]:
    """The modes of a stored run: (modes, the score threshold used, how many useful gaits were
    stored without descriptors and left out). Useful: not fallen, finite, scoring at least
    ``min_score`` (default: :data:`MIN_SHARE` of the run's best, and above 0). ``rescore``: a
    search run's useful gaits stored without descriptors (before sanlab computed them) are
    evaluated again, as the run evaluated them, for their descriptors (nothing is stored).
    Raises LibraryError for an unknown run, ValueError when ``rescore`` cannot rebuild its
    evaluation (not a search run)."""
    from sanlab.creature import loads

    run = lib.get_run(run_id)
    evs = [e for e in lib.top(run.run_id, None) if not e.fell and not e.nonfinite and math.isfinite(e.score)]
    best = max((e.score for e in evs), default=0.0)
    threshold = MIN_SHARE * best if min_score is None else float(min_score)
    useful = [e for e in evs if e.score >= threshold and (min_score is not None or e.score > 0)]
    stored = {e.idx: e.extra["descriptors"] for e in useful
              if e.extra is not None and isinstance(e.extra.get("descriptors"), dict)}
    if rescore and len(stored) < len(useful):
        stored.update(_rescored(lib, run_id, [e for e in useful if e.idx not in stored]))
    gaits = [Gait(e.gait_id, e.score, e.speed_cm_s, stored[e.idx]) for e in useful if e.idx in stored]
    spec = loads(run.creature_text, source=run.creature)
    seconds = float(run.params.get("seconds") or spec.evaluation.seconds)
    return find(gaits, seconds=seconds, water=spec.world.water_drag > 0, min_cluster=min_cluster,
                plane=spec.world.plane), threshold, len(useful) - len(gaits)


def _rescored(lib: Library, run_id: str, evaluations: Sequence[Any]) -> dict[int, dict]:
    """{idx: descriptors} of a search run's ``evaluations``, evaluated again with the run's own
    settings (creature, metric, time, ensemble, keys, dtype)."""
    from sanlab.creature import loads
    from sanlab.evaluate import Evaluator
    from sanlab.evaluate.ensemble import search_key
    from sanlab.library import SearchSettings

    run = lib.get_run(run_id)
    s = run.settings
    if not isinstance(s, SearchSettings) or run.seed is None:
        raise ValueError(f"run {run_id} is a {run.kind} run: only a search run's gaits can be re-scored here")
    spec = loads(run.creature_text, source=s.source or run.creature)
    ev = Evaluator(spec, metric=s.metric, seconds=s.seconds, dtype=run.dtype or "float32", batch=min(s.batch, 256),
                   ensemble=s.ensemble)
    W = np.stack([ev.san.decode(e.encoding) for e in evaluations])
    scores = ev(W, None, [search_key(run.seed, e.idx) for e in evaluations])
    return {e.idx: scores.row(k).descriptors or {} for k, e in enumerate(evaluations)}


def features(gaits: Sequence[Gait]) -> np.ndarray:
    """[G, F] standardised descriptor vectors (``FEATURES`` then each touch sensor's duty factor):
    centred, divided by the largest of the standard deviation, :data:`RESOLUTION` and a tenth of
    the median magnitude; a missing value is the feature's median."""
    n_duty = max((len(g.descriptors.get("duty") or ()) for g in gaits), default=0)
    rows = []
    for g in gaits:
        d = g.descriptors
        duty = list(d.get("duty") or ())
        rows.append([_num(d.get(k)) for k in FEATURES] + [_num(x) for x in duty] + [math.nan] * (n_duty - len(duty)))
    X = np.asarray(rows, float).reshape(len(gaits), -1)
    med = np.nanmedian(np.where(np.isfinite(X), X, np.nan), 0) if len(X) else np.zeros(X.shape[1])
    med = np.where(np.isfinite(med), med, 0.0)
    X = np.where(np.isfinite(X), X, med)
    floor = np.array([RESOLUTION[k] for k in FEATURES] + [RESOLUTION["duty"]] * n_duty)
    scale = np.maximum.reduce([X.std(0), floor, 0.1 * np.median(np.abs(X), 0)])
    # n duty factors weigh as much as sqrt(n) descriptors: a caterpillar's five feet would
    # otherwise outweigh its speed, height and turns together and split every gait from the next
    scale[len(FEATURES):] *= math.sqrt(n_duty) if n_duty else 1.0
    return (X - X.mean(0)) / scale


def _density(X: np.ndarray, min_cluster: int) -> np.ndarray:
    """[G] cluster labels (0, 1, ...) of the gaits of one kind (rows of ``X``): HDBSCAN's, its
    smallest cluster the larger of ``min_cluster`` and half the square root of G, every noise
    point given its nearest clustered point's label; all 0 (one mode) where HDBSCAN finds no
    cluster or G is too small to split."""
    n = len(X)
    size = max(min_cluster, round(math.sqrt(n) / 2))
    if n < 2 * size:  # not two clusters' worth: one mode
        return np.zeros(n, int)
    from sklearn.cluster import HDBSCAN

    options: dict[str, Any] = {"min_cluster_size": size, "copy": True}  # copy: sklearn 1.9 warns without it
    labels = HDBSCAN(**options).fit_predict(X)
    clustered = np.flatnonzero(labels >= 0)
    if not len(clustered):
        return np.zeros(n, int)
    for i in np.flatnonzero(labels < 0):
        labels[i] = labels[clustered[np.argmin(np.linalg.norm(X[clustered] - X[i], axis=1))]]
    return labels


def _mode(gaits: list[Gait]) -> Mode:
    summary = {}
    for k in NAMES:
        v = np.array([_num(g.descriptors.get(k)) for g in gaits])
        v = v[np.isfinite(v)]
        summary[k] = float(np.median(v)) if len(v) else math.nan
    duties = [list(g.descriptors.get("duty") or ()) for g in gaits]
    n = min((len(d) for d in duties), default=0)
    duty = tuple(float(np.median([d[j] for d in duties if _num(d[j]) == _num(d[j])] or [math.nan])) for j in range(n))
    sigs = [g.descriptors.get("signature") for g in gaits if periodic(g.descriptors.get("signature"))]
    sig = max(dict.fromkeys(sigs), key=sigs.count) if sigs else None
    return Mode("", tuple(gaits), summary, sig, duty)


def name(summary: dict[str, float], duty: Sequence[float], *, seconds: float, water: bool,
         plane: str = "vertical") -> str | None:
    """The mode's name from its descriptor medians, first rule that fits. In the horizontal
    plane (seen from above) the body's turns are turns of its heading, nothing leaves the floor
    and every contact touches: the rules there are

    - ``circling``: at least 1.5 net turns of its heading over the run;
    - ``turning``: between 0.4 and 1.5 turns;
    - ``swimming``: the creature is in water;
    - ``undulating``: moving with its joints (at least 0.2 rad/s);
    - ``sliding``: its joints all but still.

    In the vertical plane:

    - ``rolling``: at least 1.5 net turns of the body over the run;
    - ``flipping``: between 0.4 and 1.5 turns (it went over, about once);
    - ``swimming``: the creature is in water;
    - ``hopping``: airborne at least 10 % of the time;
    - ``walking``: two or more touch sensors each on between 15 % and 85 % of the time;
    - ``shuffling``: never (under 2 %) airborne, moving with its joints;
    - ``sliding``: never airborne, its joints all but still (under 0.2 rad/s).

    None where no rule fits (the caller numbers it)."""
    turns = abs(_num(summary.get("turns_per_s"))) * seconds
    air = _num(summary.get("airborne"))
    joints = _num(summary.get("joint_speed_rad_s"))
    if plane == "horizontal":  # a top view: nothing can roll, flip, hop or lift a foot
        if turns >= 1.5:
            return "circling"
        if turns >= 0.4:
            return "turning"
        if water:
            return "swimming"
        if joints == joints:
            return "undulating" if joints >= 0.2 else "sliding"
        return None
    if turns >= 1.5:
        return "rolling"
    if turns >= 0.4:
        return "flipping"
    if water:
        return "swimming"
    if air >= 0.10:
        return "hopping"
    if sum(0.15 <= _num(d) <= 0.85 for d in duty) >= 2:
        return "walking"
    if air < 0.02 and joints == joints:
        return "shuffling" if joints >= 0.2 else "sliding"
    return None


def _json(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _num(x) -> float:
    try:
        return float(x) if x is not None else math.nan
    except (TypeError, ValueError):
        return math.nan
