"""Behaviour descriptors: how a gait moves, beside how far (issue 31; the paper's abstract,
"automatically discover many possible modes of locomotion", and §6.1's five cart gaits told
apart by eye).

Computed inside the kernel's rollout by an observer (:class:`Descriptors`, beside the metric's),
so no second replay is needed; ``sanlab.evaluate`` stores each evaluation's ensemble medians. With
T the evaluation time and the creature's centre of mass (COM):

- ``vx_cm_s``: signed mean speed along x, (x(T) - x(0)) / T (cm/s; from the metric's ``dx_m``).
- ``height_m``, ``height_sd_m``: mean and standard deviation over time of the COM's height above
  the ground under it (m; 0 in the horizontal plane).
- ``turns_per_s``: net rotation of the root link (the first free tree's) per second, in turns
  (counterclockwise positive): a roll or cartwheel turns at least once over the run, a flip about
  once; 0 without a rotating root.
- ``airborne``: fraction of the steps in which no contact point touches the ground (0 in the
  horizontal plane, where every contact touches).
- ``duty``: per touch sensor, the fraction of the steps it is on ([n_touch]).
- ``joint_speed_rad_s``: mean over time and joints of |joint angle rate| (rad/s).
- ``period_s`` and ``signature``: binary sensors make a gait's rhythm exact. The sequence of
  distinct sensor words (all sensors' 0/1 values, in the creature file's order) is recorded as it
  changes (a word counts once it has lasted :data:`DEBOUNCE_S`: a bouncing contact chatters for a
  few steps); after the transient (the run's second half) the smallest cycle that repeats at least
  twice is the gait's ``signature``, rotated to start at its lexicographically smallest word
  (``"10.11.01"``: one word per change, one digit per sensor), and ``period_s`` the time one cycle
  takes. Two controllers with the same cyclic pattern are the same mode by construction. A run
  whose sensors stop changing has the one word it kept as signature (period NaN); one whose words
  do not repeat within :data:`EVENTS` changes has none (None, period NaN).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

EVENTS = 64  # sensor-word changes kept (the last ones of the run)
DEBOUNCE_S = 0.02  # s: a sensor word shorter than this is contact chatter, not a change
MAX_SENSORS = 30  # a word is packed into an int32
NAMES = ("vx_cm_s", "height_m", "height_sd_m", "turns_per_s", "airborne", "joint_speed_rad_s", "period_s")
UNITS = {"vx_cm_s": "cm/s", "height_m": "m", "height_sd_m": "m", "turns_per_s": "turns/s", "airborne": "fraction",
         "joint_speed_rad_s": "rad/s", "period_s": "s", "duty": "fraction per touch sensor"}


class DescriptorAcc(NamedTuple):
    """What :class:`Descriptors` accumulates along one rollout (a batch axis first once batched)."""

    steps: Any  # steps seen
    height: Any  # sum of COM heights above the ground (m)
    height2: Any  # sum of their squares (m^2)
    turn: Any  # net root rotation so far (rad)
    angle: Any  # the root's absolute angle at the last step seen (rad)
    airborne: Any  # steps with no contact touching
    duty: Any  # [n_touch] steps each touch sensor was on
    joint_speed: Any  # sum over steps of the mean |joint rate| (rad/s)
    word: Any  # int32: the sensor word in force (-1 before the first has lasted DEBOUNCE_S)
    candidate: Any  # int32: the word the sensors show now
    since: Any  # s: when they began to show it
    words: Any  # [EVENTS] int32: ring of the last words in force
    times: Any  # [EVENTS] s: when each of them began
    changes: Any  # int32: words that came into force (the first counts as one)


@dataclass(frozen=True)
class Descriptors:
    """Observer of the descriptors (see the module docstring); hashable, built by
    :meth:`for_creature`."""

    root: int = -1  # link whose absolute angle is the body's (-1: none rotates)
    joints: tuple[int, ...] = ()  # dofs of the joint angles
    touch: tuple[int, ...] = ()  # sensor indices of the touch sensors
    n_sensors: int = 0

    @classmethod
    def for_creature(cls, model) -> "Descriptors":
        """The observer for a compiled creature (``sanlab.sim.Model``)."""
        st = model.structure
        root = next((t.root for t in st.trees if t.free and st.links[t.root].dof_rot >= 0), -1)
        joints = tuple(ls.dof_rot for ls in st.links if ls.parent >= 0 and ls.dof_rot >= 0)
        touch = tuple(i for i, s in enumerate(st.sensors) if s[0] == "touch")
        return cls(root, joints, touch, st.n_sensors)

    def observe(self):
        """What the kernel accumulates for the descriptors (``sanlab.sim.rollout``'s observers)."""
        from sanlab.sim import Observe

        return Observe(root=self.root, sensors=self.n_sensors if 0 < self.n_sensors <= MAX_SENSORS else 0,
                       joints=self.joints, touch=self.touch)

    def collect(self, c: dict) -> DescriptorAcc:
        """The accumulator from the kernel's columns (``sanlab.sim.rollout.columns``)."""
        i = lambda x: np.asarray(x).astype(np.int32)
        return DescriptorAcc(c["steps"], c["height"], c["height2"], c["turn"], c["angle"], c["airborne"], c["duty"],
                             c["joint_speed"], i(c["word"]), i(c["candidate"]), c["since"], i(c["words"]), c["times"],
                             i(c["changes"]))


def values(obs: Descriptors, acc: DescriptorAcc, dx_m, seconds: float) -> tuple[dict[str, np.ndarray], list]:
    """Per-row descriptors from a batched accumulator: ({name: [B] array, "duty": [B, n_touch]},
    [B] signatures (str or None)). ``dx_m`` [B]: the metric's signed displacement (m);
    ``seconds``: the evaluation time T (s)."""
    n = np.maximum(np.asarray(acc.steps, float), 1.0)
    h = np.asarray(acc.height, float) / n
    sd = np.sqrt(np.maximum(np.asarray(acc.height2, float) / n - h * h, 0.0))
    out = {
        "vx_cm_s": np.asarray(dx_m, float) / seconds * 100.0,
        "height_m": h,
        "height_sd_m": sd,
        "turns_per_s": np.asarray(acc.turn, float) / (2 * math.pi) / seconds,
        "airborne": np.asarray(acc.airborne, float) / n,
        "joint_speed_rad_s": np.asarray(acc.joint_speed, float) / n,
        "duty": np.asarray(acc.duty, float).reshape(len(n), -1) / n[:, None],
    }
    words, times, changes = np.asarray(acc.words), np.asarray(acc.times, float), np.asarray(acc.changes)
    sigs, periods = [], np.full(len(n), np.nan)
    for b in range(len(n)):
        sig, period = cycle(words[b], times[b], int(changes[b]), seconds / 2, obs.n_sensors)
        sigs.append(sig)
        periods[b] = period
    out["period_s"] = periods
    return out, sigs


def cycle(words: np.ndarray, times: np.ndarray, changes: int, after: float, n_sensors: int) -> tuple[str | None, float]:
    """(signature, period in s) of one run's ring of sensor words (see the module docstring):
    ``words``/``times`` [EVENTS] the ring, ``changes`` how many were written, ``after`` the time
    the transient is taken to end (s)."""
    if n_sensors == 0 or n_sensors > MAX_SENSORS or changes == 0:
        return None, math.nan
    k = min(changes, EVENTS)
    order = [(changes - k + j) % EVENTS for j in range(k)]  # oldest first
    w = [int(words[i]) for i in order]
    t = [float(times[i]) for i in order]
    late = [j for j in range(k) if t[j] >= after]
    if not late:  # nothing changed after the transient: the word it kept
        return _word(w[-1], n_sensors), math.nan
    first = late[0]
    if first == 0 and changes > EVENTS:
        first = 1  # the oldest kept word may have begun before the ring: its start time is not the change's
    seq, ts = w[first:], t[first:]
    for p in range(2, len(seq) // 2 + 1):
        if all(seq[j] == seq[j + p] for j in range(len(seq) - p)):
            reps = (len(seq) - 1) // p
            period = (ts[-1] - ts[-1 - reps * p]) / reps
            cyc = seq[-p:]
            rot = min(range(p), key=lambda r: [_word(x, n_sensors) for x in cyc[r:] + cyc[:r]])
            return ".".join(_word(x, n_sensors) for x in cyc[rot:] + cyc[:rot]), period
    return None, math.nan


def _word(w: int, n: int) -> str:
    return "".join("1" if (w >> i) & 1 else "0" for i in range(n))
