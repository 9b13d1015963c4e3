"""The MuJoCo route of the benchmark: how many creature-steps per second MuJoCo + NumPy reach.

The same job as sanlab's batched simulator: evaluate many sensor-actuator networks on the bounder,
dt = 1 ms, with ground contact, the network closed around the physics every step:

* the bounder (``sanlab.creature.load("bounder")``) converted by the one MJCF converter,
  ``sanlab.interop.mjcf``: a plane and a 1 mm sphere at every contact point (feet, knees, hips,
  body corners), friction 0.6, MuJoCo's default soft contacts, semi-implicit ``Euler`` at 1 ms;
* every step, for every creature, in NumPy: 8 binary sensors (2 foot touches: the foot's contact
  point at or below the ground, z < 1 mm; 6 joint-angle range checks, angles wrapped to
  [-pi, pi)), then the SAN of Figure 7 (12 threshold nodes x 20 integer weights in [-2, 2] over
  8 sensors + 12 node outputs; istate += k1 dt if the sum > 0 else k2 dt, clamped to [0, 1],
  output on at 1 and off at 0), then the 4 actuator nodes' sums clipped to [-2, 2] and mapped
  onto each actuator's [min, max] (rad) as a target angle written to ``data.ctrl``, then
  ``mj_step``;
* the PD servos T = ks (target - angle) - kd angle' (ks N m/rad, kd N m s/rad, as the loader
  converts the file's per-degree gains) are MuJoCo's ``position`` actuators (the converter's
  ``servos=True``: kp = ks, kv = kd), integrated by "implicitfast", which takes the servos'
  damping implicitly, as sanlab's step does. Computing the torque in NumPy and writing it to
  ``motor`` actuators, as this route once did, is explicit in the damping, and the bounder's
  0.15 m shins are too light for that at 1 ms: h kd / I_eff is about 3.7 at the knees (stable
  only below 2), so every creature blew up within its first ~20 steps and MuJoCo reset it; the
  figures that route gave ("63.5 x MuJoCo with the SAN in NumPy") timed that, not the bounder;
* each episode lasts the creature's evaluation time (6 s); then that creature restarts from its
  initial pose with fresh random weights, as in a search.

Each worker process (one per CPU core) steps ``creatures`` copies (one ``MjData`` each, the SAN
arithmetic vectorised over them) for a fixed wall time; the result is the sum over workers of
creature-steps per second. Setup (imports, model compilation) is not timed. A run in which MuJoCo
reports any instability (a warning on any creature, warm-up included) raises RuntimeError instead
of returning a rate: it would time a different job.

    python benchmarks/mujoco_route.py [seconds]       # prints the number
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path
from typing import Any

_ROOT = Path(__file__).resolve().parent.parent
TOUCH_HEIGHT = 1.0e-3  # m: a contact point below this height counts as touching


def _sanlab_path() -> None:
    """Make this checkout's sanlab importable when it is not installed."""
    if str(_ROOT) not in sys.path:
        sys.path.insert(0, str(_ROOT))


def _converter():
    """``sanlab.interop.mjcf``, the one copy of the converter."""
    _sanlab_path()
    from sanlab.interop import mjcf

    return mjcf


def bounder_spec():
    """The built-in bounder (sanlab.creature.load)."""
    _sanlab_path()
    from sanlab.creature import load

    return load("bounder")


