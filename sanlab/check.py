"""``sanlab check FILE --simulate``: what only a simulation shows about a creature file (the
counterpart of Gymnasium's environment checker).

The creature is dropped for two seconds with every servo holding the middle of its range (a
second to settle from its start pose into that one, as the bounder needs, and one to see it
rest), and also run while its actuators sweep their ranges (to see which sensors can change);
each of these is reported in one line, as a warning when it looks wrong:

- ``start``: how deep its start pose puts a contact point into the ground (and which; the
  simulator lifts the creature onto the ground), or how high it floats above it;
- ``sinking``: links that go below the ground in the drop where they have no contact point;
- ``ground``: the static sag on the ground and the ground's damping ratio for this creature;
- ``standing``: whether it stays up (the file's fell rule never fires: a note when it does) and
  comes to rest (the drift of its centre of mass, its speed at the end);
- ``actuators``: a creature with no actuator that drives anything (none, or every ``ks`` 0),
  which no SAN can move (``search`` refuses it without ``--force``);
- ``strength``: each actuator's strength against its gravity load at its longest lever (paper
  §3.3: a 10 degree deflection should hold half the body weight; a note below 1x, a warning
  beyond 20x either way);
- ``radians``: angle ranges that look like radians (every |value| < 6.3 on a ``_deg`` field);
- ``resolution``: servos the step cannot resolve (underdamped and omega dt > 1,
  ``sanlab.evaluate.resolution``): every evaluation of such a creature is flagged non-finite;
- ``sensors``: sensors that never turn on, or never turn off, in the drop or the sweeps (those
  the actuators move: touch, joint-angle and length sensors; tilt sensors, angle sensors on a
  root and eyes depend on the body's attitude or the follow point, and are not judged, nor is
  a touch sensor on the body that stays off: it touches once the body lies down);
- ``at rest``: whether any sensor is on in the drop. A SAN has no bias (``sanlab.san``: each
  node integrates a weighted sum of the sensors and of the nodes' outputs, which all start at
  0), so while every sensor is off every sum is 0, no node ever turns on and every actuator is
  driven to the middle of its range: the drop *is* what every SAN does, and a creature none of
  whose sensors turns on in it can never move, whatever the search tries.
  :func:`at_rest` tells the same without simulating, where the start pose can tell.

The ground's damping ratio is judged from the contact law N = max(0, k d - c v)
(``docs/simulator.md``, "Forces"): the ground pushes and never pulls, so an overdamped contact (damping
ratio above 1: beyond critical for the mass each contact carries) only means that landings do
not bounce, which is fine (it is what real ground does); an underdamped one rings down a
little. Only the extremes are warnings: a ratio below 0.02 bounces, and one above 20 stops a
landing dead and lets a contact settle into its sag only over c/k seconds, like mud.

Each line is "ok" only where what it checks held, a warning where it looks wrong, and a note
(:attr:`Finding.note`) for a fact that may well be meant but is not what the check asks for.
Nothing is said about parts the creature does not have (no sensor line without sensors to judge,
no strength line without actuators). Warnings, never errors: a creature may mean to float or to
fall. :func:`warnings` is the short
form a command that starts a run can print once; :func:`static` the findings that need no
simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sanlab.creature import geometry
from sanlab.creature.spec import AngleSensor, AngularActuator, Creature, EyeSensor, LengthSensor, TiltSensor, TouchSensor

SECONDS = 2.0  # the drop (and each sweep: one cycle of every actuator through its range)
FPS = 100.0  # frames recorded per second
RADIAN_LIKE = 6.3  # |value| below this on every end of a _deg range: probably radians (2 pi = 6.28)
STRENGTH_BAND = (1 / 20, 20.0)  # strength / gravity load outside it: an order-of-magnitude mistake
FLOAT_TOLERANCE = 0.01  # m above the ground before a start pose "floats"
SINK_TOLERANCE = 0.01  # m below the ground before a link without a contact there "sinks"
SAG_LIMIT = 0.02  # m of static sag before the ground is "too soft"
DAMPING_BAND = (0.02, 20.0)  # the ground's damping ratio outside it: bouncing, or mud
REST_SPEED = 0.02  # m/s: the centre of mass at rest at the end of the second
SWEEPS = 4  # runs with the actuators sweeping their ranges (different phases), besides the drop
TOUCH_TOLERANCE = 0.005  # m: a contact this close to its tree's lowest one is taken to rest on the ground
PATH_POSES = 9  # poses from the start pose to the servos' mid targets, both ends included (at_rest)


@dataclass(frozen=True)
class Finding:
    """One line of the report: ``check`` (start, sinking, ground, standing, actuators, strength,
    radians, resolution, sensors, at rest), whether it is a ``warning``, the ``message`` and its
    numbers (SI units). A ``note`` (never also a warning) is a fact that may well be meant but
    is not what the check asks for (a servo weaker than §3.3's sizing at full reach, a creature
    that falls at its mid targets): printed as "note", never as "ok"."""

    check: str
    warning: bool
    message: str
    values: dict = field(default_factory=dict)
    note: bool = False


# -- without simulating ----------------------------------------------------------------------------


def radian_ranges(spec: Creature) -> list[Finding]:
    """Angle ranges of the file (``min_deg``/``max_deg``, ``fell_angle_deg``) every end of which
    is below 6.3 in magnitude: likely radians written where degrees belong."""
    out = []
    looked = 0

    def look(where: str, lo: float, hi: float) -> None:
        nonlocal looked
        looked += 1
        d = (math.degrees(lo), math.degrees(hi))
        if max(abs(d[0]), abs(d[1])) < RADIAN_LIKE and d != (0.0, 0.0):
            out.append(Finding("radians", True, f"{where}: min_deg, max_deg = [{d[0]:g}, {d[1]:g}] look like radians "
                               f"(every |value| < {RADIAN_LIKE}); the file takes degrees, e.g. [{_suggest(d[0])}, "
                               f"{_suggest(d[1])}]", {"min_deg": d[0], "max_deg": d[1]}))

    for a in spec.actuators:
        if isinstance(a, AngularActuator):
            look(f"actuator {a.name}", a.min, a.max)
    for s in spec.sensors:
        if isinstance(s, (AngleSensor, TiltSensor, EyeSensor)):
            look(f"sensor {s.name} ({s.kind})", s.min, s.max)
    for link in spec.links:
        if link.limit is not None:
            look(f"link {link.name} limit", link.limit.min, link.limit.max)
    fell = math.degrees(spec.evaluation.fell_angle)
    looked += bool(spec.evaluation.fell_links)
    if spec.evaluation.fell_links and fell < RADIAN_LIKE:
        out.append(Finding("radians", True, f"evaluation.fell_angle_deg = {fell:g} looks like radians (below "
                           f"{RADIAN_LIKE}); the file takes degrees", {"fell_angle_deg": fell}))
    if not out and looked:  # nothing said of a file without angle ranges
        out.append(Finding("radians", False, "angle ranges: in degrees as the file wants (none looks like radians)"))
    return out


def _suggest(radians_like: float) -> str:
    """The value in degrees that ``radians_like`` (written in a _deg field) likely meant, with
    enough digits that a small one does not round to 0 (0.001 rad is 0.0573 deg)."""
    d = math.degrees(radians_like)
    return f"{d:.0f}" if abs(d) >= 10 or d == 0 else f"{d:.3g}"


def _subtree(spec: Creature, root: str) -> list[int]:
    inside = {root}
    for link in spec.links:  # parents come before children
        if link.parent in inside:
            inside.add(link.name)
    return [i for i, link in enumerate(spec.links) if link.name in inside]


def actuators(spec: Creature) -> list[Finding]:
    """A warning when no actuator can move anything: the file has none, or every one has
    ``ks = 0`` (a servo's drive is ks times its error; kd only damps). A SAN drives nothing but
    actuators, so every controller scores what the creature does by itself (``search`` refuses
    such a creature without ``--force``); nothing is said otherwise."""
    if not spec.actuators:
        return [Finding("actuators", True, "actuators: none, so no SAN can move any part (a SAN drives only "
                        "actuators: every controller scores what the body does by itself); add [[actuators]]",
                        {"actuators": 0, "driven": 0})]
    if all(a.ks == 0 for a in spec.actuators):
        return [Finding("actuators", True, f"actuators: every one has ks = 0 (actuators[*].ks: all {len(spec.actuators)} "
                        "switched off), so no SAN can move any part; give one a ks above 0",
                        {"actuators": len(spec.actuators), "driven": 0})]
    return []


def strength(spec: Creature) -> list[Finding]:
    """Each actuator's holding force at a 10 degree error (a tenth of its range for a linear one)
    against its gravity load at its longest lever: the larger of lifting what hangs from it (its
    subtree's weight, each link's centre of mass at its distance from the joint, as if held out
    level) and, for a limb that can stand (contact points below the joint), half the creature's
    weight at the limb's whole reach. Paper §3.3 sizes a servo to hold half the body weight with
    a bent leg, whose lever is shorter than the reach, so: "ok" at 1x and up to 20x (it holds even
    at full reach), a note between 1/20x and 1x (the paper's own bounder holds 0.49x, sized at a
    bent leg's 0.19 m lever), a warning outside [1/20, 20] (an order-of-magnitude mistake, e.g.
    N m/rad where N m/deg belongs), and a note for ``ks = 0`` (switched off: it holds nothing;
    :func:`actuators` warns when every one is). Nothing is said of a creature without actuators."""
    g = spec.world.gravity
    if not spec.actuators:
        return []
    if spec.world.plane != "vertical" or g == 0:
        return [Finding("strength", False, "actuators: no gravity load to compare with (" +
                        ("horizontal plane)" if spec.world.plane != "vertical" else "no gravity)"))]
    frames = geometry.initial_frames(spec)
    weight = g * sum(link.mass for link in spec.links if not (link.parent is None and link.fixed))
    out = []
    for n, act in enumerate(spec.actuators):
        if isinstance(act, AngularActuator):
            joint = frames[act.joint][:2]
            members = _subtree(spec, act.joint)
            held = act.ks * math.radians(10)
            how = "10 deg of error"
        else:
            joint = geometry.world_point(spec, act.a.link, act.a.at)
            members = _subtree(spec, act.b.link)
            held = act.ks * 0.1 * (act.max - act.min)
            how = "a tenth of its range"
        lift = reach = 0.0
        for i in members:
            link = spec.links[i]
            f = frames[link.name]
            c = geometry.transform(f, link.com)
            lift += g * link.mass * math.dist(c, joint)
            for p in link.contacts:
                reach = max(reach, math.dist(geometry.transform(f, p), joint))
        load = max(lift, 0.5 * weight * reach)
        unit = "N m" if isinstance(act, AngularActuator) else "N"
        if not isinstance(act, AngularActuator):  # a force against half the weight
            load = 0.5 * weight if reach > 0 else lift / max(reach, 1e-9) if lift else 0.5 * weight
        if held == 0:  # before the ratio: 1 / ratio would divide by zero
            out.append(Finding("strength", False, f"actuator {act.name}: actuators[{n}].ks = 0 (switched off): it drives nothing and "
                               f"holds nothing of its gravity load of up to {load:.3g} {unit}", {"held": 0.0, "load": load},
                               note=True))  # a motor switched off on purpose; all of them off is a warning (actuators)
            continue
        if load <= 0:
            out.append(Finding("strength", False, f"actuator {act.name}: carries no gravity load", {"held": held}))
            continue
        ratio = held / load
        lo, hi = STRENGTH_BAND
        values = {"held": held, "load": load, "ratio": ratio}
        times = f"{ratio:.0f}" if ratio >= 10 else f"{ratio:.2g}"
        text = (f"actuator {act.name}: {how} holds {held:.3g} {unit} against a gravity load of up to {load:.3g} {unit} "
                f"({times}x)")
        if ratio > hi:
            out.append(Finding("strength", True, text + f": {ratio:.0f} times stronger than §3.3's sizing (ks in N m/rad "
                               "where N m/deg belongs?)", values))
        elif ratio < lo:
            out.append(Finding("strength", True, text + f": {1 / ratio:.0f} times weaker than §3.3's sizing "
                               "(it cannot hold itself up)", values))
        elif ratio < 1:
            out.append(Finding("strength", False, text + ": below §3.3's sizing at full reach; it holds the load at "
                               f"levers up to {ratio:.0%} of the longest (§3.3 sizes for a bent leg's shorter one)",
                               values, note=True))
        else:
            out.append(Finding("strength", False, text + ": holds it even at full reach (§3.3's sizing met)", values))
    return out


NO_BIAS = ("a SAN has no bias (each node sums weights times its inputs, all 0 here), so no node turns on, every "
           "actuator holds the middle of its range and no controller can ever move the creature")
FIX = ("add a sensor that is on at the start, e.g. a \"straight\" angle sensor whose range contains a joint's start "
       "angle ({ type = \"angle\", link = ..., min_deg = -10, max_deg = 10 } on a joint that starts at 0), or a touch "
       "sensor on a contact it stands on")


def _wrap(a: float) -> float:
    """``a`` wrapped to [-pi, pi), as the simulator's sensors see angles."""
    return a - 2 * math.pi * math.floor((a + math.pi) / (2 * math.pi))


def _ground_height(spec: Creature, x: float) -> float | None:
    """The terrain's height at x (m), or None for rough terrain (its sum of sinusoids lives in the
    compiled model)."""
    t = spec.world.terrain
    if t.kind == "flat":
        return 0.0
    if t.kind == "slope":
        return math.tan(t.angle) * x
    if t.kind == "hill":
        half = t.width / 2
        return t.height * (1 + math.cos(math.pi * (x - t.center) / half)) / 2 if abs(x - t.center) < half else 0.0
    return None


def _tree_of(spec: Creature) -> dict[str, str]:
    """Each link's root (parents come before children)."""
    root: dict[str, str] = {}
    for link in spec.links:
        root[link.name] = root[link.parent] if link.parent is not None else link.name
    return root


def _on_in_pose(spec: Creature, frames: dict) -> list[bool | None]:
    """Each sensor's value in the pose ``frames`` (as :func:`geometry.link_frames` gives), True or
    False, or None where the pose cannot tell (a touch sensor on rough terrain)."""
    by_name = {link.name: link for link in spec.links}
    root = _tree_of(spec)
    falls = spec.world.gravity > 0
    lowest: dict[str, float] = {}  # per tree: the gap below its lowest contact (m)
    gaps: dict[tuple[str, int], float | None] = {}
    for link in spec.links:
        for k, p in enumerate(link.contacts):
            x, y = geometry.transform(frames[link.name], p)
            h = _ground_height(spec, x)
            gaps[(link.name, k)] = None if h is None else y - h
            if h is not None:
                lowest[root[link.name]] = min(lowest.get(root[link.name], math.inf), y - h)
    out: list[bool | None] = []
    for s in spec.sensors:
        if isinstance(s, TouchSensor):
            if spec.world.plane != "vertical":
                out.append(True)  # every contact rests on the floor
                continue
            gap, tree = gaps[(s.link, s.contact)], by_name[root[s.link]]
            if gap is None:
                out.append(None)
            elif falls and not tree.fixed:  # it falls (or is lifted) onto its lowest contacts
                out.append(gap <= lowest[tree.name] + TOUCH_TOLERANCE or gap <= 0)
            else:
                out.append(gap <= 0)
        elif isinstance(s, (AngleSensor, TiltSensor)):
            link = by_name[s.link]
            a = frames[s.link][2]
            if isinstance(s, AngleSensor) and link.parent is not None:
                a -= frames[link.parent][2]
            out.append(s.min <= _wrap(a) <= s.max)
        elif isinstance(s, EyeSensor):
            follow = spec.world.follow
            assert follow is not None  # the loader demands a follow path of a creature with eyes
            tx, ty = follow.points[0]  # where the follow point starts
            ex, ey = geometry.transform(frames[s.at.link], s.at.at)
            if s.axis is not None:
                (x0, y0, _), (x1, y1, _) = frames[s.axis[0]], frames[s.axis[1]]
                ax = (x1 - x0, y1 - y0)
            else:
                ax = (math.cos(frames[s.at.link][2]), math.sin(frames[s.at.link][2]))
            dx, dy = tx - ex, ty - ey
            a = math.atan2(ax[0] * dy - ax[1] * dx, ax[0] * dx + ax[1] * dy)
            out.append(s.min <= a <= s.max)
        else:
            assert isinstance(s, LengthSensor)
            pa = geometry.transform(frames[s.a.link], s.a.at)
            pb = geometry.transform(frames[s.b.link], s.b.at)
            out.append(s.min <= math.dist(pa, pb) <= s.max)
    return out


def _path_to_mid(spec: Creature) -> list[dict]:
    """The poses from the file's start pose to the one with every angular servo's joint at its
    mid target (the rest of the pose as the file starts it), :data:`PATH_POSES` of them."""
    mid = {a.joint: (a.min + a.max) / 2 for a in spec.actuators if isinstance(a, AngularActuator)}
    poses = []
    for i in range(PATH_POSES):
        f = i / (PATH_POSES - 1)
        q: list[float] = []
        for link in spec.links:
            if link.parent is None:
                if link.dofs:
                    q += [link.position[0], link.position[1], link.angle][: link.dofs]
            else:
                q.append(link.angle + f * (mid[link.name] - link.angle) if link.name in mid else link.angle)
        poses.append(geometry.link_frames(spec.links, q))
    return poses


def _rotation(theta: float) -> np.ndarray:
    return np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])


