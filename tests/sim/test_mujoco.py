"""sanlab's dynamics against MuJoCo, an independent rigid-body engine.

The creature specs are converted with ``sanlab.interop.mjcf``: the same bodies, masses, inertias,
joints and generalised coordinates. sanlab's coordinates of a free tree are its centre of mass;
MuJoCo's (and the converter's) are the root link's origin: ``sim.root_coordinates`` converts, and
:func:`sanlab.interop.mjcf.qpos_index` maps the order.

Without contacts both simulators integrate the same ODE M(q) q'' = f(q, q'). sanlab's step is its
own (semi-implicit Euler in momentum form, docs/simulator.md "The step"), so it is checked against
the continuous-time motion, MuJoCo's RK4, and must *converge* to it: within the tolerance at
dt = 1e-4, and with half the error at half the step (first order). Any modelling difference (a
mass-matrix entry, an inertial term, the sign of gravity's torque, the angle convention, the frame
of ``com`` or ``anchor``) would leave an error that does not shrink with the step.

The drop test has contacts, which the two model differently (sanlab: penalty springs; MuJoCo: soft
constraints), so it compares only where a passive body comes to rest.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")


from sanlab import sim  # noqa: E402
from sanlab.creature.spec import Creature, Ground, JointSpring, Link, Shape, World  # noqa: E402
from sanlab.interop import mjcf as mm  # noqa: E402

REFERENCE_TOL = 1e-3  # rad: against MuJoCo RK4 (the continuous-time motion), double pendulum
TUMBLE_TOL = 1e-2  # rad or m: the fast free-flight tumble, at dt = 1e-4
FIRST_ORDER = 0.6  # error at dt / 2 over error at dt: first order would be 0.5


# ------------------------------------------------------------------------------------ creatures


def _rod(name, length, mass, parent, anchor, angle, com_off=0.0):
    """A uniform rod along its frame's +x axis (its joint at x = 0)."""
    return Link(
        name=name, mass=mass, inertia=mass * length**2 / 12, com=(length / 2, com_off),
        shape=Shape("segment", ((0.0, 0.0), (length, 0.0))), parent=parent, anchor=anchor,
        angle=angle,
    )  # fmt: skip


def double_pendulum(dt: float = 1e-4) -> Creature:
    """A fixed, tilted, offset base with two rods hanging from it, released from far off vertical.
    The second rod's COM is off its axis, so a wrong sign of com/anchor y would show."""
    base = Link(
        name="base", mass=1.0, inertia=0.01, com=(0.0, 0.0),
        shape=Shape("segment", ((-0.1, 0.0), (0.1, 0.0))), position=(0.1, 1.0), angle=0.3,
        fixed=True,
    )  # fmt: skip
    return Creature(
        name="double_pendulum",
        links=(
            base,
            _rod("upper", 0.5, 1.0, "base", (0.05, -0.02), -1.2),
            _rod("lower", 0.4, 0.7, "upper", (0.5, 0.0), 0.9, com_off=0.03),
        ),
        dt=dt,
    )


def _leg(name, parent, anchor, angle, mass, com=None):
    """A 0.25 m leg segment drawn along -y (0 = hanging straight down), as in bounder.toml."""
    return Link(
        name=name, mass=mass, inertia=mass * 0.25**2 / 12, com=com or (0.0, -0.125),
        shape=Shape("segment", ((0.0, 0.0), (0.0, -0.25))), parent=parent, anchor=anchor,
        angle=angle,
    )  # fmt: skip


def tumbler(dt: float = 1e-4) -> Creature:
    """Bounder-like: a body on two two-segment legs, free root, no contacts (free flight).

    Links are listed breadth first (thighs before shins), so sanlab's dof order differs from
    MuJoCo's depth-first qpos order and the mapping is exercised too. The body's COM is off its
    frame origin and one shin's COM off its axis."""
    body = Link(
        name="body", mass=2.4, inertia=0.052, com=(0.03, 0.01),
        shape=Shape("polygon", ((-0.25, -0.05), (0.25, -0.05), (0.25, 0.05), (-0.25, 0.05))),
        position=(0.2, 3.0), angle=0.4,
    )  # fmt: skip
    return Creature(
        name="tumbler",
        links=(
            body,
            _leg("front_thigh", "body", (0.2, -0.05), 0.35, 0.5),
            _leg("back_thigh", "body", (-0.2, -0.05), -0.5, 0.5),
            _leg("front_shin", "front_thigh", (0.0, -0.25), -0.7, 0.3, com=(0.01, -0.12)),
            _leg("back_shin", "back_thigh", (0.0, -0.25), 0.3, 0.3),
        ),
        dt=dt,
    )


