"""The one evaluator of both phases: batches of controllers -> :class:`~sanlab.evaluate.records.ScoreBatch`.

An :class:`Evaluator` scores controllers on one creature with one metric for a fixed time. Each
controller is its SAN weights (or an open-loop pattern, ``patterns``), optionally with a
parameter vector of Figure 8 (phase 2: node delays, actuator and sensor ranges and gains, link lengths; mapped onto the model by a
``sanlab.search.space.Space``), and with the key of its ensemble draws
(``sanlab.evaluate.ensemble``). Each controller runs once per member of the ensemble and once per
terrain of the evaluator's terrain set, all in one batched rollout (every such copy is one row);
its score is the median over members of the member's mean over terrains.

It compiles its creature once (lazily, on the first call) and always rolls out batches padded to
the same number of rows, so a whole run, resumed or not, runs one compiled program. It pickles
without its compiled state, so a remote worker (``sanlab.evaluate.backends``) rebuilds the same
evaluator and compiles it once there.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from sanlab import descriptors
from sanlab.creature.spec import Creature, Terrain
from sanlab.evaluate.ensemble import Ensemble, Key
from sanlab.evaluate.records import ScoreBatch
from sanlab.evaluate.resolution import Servos
from sanlab.metrics import Metric, scores
from sanlab.san import San, SanParams
from sanlab.sim import Observe
from sanlab.sim.model import Model

# Named terrain sets (§6.2), scored as the mean over their grounds: rough = three rough grounds
# (RMS height 1.5 cm, shortest wavelength 0.25 m, seeds 1-3); hill = four smooth hills 8 cm high
# and 1 m wide, centred 0.7 m and 1.2 m ahead and behind (creatures may go either way).
TERRAINS: dict[str, tuple[Terrain, ...]] = {
    "flat": (),
    "rough": tuple(Terrain(kind="rough", height=0.015, wavelength=0.25, seed=s) for s in (1, 2, 3)),
    "hill": tuple(Terrain(kind="hill", height=0.08, width=1.0, center=c) for c in (0.7, -0.7, 1.2, -1.2)),
}


class ParamSpace(Protocol):
    """What the evaluator needs of a parameter space (``sanlab.search.space.Space`` is one)."""

    def batch(self, thetas: np.ndarray, model: Model, /) -> tuple[Any, Any, Model]:
        """Vectors [B, P] -> (k1 [B, N], k2 [B, N], the model with a leading batch axis on every
        parameter)."""
        ...


@dataclass(frozen=True)
class Request:
    """One batch to evaluate: B controllers.

    weights: [B, N, I] integers in [-2, 2]. thetas: [B, P] parameter vectors (the evaluator's
    space), or None for the creature file's own parameters. keys: one ensemble key per
    controller (may be empty with a one-member ensemble). patterns: [B, 4 A + 1] open-loop
    square waves (``sanlab.sim.PatternController``) run instead of the SANs (whose weights are
    then unused), or None.
    """

    weights: np.ndarray
    thetas: np.ndarray | None = None
    keys: tuple[Key, ...] = ()
    patterns: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.weights)


def describe_devices() -> str:
    """What a local evaluation runs on, e.g. "2 x cpu (kernel, 8 lanes)": stored with every run."""
    from sanlab.sim import devices, lanes

    return f"{len(devices())} x cpu (kernel, {lanes()} lanes)"


class Evaluator:
    """Score controllers on ``spec`` (see the module docstring).

    metric: a name of ``sanlab.creature.spec.METRICS`` (default: the creature file's). seconds:
    evaluation time (default: the file's). dtype: "float32" or "float64". batch: controllers per
    rollout (a larger request is split; every rollout is padded to it). terrain: a name of
    :data:`TERRAINS` or a sequence of grounds of one kind (vertical plane only; default: the
    creature's own ground). ensemble: :class:`~sanlab.evaluate.ensemble.Ensemble`. space: maps
    parameter vectors onto the model (needed to evaluate vectors). Raises ValueError on a bad
    metric, terrain or ensemble.
    """

    def __init__(self, spec: Creature, *, metric: str | None = None, seconds: float | None = None,
                 dtype: str = "float64", batch: int = 256, terrain: str | Sequence[Terrain] = "flat",
                 ensemble: Ensemble | None = None, space: ParamSpace | None = None):
        if isinstance(terrain, str):
            if terrain not in TERRAINS:
                raise ValueError(f"terrain: expected one of {list(TERRAINS)}, got {terrain!r}")
            grounds = TERRAINS[terrain]
        else:
            grounds = tuple(terrain)
        if grounds and spec.world.plane != "vertical":
            raise ValueError("terrain: only creatures in the vertical plane walk on terrain")
        if len({g.kind for g in grounds}) > 1:
            raise ValueError("terrain: the grounds of one set must be of one kind")
        if batch < 1:
            raise ValueError(f"batch: expected >= 1, got {batch}")
        if grounds:
            spec = dataclasses.replace(spec, world=dataclasses.replace(spec.world, terrain=grounds[0]))
        self.spec = spec
        self.terrain = terrain if isinstance(terrain, str) else "custom"
        self.grounds = grounds
        self.san = San.for_creature(spec)
        self.metric = Metric.for_creature(spec, metric)
        self.seconds = float(seconds if seconds is not None else spec.evaluation.seconds)
        self.dtype = dtype
        self.batch = int(batch)
        self.ensemble = ensemble if ensemble is not None else Ensemble()
        self.space = space
        self.servos = Servos.of(spec)
        self._compiled: tuple[Model, list[Any]] | None = None
        self._observer: Observers | None = None

    # A worker process receives the evaluator pickled and compiles it there.
    def __getstate__(self) -> dict:
        return {**self.__dict__, "_compiled": None, "_observer": None}

    @property
    def observer(self) -> Observers:
        """What every rollout observes: the metric's ingredients and the descriptors."""
        if self._observer is None:
            self._observer = Observers(self.metric, descriptors.Descriptors.for_creature(self.model))
        return self._observer

    @property
    def model(self) -> Model:
        """The compiled creature (nominal parameters, the first ground of the set)."""
        return self._compile()[0]

    def _compile(self) -> tuple[Model, list[Any]]:
        if self._compiled is None:
            from sanlab import sim

            model = sim.compile_creature(self.spec, self.dtype)
            variants = [sim.compile_creature(dataclasses.replace(
                self.spec, world=dataclasses.replace(self.spec.world, terrain=g)), self.dtype).params
                for g in self.grounds] if len(self.grounds) > 1 else []
            self._compiled = (model, variants)
        return self._compiled

    def delays(self) -> tuple[float, float]:
        """The creature's nominal node delays (T_on, T_off) in s: a phase-1 controller's."""
        return self.spec.san.delay_on, self.spec.san.delay_off

    def evaluate(self, request: Request) -> ScoreBatch:
        """Score one :class:`Request`."""
        return self(request.weights, request.thetas, request.keys, patterns=request.patterns)

    def __call__(self, weights: np.ndarray, thetas: np.ndarray | None = None,
                 keys: Sequence[Key] | None = None, *, patterns: np.ndarray | None = None) -> ScoreBatch:
        """weights [B, N, I], thetas [B, P] or None, keys: B ensemble keys (optional with one
        member) -> the B evaluations' scores. Each controller's scores depend only on itself and
        its key, never on the rest of the batch. With ``patterns`` [B, 4 A + 1] the controllers
        are those open-loop square waves instead of SANs (the weights are unused; the pattern
        ceiling, ``sanlab.search.pattern``), scored by the same ensemble, metric and terrains."""
        W = np.asarray(weights)
        B = len(W)
        if patterns is not None:
            patterns = np.asarray(patterns, float)
            if patterns.shape != (B, 4 * len(self.spec.actuators) + 1):
                raise ValueError(f"patterns: expected shape {(B, 4 * len(self.spec.actuators) + 1)}, got {patterns.shape}")
        if thetas is not None:
            if self.space is None:
                raise ValueError("parameter vectors need an evaluator with a space")
            thetas = np.asarray(thetas, float)
            if len(thetas) != B:
                raise ValueError(f"{len(thetas)} parameter vectors for {B} controllers")
        if keys is None or len(keys) == 0:
            if self.ensemble.members > 1:
                raise ValueError("an ensemble of several members needs each evaluation's key")
            keys = [()] * B
        if len(keys) != B:
            raise ValueError(f"{len(keys)} ensemble keys for {B} controllers")
        out = []
        for i in range(0, B, self.batch):
            j = min(B, i + self.batch)
            out.append(self._rollout(W[i:j], None if thetas is None else thetas[i:j], list(keys[i:j]),
                                     None if patterns is None else patterns[i:j]))
        return ScoreBatch.concat(out)

    def _rollout(self, W: np.ndarray, thetas: np.ndarray | None, keys: list[Key],
                 patterns: np.ndarray | None = None) -> ScoreBatch:
        from sanlab import sim

        model, variants = self._compile()
        n = P = len(W)  # the kernel runs a batch of any size: no padding
        pad = lambda x: x
        T, K = max(1, len(variants)), self.ensemble.members
        reps = T * K
        R = P * reps  # rows: controller-major, then terrain, then member
        if thetas is None:
            on, off = self.delays()
            k1 = np.full((P, self.san.n_nodes), 1.0 / on)
            k2 = np.full((P, self.san.n_nodes), -1.0 / off)
            m, batched = model, False
        else:
            assert self.space is not None
            k1, k2, m = self.space.batch(pad(thetas), model)
            batched = True
        need = batched or T > 1 or (K > 1 and (self.ensemble.friction > 0 or self.ensemble.dt > 0))
        if batched:
            m = _tree(lambda x: np.repeat(np.asarray(x), reps, axis=0), m)
        elif need:
            m = _tree(lambda x: np.repeat(np.asarray(x)[None], R, axis=0), m)
        if T > 1:
            which = (np.arange(R) // K) % T
            m = m.with_params(terrain=np.stack([np.asarray(v.terrain) for v in variants])[which],
                              rough=np.stack([np.asarray(v.rough) for v in variants])[which])
        state0, step = None, None
        if K > 1:
            st = model.structure
            draws = [self.ensemble.draws(st, k, len(self.spec.links)) for k in keys]
            dq = np.repeat(np.stack([d[0] for d in draws])[:, None], T, axis=1).reshape(R, -1)
            if need and self.ensemble.friction > 0:
                mu = np.repeat(np.stack([d[1] for d in draws])[:, None], T, axis=1).reshape(R, -1)
                m = m.with_params(mu=(np.asarray(m.params.mu, float) * mu[:, :, None]).astype(model.dtype))
            if need and self.ensemble.dt > 0:
                step = np.repeat(np.stack([self.ensemble.step_scales(k) for k in keys])[:, None], T, axis=1).reshape(R)
                m = m.with_params(dt=(np.asarray(m.params.dt, float) * step).astype(model.dtype))
            q0 = np.broadcast_to(np.asarray(m.params.q0, float), (R, st.ndof))
            q = (q0 + dq).astype(model.dtype)  # member 0: exactly the start
            member0 = np.arange(R) % K == 0
            state0 = _start(m, q, member0, need)
        if patterns is None:
            ctl: Any = self.san
            cp: Any = SanParams(np.repeat(W, reps, axis=0).astype(self.dtype),
                                np.repeat(k1, reps, axis=0).astype(self.dtype), np.repeat(k2, reps, axis=0).astype(self.dtype))
        else:
            ctl, cp = sim.PatternController(), np.repeat(patterns, reps, axis=0)
        factors = self.ensemble.dt_factors
        if len(factors) == 1:
            r = sim.rollout(m, ctl, cp, self.seconds, observer=self.observer, state0=state0,
                            params_batched=need)
            s, d, sig = self._scores(r)
        else:
            s, d, sig = self._groups(m, ctl, cp, state0, need, R, K)
        if step is not None:  # a member with a longer step ran longer: compare over the nominal time
            for name in ("score", "speed_cm_s", "distance_m", "dx_m"):
                s[name] = s[name] / step
            d["turns_per_s"] = d["turns_per_s"] / step
        d["vx_cm_s"] = np.asarray(s["dx_m"], float) / self.seconds * 100.0
        # A servo the step cannot resolve makes every number of the run the integrator's: scored
        # and flagged as a run that blew up (sanlab.evaluate.resolution).
        bad = np.broadcast_to(self.servos.unresolved(m.params.act_ks, m.params.act_kd, self.spec.dt), (R,))
        if bad.any():
            s["nonfinite"] = np.asarray(s["nonfinite"]) | bad
            for name in ("score", "speed_cm_s", "distance_m", "dx_m"):
                s[name] = np.where(bad, 0.0, s[name])
        groups = self.ensemble.groups()
        batch = robust({k: np.asarray(v).reshape(P, T, K) for k, v in s.items()}, groups)
        summary, signature = summarise({k: np.asarray(v).reshape(P, T, K, *np.shape(v)[1:]) for k, v in d.items()},
                                       np.asarray(sig, dtype=object).reshape(P, T, K), batch, groups)
        return dataclasses.replace(batch, descriptors=summary, signature=signature).take(slice(0, n))

    def _scores(self, r) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], list]:
        """A rollout's rows: the metric's arrays, the descriptors' and the signatures."""
        s = scores(self.metric, r.acc[0], r.finite, self.seconds, self.spec.world.plane)
        d, sig = descriptors.values(self.observer.descriptors, r.acc[1], s["dx_m"], self.seconds)
        return s, d, sig

    def _groups(self, m: Model, ctl: Any, cp: Any, state0, need: bool, R: int,
                K: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], list]:
        """The rows' metric scores when the ensemble's members run at several steps: one rollout
        per step factor over its members' rows (each simulating ``seconds``, so a member at dt/2
        runs twice the steps); when the factors divide the members evenly the rollouts are of one
        size and share one compiled program."""
        from sanlab import sim

        member = np.arange(R) % K
        dt0 = float(np.asarray(self.model.params.dt))
        out: dict[str, np.ndarray] = {}
        desc: dict[str, np.ndarray] = {}
        sig: list = [None] * R
        for f, members in zip(self.ensemble.dt_factors, self.ensemble.groups(), strict=True):
            rows = np.flatnonzero(np.isin(member, members))
            take = lambda x, rows=rows: x[rows]
            mj = _tree(lambda x, rows=rows: np.asarray(x)[rows], m) if need else m
            mj = mj.with_params(dt=(np.asarray(mj.params.dt, float) * f).astype(self.model.dtype))
            s0 = None if state0 is None else type(state0)(*(take(np.asarray(x)) for x in state0))
            cj = SanParams(*(take(np.asarray(x)) for x in cp)) if isinstance(cp, SanParams) else take(cp)
            r = sim.rollout(mj, ctl, cj, steps=int(round(self.seconds / (dt0 * f))),
                            observer=self.observer, state0=s0, params_batched=need)
            sj, dj, gj = self._scores(r)
            for into, part in ((out, sj), (desc, dj)):
                for name, v in part.items():
                    v = np.asarray(v)
                    if name not in into:
                        into[name] = np.zeros((R, *v.shape[1:]), v.dtype)
                    into[name][rows] = v
            for row, g in zip(rows, gj, strict=True):
                sig[row] = g
        return out, desc, sig


def robust(rows: dict[str, np.ndarray], groups: Sequence[np.ndarray] | None = None) -> ScoreBatch:
    """Evaluations' scores from their rows' (``metrics.scores`` arrays shaped [B, T terrains,
    K members]): a member's score, speed and distance are its means over the terrains (it fell,
    or went non-finite, if it did on any); an evaluation's are the medians over its members, it
    fell if more than half of its members fell, and it is non-finite if any member was: then it
    scores 0 (score, speed and distance), like a single rollout that blew up. A controller that
    blows up on some perturbed copies is an artefact of the simulation however well its other
    copies move, and the median of those would rank it. The members' own values are kept.

    ``groups`` (the members of each step factor, ``Ensemble.groups``): with several, an
    evaluation's score, speed and distances are the medians of the group whose median score is
    the lowest (the step cannot win: ``sanlab.evaluate.ensemble``)."""
    member_score = rows["score"].mean(1)
    member_speed = rows["speed_cm_s"].mean(1)
    member_dist = rows["distance_m"].mean(1)
    member_dx = rows["dx_m"].mean(1) if "dx_m" in rows else None
    fell = np.any(rows["fell"], axis=1)
    nonfinite = np.any(rows["nonfinite"], axis=(1, 2))
    K = member_score.shape[1]
    chosen = _chosen(member_score, groups)
    med = lambda x: np.where(nonfinite, 0.0, _median(x, chosen))
    return ScoreBatch(med(member_score), med(member_speed), med(member_dist),
                      np.sum(fell, axis=1) > K / 2, nonfinite, member_score, member_speed,
                      None if member_dx is None else med(member_dx))


def _chosen(member_score: np.ndarray, groups: Sequence[np.ndarray] | None) -> tuple[list[np.ndarray], np.ndarray]:
    """(the member groups, per evaluation the index of the one its medians are taken over): all
    members as one group, or the group of the lowest median score."""
    B, K = member_score.shape
    if groups is None or len(groups) <= 1:
        return [np.arange(K)], np.zeros(B, int)
    groups = [np.asarray(g) for g in groups]
    return groups, np.argmin(np.stack([np.median(member_score[:, g], 1) for g in groups], 1), 1)


def _median(x: np.ndarray, chosen: tuple[list[np.ndarray], np.ndarray]) -> np.ndarray:
    """x [B, K, ...] -> [B, ...]: each evaluation's median over its chosen group of members."""
    groups, which = chosen
    per = np.stack([np.median(x[:, g], 1) for g in groups], 1)  # [B, G, ...]
    return per[np.arange(len(which)), which]


def summarise(rows: dict[str, np.ndarray], signatures: np.ndarray, batch: ScoreBatch,
              groups: Sequence[np.ndarray] | None) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Evaluations' descriptors from their rows' (each [B, T, K, ...], ``sanlab.descriptors``):
    a member's are its means over the terrains, an evaluation's the medians over the members its
    score was taken from (see :func:`robust`; NaN where it went non-finite), and its signature
    the most common of those members' (terrains' and members' in order on a tie)."""
    chosen = _chosen(np.asarray(batch.member_score), groups)
    bad = np.asarray(batch.nonfinite)
    out = {}
    for name, v in rows.items():
        m = _median(np.asarray(v, float).mean(1), chosen)
        out[name] = np.where(bad.reshape(-1, *([1] * (m.ndim - 1))), np.nan, m)
    sig = np.full(len(bad), None, dtype=object)
    groups, which = chosen
    for b in range(len(bad)):
        if bad[b]:
            continue
        seen = [s for s in signatures[b][:, groups[which[b]]].reshape(-1) if s is not None]
        if seen:
            sig[b] = max(dict.fromkeys(seen), key=seen.count)
    return out, sig


@dataclass(frozen=True)
class Observers:
    """The metric's observer and the descriptors' in one rollout (``sim.rollout`` takes one)."""

    metric: Metric
    descriptors: descriptors.Descriptors

    def observe(self) -> Observe:
        import dataclasses as dc

        d = self.descriptors.observe()
        return dc.replace(self.metric.observe(), root=d.root, sensors=d.sensors, joints=d.joints, touch=d.touch)

    def collect(self, c: dict) -> tuple:
        return self.metric.collect(c), self.descriptors.collect(c)


def _tree(fn, model: Model) -> Model:
    """``model`` with ``fn`` applied to every parameter array."""
    p = model.params
    return model.with_params(**{f.name: fn(getattr(p, f.name)) for f in dataclasses.fields(p)})


def _start(model: Model, q: np.ndarray, member0: np.ndarray, batched: bool):
    """Rows' start states: coordinates q [R, D] re-seated on the ground (vertical plane) except
    where ``member0`` (the unperturbed start, left exactly as compiled), at rest."""
    from sanlab.sim.state import start_states

    return start_states(model, q, ~np.asarray(member0, bool), params_batched=batched)