def _tipped(spec: Creature, frames: dict) -> dict:
    """The pose ``frames`` after each free tree, held rigid, has tipped over on flat ground until
    its centre of mass is above its support: it turns about its outermost lowest contact, towards
    the centre of mass, until the next contact lands, and again while the centre of mass is
    outside the contacts on the ground (a body balanced on one point falls over; the built-in
    cart starts on its keel). The frames themselves where the plane is horizontal, gravity is
    off or the ground is not flat."""
    if spec.world.plane != "vertical" or spec.world.gravity <= 0 or spec.world.terrain.kind != "flat":
        return frames
    root, by_name, out = _tree_of(spec), {link.name: link for link in spec.links}, dict(frames)
    for tree in dict.fromkeys(root.values()):
        links = [link for link in spec.links if root[link.name] == tree]
        pts = np.array([geometry.transform(frames[link.name], p) for link in links for p in link.contacts], float)
        mass = sum(link.mass for link in links)
        if by_name[tree].fixed or len(pts) < 2 or mass <= 0:
            continue
        com = np.sum([link.mass * np.array(geometry.transform(frames[link.name], link.com)) for link in links], axis=0) / mass
        turn, shift = 0.0, np.zeros(2)  # the rigid motion so far: p -> R(turn) p + shift
        for _ in range(len(pts) + 1):
            low = pts[:, 1] <= pts[:, 1].min() + 1e-9
            left, right = pts[low, 0].min(), pts[low, 0].max()
            side = 1.0 if com[0] > right + 1e-9 else -1.0 if com[0] < left - 1e-9 else 0.0
            if side == 0.0:
                break
            pivot = np.array([right if side > 0 else left, pts[:, 1].min()])
            r = pts - pivot
            ahead = side * r[:, 0] > 1e-9  # contacts on the side it falls towards
            if not ahead.any():
                break  # nothing to land on: it rolls off its last contact
            theta = -side * float(np.arctan2(r[ahead, 1], side * r[ahead, 0]).min())
            rot = _rotation(theta)
            pts, com = (pts - pivot) @ rot.T + pivot, rot @ (com - pivot) + pivot
            turn, shift = turn + theta, rot @ (shift - pivot) + pivot
        rot = _rotation(turn)
        for link in links:
            x, y, a = frames[link.name]
            nx, ny = rot @ np.array([x, y]) + shift
            out[link.name] = (float(nx), float(ny), a + turn)
    return out