TUMBLER_QD0 = (0.8, 2.0, 3.0, -4.0, 6.0, 5.0, -7.0)  # x', y', body angle', then the four joints


def _box(w, h, x0=None):
    x0 = -w / 2 if x0 is None else x0
    return ((x0, -h / 2), (x0 + w, -h / 2), (x0 + w, h / 2), (x0, h / 2))


DROP_GROUND = Ground(stiffness=5.0e4, damping=300.0, friction=0.6)


def drop_body() -> Creature:
    """Two boxes (0.4 x 0.1 m, 2 kg and 0.3 x 0.1 m, 1 kg) joined at mid-height by a stiff
    spring-damper joint (rest 0), with contacts at their corners; dropped from 0.25 m (lowest
    corner) tilted and bent, so it lands on a corner, bounces, and settles flat: the unique
    resting pose is "both boxes flat on the ground", with PE = 3 kg g (0.05 m - sink).

    The ground is 10x the default stiffness so that sanlab's penalty sink (~0.17 mm) is a small
    fraction of the 5 cm COM height; MuJoCo's soft contacts sink ~0.03 mm."""
    hull = Link(
        name="hull", mass=2.0, inertia=2.0 * (0.4**2 + 0.1**2) / 12, com=(0.0, 0.0),
        shape=Shape("polygon", _box(0.4, 0.1)), contacts=_box(0.4, 0.1), position=(0.0, 0.3),
        angle=0.25,
    )  # fmt: skip
    flap = Link(
        name="flap", mass=1.0, inertia=1.0 * (0.3**2 + 0.1**2) / 12, com=(0.15, 0.0),
        shape=Shape("polygon", _box(0.3, 0.1, 0.0)), contacts=_box(0.3, 0.1, 0.0), parent="hull",
        anchor=(0.2, 0.0), angle=-0.2, spring=JointSpring(30.0, 0.5, 0.0),
    )  # fmt: skip
    return Creature(name="drop", links=(hull, flap), world=World(ground=DROP_GROUND), dt=1e-3)


# ------------------------------------------------------------------------------------ helpers


def sanlab_frames(spec: Creature, seconds: float, record_fps: float, qd0=None, dt=None) -> np.ndarray:
    """sanlab float64 rollout from the spec's pose (and velocities qd0, in root-origin form),
    at the spec's dt or ``dt``: root-origin q (MuJoCo's convention) at each frame [F, D]."""
    if dt is not None:
        spec = dataclasses.replace(spec, dt=dt)
    model = sim.compile_creature(spec, "float64")
    state0 = None
    if qd0 is not None:
        q_root = sim.root_coordinates(model, model.params.q0)
        q0, qd = sim.from_root_coordinates(model, q_root, np.asarray(qd0, np.float64))
        state0 = sim.make_state(model, q0, qd)
    res = sim.rollout(
        model, sim.ConstantController(), np.zeros((1, 0)), seconds=seconds,
        record_fps=record_fps, state0=state0,
    )  # fmt: skip
    assert bool(res.finite[0])
    return np.stack([sim.root_coordinates(model, q) for q in res.frames.q[0]])


def mujoco_frames(spec: Creature, n_frames: int, every: int, qd0=None, **kw) -> np.ndarray:
    """MuJoCo rollout: sanlab-ordered q at each frame (before its steps) [F, D]."""
    m, d = mm.load(spec, **kw)
    if qd0 is not None:
        mm.set_state(spec, m, d, mm.initial_q(spec), qd0)
    idx = mm.qpos_index(spec, m)
    out = np.empty((n_frames, len(idx)))
    for f in range(n_frames):
        out[f] = d.qpos[idx]
        for _ in range(every):
            mujoco.mj_step(m, d)
    return out



# ------------------------------------------------------------------------------------ tests