def job(spec=None) -> dict:
    """Everything a worker needs, as plain picklable values (the worker imports no sanlab)."""
    mm = _converter()
    from sanlab.creature.spec import AngularActuator

    spec = bounder_spec() if spec is None else spec
    if spec.dt != 1e-3:
        raise ValueError(f"the benchmark runs at dt = 1 ms, {spec.name} has {spec.dt}")
    xml = mm.to_mjcf(spec, ground=True, servos=True, integrator="implicitfast")
    import mujoco

    mj: Any = mujoco  # compiled bindings: nothing a type checker can read
    m = mj.MjModel.from_xml_string(xml)
    _check_servos(spec, m)
    idx = [int(i) for i in mm.qpos_index(spec, m)]
    names = {l.name: i for i, l in enumerate(spec.links)}
    rot_dof = {name: idx[k] for name, k in mm.rotation_dofs(spec).items()}
    # per link: (parent index or -1, anchor or fixed position, qpos address of its angle, of its
    # x, of its y (roots; -1 otherwise), fixed root's angle)
    links = []
    for l in spec.links:
        if l.parent is None and l.fixed:
            links.append((-1, tuple(l.position), -1, -1, -1, l.angle))
        elif l.parent is None:
            x, y = (int(m.joint(f"{l.name}:{c}").qposadr[0]) for c in "xy")
            links.append((-1, (0.0, 0.0), rot_dof[l.name], x, y, 0.0))
        else:
            links.append((names[l.parent], tuple(l.anchor), rot_dof[l.name], -1, -1, 0.0))
    touch, angle_dofs, angle_min, angle_max = [], [], [], []
    for s in spec.sensors:
        if s.kind == "touch":
            touch.append((names[s.link], tuple(spec.link(s.link).contacts[s.contact])))
        elif s.kind == "angle":
            angle_dofs.append(rot_dof[s.link])  # relative joint angle, or a root's absolute angle
            angle_min.append(s.min)
            angle_max.append(s.max)
        else:
            raise NotImplementedError(f"sensor kind {s.kind!r}")
    qpos0 = [0.0] * m.nq
    for d, v in zip(idx, mm.initial_q(spec)):
        qpos0[d] = float(v)
    hidden = spec.n_hidden
    return dict(
        xml=xml,
        qpos0=qpos0,
        links=links,
        touch=touch,
        angle_dofs=angle_dofs,
        angle_min=angle_min,
        angle_max=angle_max,
        n_act=sum(isinstance(a, AngularActuator) for a in spec.actuators),  # all (to_mjcf refuses others)
        act_min=[a.min for a in spec.actuators],
        act_max=[a.max for a in spec.actuators],
        hidden=hidden,
        k1=1.0 / spec.san.delay_on,
        k2=-1.0 / spec.san.delay_off,
        episode_steps=int(round(spec.evaluation.seconds / spec.dt)),
        dt=spec.dt,
    )


def _check_servos(spec, m) -> None:
    """MuJoCo's actuators are sanlab's PD servos: actuator a is a position servo on its joint with
    force ks (ctrl - q) - kd q' (SI units: the spec's, after the loader's degree conversion)."""
    import numpy as np

    for k, a in enumerate(spec.actuators):
        act = m.actuator(k)
        ok = (
            act.name == a.name
            and m.joint(int(act.trnid[0])).name == f"{a.joint}:joint"
            and np.allclose([act.gear[0], act.gainprm[0], *act.biasprm[:3]], [1.0, a.ks, 0.0, -a.ks, -a.kd])
            and np.allclose(act.ctrlrange, [a.min, a.max])
        )
        if not ok:
            raise RuntimeError(f"actuator {a.name}: MuJoCo's servo is not ks = {a.ks}, kd = {a.kd} on {a.joint}")