def at_rest(spec: Creature) -> list[Finding]:
    """Without simulating: whether any sensor is on in the start pose or on the way to the
    servos' mid targets (the pose every SAN drives the creature to while its sensors are off; see
    the module docstring). A warning when none is, which the simulation (:func:`simulate`)
    settles for sure: each pose is taken as the joints put it and again tipped over, held rigid,
    onto its contacts (:func:`_tipped`); a touch sensor counts as on when its contact is within
    5 mm of its tree's lowest. Nothing is said of a creature
    with linear actuators (where their mid targets put it needs a simulation), of one on rough
    terrain whose touch sensors decide, or of one whose eyes watch a follow point that moves
    (it may come into view however still the creature is)."""
    if any(not isinstance(a, AngularActuator) for a in spec.actuators) or _watches(spec):
        return []
    if not spec.sensors:
        return [Finding("at rest", True, f"sensors at rest: it has no sensors, and {NO_BIAS}; {FIX}", {"on": []})]
    values = [_on_in_pose(spec, f) for frames in _path_to_mid(spec) for f in (frames, _tipped(spec, frames))]
    if any(v is None for pose in values for v in pose):
        return []
    on = [s.name for i, s in enumerate(spec.sensors) if any(pose[i] for pose in values)]
    if on:
        return [Finding("at rest", False, f"sensors at rest: {', '.join(on[:4])}{', ...' * (len(on) > 4)} on in the start "
                        "pose or on the way to the servos' mid targets: a SAN has an input to act on", {"on": on})]
    return [Finding("at rest", True, "sensors at rest: none is on in the start pose, nor on the way to the servos' mid "
                    f"targets (sanlab check --simulate tells for sure); {NO_BIAS}; {FIX}", {"on": []})]