def test_angle_convention_and_kinematics():
    """A positive sanlab angle turns x toward y; in MuJoCo's x-z plane it must turn x toward z.
    Link origins and absolute angles agree between sanlab's kinematics, the NumPy reference
    (``mjcf.link_poses``) and MuJoCo at a random, far-from-zero pose."""
    spec = tumbler()
    rng = np.random.default_rng(0)
    q = np.concatenate([[0.3, 1.7], rng.uniform(-2.5, 2.5, spec.dofs - 2)])
    m, d = mm.load(spec)
    mm.set_state(spec, m, d, q)
    mujoco.mj_kinematics(m, d)
    names = [l.name for l in spec.links]
    bid = [m.body(n).id for n in names]
    mj_xy = d.xpos[bid][:, [0, 2]]
    mj_th = np.arctan2(d.xmat[bid, 6], d.xmat[bid, 0])  # body x axis = (xmat[0], ., xmat[6])
    X, th = mm.link_poses(spec, q)
    np.testing.assert_allclose(mj_xy, X, atol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (mj_th - th))), 0.0, atol=1e-12)
    np.testing.assert_allclose(d.xipos[bid][:, [0, 2]], mm.com_positions(spec, q), atol=1e-12)

    # the sign on its own: body at +90 deg puts its x axis on world +z
    q90 = mm.initial_q(spec)
    q90[2] = math.pi / 2
    mm.set_state(spec, m, d, q90)
    mujoco.mj_kinematics(m, d)
    np.testing.assert_allclose(d.xmat[m.body("body").id].reshape(3, 3)[:, 0], (0, 0, 1), atol=1e-12)

    # sanlab's own kinematics (the kernel's, which the step uses)
    model = sim.compile_creature(spec, "float64")
    poses = sim.poses(model, sim.from_root_coordinates(model, q))["links"]
    np.testing.assert_allclose(poses[:, :2], X, atol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (poses[:, 2] - th))), 0.0, atol=1e-12)


def test_double_pendulum_matches_mujoco():
    """Fixed root, two rods released from -1.2 / +0.9 rad: 1 s, every joint angle, against
    MuJoCo's RK4 (the continuous-time motion: RK4 at dt = 1e-5 agrees with RK4 at 1e-4 to
    ~1e-13 rad)."""
    spec = double_pendulum(dt=1e-4)
    ours = sanlab_frames(spec, 1.0, 1000)
    assert ours.shape == (1000, 2)
    assert np.ptp(ours[:, 0]) > 1.0 and np.ptp(ours[:, 1]) > 1.0  # it really swings

    rk4 = mujoco_frames(spec, 1000, 10, integrator="RK4")
    err = np.abs(ours - rk4).max(axis=0)
    assert np.all(err < REFERENCE_TOL), f"max |sanlab - MuJoCo RK4| per joint: {err} rad"
    half = sanlab_frames(spec, 1.0, 1000, dt=5e-5)
    err_half = np.abs(half - rk4).max(axis=0)
    assert np.all(err_half < FIRST_ORDER * err), f"no first-order convergence: {err} -> {err_half} rad"


def test_tumbling_bounder_matches_mujoco_in_free_flight():
    """A bounder-like 5-link tree thrown spinning (root and every joint moving), no ground:
    all seven generalised coordinates (root x, y, angle; four relative joint angles) over 1 s,
    against MuJoCo's RK4. The tumble is fast (joints up to 7 rad/s): a first-order step at
    dt = 1e-4 is a few mrad from the continuous-time motion after 1 s."""
    spec = tumbler(dt=1e-4)
    ours = sanlab_frames(spec, 1.0, 1000, qd0=TUMBLER_QD0)
    assert ours.shape == (1000, 7)
    assert np.ptp(ours[:, 2]) > 2.0 and np.all(np.ptp(ours[:, 3:], axis=0) > 0.5)  # it tumbles

    theirs = mujoco_frames(spec, 1000, 10, qd0=TUMBLER_QD0, integrator="RK4")
    err = np.abs(ours - theirs).max(axis=0)
    assert np.all(err < TUMBLE_TOL), f"max |sanlab - MuJoCo RK4| per coordinate: {err}"
    half = sanlab_frames(spec, 1.0, 1000, qd0=TUMBLER_QD0, dt=5e-5)
    err_half = np.abs(half - theirs).max(axis=0)
    assert err_half.max() < FIRST_ORDER * err.max(), f"no first-order convergence: {err} -> {err_half}"