class _Batch:
    """``n`` creatures, each with its own MjData and SAN, stepped in lock step."""

    def __init__(self, job: dict, n: int, seed: int):
        import mujoco
        import numpy as np

        mj: Any = mujoco  # compiled bindings: nothing a type checker can read
        self.mj, self.np = mj, np
        self.model = m = mj.MjModel.from_xml_string(job["xml"])
        self.data = [mj.MjData(m) for _ in range(n)]
        self.n = n
        self.rng = np.random.default_rng(seed)
        self.qpos0 = np.asarray(job["qpos0"])
        self.links, self.touch = job["links"], job["touch"]
        self.adofs = np.asarray(job["angle_dofs"], int)
        self.amin, self.amax = np.asarray(job["angle_min"]), np.asarray(job["angle_max"])
        self.tmin = np.asarray(job["act_min"])
        self.tspan = np.asarray(job["act_max"]) - self.tmin
        self.H, self.A = job["hidden"], job["n_act"]
        self.S = len(self.touch) + len(self.adofs)
        self.N = self.H + self.A
        self.k1, self.k2, self.dt = job["k1"], job["k2"], job["dt"]
        self.episode = job["episode_steps"]
        self.W = np.zeros((n, self.N, self.S + self.N))
        self.istate = np.zeros((n, self.N))
        self.out = np.zeros((n, self.N))
        self.x = np.zeros((n, self.S + self.N))
        # qpos rows (the sensors read only angles and heights) and control rows, bound once: one
        # C call each per creature
        self.sig_state = mj.mjtState.mjSTATE_QPOS
        self.sig_ctrl = mj.mjtState.mjSTATE_CTRL
        self.state = np.zeros((n, m.nq))
        self.ctrl = np.zeros((n, m.nu))
        self.state_rows = [self.state[i] for i in range(n)]
        self.ctrl_rows = [self.ctrl[i] for i in range(n)]
        self.t = 0
        self.unstable = 0  # creature-episodes in which MuJoCo warned of an instability
        for i in range(n):
            self._restart(i)

    def warnings(self) -> int:
        """Creature-episodes so far in which MuJoCo warned (mj_resetData clears the counters, and
        MuJoCo's own reset after an instability sets its count back to 1, so any count > 0 on
        a creature means at least one warning in its episode)."""
        return self.unstable + sum(int(d.warning.number.sum() > 0) for d in self.data)

    def _restart(self, i: int) -> None:
        d = self.data[i]
        self.unstable += int(d.warning.number.sum() > 0)
        self.mj.mj_resetData(self.model, d)
        d.qpos[:] = self.qpos0
        self.mj.mj_forward(self.model, d)
        self.W[i] = self.rng.integers(-2, 3, size=self.W.shape[1:])
        self.istate[i] = 0.0
        self.out[i] = 0.0

    def _touch(self, qpos):
        """Heights of the touch sensors' contact points [n, T]: planar forward kinematics."""
        np = self.np
        th, X, Y = [], [], []
        for parent, (ax, ay), rot, dx, dy, th0 in self.links:
            if parent < 0:
                a = qpos[:, rot] if rot >= 0 else th0
                x = qpos[:, dx] if dx >= 0 else ax
                y = qpos[:, dy] if dy >= 0 else ay
            else:
                c, s = np.cos(th[parent]), np.sin(th[parent])
                x = X[parent] + c * ax - s * ay
                y = Y[parent] + s * ax + c * ay
                a = th[parent] + qpos[:, rot]
            th.append(a)
            X.append(x)
            Y.append(y)
        heights = [Y[i] + np.sin(th[i]) * px + np.cos(th[i]) * py for i, (px, py) in self.touch]
        return np.stack(heights, 1)

    def step(self) -> None:
        np, mj, m = self.np, self.mj, self.model
        get, sig = mj.mj_getState, self.sig_state
        for d, row in zip(self.data, self.state_rows):
            get(m, d, row, sig)
        qpos = self.state
        # sensors
        ang = qpos[:, self.adofs]
        ang = ang - 2 * math.pi * np.floor((ang + math.pi) / (2 * math.pi))
        ns = len(self.touch)
        self.x[:, :ns] = self._touch(qpos) < TOUCH_HEIGHT
        self.x[:, ns : self.S] = (ang >= self.amin) & (ang <= self.amax)
        self.x[:, self.S :] = self.out
        # the SAN (Figure 7)
        total = np.einsum("bni,bi->bn", self.W, self.x)
        rate = np.where(total > 0, self.k1, self.k2)
        self.istate = np.clip(self.istate + rate * self.dt, 0.0, 1.0)
        self.out = np.where((self.out == 1) & (self.istate == 0.0), 0.0, self.out)
        self.out = np.where((self.out == 0) & (self.istate == 1.0), 1.0, self.out)
        u = (np.clip(total[:, self.H :], -2.0, 2.0) + 2.0) * 0.25
        # the servos' targets (rad): MuJoCo's position actuators apply the PD law
        self.ctrl[:] = self.tmin + u * self.tspan
        put, sig, step = mj.mj_setState, self.sig_ctrl, mj.mj_step
        for d, row in zip(self.data, self.ctrl_rows):
            put(m, d, row, sig)
            step(m, d)
        self.t += 1
        if self.t % self.episode == 0:
            for i in range(self.n):
                self._restart(i)


def _worker(job: dict, creatures: int, seconds: float, seed: int, barrier, queue) -> None:
    batch = _Batch(job, creatures, seed)
    for _ in range(20):  # warm up caches
        batch.step()
    if barrier is not None:
        barrier.wait()
    steps = 0
    t0 = time.perf_counter()
    end = t0 + seconds
    while True:
        for _ in range(50):
            batch.step()
        steps += 50 * creatures
        now = time.perf_counter()
        if now >= end:
            break
    warnings = batch.warnings()
    if not batch.np.all(batch.np.isfinite(batch.state)):
        warnings = max(warnings, 1)
    queue.put((steps, now - t0, warnings))