def static(spec: Creature) -> list[Finding]:
    """Every finding that needs no simulation: :func:`actuators`, :func:`strength`,
    :func:`resolution`, :func:`radian_ranges` and :func:`at_rest`."""
    return [*actuators(spec), *strength(spec), *resolution(spec), *radian_ranges(spec), *at_rest(spec)]


# -- simulating ------------------------------------------------------------------------------------


def simulate(spec: Creature, seconds: float = SECONDS, dtype: str = "float64") -> list[Finding]:
    """Every finding of the module docstring, in its order (one compile and one batched rollout
    of the drop and the sweeps)."""
    from sanlab import sim

    if spec.dofs == 0:  # the loader refuses such a file; a Creature built in code gets the same answer
        raise ValueError(f"{spec.name}: expected at least one degree of freedom to simulate, got every link fixed")
    model = sim.compile_creature(spec, dtype)
    A = len(spec.actuators)
    rng = np.random.default_rng(0)
    rows = [np.zeros(A + 1)]  # f = 0, phase 0: every servo at mid target
    for k in range(SWEEPS):  # 1 Hz sweeps through the whole range, phases varied between them
        phases = rng.uniform(0, 2 * math.pi, A) if k else np.zeros(A)
        rows.append(np.concatenate([phases, [1.0 / seconds]]))
    params = np.stack(rows).astype(dtype)
    r = sim.rollout(model, sim.SineController(), params, seconds, record_fps=FPS)
    assert r.frames is not None
    q = np.asarray(r.frames.q, float)  # [B, F, D]
    bits = np.asarray(r.frames.bits) > 0.5  # [B, F, S]
    P = sim.poses(model, q)
    finite = bool(np.all(np.isfinite(q[0])))

    def ground(x: np.ndarray) -> np.ndarray:
        if spec.world.plane != "vertical":
            return np.full(np.shape(x), -np.inf)
        h, _ = sim.terrain_height(model, np.asarray(x, float))
        return np.broadcast_to(np.asarray(h, float), np.shape(x))

    out = [_start(spec, ground)]
    if not finite:
        out.append(Finding("standing", True, "the drop went non-finite within the second: nothing else can be judged"))
    else:
        out += _sinking(spec, P, ground)
        out += _ground(spec, P)
        out.append(_standing(spec, P, r.frames.t, ground))
    out += actuators(spec)
    out += strength(spec)
    out += resolution(spec)
    out += radian_ranges(spec)
    out += _sensors(spec, bits)
    out.append(_at_rest(spec, bits[0]))
    return out