def test_passive_drop_rests_at_mujocos_potential_energy():
    """The two-box body dropped onto flat ground comes to rest flat in both simulators, at the
    same potential energy sum m g y_com within 1 %."""
    spec = drop_body()
    seconds = 3.0
    ours = sanlab_frames(spec, seconds, 100)
    theirs = mujoco_frames(spec, 300, 10, ground=True, integrator="Euler")

    pe_start = mm.potential_energy(spec, mm.initial_q(spec))
    pe_flat = sum(l.mass for l in spec.links) * spec.world.gravity * 0.05  # no sink at all
    pe_ours, pe_theirs = mm.potential_energy(spec, ours[-1]), mm.potential_energy(spec, theirs[-1])
    assert pe_start > 6 * pe_flat  # it fell

    # both at rest (the last 0.5 s), flat (hull level, joint straight), above the ground
    for name, q in (("sanlab", ours), ("MuJoCo", theirs)):
        assert np.abs(q[-50:] - q[-1]).max() < 1e-5, f"{name} is not at rest"
        assert np.all(np.abs(q[-1, 2:]) < 2e-3), f"{name} did not come to rest flat: {q[-1]}"
        assert 0.045 < q[-1, 1] < 0.05, f"{name}: hull centre at y = {q[-1, 1]} m"
    assert pe_ours == pytest.approx(pe_theirs, rel=0.01), (pe_ours, pe_theirs, pe_flat)


def test_servoed_bounder_falls_and_rests_like_mujoco():
    """The bounder as first designed (tests/data/bounder_first.toml: the built-in's later design
    has 0.15 m shins whose servos an explicit PD at 1 ms, as MuJoCo is driven here, cannot step;
    sanlab integrates them implicitly) on the ground, its four PD servos held at mid-range (u =
    0.5: hips straight down, knees bent 60 deg), so its feet end up behind its hips and it tips forward onto
    the body's front corner. Contacts, friction and the servos are all in play; the PD torque is
    computed in Python for MuJoCo (motor actuators). After 3 s both have come to rest in the same
    pose: height and the knees within 5 mm / 5 mrad, x within 2 cm, and the body's tilt and the
    hips within 30 mrad: resting on a corner and two feet that friction holds, the pose is not
    unique (static friction can hold any of a family of poses), and where each simulator's feet
    stopped sliding (penalty contacts with anchors here, soft constraints there) picks one."""
    from pathlib import Path

    from sanlab.creature.loader import loads

    spec = loads((Path(__file__).resolve().parents[1] / "data" / "bounder_first.toml").read_text())
    seconds, u = 3.0, 0.5
    model = sim.compile_creature(spec, "float64")
    res = sim.rollout(
        model, sim.ConstantController(), np.full((1, len(spec.actuators)), u),
        seconds=seconds, record_fps=10,
    )  # fmt: skip
    assert bool(res.finite[0])
    ours = np.stack([sim.root_coordinates(model, q) for q in res.frames.q[0]])

    m, d = mm.load(spec, ground=True, motors=True, integrator="Euler")
    idx = mm.qpos_index(spec, m)
    rot = mm.rotation_dofs(spec)
    adof = idx[[rot[a.joint] for a in spec.actuators]]
    target = np.array([a.min + u * (a.max - a.min) for a in spec.actuators])
    ks, kd = np.array([a.ks for a in spec.actuators]), np.array([a.kd for a in spec.actuators])
    theirs = []
    for k in range(int(round(seconds / spec.dt))):
        if k % 100 == 0:
            theirs.append(d.qpos[idx].copy())
        d.ctrl[:] = ks * (target - d.qpos[adof]) - kd * d.qvel[adof]
        mujoco.mj_step(m, d)
    theirs = np.array(theirs)
    assert d.warning.number.sum() == 0

    for name, q in (("sanlab", ours), ("MuJoCo", theirs)):
        assert -1.4 < q[-1, 2] < -1.0, f"{name}: the body should have tipped forward: {q[-1]}"
        assert np.abs(q[-5:] - q[-1]).max() < 2e-3, f"{name} is not at rest"
    err = np.abs(ours[-1] - theirs[-1])
    hips = [mm.rotation_dofs(spec)[a.joint] for a in spec.actuators if "thigh" in a.joint]
    loose = [2, *hips]  # the body's tilt and the hips
    tight = [i for i in range(1, len(err)) if i not in loose]
    assert err[0] < 0.02 and np.all(err[tight] < 5e-3) and np.all(err[loose] < 0.03), \
        f"|sanlab - MuJoCo| at rest: {err}"