def _cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def mujoco_steps_per_s(
    seconds_budget: float = 5.0, *, workers: int | None = None, creatures: int = 128, seed: int = 0,
    details: bool = False,
) -> Any:
    """Creature-steps per second of the MuJoCo route on the bounder (see the module docstring).

    seconds_budget: wall time each worker steps for (setup excluded). workers: processes (default:
    one per CPU core). creatures: MjData copies per worker, stepped in lock step with the SAN
    vectorised over them (128: NumPy's per-call cost spread wider than at 32, which ran 10-40 %
    slower on 2 shared cores; 512 is no faster). details: return (rate, dict) instead, the dict with per-worker numbers
    and MuJoCo's warning count (always 0: a run with any instability raises RuntimeError, as it
    would time a different job).
    """
    import multiprocessing as mp

    workers = workers or _cores()
    jb = job()
    ctx = mp.get_context("spawn")  # no fork of a process that may have started JAX threads
    barrier = ctx.Barrier(workers)
    queue = ctx.Queue()
    procs = [
        ctx.Process(target=_worker, args=(jb, creatures, seconds_budget, seed + w, barrier, queue))
        for w in range(workers)
    ]
    for p in procs:
        p.start()
    results = [queue.get(timeout=seconds_budget + 300) for _ in procs]
    for p in procs:
        p.join()
    rate = sum(steps / wall for steps, wall, _ in results)
    unstable = sum(w for _, _, w in results)
    if unstable:
        raise RuntimeError(f"INVALID: MuJoCo reported instabilities in {unstable} creature-episodes of the "
                           f"bounder (the route would time a different job)")
    if details:
        return rate, dict(
            workers=workers, creatures=creatures,
            per_worker=[steps / wall for steps, wall, _ in results],
            warnings=sum(w for _, _, w in results),
        )  # fmt: skip
    return rate


def mujoco_c_loop_steps_per_s(spec=None, *, batch: int = 256, steps: int = 1000, repeats: int = 3,
                              threads: int | None = None, seed: int = 0) -> float:
    """Creature-steps per second of MuJoCo's own C rollout loop (``mujoco.rollout``, one thread
    per core) on the same converted model: the strongest route a MuJoCo user would write.

    ``mujoco.rollout`` runs open-loop controls, so there is no network in the loop: each creature
    gets a fixed random sequence of servo targets in its actuators' ranges (each held for 70 ms,
    the SAN's fastest node delay), and MuJoCo's own ``position`` actuators (kp = ks, kv = kd, the
    same PD servos) turn them into torques inside the C loop, integrated by "implicitfast" (its
    velocity-implicit Euler: the servos' damping is stiff for light links at 1 ms). The best of ``repeats`` timed calls
    after a warm-up call; raises RuntimeError if MuJoCo reports an unstable run (that would
    time a different job).
    """
    import mujoco
    import numpy as np
    from mujoco import rollout as mjr

    mm = _converter()
    spec = bounder_spec() if spec is None else spec
    mj: Any = mujoco
    xml = mm.to_mjcf(spec, ground=True, motors=True, integrator="implicitfast")
    from sanlab.creature.spec import AngularActuator

    for a in spec.actuators:  # the converter's motors, as MuJoCo's PD servos
        assert isinstance(a, AngularActuator)  # to_mjcf refuses linear ones
        motor = f'<motor name="{a.name}" joint="{a.joint}:joint" gear="1"/>'
        if motor not in xml:
            raise RuntimeError(f"unexpected MJCF for actuator {a.name}")
        xml = xml.replace(motor, f'<position name="{a.name}" joint="{a.joint}:joint" kp="{a.ks!r}" kv="{a.kd!r}"/>')
    m = mj.MjModel.from_xml_string(xml)
    threads = threads or _cores()
    datas = [mj.MjData(m) for _ in range(threads)]
    d = datas[0]
    qpos0 = np.zeros(m.nq)
    qpos0[np.asarray(mm.qpos_index(spec, m), int)] = mm.initial_q(spec)
    d.qpos[:] = qpos0
    mj.mj_forward(m, d)
    sig = mj.mjtState.mjSTATE_FULLPHYSICS
    x0 = np.zeros(mj.mj_stateSize(m, sig))
    mj.mj_getState(m, d, x0, sig)
    rng = np.random.default_rng(seed)
    hold = max(1, int(round(0.07 / m.opt.timestep)))
    span = np.array([[a.min, a.max] for a in spec.actuators])
    n_hold = -(-steps // hold)
    pick = rng.uniform(span[:, 0], span[:, 1], size=(batch, n_hold, len(span)))
    ctrl = np.repeat(pick, hold, axis=1)[:, :steps]
    state0 = np.repeat(x0[None], batch, axis=0)
    states = np.asarray(mjr.rollout([m] * batch, datas, state0, ctrl, nstep=steps)[0])  # warm-up
    if not np.all(np.isfinite(states)) or any(int(dd.warning.number.sum()) for dd in datas):
        raise RuntimeError(f"MuJoCo's rollout of {spec.name} went unstable")
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        mjr.rollout([m] * batch, datas, state0, ctrl, nstep=steps)
        best = min(best, time.perf_counter() - t0)
    return batch * steps / best


if __name__ == "__main__":
    budget = float(sys.argv[1]) if len(sys.argv) > 1 else 5.0
    print(f"{mujoco_steps_per_s(budget):.0f}")
