"""Read a planar MJCF model into a sanlab creature file: :func:`mjcf_to_toml` (``sanlab import-mjcf``).

MuJoCo itself compiles the model (``mujoco.MjModel.from_xml_path``), so ``<default>`` classes,
``fromto`` capsules, ``pos``/``quat``/``euler``/``axisangle`` frames, ``inertiafromgeom`` and
``settotalmass`` mean here exactly what they mean to MuJoCo: every number below is read from the
compiled model (``body_mass``, ``body_inertia``, ``jnt_range``, ...) and from
``mj_kinematics`` at the model's reference pose ``qpos0`` (``xanchor``, ``xaxis``, ``xipos``,
``geom_xpos``, ``geom_xmat``), never from the XML text.

What is planar (the errors name the offending joint):

* the plane is MuJoCo's x-z plane, sanlab's (x, y): a point (x, y, z) becomes (x, z) and gravity
  must be along -z (the same conventions as :mod:`sanlab.interop.mjcf`);
* a root (a body hanging from the world) has two slides spanning the x-z plane and one hinge about
  y, as Gymnasium's ``rootx``/``rootz``/``rooty``, or a ``<freejoint/>`` (a free planar body: its
  out-of-plane motion is dropped, with a warning); a body without joints under the world is
  static scenery and is left out;
* every other body has one hinge whose axis, at ``qpos0``, is (0, -1, 0) or (0, 1, 0), or no joint
  at all (it is welded to its parent and merged into the parent's link).

Frames: every link's frame is drawn at ``qpos0`` aligned with the world, its origin at its joint
(a root's: at its hinge, or its body origin for a free joint), so every joint angle is 0 in the
model's reference pose. A sanlab angle is counter-clockwise in (x, y), a rotation about **-y**: a
hinge with axis (0, -1, 0) (Gymnasium's hopper and walker2d) keeps the sign of its ``qpos``, one
about (0, 1, 0) flips it, and ranges, spring rest angles and servo targets flip with it.

What becomes what (MuJoCo's documentation, "XML Reference" and "Computation"):

* a body (with the bodies welded to it) is a link: ``body_mass``; the inertia about the centre of
  mass about the plane's normal, (R diag(``body_inertia``) R^T)_yy with R the inertial frame at
  ``qpos0``; the centre of mass ``xipos``;
* capsules, boxes, spheres, cylinders and ellipsoids are projected onto the plane: a capsule
  becomes a hexagon (its two ends and the four corners of its sides), a box its corners, a sphere
  an octagon; the link's outline is the convex hull of its geoms, and the points of the geoms
  that can collide with the floor (``contype``/``conaffinity``) are its contact points (those on
  the hull of the colliding geoms: on level ground nothing inside it touches first);
* a hinge's range is a joint limit, whose stiffness and damping follow the joint's ``solreflimit``
  (time constant tc, damping ratio zeta): k = I / (tc zeta)^2 and c = 2 I / tc, I the joint's
  inertia (its diagonal of the mass matrix at ``qpos0``, without armature); ``stiffness``,
  ``springref`` and ``damping`` are the joint spring;
* a ``motor`` on a hinge is a PD servo (paper §3.3) with ks = peak torque / 10 deg and
  kd = 0.1 s x ks: the servo gives the motor's peak torque |gear| x max |ctrlrange| (or its
  ``forcerange``) at a 10 degree error, the error at which §3.3 sizes a servo; its targets stay
  within :data:`TARGET_SPAN_DEG` (or the fall angle, if smaller) of ``qpos0``, inside the joint's
  range; a ``position`` actuator is already a PD servo (ks = kp gear^2, kd = kv gear^2, targets
  ctrlrange / gear, which MuJoCo keeps in qpos units);
* touch sensors sit on the lowest points at ``qpos0`` of the colliding geoms of the links at the
  ends of the tree (the feet), at each end of the geom when it lies flat; two angle sensors per
  joint are on within a quarter of its servo's target range (else of its range) from either end;
  the root gets two more (a balance organ), leaning past half the fall angle;
* the floor (a plane of the world body) is sanlab's ground: its friction is the largest of the
  geoms' (MuJoCo's default mixing), and its stiffness and damping follow the contacts' ``solref``
  as for limits, with half the creature's mass on each of two contact points;
* ``[evaluation]``: Gymnasium's fall test where the model is one of its environments' (Hopper-v5,
  Walker2d-v5: the torso's healthy height and angle), else a root tilted past 90 degrees; the
  metric is the distance moved forward (+x, Gymnasium's reward direction) without falling.

Everything else (armature, friction loss, self-collision, tendons, equality constraints, MuJoCo's
own sensors, actuators other than motors and position servos, ...) is not carried over: each gets
one warning line. Malformed or non-planar models raise :class:`MjcfError`, one line naming the
file.
"""

from __future__ import annotations

import math
import os
import re
import stat
import textwrap
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sanlab import __version__
from sanlab.creature import CreatureError, loads, printable

PLANE_TOL = 1e-6  # |y component| of a unit axis still "about y" / "in the x-z plane"
SERVO_ERROR_DEG = 10.0  # paper §3.3: a servo is sized by what it holds at a 10 degree error
KD_OVER_KS = 0.1  # s, paper §3.3: kd / ks of about 0.1
SENSOR_FRACTION = 0.25  # an angle sensor is on within this fraction of the range from its end
SNAP_GAP = 0.1  # m: a start pose at most this far above (or into) the floor is set onto it
# A motor's servo targets stay within this, or the fall angle if smaller, of the reference pose
# qpos0 (and inside the joint's range): qpos0 is where a legged model stands, and a servo that can
# by itself tilt the body past its fall angle throws over nearly every random network. With the
# hopper's whole ranges (hip and knee 150 degrees) all 256 of a first search fell within a second;
# the paper's walker keeps its ranges to 40-120 degrees for the same reason (walker.toml).
TARGET_SPAN_DEG = 30.0
PER_DEG = 180.0 / math.pi

# Gymnasium's fall tests ("healthy" ranges of the torso's height and angle, the environments'
# defaults in gymnasium/envs/mujoco/{hopper,walker2d}_v5.py), by MJCF model name and root body.
GYMNASIUM = {
    "hopper": {"env": "Hopper-v5", "root": "torso", "z": (0.7, math.inf), "angle": (-0.2, 0.2)},
    "walker2d": {"env": "Walker2d-v5", "root": "torso", "z": (0.8, 2.0), "angle": (-1.0, 1.0)},
}


class MjcfError(ValueError):
    """An MJCF model that cannot be imported; ``str()`` is one line: ``file: what was wrong``."""


