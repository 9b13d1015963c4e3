"""The values an evaluation takes and gives, as frozen records with one JSON form each:
:class:`GaitParams` (how a controller is evaluated) and :class:`Scores` (what its evaluation
scored), plus :class:`ScoreBatch`, the evaluator's array form of many Scores.

Each record is decoded from JSON in exactly one place, its ``from_json``; the gait library stores
the JSON (``sanlab.library.records`` decodes rows through these).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def _floats(x: Any) -> tuple[float, ...] | None:
    return None if x is None else tuple(float(v) for v in np.asarray(x, float).reshape(-1))


@dataclass(frozen=True)
class GaitParams:
    """How a controller is evaluated, beside its weights.

    A phase-1 controller has every node's delays (``delay_on``, ``delay_off``, s); a tuned one
    has per-node rates (``k1`` [N] 1/s > 0, ``k2`` [N] 1/s < 0; T_on = 1/k1, T_off = -1/k2), and
    ``model`` overrides of the creature's numbers ({``sanlab.sim.Params`` field: nested list},
    SI: actuator ranges and gains, sensor ranges, and with ``--morphology`` masses, lengths and
    the start pose), and with ``--morphology`` ``scale`` [L] (each link's length factor), or, for
    a file with free numbers, ``free`` [F] (every free number's value, ``sanlab.creature.free``).
    A *pattern* gait (the pattern ceiling, ``sanlab.search.pattern``) is no SAN: ``pattern``
    [4 A + 1] is its open-loop square wave (per actuator phase, duty, low and high level, then
    the period in s; ``sanlab.sim.PatternController``), and its weights are unused (all zero).
    Unset fields are absent from the JSON form, which is what the library stores.
    """

    delay_on: float | None = None
    delay_off: float | None = None
    k1: tuple[float, ...] | None = None
    k2: tuple[float, ...] | None = None
    model: dict[str, Any] = field(default_factory=dict)
    scale: tuple[float, ...] | None = None
    free: tuple[float, ...] | None = None  # tuned with --morphology on a file with free numbers: all of them [F]
    pattern: tuple[float, ...] | None = None  # a pattern gait's square wave [4 A + 1] (no SAN)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.delay_on is not None:
            out["delay_on"] = self.delay_on
        if self.delay_off is not None:
            out["delay_off"] = self.delay_off
        if self.k1 is not None:
            out["k1"] = list(self.k1)
        if self.k2 is not None:
            out["k2"] = list(self.k2)
        if self.k1 is not None or self.model:
            out["model"] = self.model
        if self.scale is not None:
            out["scale"] = list(self.scale)
        if self.free is not None:
            out["free"] = list(self.free)
        if self.pattern is not None:
            out["pattern"] = list(self.pattern)
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any] | None) -> GaitParams:
        """The record of a stored ``params`` object (unknown keys are ignored; {} means the
        creature file's own values)."""
        d = d or {}
        num = lambda k: None if d.get(k) is None else float(d[k])
        return cls(num("delay_on"), num("delay_off"), _floats(d.get("k1")), _floats(d.get("k2")),
                   dict(d.get("model") or {}), _floats(d.get("scale")), _floats(d.get("free")),
                   _floats(d.get("pattern")))

    def rates(self, n_nodes: int, delay_on: float, delay_off: float) -> tuple[np.ndarray, np.ndarray]:
        """(k1 [N], k2 [N]) in 1/s: the per-node rates, else from this record's delays, else from
        the given (the creature file's) delays."""
        if self.k1 is not None and self.k2 is not None:
            return np.asarray(self.k1, float), np.asarray(self.k2, float)
        on = self.delay_on if self.delay_on is not None else delay_on
        off = self.delay_off if self.delay_off is not None else delay_off
        return np.full(n_nodes, 1.0 / on), np.full(n_nodes, -1.0 / off)


@dataclass(frozen=True)
class Scores:
    """What one evaluation scored (see ``sanlab.metrics`` for each metric).

    With an ensemble of K perturbed copies (``sanlab.evaluate.ensemble``) ``score``, ``speed_cm_s``
    and ``distance_m`` are the medians of the members' values, ``fell`` says that more than half
    of the members fell, ``nonfinite`` that any member went non-finite (the evaluation then scores
    0: score, speed and distance);
    ``member_scores`` and ``member_speeds`` [K] are the members' own values (the spread). One
    member (K = 1) is the single unperturbed rollout.
    """

    score: float
    speed_cm_s: float  # cm/s
    distance_m: float  # m
    fell: bool
    nonfinite: bool
    member_scores: tuple[float, ...] = ()
    member_speeds: tuple[float, ...] = ()  # cm/s
    dx_m: float | None = None  # m, signed displacement along x (the members' median; None: unknown)
    descriptors: dict[str, Any] | None = None  # sanlab.descriptors: {name: float (None: NaN), "duty": [..], "signature": str | None}

    def to_json(self) -> dict[str, Any]:
        out = {"score": self.score, "speed_cm_s": self.speed_cm_s, "distance_m": self.distance_m,
               "fell": self.fell, "nonfinite": self.nonfinite,
               "members": {"score": list(self.member_scores), "speed_cm_s": list(self.member_speeds)}}
        if self.dx_m is not None and math.isfinite(self.dx_m):
            out["dx_m"] = self.dx_m
        if self.descriptors is not None:
            out["descriptors"] = self.descriptors
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Scores:
        """The record of :meth:`to_json`'s object; a row stored before ensembles (no
        ``members``, no ``distance_m``) reads as one member."""
        nan = float("nan")
        score = nan if d.get("score") is None else float(d["score"])
        speed = nan if d.get("speed_cm_s") is None else float(d["speed_cm_s"])
        members = d.get("members") or {}
        ms = members.get("score")
        mv = members.get("speed_cm_s")
        return cls(score, speed, nan if d.get("distance_m") is None else float(d["distance_m"]),
                   bool(d.get("fell", False)), bool(d.get("nonfinite", False)),
                   tuple(float(x) for x in ms) if ms else (score,),
                   tuple(float(x) for x in mv) if mv else (speed,),
                   None if d.get("dx_m") is None else float(d["dx_m"]),
                   d["descriptors"] if isinstance(d.get("descriptors"), dict) else None)


@dataclass(frozen=True)
class ScoreBatch:
    """Scores of a batch of B evaluations as arrays (what an evaluator returns; compact to send
    between processes): score, speed_cm_s, distance_m [B] float64; fell, nonfinite [B] bool;
    member_score, member_speed_cm_s [B, K] float64; dx_m [B] float64 (m, signed displacement
    along x, the members' median; NaN where unknown); descriptors: {name: [B] or [B, n]} float64,
    the members' medians of ``sanlab.descriptors`` (None: not computed); signature [B] object
    (str or None), the members' most common."""

    score: np.ndarray
    speed_cm_s: np.ndarray
    distance_m: np.ndarray
    fell: np.ndarray
    nonfinite: np.ndarray
    member_score: np.ndarray
    member_speed_cm_s: np.ndarray
    dx_m: Any = None
    descriptors: dict[str, np.ndarray] | None = None
    signature: Any = None

    def __post_init__(self):
        if self.dx_m is None:
            object.__setattr__(self, "dx_m", np.full(len(self.score), np.nan))
        if self.descriptors is not None and self.signature is None:
            object.__setattr__(self, "signature", np.full(len(self.score), None, dtype=object))

    def __len__(self) -> int:
        return len(self.score)

    def row(self, k: int) -> Scores:
        """Evaluation ``k`` as a record."""
        return Scores(float(self.score[k]), float(self.speed_cm_s[k]), float(self.distance_m[k]),
                      bool(self.fell[k]), bool(self.nonfinite[k]),
                      tuple(float(x) for x in self.member_score[k]),
                      tuple(float(x) for x in self.member_speed_cm_s[k]),
                      float(self.dx_m[k]) if np.isfinite(self.dx_m[k]) else None,
                      self._descriptors(k))

    def _descriptors(self, k: int) -> dict[str, Any] | None:
        if self.descriptors is None:
            return None
        out: dict[str, Any] = {}
        for name, v in self.descriptors.items():
            x = np.asarray(v[k], float)
            out[name] = [_json_float(y) for y in x] if x.ndim else _json_float(x)
        out["signature"] = self.signature[k]
        return out

    def rows(self) -> list[Scores]:
        return [self.row(k) for k in range(len(self))]

    def take(self, index: Any) -> ScoreBatch:
        """The evaluations at ``index`` (a slice or an index array)."""
        d = None if self.descriptors is None else {k: np.asarray(v)[index] for k, v in self.descriptors.items()}
        sig = None if d is None else np.asarray(self.signature, dtype=object)[index]
        return ScoreBatch(*(np.asarray(getattr(self, f))[index] for f in _FIELDS), descriptors=d, signature=sig)

    @staticmethod
    def concat(batches: list[ScoreBatch]) -> ScoreBatch:
        d = sig = None
        if batches and all(b.descriptors is not None for b in batches):
            d = {k: np.concatenate([b.descriptors[k] for b in batches]) for k in batches[0].descriptors}  # type: ignore[index]
            sig = np.concatenate([np.asarray(b.signature, dtype=object) for b in batches])
        return ScoreBatch(*(np.concatenate([getattr(b, f) for b in batches]) for f in _FIELDS), descriptors=d,
                          signature=sig)


def _json_float(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


_FIELDS = ("score", "speed_cm_s", "distance_m", "fell", "nonfinite", "member_score", "member_speed_cm_s", "dx_m")