def resolution(spec: Creature) -> list[Finding]:
    """Servos, springs and stops the step cannot resolve (``sanlab.evaluate.resolution``): one
    warning each, or one line saying every servo is resolved (and one for springs and stops)."""
    from sanlab.evaluate.resolution import OMEGA_DT, Servos

    sv = Servos.of(spec)
    return _servo_resolution(spec, sv, OMEGA_DT) + _passive_resolution(spec, sv, OMEGA_DT)


def _passive_resolution(spec: Creature, sv: Any, bound: float) -> list[Finding]:
    out = []
    for p in sv.passive:
        if p.unresolved(spec.dt):
            out.append(Finding("resolution", True, (
                f"{p.what}: rings at {p.omega / (2 * math.pi):.3g} Hz (damping ratio {p.zeta:.2g}), "
                f"{p.omega * spec.dt:.3g} rad per step of {spec.dt:g} s: the step cannot follow it, so every evaluation "
                "is flagged non-finite (raise its damping, lower its stiffness, or lower dt)"),
                {"omega_dt": float(p.omega * spec.dt), "zeta": float(p.zeta)}))
    if sv.passive and not out:
        rings = [p.omega * spec.dt for p in sv.passive if p.zeta < 1.0]
        how = (f"largest omega dt {max(rings):.2g} rad per step of those that ring, at most {bound:g}" if rings
               else "every one is overdamped: none rings")
        out.append(Finding("resolution", False, f"springs and stops: the step resolves every one ({how})"))
    return out