def mjcf_to_toml(path: str | os.PathLike) -> tuple[str, list[str]]:
    """(creature TOML text, warnings) of the planar MJCF model at ``path``.

    The text is a commented creature file (``sanlab/creature/FORMAT.md``) that
    ``sanlab.creature.loads`` accepts; each warning is one line about something the format cannot
    carry (see the module docstring). Raises :class:`MjcfError` (one line naming the file) for a
    missing or unreadable file, XML MuJoCo refuses, or a model that is not planar (naming the
    joint), and ImportError when the ``mujoco`` package is not installed.
    """
    shown = printable(str(path))
    m, said = _compile(Path(path), shown)
    importer = _Importer(m, shown, Path(path).name)
    for line in said:
        importer.warn(f"MuJoCo: {' '.join(line.split())}")
    try:
        return importer.run()
    except importer.mj.FatalError as e:  # MuJoCo's own limits (its memory arena, ...): one line too
        raise MjcfError(f"{shown}: MuJoCo could not compute the model ({printable(' '.join(str(e).split()))[:300]})") from None


FOLD = 3  # warnings of one kind printed one by one; beyond, one line says how many more


def fold(warnings: list[str]) -> list[str]:
    """``warnings`` with those that differ only in the names they quote ('s0', 's1', ...) folded
    into their first, which then says how many more there were and names a few: a model of 1,500
    static bodies gave 1,500 lines. Order of first appearance kept."""
    groups: dict[str, list[str]] = {}
    for line in warnings:
        groups.setdefault(re.sub(r"'[^']*'", "'*'", line), []).append(line)
    out = []
    for lines in groups.values():
        if len(lines) <= FOLD:
            out.extend(lines)
            continue
        names = [m.group() for m in (re.search(r"'[^']*'", x) for x in lines[1:]) if m]
        shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
        out.append(f"{lines[0]} (and {len(lines) - 1:,} more like it: {shown})")
    return out


# -- compiling -------------------------------------------------------------------------------------


