"""Phase 1 by the rhythm: SANs whose hidden nodes make a clock, searched by CMA-ES over its rhythm.

The paper's SAN can hold a rhythm of its own: a node fed +1 by an input that is always on and -2
by itself switches on after T_on and off after T_off, for ever (Figure 7's hysteresis), and its
delays are among the parameters phase 2 tunes (§5.3). Random weights rarely make such a clock, so
random search finds the rhythms the sensors happen to make; on the bounder and the walker the
fastest open-loop square waves (``sanlab.search.pattern``, the pattern ceiling) run 2x the SANs
that search finds (issue 56). This strategy searches SANs *as* rhythms: CMA-ES over the same
2 A + 1 numbers as the pattern search (per actuator a phase and a duty, one period), each point
built into a SAN by :func:`clock` and evaluated, and stored, as that SAN: its weights, node
delays and actuator and sensor ranges (a gait like a tuned one, ``GaitParams.k1``/``model``),
tuned, audited, exported and shown as any.

The clock (:func:`clock`), in steps of the creature's dt (P steps a period):

- a *bias*: the first angle, tilt, eye or length sensor, its range opened to the whole circle (a
  length sensor's to [0, 1000 m]), is always on (on a horizontal plane, where a touch sensor is
  always on, that one serves when there is no other); a creature with touch sensors only gives
  its last hidden node to a *latch* (+1 from every touch sensor, +2 from itself), which a foot on
  the ground at rest switches on 10 ms after the start, for ever;
- a *root* node: +1 from the bias, -2 from itself, a free-running oscillator of period P that
  switches off as the pattern's time 0 passes (its on-steps chosen, among half and eighths of
  the period, to let the followers keep their phases best); where no hidden node is spare,
  actuator 0's node is the root and the SAN starts where that one switches off;
- every actuator's node a *follower*: triggered by the rising edge of a node (+1 from it) or its
  falling edge (-1 from it, +1 from the bias), -2 from itself; it switches on T_on after the
  edge and off T_off later, so it keeps its phase to the root cycle after cycle (no drift).
  Each follower takes the trigger that keeps its phase and duty exactly when one does: its pulse
  must end before the next edge, not fire twice within one window, and come in the first cycle
  too (every node starts off, §4, and a node not yet on reads as one that has just switched
  off); the steps it misses by otherwise are the clock's *slip*;
- an actuator that the pattern starts at its upper level follows a node carrying its lower
  phases, inverted (-2 from it): every node starts off, and so does that node's wave, so the
  SAN plays the pattern from its first step;
- each actuator node sums ±2 from its clock node and a constant from the bias, so its
  activation switches between two of 0, 1/4, ..., 1, half the range apart, and the actuator's
  range is set so that those are the ends of its range; where that range would not fit the
  actuator's bounds (±180°) and a hidden node is spare, a *twin* of the clock node (same inputs
  and delays, so the same output) adds 2 more, and the activation switches between 0 and 1.

With fewer hidden nodes than actuators, the first H actuators get a node each and every other
one follows the node, or the node inverted, whose wave is nearest its own (the steps they differ
by count as slip; two nodes and their inverses make a wave travelling along four segments, as a
caterpillar's). It needs a hidden node (two with a latch) and a sensor to start it (ValueError
otherwise). Where a
gait starts matters (the walker's best pattern, started at 6 of 8 other points of its cycle,
falls), and the search scores the SAN, not the square wave. The SAN senses nothing but its
bias: a loop through its sensors is what catcma and random search find (the cart, the
fourlink); ``benchmarks/search_strength.py`` and docs/search-strength.md compare them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sanlab.evaluate.ensemble import search_key
from sanlab.evaluate.records import ScoreBatch
from sanlab.library.records import EvaluationRow
from sanlab.search.base import Candidate, Problem
from sanlab.search.pattern import PatternSearch, decode
from sanlab.search.space import Space

LENGTH_OPEN = 1000.0  # m: a length sensor's upper end when it serves as the bias
WARMUP = 1 / 6  # of the budget on random SANs first, as ``sanlab.search.catcma`` spends it
REFLEX = 1 / 4  # of the budget after the warm-up on the best SAN's reflexes, last
REFLEX_SPREAD = 0.6  # a reflex weight's standard deviation about the best SAN's (the alphabet's step is 1)


@dataclass(frozen=True)
class Clock:
    """A SAN built from a pattern: weights [N, I] (int8), its parameter vector [P] of ``space``
    (node delays, actuator and sensor ranges), and its slip (steps by which the followers miss
    the pattern's phases and duties, summed; 0: exact)."""

    weights: np.ndarray
    theta: np.ndarray
    slip: float


def bias_sensor(space: Space) -> int | None:
    """The sensor :func:`clock` holds always on, or None when the creature has none that can be."""
    spec = space.spec
    for s, x in enumerate(spec.sensors):
        if x.kind in ("angle", "tilt", "eye", "length"):
            return s
    if spec.world.plane == "horizontal":
        return next((s for s, x in enumerate(spec.sensors) if x.kind == "touch"), None)
    return None


def clock(space: Space, pattern: np.ndarray) -> Clock:
    """The SAN that plays ``pattern`` ([4 A + 1]: per actuator phase, duty, low, high, then the
    period, s; ``sim.PatternController``) on ``space``'s creature (module docstring). ValueError
    when the creature has no sensor to start it or no hidden node for it (besides a latch's)."""
    spec, san = space.spec, space.san
    S, H, A = san.n_sensors, san.n_hidden, san.n_actuators
    NA = H  # the first actuator node's row (H: the clock's nodes, one fewer with a latch)
    bias = bias_sensor(space)
    touch = [i for i, x in enumerate(spec.sensors) if x.kind == "touch"]
    latch = bias is None and bool(touch)  # no range sensor: a node that a touch at rest latches on
    if H < 1 + latch or (bias is None and not touch):
        raise ValueError(f"{spec.name}: a clock needs a sensor to start it (an angle, tilt, eye, length or touch sensor)"
                         if bias is None and not touch else
                         f"{spec.name}: a clock needs a hidden node" + (" besides the one a touch sensor latches on"
                                                                         if latch else ""))
    pattern = np.asarray(pattern, float)
    index = {name: i for i, name in enumerate(space.names)}
    theta = space.nominal()

    def put(name: str, value: float) -> None:
        i = index[name]
        p = space.params[i]
        theta[i] = min(max(value, p.lo), p.hi)

    W = np.zeros((san.n_nodes, san.n_inputs), np.int8)
    if bias is not None:
        on_input = bias  # the input that is always on
        sensor = spec.sensors[bias]
        if sensor.kind in ("angle", "tilt", "eye"):
            put(f"{sensor.name}.min", -math.pi)
            put(f"{sensor.name}.max", math.pi)
        elif sensor.kind == "length":
            put(f"{sensor.name}.max", LENGTH_OPEN)
            put(f"{sensor.name}.min", 0.0)
    else:  # the last hidden node: +1 from every touch sensor, +2 from itself, on for ever once on
        H -= 1
        W[H, touch] = 1
        W[H, S + H] = 2
        on_input = S + H
    dt = spec.dt
    P = max(4, int(round(pattern[4 * A] / dt)))
    lo_steps = math.ceil(0.01 / dt + 0.25)  # the shortest and longest delays the space allows (0.01-1 s)
    hi_steps = max(lo_steps, math.floor(1.0 / dt + 0.25))
    rise = np.mod(np.round(np.mod(pattern[0:4 * A:4], 1.0) * P), P).astype(int)
    on = np.clip(np.round(pattern[1:4 * A:4] * P), 1, P - 1).astype(int)
    # an actuator the pattern starts at its upper level is driven by a node carrying its lower
    # phases, inverted: every node starts off (§4), and so does that one's wave
    starts_high = ((-rise) % P) < on
    wanted = [_wave(r, o, P) for r, o in zip(rise, on)]
    rise, on = np.where(starts_high, (rise + on) % P, rise), np.where(starts_high, P - on, on)
    own = min(A, H)  # actuators with a node of their own: the first H; the others share one

    def fit(n) -> int:
        return min(max(int(n), lo_steps), hi_steps)

    # the root, free-running on the bias: a node of its own, switching off as the pattern's time 0
    # passes (so the SAN, all nodes off at first, starts where the pattern starts), on for the
    # part of the period that lets the followers keep their phases best; with no node to spare,
    # actuator 0's node (the SAN then starts where that one switches off)
    if H > A:
        trees = [_tree(np.append(rise, P - o), np.append(on, o), P, A, fit) for o in _root_lengths(P)]
        tree = min(trees, key=lambda t: t[3])
    else:
        tree = _tree(rise[:own], on[:own], P, 0, fit)
    node, trigger, delays, slip = tree
    # an actuator without a node of its own follows the node, or the node inverted, whose wave
    # is nearest its own (the steps they differ by count as slip): two nodes and their inverses
    # make a wave travelling along four segments
    drive = {a: (node[a], -1 if starts_high[a] else 1) for a in range(own)}
    waves = {node[w]: _wave(rise[w], on[w], P) for w in node} if own < A else {}  # (no root of its own then)
    for a in range(own, A):
        miss, k, sign = min((int(np.count_nonzero(wanted[a] != (x if sign == 1 else ~x))), k, sign)
                            for k, x in waves.items() for sign in (1, -1))
        drive[a] = (k, sign)
        slip += miss
    for k, (h, edge) in trigger.items():
        if h < 0:
            W[k, on_input] = 1
        else:
            W[k, S + h] = edge
            if edge == -1:
                W[k, on_input] = 1
        W[k, S + k] = -2
    # the actuators: levels from the clock node, the bias offset and, where needed, a twin
    ends = []
    for a, act in enumerate(spec.actuators):
        low, high = pattern[4 * a + 2], pattern[4 * a + 3]
        tl, th = act.min + low * (act.max - act.min), act.min + high * (act.max - act.min)
        p = space.params[index[f"{act.name}.min"]]
        best_c = None
        for c in (-1, -2, 0):
            width = 2 * (th - tl)
            amin = tl - (c + 2) / 4 * width
            over = max(0.0, p.lo - amin) + max(0.0, amin + width - p.hi)
            if best_c is None or over < best_c[0] - 1e-12:
                best_c = (over, c, amin, amin + width)
        assert best_c is not None
        ends.append(best_c)
    spare = list(range(len(node), H))
    for a in sorted(range(A), key=lambda a: -ends[a][0]):
        act = spec.actuators[a]
        h, sign = drive[a]
        W[NA + a, S + h] = 2 * sign
        over, c, amin, amax = ends[a]
        if over > 1e-12 and spare and a < own:
            t = spare.pop(0)
            W[t] = W[h]
            W[t, S + h], W[t, S + t] = 0, -2
            delays[t] = delays[h]
            W[NA + a, S + t] = 2 * sign
            c, amin, amax = -2, act.min + pattern[4 * a + 2] * (act.max - act.min), act.min + pattern[4 * a + 3] * (act.max - act.min)
        swing = 2 * int(np.count_nonzero(W[NA + a, S:S + NA]))  # 2 from the node, 2 more from a twin
        W[NA + a, on_input] = c if sign == 1 else c + swing  # inverted: the same two levels
        put(f"{act.name}.max", amax)
        put(f"{act.name}.min", amin)
    if bias is None:
        delays[H] = (lo_steps, hi_steps)  # the latch: on as soon as a touch has lasted 10 ms
    for h, (n_r, n_f) in delays.items():
        # a quarter step short of whole steps: the node switches on the same step at dt and dt/2
        put(f"H{h + 1}.T_on", (n_r - 0.25) * dt)
        put(f"H{h + 1}.T_off", (n_f - 0.25) * dt)
    return Clock(W, theta, float(slip))


def _wave(rise: int, on: int, P: int) -> np.ndarray:
    """A wave's cycle [P] (bool): on for ``on`` steps from step ``rise``."""
    return ((np.arange(P) - rise) % P) < on


def _root_lengths(P: int) -> list[int]:
    """The root's on-steps tried: half the period first (ties keep it), then eighths."""
    return [P // 2] + [P * k // 8 for k in (1, 2, 3, 5, 6, 7) if 0 < P * k // 8 < P]


def _tree(rise: np.ndarray, on: np.ndarray, P: int, root: int, fit):
    """The clock's wiring for waves ``rise``/``on`` (steps; index ``root`` is the root's): which
    node each wave gets (wave -> node), each node's trigger (node -> (trigger node or -1 for the
    bias, +1 rising or -1 falling edge)), each node's (T_on, T_off) in steps, and the slip."""
    node = {root: 0}
    trigger: dict[int, tuple[int, int]] = {0: (-1, 1)}
    delays = {0: (fit(P - on[root]), fit(on[root]))}
    slip = float(abs(delays[0][0] - (P - on[root])) + abs(delays[0][1] - on[root]))
    todo = [b for b in range(len(rise)) if b != root]
    while todo:
        best = None
        for b in todo:
            for a, h in node.items():
                for edge in (1, -1):  # rising, falling
                    start = rise[a] if edge == 1 else rise[a] + on[a]
                    window = on[a] if edge == 1 else P - on[a]
                    n_r, n_f = (rise[b] - start) % P, on[b]
                    miss = 0.0
                    if n_r > window:  # the trigger is off before the follower has risen
                        miss += n_r - window
                        n_r = window
                    n_r2, n_f2 = fit(n_r), fit(n_f)
                    miss += abs(n_r2 - n_r) + abs(n_f2 - n_f)
                    if n_r2 + n_f2 > P:  # still on at the next edge: it slips a cycle
                        miss += n_r2 + n_f2 - P
                    rest = window - n_r2 - n_f2  # steps it rises again within the window
                    if rest >= n_r2:
                        miss += P  # a second pulse
                    elif rest > 0 and rest * n_f2 / n_r2 > P - window:
                        miss += rest * n_f2 / n_r2 - (P - window)  # not yet back to rest at the next edge
                    # the first cycle: every node starts off and the root has just switched off
                    if start % P > rise[b]:
                        miss += on[b]  # its trigger's edge first comes after it should rise: a pulse lost
                    if edge == -1 and a != root:  # a node not yet on reads as one just switched off
                        if n_r2 <= rise[a]:
                            miss += on[b]  # an extra pulse before the trigger's first
                        elif rise[a] * n_f2 / n_r2 > on[a]:
                            miss += rise[a] * n_f2 / n_r2 - on[a]  # not back to rest when it first falls
                    if best is None or miss < best[0]:
                        best = (miss, b, h, edge, n_r2, n_f2)
        assert best is not None
        miss, b, h, edge, n_r, n_f = best
        slip += miss
        k = len(node)
        node[b] = k
        trigger[k] = (h, edge)
        delays[k] = (n_r, n_f)
        todo.remove(b)
    return node, trigger, delays, slip


CLOCKS = ("rhythm", "reflex")  # the strategies of this module: their runs hold clocks after a random warm-up


def starts(lib, run_id: str, k: int) -> list:
    """Where phase 2 starts on the finished search run ``run_id``: its ``k`` best evaluations
    (``Library.top``), but for a run of the rhythm search (``rhythm``, ``reflex``) and k > 1 its k - 1
    best and the best SAN of its random warm-up (indices below ``int(controllers * WARMUP)``), where
    no warm-up SAN is among the k best and that one neither fell nor blew up.

    Why: a clock is an open loop, and its best few are close kin. Where a body's gait needs its
    sensors, a closed loop that random weights make is what keeps its speed through the audit: on
    the fourlink (Table 1, sanlab's budget) the clocks' tuned gaits lost 5-7 % at dt/4 on fresh
    draws on four seeds of five, and a chain from the warm-up's best kept a robust gait on two of
    those four (docs/search.md, "Phase 2 on a clock search")."""
    from sanlab.library.records import SearchSettings

    best = lib.top(run_id, k)
    s = lib.get_run(run_id).settings
    if k < 2 or not isinstance(s, SearchSettings) or s.strategy not in CLOCKS:
        return best
    n = min(int(s.controllers * WARMUP), s.controllers)
    if any(e.idx < n for e in best):
        return best
    warm = next((e for e in lib.top(run_id, None) if e.idx < n), None)
    if warm is None or warm.fell or warm.nonfinite:
        return best
    return [*best[: k - 1], warm]


class RhythmSearch(PatternSearch):
    """``problem.budget`` SANs: the first :data:`WARMUP` of them the random SANs a random search
    of the same seed draws (stored as its rows are, so the closed loops random search finds are
    found here too), then each the :func:`clock` of a pattern drawn by the pattern search's CMA-ES
    (restarts, population and ranges as ``sanlab.search.pattern``), stored as a SAN with its own
    node delays and ranges. :class:`ReflexSearch` ends with reflexes on the best of them.

    Needs ``problem.space`` (a Space without morphology; the evaluator must hold the same);
    ValueError when the creature cannot hold a clock."""

    needs_space = True  # the runner gives the problem and the evaluator a Space of the creature
    reflex = 0.0  # the share of the budget after the warm-up spent on reflexes, last (ReflexSearch's)

    def __init__(self, problem: Problem):
        super().__init__(problem)
        if problem.space is None or problem.space.morphology:
            raise ValueError("the rhythm search needs the creature's parameter space, without morphology")
        self.space = problem.space
        self._nominal = self.space.nominal()
        self.warmup = int(problem.budget * WARMUP)
        clock(self.space, decode(np.full(self.dim, 0.5), self.actuators))  # a creature that cannot hold one fails here
        after = max(0, problem.budget - self.warmup)
        # the first generation of reflexes (none: past the last generation)
        self.reflex_from = int(after * (1 - self.reflex)) // self.popsize if self.reflex else after // self.popsize + 1
        san = problem.san
        bias = bias_sensor(self.space)
        self._sensors = [s for s in range(san.n_sensors) if s != bias]
        self._base: Candidate | None = None  # the SAN the reflexes in flight are added to

    def restart_of(self, g: int) -> int:
        if g < self.reflex_from:
            return super().restart_of(g)
        return 1_000_000 + (g - self.reflex_from) // (self.generations or 1)  # the reflexes: optimisers of their own

    def optimiser(self, seed: int) -> Any:
        if (self._next - self._n_warm) // self.popsize < self.reflex_from or not self._sensors or self.elite is None:
            return super().optimiser(seed)
        from sanlab.search.catcma import around

        self._base = self.elite[2]
        H = self.problem.san.n_hidden
        return around(self._base.weights[H:, self._sensors], REFLEX_SPREAD, self.popsize, seed)

    def warm(self, idx: int) -> Candidate:
        """Random SAN ``idx`` of the run's seed, with the creature file's parameters."""
        p = self.problem
        return Candidate(idx, p.san.random_weights(p.seed, idx), self._nominal, search_key(p.seed, idx))

    def candidate(self, idx: int, point) -> Candidate:
        key = search_key(self.problem.seed, idx)
        if hasattr(point, "z"):  # a reflex point (CatCMAwM's), on the SAN the optimiser started from
            assert self._base is not None and self._base.theta is not None
            w = self._base.weights.copy()
            H = self.problem.san.n_hidden
            w[H:, self._sensors] = np.rint(np.asarray(point.z)).astype(np.int8).reshape(len(w) - H, len(self._sensors))
            return Candidate(idx, w, self._base.theta, key)
        c = clock(self.space, decode(point, self.actuators))
        return Candidate(idx, c.weights, c.theta, key)

    def row(self, candidate: Candidate, scores: ScoreBatch, k: int) -> EvaluationRow:
        p = self.problem
        assert candidate.theta is not None
        params = p.gait_params if candidate.idx < self._n_warm else self.space.gait_params(candidate.theta, None)
        return EvaluationRow(p.run_id, candidate.idx, p.san.encode(candidate.weights), params, scores.row(k))


class ReflexSearch(RhythmSearch):
    """The rhythm search (:class:`RhythmSearch`), its last :data:`REFLEX` of the budget after the
    warm-up on *reflexes*: CatCMAwM (``cmaes.CatCMAwM``, as ``sanlab.search.catcma``) over the
    weights from the sensors (the bias's aside) to the actuator nodes of the best SAN so far,
    from its own, each spread by :data:`REFLEX_SPREAD`, with its delays and ranges. A clock's
    nodes are not touched, so its rhythm holds while the sensors bend each actuator's targets:
    a closed loop on an open one. The bounder's best clock, 600 evaluations of reflexes searched
    on rough ground: 164 -> 231 cm/s held out there, 234 -> 250 on the flat."""

    reflex = REFLEX