def _servo_resolution(spec: Creature, sv: Any, OMEGA_DT: float) -> list[Finding]:
    if not len(sv.index):
        return []
    ks = np.array([a.ks for a in spec.actuators])
    kd = np.array([a.kd for a in spec.actuators])
    omega, zeta = sv.modes(ks, kd)
    out = []
    for j, k in enumerate(sv.index):
        if zeta[j] < 1.0 and omega[j] * spec.dt > OMEGA_DT:
            out.append(Finding("resolution", True, (
                f"actuator {spec.actuators[k].name}: rings at {omega[j] / (2 * math.pi):.3g} Hz (damping ratio "
                f"{zeta[j]:.2g}), {omega[j] * spec.dt:.3g} rad per step of {spec.dt:g} s: the step cannot follow it, so "
                "every evaluation is flagged non-finite (raise its kd, lower its ks, or lower dt)"),
                {"omega_dt": float(omega[j] * spec.dt), "zeta": float(zeta[j])}))
    if not out:
        rings = zeta < 1.0  # an overdamped servo does not ring: the step follows it whatever its omega dt
        how = (f"largest omega dt {float(np.max(omega[rings] * spec.dt)):.2g} rad per step of those that ring, at most "
               f"{OMEGA_DT:g}" + ("; the others are overdamped and do not ring" if not rings.all() else "")
               if rings.any() else "every one is overdamped: none rings")
        out.append(Finding("resolution", False, f"servos: the step resolves every one ({how})"))
    return out


def _start(spec: Creature, ground: Any) -> Finding:
    """How the file's start pose meets the ground (before the simulator seats it)."""
    if spec.world.plane != "vertical":
        return Finding("start", False, "start: horizontal plane, every contact rests on the floor")
    frames = geometry.initial_frames(spec)
    worst = None
    for link in spec.links:
        for k, p in enumerate(link.contacts):
            x, y = geometry.transform(frames[link.name], p)
            gap = y - float(ground(np.array(x)))
            if worst is None or gap < worst[0]:
                worst = (gap, link.name, k)
    if worst is None:
        return Finding("start", False, "start: no contact points (nothing can touch the ground)")
    gap, name, k = worst
    values = {"gap_m": gap, "link": name, "contact": k}
    if gap < -1e-6:
        return Finding("start", True, f"start: contact {k} of link {name} starts {-gap * 100:.3g} cm below the ground "
                       "(the simulator lifts the creature onto it; fix position or angle_deg)", values)
    if gap > FLOAT_TOLERANCE:
        return Finding("start", True, f"start: floats {gap * 100:.3g} cm above the ground (lowest: contact {k} of link "
                       f"{name}); it falls that far first", values)
    return Finding("start", False, f"start: rests on the ground (lowest contact {gap * 1000:.2g} mm above it, contact {k} "
                   f"of link {name})", values)


def _sinking(spec: Creature, P: dict, ground: Any) -> list[Finding]:
    """Links whose outline goes below the ground where they have no contact point, in the drop
    (a sweep may throw a creature over, and whether a fallen creature's back has contacts is
    another question)."""
    if spec.world.plane != "vertical":
        return []
    links = P["links"][0]  # [F, L, 3]: the drop
    out = []
    for i, link in enumerate(spec.links):
        pts = [p for p in (*link.shape.points, (0.0, 0.0)) if not any(math.dist(p, c) < 1e-9 for c in link.contacts)]
        if not pts:
            continue
        p = np.asarray(pts, float)
        x, y, a = links[..., i, 0:1], links[..., i, 1:2], links[..., i, 2:3]
        wx = x + np.cos(a) * p[:, 0] - np.sin(a) * p[:, 1]
        wy = y + np.sin(a) * p[:, 0] + np.cos(a) * p[:, 1]
        depth = float(np.max(ground(wx) - wy))
        if depth > SINK_TOLERANCE:
            why = "it has none" if not link.contacts else "its contacts are elsewhere"
            out.append(Finding("sinking", True, f"link {link.name} goes {depth * 100:.3g} cm below the ground where it has "
                               f"no contact point ({why}: add contacts there)", {"link": link.name, "depth_m": depth}))
    if not out:
        out.append(Finding("sinking", False, "sinking: no link goes below the ground away from its contact points"))
    return out