def _compile(path: Path, shown: str) -> tuple[Any, list[str]]:
    """(MjModel, MuJoCo's warnings), or MjcfError. The warnings are caught rather than left to
    MuJoCo's handler, which prints them and writes MUJOCO_LOG.TXT into the current folder."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise MjcfError(f"{shown}: no such file") from None
    except OSError as e:
        raise MjcfError(f"{shown}: cannot read ({e.strerror or e})") from None
    if not stat.S_ISREG(mode):
        raise MjcfError(f"{shown}: expected an MJCF file, got {'a directory' if stat.S_ISDIR(mode) else 'not a regular file'}")
    import mujoco

    mj: Any = mujoco  # compiled bindings: nothing a type checker can read
    said: list[str] = []
    handler = mj.get_mju_user_warning()
    mj.set_mju_user_warning(said.append)
    try:
        return mj.MjModel.from_xml_path(str(path)), said
    except ValueError as e:  # MuJoCo's parser and compiler: several lines, with the element and line
        lines = [s.strip() for s in str(e).splitlines() if s.strip()]
        raise MjcfError(f"{shown}: expected a MuJoCo model, got {printable('; '.join(lines)) or 'an error'}") from None
    finally:
        mj.set_mju_user_warning(handler)


# -- geometry --------------------------------------------------------------------------------------


def _hull(points: Iterable[tuple[float, float]], tol: float = 1e-9) -> list[tuple[float, float]]:
    """Convex hull, counter-clockwise, without collinear points (Andrew's monotone chain)."""
    pts = sorted(set((round(x, 12), round(y, 12)) for x, y in points))
    if len(pts) <= 2:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= tol:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= tol:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def _ellipse(centre: np.ndarray, S: np.ndarray, n: int = 8) -> list[tuple[float, float]]:
    """``n`` points on the ellipse {centre + A u : |u| = 1}, A A^T = S (2 x 2), from its major axis."""
    w, v = np.linalg.eigh(S)
    A = v @ np.diag(np.sqrt(np.maximum(w, 0.0)))
    t = np.arange(n) * 2 * math.pi / n
    return [(float(p[0]), float(p[1])) for p in (centre + A @ np.array([math.cos(a), math.sin(a)]) for a in t)]


_P = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # world (x, y, z) -> the plane (x, z)


def geom_outline(kind: str, size: np.ndarray, pos: np.ndarray, mat: np.ndarray) -> list[tuple[float, float]] | None:
    """A geom's outline projected onto the x-z plane, in world (x, z) (m): its corners, ends and
    sides (see the module docstring), counter-clockwise; None for a kind without one (mesh,
    height field, plane, SDF). ``size``: MuJoCo's ``geom_size``; ``pos``, ``mat``: its world
    position [3] and rotation [3, 3] (``geom_xpos``, ``geom_xmat``)."""
    c = _P @ pos
    R = mat.reshape(3, 3)
    if kind == "sphere":
        return _hull(_ellipse(c, size[0] ** 2 * np.eye(2)))
    if kind == "ellipsoid":
        A = _P @ R @ np.diag(size[:3])
        return _hull(_ellipse(c, A @ A.T))
    if kind == "box":
        corners = [pos + R @ (np.array([sx, sy, sz]) * size[:3]) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
        return _hull(tuple(_P @ p) for p in corners)
    if kind in ("capsule", "cylinder"):
        r, h = float(size[0]), float(size[1])
        axis = _P @ R[:, 2]  # the geom's z axis is its axis, MuJoCo's convention
        length = float(np.hypot(*axis))
        if length * h < 1e-6 * max(r, 1e-9):  # seen end on: a disc
            return _hull(_ellipse(c, r * r * np.eye(2)))
        u = axis / length
        n = np.array([-u[1], u[0]])
        a, b = c - h * axis, c + h * axis
        pts = [a + r * n, a - r * n, b + r * n, b - r * n]
        if kind == "capsule":
            pts += [a - r * u, b + r * u]  # its two ends
        else:  # a cylinder's rims, seen at a slant, are ellipses: their extreme points
            out = r * abs(float(R[1, 2]))  # how far the rim discs open up in the plane
            pts += [a - out * u, b + out * u] if out > 1e-9 else []
        return _hull(tuple(p) for p in pts)
    return None


# -- the importer ----------------------------------------------------------------------------------


def _num(x: float) -> str:
    """A number for the file: 10 significant digits (below any tolerance in it), no '-0'."""
    x = float(x)
    if abs(x) < 1e-12:
        return "0"
    return f"{x:.10g}"  # an integral value prints as a TOML integer, which the loader takes as a number


def _pt(p: Iterable[float]) -> str:
    x, y = p
    return f"[{_num(x)}, {_num(y)}]"


def _pts(ps: Iterable[Iterable[float]]) -> str:
    return "[" + ", ".join(_pt(p) for p in ps) + "]"


def _q(s: str) -> str:
    """A TOML basic string; every control character escaped (TOML allows none raw in one)."""
    body = s.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + "".join(f"\\u{ord(c):04x}" if ord(c) < 0x20 or 0x7F <= ord(c) < 0xA0 else c for c in body) + '"'


@dataclass
class _Link:
    name: str
    body: int  # the MuJoCo body id (the top of its weld group)
    bodies: list[int]  # every body merged into it
    origin: np.ndarray  # world (x, z) of the frame origin at qpos0
    parent: _Link | None = None
    joint: int | None = None  # its hinge (jointed links), or the root's hinge (free roots)
    sign: float = 1.0  # sanlab angle = sign (qpos - qpos0)
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(2))  # world (x, z)
    inertia: float = 0.0
    outline: list[tuple[float, float]] = field(default_factory=list)  # world (x, z)
    contacts: list[tuple[float, float]] = field(default_factory=list)  # world (x, z)
    contact_geoms: list[int] = field(default_factory=list)  # the geom of each contact
    geoms: list[int] = field(default_factory=list)
    children: list[_Link] = field(default_factory=list)
    spring: tuple[float, float, float] | None = None  # (k N m/rad, c N m s/rad, rest rad)
    limit: tuple | None = None  # (min rad, max rad, k N m/rad, c N m s/rad, solreflimit, joint inertia kg m^2)
    friction: float | None = None  # its own, where it differs from the floor's
    notes: list[str] = field(default_factory=list)  # comments above the link

    def local(self, p) -> tuple[float, float]:
        """A world (x, z) point in this link's frame (aligned with the world at qpos0)."""
        return (float(p[0] - self.origin[0]), float(p[1] - self.origin[1]))


class _Importer:
    def __init__(self, m: Any, shown: str, filename: str):
        import mujoco

        self.mj: Any = mujoco
        # the file's name goes into comments and strings of the creature file: printable there
        self.m, self.shown, self.filename = m, shown, printable(filename)
        self.d = self.mj.MjData(m)
        self.d.qpos[:] = m.qpos0
        self.mj.mj_kinematics(m, self.d)
        self.warnings: list[str] = []
        self.links: list[_Link] = []
        self.by_body: dict[int, _Link] = {}
        self.notes: list[str] = []  # lines for the file's header

    # -- names and messages

    def raw_name(self, kind: str, i: int) -> str:
        """The MJCF name of element ``i`` of ``kind`` (body, joint, geom, actuator, sensor; model:
        the model's), "" if it has none. Raises MjcfError naming the element for a name that is
        not UTF-8 (MuJoCo compiles one; its bindings then raise UnicodeDecodeError) or holds a
        control or format character (a newline would end a line of the creature file)."""
        m = self.m
        start = 0 if kind == "model" else int({"body": m.name_bodyadr, "joint": m.name_jntadr, "geom": m.name_geomadr,
                                                "actuator": m.name_actuatoradr, "sensor": m.name_sensoradr}[kind][i])
        raw = bytes(m.names[start : m.names.index(b"\0", start)]) if m.names else b""
        element = "the model's name (<mujoco model=...>)" if kind == "model" else f"the name of {kind} {i} (<{kind}>)"
        try:
            name = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            raise self.fail(f"{element}: expected UTF-8 text, got {raw!r} (undecodable at byte {e.start}; save the model "
                            "as UTF-8)") from None
        if not name.isprintable():
            raise self.fail(f"{element}: expected a printable name (no newline, tab or escape sequence), got {name!r}")
        return name

    def name(self, kind: str, i: int) -> str:
        return self.raw_name(kind, i) or f"{kind}{i}"

    def fail(self, what: str) -> MjcfError:
        return MjcfError(f"{self.shown}: {printable(what)}")

    def warn(self, what: str) -> None:
        self.warnings.append(printable(what))

    def geom_kind(self, g: int) -> str:
        return self.mj.mjtGeom(int(self.m.geom_type[g])).name[len("mjGEOM_"):].lower()

    def joint_kind(self, j: int) -> str:
        return self.mj.mjtJoint(int(self.m.jnt_type[j])).name[len("mjJNT_"):].lower()

    # -- the steps

    def run(self) -> tuple[str, list[str]]:
        m = self.m
        g = np.asarray(m.opt.gravity, float)
        if abs(g[0]) > 1e-9 or abs(g[1]) > 1e-9 or g[2] > 0:
            self.warn(f"gravity {tuple(float(x) for x in g)}: sanlab's pulls along -z only; its magnitude "
                      f"{float(np.linalg.norm(g)):g} m/s^2 kept, its direction dropped")
        self.gravity = float(np.linalg.norm(g))
        self.floor = self._floor()
        self._bodies()
        if not self.links:
            raise self.fail("expected at least one moving body (a body with joints under the world body), got none")
        self._mass_properties()
        self._geoms()
        self._joints()
        self.evaluation = self._evaluation()
        self.actuators = self._actuators()
        self.sensors = self._sensors()
        self._leftovers()
        self._snap()
        self.ground = self._ground()
        for link in self.links:
            link.friction = self._friction(link, self.ground["friction"])
        self.dt = min(max(float(m.opt.timestep), 1e-5), 0.01)
        if self.dt != float(m.opt.timestep):
            self.warn(f"timestep {float(m.opt.timestep):g} s: outside sanlab's [1e-05, 0.01] s, {self.dt:g} s used")
        self.warnings = fold(self.warnings)
        text = self._write()
        try:
            loads(text, self.filename)
        except CreatureError as e:  # a limit of the format (too many links, contacts...), said as the loader says it
            raise self.fail(f"cannot be written as a creature file ({e})") from None
        return text, self.warnings

    def _floor(self) -> int | None:
        """The floor: a plane geom of the world body facing +z (the highest, if several)."""
        m = self.m
        planes = [g for g in range(m.ngeom) if m.geom_bodyid[g] == 0 and self.geom_kind(g) == "plane"]
        if not planes:
            self.warn("no floor (a plane of the world body): sanlab's ground is the plane z = 0")
            return None
        upright = [g for g in planes if float(self.d.geom_xmat[g].reshape(3, 3)[2, 2]) > 1 - 1e-9]
        if not upright:
            self.warn(f"floor {self.name('geom', planes[0])!r} is tilted: sanlab's ground is level (z = its height)")
            upright = planes
        return max(upright, key=lambda g: float(self.d.geom_xpos[g][2]))

    @property
    def floor_z(self) -> float:
        return 0.0 if self.floor is None else float(self.d.geom_xpos[self.floor][2])

    def xz(self, p) -> np.ndarray:
        """World (x, y, z) -> sanlab (x, y): the x-z plane, heights from the floor."""
        return np.array([float(p[0]), float(p[2]) - self.floor_z])

    def _bodies(self) -> None:
        """One link per body with joints, the bodies welded to it merged in; planarity checked."""
        m = self.m
        for b in range(1, m.nbody):
            joints = list(range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])) if m.body_jntnum[b] else []
            parent = int(m.body_parentid[b])
            weld = int(m.body_weldid[b])
            if not joints:
                if weld == 0:
                    if any(m.geom_bodyid[g] == b for g in range(m.ngeom)):
                        self.warn(f"body {self.name('body', b)!r} is fixed to the world: static scenery, not carried over "
                                  "(sanlab's world is its ground)")
                    continue
                link = self.by_body[weld]
                link.bodies.append(b)
                self.by_body[b] = link
                continue
            if parent == 0 or int(m.body_weldid[parent]) == 0:
                self.links.append(self._root(b, joints))
            else:
                self.links.append(self._jointed(b, joints, self.by_body[int(m.body_weldid[parent])]))
            self.by_body[b] = self.links[-1]

    def _axis(self, j: int) -> np.ndarray:
        return np.asarray(self.d.xaxis[j], float)

    def _about_y(self, j: int) -> float | None:
        """+1 for a hinge about -y (sanlab's sign), -1 about +y, None otherwise."""
        a = self._axis(j)
        if abs(a[0]) < PLANE_TOL and abs(a[2]) < PLANE_TOL:
            return 1.0 if a[1] < 0 else -1.0
        return None

    def _planar_error(self, j: int, what: str) -> MjcfError:
        a = ", ".join(f"{float(x):.3g}" for x in self._axis(j))
        return self.fail(f"joint {self.name('joint', j)!r} ({self.joint_kind(j)}, axis ({a}) at qpos0): expected {what}; "
                         "not a planar model in the x-z plane (sanlab's plane)")

    def _root(self, b: int, joints: list[int]) -> _Link:
        name = self.name("body", b)
        kinds = [self.joint_kind(j) for j in joints]
        if kinds == ["free"]:
            j = joints[0]
            self.warn(f"joint {self.name('joint', j)!r} (free) of body {name!r}: a free body in the x-z plane; its motion "
                      "out of the plane (along y, turning about x and z) is dropped")
            link = _Link(name, b, [b], self.xz(self.d.xpos[b]))
            link.notes.append(f"body {name!r}: a free joint ({self.name('joint', j)!r}), imported as a free body in the plane")
            return link
        hinges = [j for j, k in zip(joints, kinds) if k == "hinge"]
        slides = [j for j, k in zip(joints, kinds) if k == "slide"]
        for j, k in zip(joints, kinds):
            if k not in ("hinge", "slide"):
                raise self._planar_error(j, "two slides in the x-z plane and a hinge about y, or one free joint, on a root")
        for j in slides:
            if abs(self._axis(j)[1]) > PLANE_TOL:
                raise self._planar_error(j, "a slide in the x-z plane")
        for j in hinges:
            if self._about_y(j) is None:
                raise self._planar_error(j, "a hinge about the plane's normal y")
        if len(slides) != 2 or len(hinges) != 1 or abs(float(np.cross(self._axis(slides[0]), self._axis(slides[1]))[1])) < 1e-6:
            got = ", ".join(f"{self.name('joint', j)!r} ({k})" for j, k in zip(joints, kinds))
            raise self.fail(f"body {name!r} hangs from the world by {got}: expected two slides spanning the x-z plane and "
                            "a hinge about y (as Gymnasium's rootx, rootz, rooty), or one free joint; sanlab's roots "
                            "move freely in the plane")
        h = hinges[0]
        link = _Link(name, b, [b], self.xz(self.d.xanchor[h]), joint=h, sign=float(self._about_y(h) or 1.0))
        link.notes.append(f"body {name!r}: the root, free in the plane (joints "
                          + ", ".join(repr(self.name("joint", j)) for j in joints) + f"); its frame's origin is hinge "
                          f"{self.name('joint', h)!r}")
        for j in joints:
            self._root_joint_leftovers(j)
        return link

    def _root_joint_leftovers(self, j: int) -> None:
        m, dof = self.m, int(self.m.jnt_dofadr[j])
        lost = [(what, float(v)) for what, v in (("damping", m.dof_damping[dof]), ("armature", m.dof_armature[dof]),
                                                 ("stiffness", m.jnt_stiffness[j]), ("frictionloss", m.dof_frictionloss[dof]))
                if float(v) != 0.0]
        if m.jnt_limited[j]:
            lost.append(("range", float("nan")))
        if lost:
            self.warn(f"root joint {self.name('joint', j)!r}: " + ", ".join(w if math.isnan(v) else f"{w} {v:g}" for w, v in lost)
                      + " not carried over (a sanlab root has no joint to hold them)")

    def _jointed(self, b: int, joints: list[int], parent: _Link) -> _Link:
        name = self.name("body", b)
        if len(joints) > 1:
            names = ", ".join(repr(self.name("joint", j)) for j in joints)
            raise self.fail(f"body {name!r} has joints {names}: expected one hinge about y below the root "
                            "(a sanlab link turns about one joint)")
        j = joints[0]
        if self.joint_kind(j) != "hinge":
            raise self._planar_error(j, "a hinge about y (below the root, sanlab's joints are hinges)")
        sign = self._about_y(j)
        if sign is None:
            raise self._planar_error(j, "a hinge about the plane's normal y")
        link = _Link(name, b, [b], self.xz(self.d.xanchor[j]), parent=parent, joint=j, sign=sign)
        parent.children.append(link)
        return link

    def _mass_properties(self) -> None:
        m, d = self.m, self.d
        for link in self.links:
            masses = np.array([float(m.body_mass[b]) for b in link.bodies])
            coms = np.array([self.xz(d.xipos[b]) for b in link.bodies])
            M = float(masses.sum())
            if M <= 0:
                raise self.fail(f"body {link.name!r}: expected a positive mass, got {M:g} kg")
            C = (masses[:, None] * coms).sum(0) / M
            inertia = 0.0
            for b, mb, cb in zip(link.bodies, masses, coms):
                R = np.asarray(d.ximat[b], float).reshape(3, 3)
                I = R @ np.diag(np.asarray(m.body_inertia[b], float)) @ R.T
                inertia += float(I[1, 1]) + mb * float(np.sum((cb - C) ** 2))  # parallel axes, in the plane
            link.mass, link.com, link.inertia = M, C, inertia
            if len(link.bodies) > 1:
                link.notes.append("with " + ", ".join(repr(self.name("body", b)) for b in link.bodies[1:])
                                  + " welded to it (no joint): one link, masses and inertias combined")

    def _collides_with_floor(self, g: int) -> bool:
        m = self.m
        if self.floor is None:  # sanlab's ground stands in for a floor every geom could touch
            return bool(m.geom_contype[g] or m.geom_conaffinity[g])
        f = self.floor
        if not ((m.geom_contype[g] & m.geom_conaffinity[f]) or (m.geom_contype[f] & m.geom_conaffinity[g])):
            return False
        b = int(m.geom_bodyid[g])
        signature = ((0 + 1) << 16) + b + 1 if 0 < b else 0  # MuJoCo's exclude_signature of (world, body)
        return not (m.nexclude and signature in set(int(s) for s in m.exclude_signature))

    def _geoms(self) -> None:
        m, d = self.m, self.d
        margins = []
        for g in range(m.ngeom):
            b = int(m.geom_bodyid[g])
            if b not in self.by_body:
                continue
            link = self.by_body[b]
            kind = self.geom_kind(g)
            outline = geom_outline(kind, np.asarray(m.geom_size[g], float), np.asarray(d.geom_xpos[g], float),
                                   np.asarray(d.geom_xmat[g], float))
            if outline is None:
                self.warn(f"geom {self.name('geom', g)!r} ({kind}) of body {self.name('body', b)!r}: no outline or contact "
                          "points (only capsules, boxes, spheres, cylinders and ellipsoids are projected onto the plane)")
                continue
            outline = [(float(p[0]), float(p[1]) - self.floor_z) for p in outline]
            link.geoms.append(g)
            link.outline += outline
            if self._collides_with_floor(g):
                for p in outline:
                    if not any(math.dist(p, c) < 1e-9 for c in link.contacts):
                        link.contacts.append(p)
                        link.contact_geoms.append(g)
                if float(m.geom_margin[g]) > 0 or float(m.geom_gap[g]) > 0:
                    margins.append(float(m.geom_margin[g]))
        if margins:
            self.warn(f"contact margin up to {max(margins):g} m on {len(margins)} geoms: not carried over (sanlab's "
                      "contacts start at the outline)")
        for link in self.links:
            # On level ground the lowest point of a convex body is a corner of its hull: contact
            # points inside the hull of the colliding geoms (an end buried in a sphere) never touch.
            corners = _hull(link.contacts)
            keep = [i for i, c in enumerate(link.contacts) if len(corners) < 3 or any(math.dist(c, h) < 1e-9 for h in corners)]
            link.contacts = [link.contacts[i] for i in keep]
            link.contact_geoms = [link.contact_geoms[i] for i in keep]
            hull = _hull(link.outline)
            if len(hull) < 3:  # no geom, or a flat one seen edge on: a segment from the joint to the COM
                far = max(hull, key=lambda p: math.dist(p, link.origin), default=tuple(link.com))
                if math.dist(far, link.origin) < 1e-6:
                    far = (link.origin[0] + 0.01, link.origin[1])
                hull = [tuple(link.origin), far]
            link.outline = hull
        self._self_collision()

    def _self_collision(self) -> None:
        m = self.m
        geoms = [(g, self.by_body[int(m.geom_bodyid[g])]) for lk in self.links for g in lk.geoms]
        for i, (g1, l1) in enumerate(geoms):
            for g2, l2 in geoms[i + 1:]:
                if l1 is l2 or l1.parent is l2 or l2.parent is l1:  # MuJoCo filters parent and child
                    continue
                if (m.geom_contype[g1] & m.geom_conaffinity[g2]) or (m.geom_contype[g2] & m.geom_conaffinity[g1]):
                    self.warn(f"geoms of different bodies collide with each other in MuJoCo (e.g. {self.name('geom', g1)!r} "
                              f"and {self.name('geom', g2)!r}): sanlab has no self-collision, its links pass through each other")
                    return

    def _effective_inertia(self) -> np.ndarray:
        """Each dof's diagonal of the mass matrix at qpos0, without armature (kg m^2 for a hinge)."""
        m = self.m
        armature = np.array(m.dof_armature, copy=True)
        m.dof_armature[:] = 0.0
        try:
            d = self.mj.MjData(m)
            d.qpos[:] = m.qpos0
            # the mass matrix only: mj_forward would also run collision detection, whose arena a
            # model of thousands of static geoms overflows (mujoco.FatalError: mj_stackAlloc)
            self.mj.mj_kinematics(m, d)
            self.mj.mj_comPos(m, d)
            make_m = getattr(self.mj, "mj_makeM", None)  # MuJoCo >= 3.2; before, mj_crb fills qM
            make_m(m, d) if make_m is not None else self.mj.mj_crb(m, d)
            diag = np.zeros(m.nv)
            for i in range(m.nv):  # mj_mulM: the same call in MuJoCo 3 and 4 (mj_fullM's changed)
                e, out = np.zeros(m.nv), np.zeros(m.nv)
                e[i] = 1.0
                self.mj.mj_mulM(m, d, out, e)
                diag[i] = out[i]
        finally:
            m.dof_armature[:] = armature
        return diag

    @staticmethod
    def _spring_damper(solref: np.ndarray, inertia: float) -> tuple[float, float]:
        """(stiffness, damping) of MuJoCo's soft constraint ``solref`` on ``inertia`` (kg or kg m^2):
        the mass-spring-damper of time constant tc and damping ratio zeta, k = I / (tc zeta)^2 and
        c = 2 I / tc (MuJoCo, "Computation", solver parameters, with the impedance at its maximum);
        a negative solref is (-k, -c) per unit of inertia."""
        tc, zeta = float(solref[0]), float(solref[1])
        if tc < 0:
            return -tc * inertia, max(-zeta, 0.0) * inertia
        tc = max(tc, 1e-4)
        return inertia / (tc * max(zeta, 1e-3)) ** 2, 2 * inertia / tc

    def _joints(self) -> None:
        m = self.m
        diag = self._effective_inertia()
        armature: dict[float, list[str]] = {}
        friction: list[str] = []
        self.limits: dict[str, tuple[float, float]] = {}  # link -> sanlab (min, max) rad
        for link in self.links:
            if link.parent is None or link.joint is None:
                continue
            j = link.joint
            dof, adr = int(m.jnt_dofadr[j]), int(m.jnt_qposadr[j])
            q0, s, jn = float(m.qpos0[adr]), link.sign, self.name("joint", j)
            if float(m.dof_armature[dof]) > 0:
                armature.setdefault(float(m.dof_armature[dof]), []).append(jn)
            if float(m.dof_frictionloss[dof]) > 0:
                friction.append(jn)
            k, c = float(m.jnt_stiffness[j]), float(m.dof_damping[dof])
            if k > 0 or c > 0:
                rest = s * (float(m.qpos_spring[adr]) - q0)
                link.spring = (k, c, rest)
            if m.jnt_limited[j]:
                lo, hi = sorted((s * (float(m.jnt_range[j][0]) - q0), s * (float(m.jnt_range[j][1]) - q0)))
                ks, kd = self._spring_damper(np.asarray(m.jnt_solref[j], float), float(diag[dof]))
                link.limit = (lo, hi, ks, kd, tuple(float(x) for x in m.jnt_solref[j][:2]), float(diag[dof]))
                self.limits[link.name] = (lo, hi)
        for value, names in armature.items():
            self.warn(f"armature {value:g} kg m^2 on joint{'s' * (len(names) > 1)} {', '.join(names)}: not carried over "
                      "(sanlab has no rotor inertia), so these joints are livelier than in MuJoCo")
        if friction:
            self.warn(f"frictionloss on joint{'s' * (len(friction) > 1)} {', '.join(friction)}: not carried over (sanlab's "
                      "joints have no dry friction)")

    def _actuators(self) -> list[dict]:
        m, out, driven = self.m, [], set()
        hinge_link = {lk.joint: lk for lk in self.links if lk.parent is not None}
        for a in range(m.nu):
            trn, j = int(m.actuator_trntype[a]), int(m.actuator_trnid[a][0])
            an = self.raw_name("actuator", a) or (self.name("joint", j) if trn == int(self.mj.mjtTrn.mjTRN_JOINT) else f"actuator{a}")
            if trn != int(self.mj.mjtTrn.mjTRN_JOINT) or j not in hinge_link:
                what = "a tendon, site or body" if trn != int(self.mj.mjtTrn.mjTRN_JOINT) else f"root joint {self.name('joint', j)!r}"
                self.warn(f"actuator {an!r} drives {what}: not carried over (sanlab's servos drive hinges below the root)")
                continue
            link = hinge_link[j]
            if link.name in driven:
                self.warn(f"actuator {an!r}: a second actuator on joint {self.name('joint', j)!r}, not carried over "
                          "(sanlab drives a joint with one servo)")
                continue
            gear = float(m.actuator_gear[a][0])
            gain, bias = np.asarray(m.actuator_gainprm[a], float), np.asarray(m.actuator_biasprm[a], float)
            gt, bt, dyn = int(m.actuator_gaintype[a]), int(m.actuator_biastype[a]), int(m.actuator_dyntype[a])
            if gt != 0 or dyn not in (0,) or gear == 0:
                self.warn(f"actuator {an!r}: its gain or activation dynamics (muscle, filter, integrator) are not carried "
                          "over (sanlab's servos are PD laws on a target)")
                continue
            ctrl = np.asarray(m.actuator_ctrlrange[a], float) if m.actuator_ctrllimited[a] else None
            s, q0 = link.sign, float(m.qpos0[int(m.jnt_qposadr[j])])
            rng = self.limits.get(link.name)
            span = math.radians(min(TARGET_SPAN_DEG, self.evaluation["fell_angle_deg"]))
            targets = (max(rng[0], -span), min(rng[1], span)) if rng is not None else (-span, span)
            if targets[1] - targets[0] < 1e-6:  # qpos0 outside the range: the range itself
                targets = rng or (-span, span)
            if bt == 0 and gain[0] != 0:  # a motor: force = gain ctrl, torque = gear force
                if ctrl is None and not m.actuator_forcelimited[a]:
                    self.warn(f"actuator {an!r}: no ctrlrange or forcerange, so its peak torque is taken at |ctrl| = 1")
                peak_force = abs(gain[0]) * (float(np.max(np.abs(ctrl))) if ctrl is not None else 1.0)
                if m.actuator_forcelimited[a]:
                    peak_force = min(peak_force, float(np.max(np.abs(m.actuator_forcerange[a]))))
                peak = abs(gear) * peak_force
                ks = peak / math.radians(SERVO_ERROR_DEG)
                how = (f"motor, gear {gear:g}, ctrlrange [{', '.join(f'{c:g}' for c in ctrl)}]" if ctrl is not None else
                       f"motor, gear {gear:g}") + f": peak torque {peak:.4g} N m at a {SERVO_ERROR_DEG:g} deg error"
                out.append({"name": an, "joint": link.name, "min": targets[0], "max": targets[1], "ks": ks, "kd": KD_OVER_KS * ks,
                            "how": how, "jname": self.name("joint", j)})
            elif bt == 1 and gain[0] > 0 and abs(bias[1] + gain[0]) <= 1e-9 * gain[0] and bias[0] == 0:
                kp, kv = gain[0], -bias[2]  # a position servo: force = kp (ctrl - gear q) - kv gear qdot
                lo, hi = targets
                if ctrl is not None:  # its targets, in qpos units (MuJoCo never converts ctrlrange to radians)
                    lo, hi = sorted((s * (ctrl[0] / gear - q0), s * (ctrl[1] / gear - q0)))
                    inside = (max(lo, rng[0]), min(hi, rng[1])) if rng is not None else (lo, hi)
                    if inside[1] - inside[0] < 1e-9 or max(abs(inside[0]), abs(inside[1])) > math.pi:
                        self.warn(f"actuator {an!r}: its target range [{math.degrees(lo):.4g}, {math.degrees(hi):.4g}] "
                                  "deg leaves the joint's range or [-180, 180]; clipped")
                        inside = (max(inside[0], -math.pi), min(inside[1], math.pi))
                        if inside[1] - inside[0] < 1e-9:
                            inside = targets
                    lo, hi = inside
                out.append({"name": an, "joint": link.name, "min": lo, "max": hi, "ks": kp * gear * gear,
                            "kd": max(kv, 0.0) * gear * gear, "how": f"position servo, kp {kp:g}, kv {kv:g}, gear {gear:g}",
                            "jname": self.name("joint", j)})
                if m.actuator_forcelimited[a]:
                    self.warn(f"actuator {an!r}: its forcerange is not carried over (sanlab's servos are not saturated)")
            else:
                self.warn(f"actuator {an!r}: neither a motor nor a position servo (its bias or gain), not carried over")
                continue
            driven.add(link.name)
        return out

    def _evaluation(self) -> dict:
        """The fall test: Gymnasium's, for its models, else the root tilted past 90 degrees."""
        roots = [lk for lk in self.links if lk.parent is None]
        root = roots[0]
        model = self.raw_name("model", 0)
        gym = GYMNASIUM.get(model)
        ev: dict[str, Any] = {"metric": "distance_upright", "direction": "forward", "fell_link": root.name,
                              "fell_angle_deg": 90.0, "why": [], "height": None}
        if gym is not None and gym["root"] == root.name and root.joint is not None:
            lo, hi = (root.sign * a for a in gym["angle"])
            lo, hi = sorted((lo, hi))
            angle = min(abs(lo), abs(hi))
            if abs(lo + hi) > 1e-9:
                self.warn(f"{gym['env']}'s healthy angle range ({gym['angle'][0]:g}, {gym['angle'][1]:g}) rad is not "
                          f"symmetric: the fall angle is +-{angle:g} rad")
            zmin, zmax = gym["z"]
            # Gymnasium tests qpos of rootz, the height of the root's frame; sanlab, the height of its COM.
            offset = float(self.xz(self.d.xpos[root.body])[1] - root.com[1])
            ev["fell_angle_deg"] = math.degrees(angle)
            ev["height"] = zmin - offset
            ev["why"] = [f"Gymnasium's {gym['env']} ends an episode once the torso leaves its \"healthy\" range: height "
                         f"(qpos of the root's z slide) in ({zmin:g}, {zmax:g}) m and angle in "
                         f"({gym['angle'][0]:g}, {gym['angle'][1]:g}) rad; here the same on the torso's centre of mass."]
            if math.isfinite(zmax):
                self.warn(f"{gym['env']}'s healthy height has an upper bound ({zmax:g} m): not carried over (sanlab's fall "
                          "test has a lower bound only)")
        else:
            ev["why"] = ["Not one of Gymnasium's models with a fall test: the root tilting past 90 degrees is a fall."]
        return ev

    def _sensors(self) -> list[dict]:
        out: list[dict] = []
        leaves = [lk for lk in self.links if not lk.children]
        for link in leaves:
            for g in link.geoms:
                idx = [i for i, gg in enumerate(link.contact_geoms) if gg == g]
                if not idx:
                    continue
                r = float(self.m.geom_size[g][0])
                low = min(link.contacts[i][1] for i in idx)
                near = [i for i in idx if link.contacts[i][1] <= low + max(1e-3, 0.01 * r)]
                ends = sorted({min(near, key=lambda i: link.contacts[i][0]), max(near, key=lambda i: link.contacts[i][0])},
                              key=lambda i: link.contacts[i][0])
                gn = self.name("geom", g)
                for k, i in enumerate(ends):
                    where = "" if len(ends) == 1 else ("_back" if k == 0 else "_front")
                    out.append({"type": "touch", "name": f"{gn}{where}", "link": link.name, "contact": i,
                                "why": f"{'the ' + where[1:] + ' end of ' if where else ''}geom {gn!r}, lowest at qpos0"})
        servo = {a["joint"]: (a["min"], a["max"]) for a in self.actuators}
        for link in self.links:
            # The range the joint works in: its servo's targets, else its stops.
            if link.name not in servo and link.name not in self.limits:
                continue
            lo, hi = servo.get(link.name) or self.limits[link.name]
            span = hi - lo
            jn = self.name("joint", link.joint) if link.joint is not None else link.name
            lo_on = min(max(lo + SENSOR_FRACTION * span, -math.pi + 1e-6), math.pi)
            hi_on = max(min(hi - SENSOR_FRACTION * span, math.pi - 1e-6), -math.pi)
            out.append({"type": "angle", "name": f"{jn}_min", "link": link.name, "min": -math.pi, "max": lo_on,
                        "why": f"joint {jn!r} near the low end of its {'targets' if link.name in servo else 'range'}"})
            out.append({"type": "angle", "name": f"{jn}_max", "link": link.name, "min": hi_on, "max": math.pi,
                        "why": f"joint {jn!r} near the high end of its {'targets' if link.name in servo else 'range'}"})
        fell = math.radians(self.evaluation["fell_angle_deg"])
        root = self.by_body[self.links[0].body]
        if fell < math.pi / 2 + 1e-9 and root.parent is None:
            half = fell / 2
            out.append({"type": "angle", "name": f"{root.name}_back", "link": root.name, "min": half, "max": math.pi,
                        "why": f"{root.name} leaning back past half the fall angle (a balance organ)"})
            out.append({"type": "angle", "name": f"{root.name}_forward", "link": root.name, "min": -math.pi, "max": -half,
                        "why": f"{root.name} leaning forward past half the fall angle"})
        seen: set[str] = set()
        for s in out:  # names unique among sensors
            base, k = s["name"], 2
            while s["name"] in seen:
                s["name"], k = f"{base}_{k}", k + 1
            seen.add(s["name"])
        return out

    def _leftovers(self) -> None:
        m = self.m
        if m.nsensor:
            names = ", ".join(repr(self.name("sensor", i)) for i in range(min(m.nsensor, 5))) + (", ..." if m.nsensor > 5 else "")
            self.warn(f"{m.nsensor} MuJoCo sensor{'s' * (m.nsensor > 1)} ({names}): not carried over (the SAN's "
                      "binary sensors are made from the feet and joint ranges instead)")
        for count, what in ((m.ntendon, "tendons"), (m.neq, "equality constraints"), (m.npair, "explicit contact pairs"),
                            (m.nkey, "keyframes (the start pose is qpos0)")):
            if count:
                self.warn(f"{count} {what}: not carried over")
        if m.opt.density > 0 or m.opt.viscosity > 0:
            self.warn(f"fluid (density {m.opt.density:g}, viscosity {m.opt.viscosity:g}): not carried over (sanlab's water "
                      "drag, world.water_drag, is a different model)")
        integrator = self.mj.mjtIntegrator(int(m.opt.integrator)).name[len("mjINT_"):]
        if integrator != "EULER":
            self.warn(f"integrator {integrator}: sanlab steps with its own semi-implicit Euler")
        condim = [int(m.geom_condim[g]) for lk in self.links for g in lk.geoms if int(m.geom_condim[g]) > 3]
        if condim:
            self.warn(f"condim {max(condim)} (torsional or rolling friction): not carried over")

    def _snap(self) -> None:
        """Set a start pose hovering (or sunk) up to SNAP_GAP onto the floor: `sanlab check` calls
        a creature floating more than 1 cm a mistake, and MuJoCo models often start a few cm up."""
        lows = [p[1] for lk in self.links for p in lk.contacts]
        self.lowered = 0.0
        if not lows:
            return
        gap = min(lows)
        if abs(gap) <= 1e-9 or abs(gap) > SNAP_GAP:
            return
        self.lowered = gap
        if abs(gap) > 1e-3:
            self.warn(f"start pose: its lowest contact point is {gap * 100:.3g} cm {'above' if gap > 0 else 'below'} the "
                      f"floor at qpos0; the creature starts {'lowered' if gap > 0 else 'raised'} onto it")

    # -- writing

    def _ground(self) -> dict:
        m = self.m
        feet = [g for lk in self.links for g in lk.contact_geoms]
        f = self.floor
        mu_floor = float(m.geom_friction[f][0]) if f is not None else 1.0
        total = sum(lk.mass for lk in self.links)
        solrefs = []
        for g in sorted(set(feet)):
            if f is not None:
                w1, w2 = float(m.geom_solmix[g]), float(m.geom_solmix[f])
                mix = 0.5 if w1 + w2 <= 0 else w1 / (w1 + w2)
                solrefs.append(mix * np.asarray(m.geom_solref[g], float) + (1 - mix) * np.asarray(m.geom_solref[f], float))
            else:
                solrefs.append(np.asarray(m.geom_solref[g], float))
        solref = np.median(np.array(solrefs), axis=0) if solrefs else np.array([0.02, 1.0])
        k, c = self._spring_damper(solref, total / 2)
        return {"stiffness": k, "damping": c, "friction": mu_floor, "solref": solref, "mass": total}

    def _friction(self, link: _Link, mu_floor: float) -> float | None:
        m = self.m
        geoms = sorted(set(link.contact_geoms))
        if not geoms:
            return None
        mus = []
        for g in geoms:
            f = self.floor
            if f is not None and int(m.geom_priority[g]) != int(m.geom_priority[f]):
                mu = float(m.geom_friction[g][0] if m.geom_priority[g] > m.geom_priority[f] else m.geom_friction[f][0])
            else:
                mu = max(float(m.geom_friction[g][0]), mu_floor)
            if f is not None and max(int(m.geom_condim[g]), int(m.geom_condim[f])) == 1:
                mu = 0.0  # condim 1: frictionless contacts
            mus.append(mu)
        if max(mus) - min(mus) > 1e-12:
            self.warn(f"link {link.name!r}: its geoms' friction differs ({', '.join(f'{x:g}' for x in mus)}); sanlab's "
                      f"is one per link, the largest kept")
        mu = max(mus)
        return None if abs(mu - mu_floor) < 1e-12 else mu

    def _write(self) -> str:
        model = self.raw_name("model", 0)
        name = model or Path(self.filename).stem
        ground, dt, ev = self.ground, self.dt, self.evaluation
        L: list[str] = []
        w = L.append

        def say(text: str, indent: str = "") -> None:  # a comment paragraph, wrapped at 100 columns
            for k, line in enumerate(textwrap.wrap(text, 98 - len(indent), break_on_hyphens=False)):
                w(("# " if k == 0 else "# " + " " * len(indent)) + (indent if k == 0 else "") + line)

        say(f"Imported from {self.filename} (MuJoCo model {model!r}) by `sanlab import-mjcf` (sanlab {__version__}, "
            f"MuJoCo {self.mj.__version__}): every mass, inertia and position is what MuJoCo compiled, read at the "
            "model's reference pose qpos0. The format is in sanlab/creature/FORMAT.md; docs/mjcf.md says what is "
            "carried over and what is not.")
        w("#")
        say("Conventions: MuJoCo's x-z plane is sanlab's (x, y) plane (z up is y up). Every link's frame is drawn at "
            "qpos0 aligned with the world, its origin at its joint, so every joint angle is 0 in the model's reference "
            "pose. A sanlab angle is counter-clockwise, a rotation about -y: a hinge with axis (0, -1, 0) keeps the sign "
            "of its qpos (here in degrees), one about (0, 1, 0) flips it.")
        if self.warnings:
            w("#")
            w("# Not carried over (the warnings of the import):")
            for line in self.warnings:
                say(line, "- ")
        w("")
        w(f"name = {_q(name)}")
        w(f"description = {_q(f'MuJoCo model {model!r} from {self.filename}, imported by sanlab import-mjcf')}")
        w(f"dt = {_num(dt)}  # s, the model's timestep")
        w("")
        w("[world]")
        w('plane = "vertical"')
        w(f"gravity = {_num(self.gravity)}  # m/s^2")
        w("")
        w("[world.ground]")
        sr = ground["solref"]
        say(f"MuJoCo's soft contact (solref: time constant {sr[0]:.3g} s, damping ratio {sr[1]:.3g}) as a penalty "
            f"spring-damper of the same time constant and damping ratio for half the creature's {ground['mass']:.4g} kg "
            "on each of two contact points: k = m / (timeconst dampratio)^2, c = 2 m / timeconst.")
        w(f"stiffness = {_num(ground['stiffness'])}  # N/m")
        w(f"damping = {_num(ground['damping'])}  # N s/m")
        w(f"friction = {_num(ground['friction'])}  # the floor's; a link whose geoms have more says so (MuJoCo takes the larger)")
        w("")
        w("[evaluation]")
        for line in ev["why"]:
            say(line)
        say("The score is the distance moved forward (+x, where Gymnasium's reward points) without falling, in sanlab's "
            "default 6 s.")
        w(f"metric = {_q(ev['metric'])}")
        w(f"direction = {_q(ev['direction'])}")
        w(f"fell_link = {_q(ev['fell_link'])}")
        w(f"fell_angle_deg = {_num(ev['fell_angle_deg'])}")
        if ev["height"] is not None:
            w(f"fell_link_height = {_num(ev['height'])}  # m, its centre of mass above the ground")
        w("")
        w("# --- Links: one per MuJoCo body with a joint " + "-" * 52)
        for link in self.links:
            w("")
            w("[[links]]")
            for note in link.notes:
                say(note)
            geoms = ", ".join(f"{self.name('geom', g)} ({self.geom_kind(g)})" for g in link.geoms) or "none"
            w(f"name = {_q(link.name)}")
            w(f"mass = {_num(link.mass)}  # kg")
            w(f"shape = {_q('polygon' if len(link.outline) >= 3 else 'segment')}")
            say(f"the outline of its geoms, {geoms}, seen in the plane")
            w(f"points = {_pts(link.local(p) for p in link.outline)}")
            w(f"inertia = {_num(link.inertia)}  # kg m^2, about the centre of mass and the plane's normal")
            w(f"com = {_pt(link.local(link.com))}")
            w(f"contacts = {_pts(link.local(p) for p in link.contacts)}" + ("" if link.contacts else "  # no geom collides with the floor"))
            if link.friction is not None:
                w(f"friction = {{ forward = {_num(link.friction)}, backward = {_num(link.friction)} }}")
            if link.parent is None:
                w(f"position = {_pt((link.origin[0], link.origin[1] - self.lowered))}")
                continue
            assert link.joint is not None
            jn = self.name("joint", link.joint)
            axis = "(0, -1, 0): the angle is qpos" if link.sign > 0 else "(0, 1, 0): the angle is -qpos"
            w(f"parent = {_q(link.parent.name)}")
            w(f"anchor = {_pt(link.parent.local(link.origin))}  # joint {jn!r}, axis {axis}")
            if link.spring is not None:
                k, c, rest = link.spring
                w(f"spring = {{ stiffness = {_num(k / PER_DEG)}, damping = {_num(c / PER_DEG)}, rest_deg = {_num(math.degrees(rest))} }}"
                  f"  # {k:g} N m/rad, {c:g} N m s/rad")
            if link.limit is not None:
                lo, hi, ks, kd, solref, inertia = link.limit
                say(f"range as a stop: solreflimit ({solref[0]:g}, {solref[1]:g}), joint inertia {inertia:.4g} kg m^2 "
                    "without armature")
                w(f"limit = {{ min_deg = {_num(math.degrees(lo))}, max_deg = {_num(math.degrees(hi))}, "
                  f"stiffness = {_num(ks / PER_DEG)}, damping = {_num(kd / PER_DEG)} }}")
        if self.sensors:
            w("")
            w("# --- Sensors " + "-" * 84)
            say("Touch sensors on the feet (the lowest points at qpos0 of the colliding geoms of the links that end the "
                f"tree); two angle sensors per joint, on within {SENSOR_FRACTION:.0%} of its servo's target range (else "
                "its range) from either end; and on the root, leaning past half the fall angle.")
        for s in self.sensors:
            w("")
            w("[[sensors]]")
            w(f"name = {_q(s['name'])}  # {s['why']}")
            w(f"type = {_q(s['type'])}")
            w(f"link = {_q(s['link'])}")
            if s["type"] == "touch":
                w(f"contact = {s['contact']}")
            else:
                w(f"min_deg = {_num(math.degrees(s['min']))}")
                w(f"max_deg = {_num(math.degrees(s['max']))}")
        if self.actuators:
            w("")
            w("# --- Actuators " + "-" * 82)
            span = min(TARGET_SPAN_DEG, ev["fell_angle_deg"])
            say(f"A MuJoCo motor applies gear x ctrl. As a PD servo (paper §3.3) it gives the motor's peak torque |gear| x "
                f"max |ctrlrange| at a {SERVO_ERROR_DEG:g} degree error: ks = peak / {SERVO_ERROR_DEG:g} deg, kd = "
                f"{KD_OVER_KS:g} s x ks; it is not saturated, so a larger error gives more than the peak. Its targets stay "
                f"within {span:.4g} degrees of qpos0 (the smaller of {TARGET_SPAN_DEG:g} and the fall angle) inside the "
                "joint's range: a servo that can tilt the body past its fall angle by itself throws over nearly every "
                "random network. Widen min_deg and max_deg towards the limit for more.")
        for a in self.actuators:
            w("")
            w("[[actuators]]")
            say(a["how"])
            w(f"name = {_q(a['name'])}")
            w('type = "angular"')
            w(f"joint = {_q(a['joint'])}  # MuJoCo joint {a['jname']!r}")
            w(f"min_deg = {_num(math.degrees(a['min']))}")
            w(f"max_deg = {_num(math.degrees(a['max']))}")
            w(f"ks = {_num(a['ks'] / PER_DEG)}  # N m/deg")
            w(f"kd = {_num(a['kd'] / PER_DEG)}  # N m s/deg")
        return "\n".join(L) + "\n"
