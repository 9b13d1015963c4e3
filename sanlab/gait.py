"""A gait: a stored controller together with the creature it drives, ready to replay or tune.

Its :class:`~sanlab.evaluate.records.GaitParams` say how the controller is evaluated beside its
weights (phase-1 delays, or a tuned gait's per-node rates and model overrides); its run's
settings say for how long, with which metric and on which ensemble it was scored.

Replaying uses the same compiled step as the search (there is no second physics).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sanlab.creature import loads
from sanlab.creature.spec import DELAY_RANGE, MAX_MAGNITUDE, Creature
from sanlab.evaluate.ensemble import Ensemble
from sanlab.evaluate.records import GaitParams
from sanlab.san import San, SanParams
from sanlab.sim.model import drag_edges

# Model overrides a stored gait may carry (what tuning writes; see sanlab.search.space), each with
# the shape of its sim.Params array and what its values must be.
_MODEL_KEYS = {
    "act_min": ("A",), "act_max": ("A",), "act_ks": ("A",), "act_kd": ("A",), "sens_min": ("S",),
    "sens_max": ("S",), "mass": ("L",), "inertia": ("L",), "com": ("L", 2), "anchor": ("L", 2),
    "contact": ("C", 2), "act_pts": ("A", 2, 2), "sens_pts": ("S", 2, 2), "spr_pts": ("N", 2, 2),
    "edge": ("E", 2, 2), "q0": ("D",), "root_pose": ("L", 3), "contact_load": ("C",),
}  # fmt: skip
_PARAM_KEYS = {"delay_on", "delay_off", "k1", "k2", "model", "scale", "free", "pattern"}
SCALE_RANGE = (0.1, 10.0)  # link length scales (tuning keeps them in [0.5, 1.5])
PERIOD_RANGE = (0.01, 100.0)  # s: a stored pattern's period (the pattern search keeps to a narrower range)


def check_params(spec: Creature, params: Any) -> None:
    """Raise ValueError (one line, naming the field) unless ``params`` are a stored gait's
    parameters that ``spec`` can run (see the module docstring): only known keys; delays in
    spec.DELAY_RANGE (s), per node if given as rates (k1 [N] > 0, k2 [N] < 0, both or neither);
    model overrides of known Params arrays with this creature's shapes, finite, of magnitude at
    most spec.MAX_MAGNITUDE, each actuator's and range sensor's min < max, gains, masses and
    inertias >= 0 (masses > 0); length scales [L] in SCALE_RANGE; a pattern [4 A + 1] whose
    phases, duties and levels lie in [0, 1] and whose period lies in PERIOD_RANGE (s)."""
    if not isinstance(params, dict):
        raise ValueError(f"params: expected an object, got {type(params).__name__}")
    unknown = sorted(str(k)[:40] for k in params if k not in _PARAM_KEYS)
    if unknown:
        raise ValueError(f"params.{unknown[0]}: unknown parameter; expected some of {sorted(_PARAM_KEYS)}")
    san = San.for_creature(spec)
    lo, hi = DELAY_RANGE
    for key in ("delay_on", "delay_off"):
        if key in params:
            _array(params[key], (), f"params.{key}", f"a delay in [{lo:g}, {hi:g}] (s)", lambda v: lo <= v <= hi)
    if ("k1" in params) != ("k2" in params):
        raise ValueError("params: expected both k1 and k2 (per-node rates), or neither")
    if "k1" in params:
        n = san.n_nodes
        _array(params["k1"], (n,), "params.k1", f"{n} rates 1/T_on with T_on in [{lo:g}, {hi:g}] s",
               lambda v: 1 / hi <= v <= 1 / lo)
        _array(params["k2"], (n,), "params.k2", f"{n} rates -1/T_off with T_off in [{lo:g}, {hi:g}] s",
               lambda v: -1 / lo <= v <= -1 / hi)
    if "scale" in params:
        a, b = SCALE_RANGE
        _array(params["scale"], (len(spec.links),), "params.scale", f"{len(spec.links)} length scales in [{a:g}, {b:g}]",
               lambda v: a <= v <= b)
    if "pattern" in params:
        A = len(spec.actuators)
        arr = _array(params["pattern"], (4 * A + 1,), "params.pattern",
                     f"{A} (phase, duty, low, high) in [0, 1] and a period (s)")
        if not np.all((arr[:-1] >= 0) & (arr[:-1] <= 1)):
            raise ValueError("params.pattern: expected phases, duties and levels in [0, 1]")
        lo, hi = PERIOD_RANGE
        if not lo <= arr[-1] <= hi:
            raise ValueError(f"params.pattern: expected a period in [{lo:g}, {hi:g}] s, got {arr[-1]:g}")
    if "free" in params:
        design = spec.design
        if design is None:
            raise ValueError("params.free: expected no free values (the creature file has no free numbers)")
        n = len(design.free)
        arr = _array(params["free"], (n,), "params.free", f"{n} values of the file's free numbers")
        for i, (x, f) in enumerate(zip(arr, design.free, strict=True)):
            if not f.min <= x <= f.max:
                raise ValueError(f"params.free[{i}]: expected a value of {f.name} within [{f.min:g}, {f.max:g}], got {x:g}")
    model = params.get("model")
    if model is None:
        return
    if not isinstance(model, dict):
        raise ValueError(f"params.model: expected an object, got {type(model).__name__}")
    sizes = {"A": len(spec.actuators), "S": len(spec.sensors), "L": len(spec.links), "D": spec.dofs,
             "C": sum(len(k.contacts) for k in spec.links), "N": len(spec.springs), "E": len(drag_edges(spec))}
    arrays = {}
    for key, value in model.items():
        if key not in _MODEL_KEYS:
            raise ValueError(f"params.model.{str(key)[:40]}: unknown model parameter; expected some of {sorted(_MODEL_KEYS)}")
        shape = tuple(sizes[d] if isinstance(d, str) else d for d in _MODEL_KEYS[key])
        ok = (lambda v: v > 0) if key == "mass" else (lambda v: v >= 0) if key in ("act_ks", "act_kd", "inertia") else None
        arrays[key] = _array(value, shape, f"params.model.{key}", "numbers" + (" >= 0" if ok else ""), ok)
    ranged = [i for i, x in enumerate(spec.sensors) if x.kind != "touch"]
    for lo_key, hi_key, idx in (("act_min", "act_max", range(len(spec.actuators))), ("sens_min", "sens_max", ranged)):
        low = arrays.get(lo_key, np.array([getattr(x, "min", 0.0) for x in (spec.actuators if lo_key == "act_min" else spec.sensors)]))
        high = arrays.get(hi_key, np.array([getattr(x, "max", 0.0) for x in (spec.actuators if lo_key == "act_min" else spec.sensors)]))
        for i in idx:
            if not low[i] < high[i]:
                raise ValueError(f"params.model.{hi_key}[{i}]: expected more than {lo_key}[{i}] ({low[i]:g}), got {high[i]:g}")


def _array(value: Any, shape: tuple, where: str, what: str, ok: Any = None) -> np.ndarray:
    """``value`` as a float array of ``shape`` whose every element is finite, of magnitude at most
    spec.MAX_MAGNITUDE and (if given) ``ok``; else ValueError "where: expected what ..."."""
    def bad(got: str) -> ValueError:
        dims = "x".join(map(str, shape))
        return ValueError(f"{where}: expected {what}" + (f" (shape {dims})" if shape else "") + f", got {got}")

    if isinstance(value, bool) or not isinstance(value, (int, float, list)):
        raise bad(type(value).__name__)
    try:
        arr = np.asarray(value, dtype=float)
    except (ValueError, TypeError, OverflowError, RecursionError):
        raise bad("a value that is not an array of numbers") from None
    if arr.shape != shape:
        raise bad(f"shape {'x'.join(map(str, arr.shape)) or 'a scalar'}")
    if not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > MAX_MAGNITUDE):
        raise bad("a value that is not finite or too large")
    if ok is not None and not all(ok(float(v)) for v in arr.reshape(-1)):
        raise bad(f"{next(float(v) for v in arr.reshape(-1) if not ok(float(v))):g}")
    return arr


@dataclass(frozen=True)
class Gait:
    gait_id: str  # "RUN#IDX" (permanent id)
    spec: Creature
    weights: np.ndarray  # [N, I] int8
    params: GaitParams  # how it is evaluated
    seconds: float  # evaluation time of its run (s)
    metric: str  # its run's metric
    ensemble: Ensemble = field(default_factory=lambda: Ensemble(members=1))  # its run's ensemble
    score: float = float("nan")
    speed_cm_s: float = float("nan")
    creature_text: str = ""  # the creature file, verbatim, as stored with its run
    source: str | None = None  # where the creature file came from (its run's settings)

    @property
    def san(self) -> San:
        return San.for_creature(self.spec)

    @property
    def kind(self) -> str:
        """"pattern" for an open-loop pattern gait (``GaitParams.pattern``), else "san"."""
        return "san" if self.params.pattern is None else "pattern"

    def require_san(self, what: str) -> None:
        """Raise ValueError (one line) if this gait is a pattern: it has no SAN to be ``what``
        (e.g. "tuned", "written as a C header")."""
        if self.kind == "pattern":
            raise ValueError(f"gait {self.gait_id} is an open-loop pattern (the pattern ceiling), not a SAN: "
                             f"it cannot be {what}")

    def patterns(self) -> np.ndarray | None:
        """A pattern gait's square wave with a leading batch axis of 1 [1, 4 A + 1] (what the
        evaluator's ``patterns`` takes), None for a SAN."""
        return None if self.params.pattern is None else np.asarray(self.params.pattern, float)[None]

    @classmethod
    def from_library(cls, library: Any, gait_id: str) -> Gait:
        """Look a gait up in a ``sanlab.library.Library`` by "RUN/RANK" or "RUN#IDX" (raises
        LibraryError if there is none)."""
        e = library.gait(gait_id)
        run = library.get_run(e.run_id)
        s = run.settings
        spec = loads(run.creature_text, source=s.source or run.creature)
        san = San.for_creature(spec)
        seconds = s.seconds if s.seconds is not None else spec.evaluation.seconds
        metric = s.metric if s.metric is not None else spec.evaluation.metric
        return cls(e.gait_id, spec, san.decode(e.encoding), e.gait_params, seconds, metric, s.ensemble,
                   e.score, e.speed_cm_s, run.creature_text, s.source)

    def san_params(self, dtype: str = "float64") -> SanParams:
        """The controller's parameters with a leading batch axis of 1 (ValueError for a pattern)."""
        self.require_san("run as a SAN")
        k1, k2 = self.params.rates(self.san.n_nodes, self.spec.san.delay_on, self.spec.san.delay_off)
        w = np.asarray(self.weights)[None]
        return SanParams(*(np.asarray(x, dtype) for x in (w, k1[None], k2[None])))

    def model(self, dtype: str = "float64"):
        """The compiled creature with this gait's parameter overrides applied."""
        from sanlab import sim

        m = sim.compile_creature(self.spec, dtype)
        over = self.params.model
        if over:
            m = m.with_params(**{k: np.asarray(v, m.dtype) for k, v in over.items()})
        return m

    def replay(self, seconds: float | None = None, fps: float = 30.0, dtype: str = "float64", model=None):
        """Roll the gait out, recording ``fps`` frames per second; returns sim.Result (batch 1)."""
        from sanlab import sim

        model = model if model is not None else self.model(dtype)
        pattern = self.patterns()
        if pattern is not None:
            return sim.rollout(model, sim.PatternController(), pattern, seconds or self.seconds, record_fps=fps)
        return sim.rollout(model, self.san, self.san_params(dtype), seconds or self.seconds, record_fps=fps)