def _ground(spec: Creature, P: dict) -> list[Finding]:
    """Static sag at the end of the drop and the ground's damping ratio for this creature."""
    if spec.world.plane != "vertical" or not P["depth"].shape[-1]:
        return []
    depth = P["depth"][0, -1]  # the drop's last frame
    touching = depth > 0
    g = spec.world.ground
    n = int(touching.sum())
    if n == 0:
        return [Finding("ground", True, "ground: nothing rests on it at the end of the second (still falling, or bouncing?)")]
    mass = sum(link.mass for link in spec.links if not (link.parent is None and link.fixed))
    sag = float(depth[touching].mean())
    zeta = g.damping / (2 * math.sqrt(g.stiffness * mass / n))
    values = {"sag_m": sag, "contacts": n, "damping_ratio": zeta}
    text = (f"ground: static sag {sag * 1000:.2g} mm on {n} contact point{'s' * (n != 1)}, damping ratio {zeta:.3g} "
            f"(stiffness {g.stiffness:g} N/m, damping {g.damping:g} N s/m, {mass / n:.3g} kg on each contact)")
    lo, hi = DAMPING_BAND
    if sag > SAG_LIMIT:
        return [Finding("ground", True, text + ": too soft for this creature (raise world.ground.stiffness)", values)]
    if zeta < lo:
        return [Finding("ground", True, text + ": it bounces (raise world.ground.damping)", values)]
    if zeta > hi:
        return [Finding("ground", True, text + f": far overdamped, a landing is stopped dead and a contact takes c/k = "
                        f"{g.damping / g.stiffness:.2g} s to settle into its sag, like mud (lower world.ground.damping)",
                        values)]
    if zeta >= 1:  # the contact law never pulls (N = max(0, k d - c v)): no bounce, and no glue either
        return [Finding("ground", False, text + ": overdamped (beyond critical for the mass on each contact), so "
                        "landings do not bounce; fine: the ground pushes and never pulls, so it holds no foot that lifts",
                        values)]
    swing = math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
    return [Finding("ground", False, text + f": underdamped, a landing rings down (each swing {swing:.0%} of the one "
                    "before) and settles", values)]


def _fell(spec: Creature, P: dict, ground: Any) -> str | None:
    """How the drop (row 0 of ``P``) meets the file's fell rule (``evaluation.fell_link`` and
    friends, as the simulator's metric judges it), or None when it never does or the file has
    no fell rule."""
    ev = spec.evaluation
    links = P["links"][0]  # [F, L, 3]
    index = {link.name: i for i, link in enumerate(spec.links)}
    for name in ev.fell_links:
        i = index[name]
        a = np.asarray(links[:, i, 2], float)
        tilt = float(np.max(np.abs(a - 2 * np.pi * np.floor((a + np.pi) / (2 * np.pi)))))
        if tilt > ev.fell_angle:
            return (f"link {name} tilts {math.degrees(tilt):.0f} deg, past evaluation.fell_angle_deg = "
                    f"{math.degrees(ev.fell_angle):.3g}")
        if ev.fell_link_height is not None and spec.world.plane == "vertical":
            cx, cy = spec.link(name).com
            x, y, th = links[:, i, 0], links[:, i, 1], links[:, i, 2]
            wx, wy = x + np.cos(th) * cx - np.sin(th) * cy, y + np.sin(th) * cx + np.cos(th) * cy
            low = float(np.min(wy - ground(wx)))
            if low < ev.fell_link_height:
                return (f"the centre of mass of link {name} comes down to {low * 100:.3g} cm above the ground, below "
                        f"evaluation.fell_link_height = {ev.fell_link_height:g} m")
    if ev.fell_com_height is not None and spec.world.plane == "vertical":
        com = P["com"][0]
        low = float(np.min(com[:, 1] - ground(com[:, 0])))
        if low < ev.fell_com_height:
            return (f"its centre of mass comes down to {low * 100:.3g} cm above the ground, below "
                    f"evaluation.fell_com_height = {ev.fell_com_height:g} m")
    return None


def _standing(spec: Creature, P: dict, t: Any, ground: Any) -> Finding:
    """Does the creature stay up (its file's fell rule never fires) and come to rest, servos at
    mid targets? Drift of its centre of mass. Falling at mid targets is a note, not a warning: a
    SAN whose sensors stay off does it, but a walker may well need its gait to stay up."""
    com = P["com"][0]  # [F, 2]
    t = np.asarray(t, float)
    drift = float(np.hypot(*(com[-1] - com[0])))
    k = max(1, int(round(0.2 * FPS)))
    speed = float(np.hypot(*(com[-1] - com[-1 - k])) / max(t[-1] - t[-1 - k], 1e-9)) if len(t) > k else 0.0
    fell = _fell(spec, P, ground)
    values = {"drift_m": drift, "end_speed_m_s": speed, "fell": fell is not None}
    if speed > REST_SPEED:
        return Finding("standing", True, f"standing: still moving at {speed * 100:.2g} cm/s after {t[-1]:.0f} s with the "
                       f"servos at mid targets (drifted {drift * 100:.2g} cm" + (f"; it fell: {fell})" if fell else ")"),
                       values)
    if fell is not None:
        return Finding("standing", False, f"standing: falls by the file's fell rule with the servos at mid targets ({fell}; "
                       f"its centre of mass moved {drift * 100:.2g} cm in all), then comes to rest: it does not stay up "
                       "by itself, and every SAN starts from this (a gait must keep it up)", values, note=True)
    rule = ("it never meets the file's fell rule" if spec.evaluation.can_fall
            else "the file has no fell rule to judge a fall by")
    return Finding("standing", False, f"standing: comes to rest with the servos at mid targets ({rule}; its centre of "
                   f"mass moved {drift * 100:.2g} cm in all)", values)


def _judged(spec: Creature, s: Any) -> bool:
    """Whether the actuators move what sensor ``s`` senses (see the module docstring)."""
    if s.kind in ("eye", "tilt"):
        return False
    return not (s.kind == "angle" and spec.link(s.link).parent is None)


def _on_body(spec: Creature, s: Any) -> bool:
    """A touch sensor on a root link (the body): it touches when the body lies down, which a drop
    does not show, so only "never turns off" is judged."""
    return s.kind == "touch" and spec.link(s.link).parent is None


def _reaches(spec: Creature, s: Any, on: bool) -> bool:
    """For a joint-angle sensor on a servo-driven joint: whether the servo's target range lets it
    turn on (``on``) or off at all. A sweep at 0.5 Hz may not push a joint to the very end of its
    range, where a real gait (with the ground pushing back) can: a sensor is reported only when
    its range misses the servo's (never on) or covers it (never off), and the simulation agrees."""
    if not isinstance(s, AngleSensor):
        return False
    servo = next((a for a in spec.actuators if isinstance(a, AngularActuator) and a.joint == s.link), None)
    if servo is None:
        return False
    if on:
        return s.max >= servo.min and s.min <= servo.max
    return not (s.min <= servo.min and servo.max <= s.max)


def _why(spec: Creature, s: Any) -> str:
    if not isinstance(s, AngleSensor):
        return ""
    servo = next((a for a in spec.actuators if isinstance(a, AngularActuator) and a.joint == s.link), None)
    if servo is None:
        return ""
    d = math.degrees
    return (f": its range [{d(s.min):.4g}, {d(s.max):.4g}] deg against the servo's targets "
            f"[{d(servo.min):.4g}, {d(servo.max):.4g}] deg")


def _sensors(spec: Creature, bits: np.ndarray) -> list[Finding]:
    """Sensors that never turn on, or never off, in the drop and the sweeps (of those the
    actuators move: see :func:`_judged` and :func:`_reaches`). Nothing is said where there is
    no sensor to judge or no actuator that sweeps (:func:`actuators` warns of that)."""
    out = []
    if not any(_judged(spec, s) for s in spec.sensors) or not any(a.ks > 0 for a in spec.actuators):
        return out
    for i, s in enumerate(spec.sensors):
        if not _judged(spec, s):
            continue
        seen = bits[..., i]
        if not seen.any() and (_reaches(spec, s, True) or _on_body(spec, s)):
            continue
        if seen.all() and _reaches(spec, s, False):
            continue
        why = _why(spec, s)
        if not seen.any():
            out.append(Finding("sensors", True, f"sensor {s.name} ({s.kind}) never turns on, not even while the actuators "
                               f"sweep their ranges{why}", {"sensor": s.name, "always": False}))
        elif seen.all():
            out.append(Finding("sensors", True, f"sensor {s.name} ({s.kind}) never turns off, not even while the actuators "
                               f"sweep their ranges{why}", {"sensor": s.name, "always": True}))
    if not out:
        skipped = [s.name for s in spec.sensors if not _judged(spec, s)]
        out.append(Finding("sensors", False, "sensors: each turns on and off while the actuators sweep their ranges" +
                           (f" (not judged: {', '.join(skipped)}, which sense the body's attitude or the follow point)"
                            if skipped else "")))
    return out


def _watches(spec: Creature) -> bool:
    """Whether an eye sensor watches a follow point that moves."""
    follow = spec.world.follow
    return follow is not None and follow.speed > 0 and any(isinstance(s, EyeSensor) for s in spec.sensors)


def _at_rest(spec: Creature, bits: np.ndarray) -> Finding:
    """Whether any sensor turns on in the drop (``bits`` [F, S]): see the module docstring."""
    on = [s.name for i, s in enumerate(spec.sensors) if bits[:, i].any()]
    if on:
        return Finding("at rest", False, f"sensors at rest: {', '.join(on[:4])}{', ...' * (len(on) > 4)} on in the drop "
                       "(servos at mid targets): a SAN has an input to act on", {"on": on})
    if _watches(spec):
        return Finding("at rest", False, "sensors at rest: none is on in the drop, but its eyes watch a follow point that "
                       "moves: a SAN has an input once the point comes into view", {"on": []})
    what = "none turns on in the drop" if spec.sensors else "it has no sensors"
    return Finding("at rest", True, f"sensors at rest: {what} with the servos at their mid targets, which is what "
                   f"every SAN does while its sensors are off; {NO_BIAS}; {FIX}", {"on": []})


def warnings(spec: Creature, dtype: str = "float64") -> list[str]:
    """The warnings of :func:`simulate`, one line each (for ``search`` to print once)."""
    return [f.message for f in simulate(spec, dtype=dtype) if f.warning]
