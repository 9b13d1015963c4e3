"""Compile a creature spec into a model: static structure plus parameter arrays.

This is the paper's "dynamics compiler" (§3.4). Everything that decides the *shape* of the
computation (which link hangs from which, which dof moves which point, the kinds of sensors,
actuators, terrain) goes into :class:`Structure`, a hashable value; every number (masses,
lengths, gains, ranges, friction, terrain heights) goes into :class:`Params`, NumPy arrays, which
tuning and batching give a leading axis of rows. The kernel (``sim.kernel.pack``) reads both as
tables: nothing is compiled per creature.

Generalised coordinates. The links form trees, each hanging from a root link. A *free* tree's
coordinates are the world position of its centre of mass (x, y), its root link's absolute angle,
then one relative angle per joint; a point mass's are its (x, y); a tree whose root is welded to
the world (``fixed``) has only its joint angles. Using the centre of mass (rather than the root
link's origin) makes the translational dynamics exact and decoupled, m x'' = F_external: with no
external horizontal force the centre of mass cannot move along x, whatever the controller does
(``docs/simulator.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from sanlab.creature.spec import AngleSensor, Creature, LengthSensor, TiltSensor, Vec2

ROUGH_TERMS = 8  # sinusoids in rough terrain
FOLLOW_SAMPLES = 512  # arc-length table of the follow-point spline


@dataclass(frozen=True)
class LinkS:
    """Static facts about link ``index``.

    dof_x, dof_y: the translation dofs of its tree: the tree's centre of mass (a point mass's
    own position); -1 in a tree welded to the world.
    dof_rot: this link's own rotational dof (root angle or joint angle), -1 for a point mass and
    for a fixed root.
    chain: link indices from its root down to itself.
    tree: index into ``Structure.trees``.
    """

    index: int
    parent: int
    point: bool
    dof_x: int
    dof_y: int
    dof_rot: int
    chain: tuple[int, ...]
    tree: int = -1


@dataclass(frozen=True)
class TreeS:
    """One tree of links: its root, members (parents before children), whether it is free
    (centre-of-mass coordinates) or welded to the world, whether it is a lone point mass, and
    the links that own a rotational dof, in order."""

    root: int
    links: tuple[int, ...]
    free: bool
    point: bool
    rot: tuple[int, ...]


@dataclass(frozen=True)
class Structure:
    """The structure of a compiled creature (hashable): what the kernel's integer tables hold."""

    name: str
    ndof: int
    links: tuple[LinkS, ...]
    trees: tuple[TreeS, ...]
    contacts: tuple[int, ...]  # owning link of each contact point
    edges: tuple[int, ...]  # owning link of each water-drag edge
    sensors: tuple[tuple[str, int, int], ...]  # (kind, link or -1, index into that kind's params)
    actuators: tuple[tuple[str, int], ...]  # (kind, joint link index for angular / -1)
    lin_act: tuple[tuple[int, int], ...]  # (link a, link b) of each linear actuator
    springs: tuple[tuple[int, int], ...]  # (link a, link b) of each linear spring
    joint_springs: tuple[int, ...]  # links whose joint has a passive spring
    limits: tuple[int, ...]  # links whose joint has a mechanical stop
    aniso: tuple[tuple[int, int, int], ...]  # per link: (has override, axis from, axis to) or (0,-1,-1)
    eyes: tuple[tuple[int, int, int], ...]  # per eye: (link of eye point, axis from, axis to)
    lengths: tuple[tuple[int, int], ...]  # per length sensor: (link a, link b)
    plane: str
    terrain: str
    water: bool
    follow: bool
    follow_loop: bool
    # the step's length (s), for the host only (a duration in steps): the step reads
    # ``params.dt``, so it is no part of the structure's identity (the audit's dt/2, dt/4 share it)
    dt: float = field(compare=False, repr=False)
    # the step's linear algebra, O(n) articulated-body (True) or dense L D L^T (False); None: the
    # kernel's choice (articulated wherever it applies, ``sim.kernel.pack``)
    articulated: bool | None = None

    @property
    def n_sensors(self) -> int:
        return len(self.sensors)

    @property
    def n_actuators(self) -> int:
        return len(self.actuators)


@dataclass(frozen=True)
class Params:
    """Every number of a creature, as arrays (SI). Shapes: L links, C contacts, E edges,
    A actuators, S sensors, N linear springs, K rough terms, F follow samples."""

    mass: Any  # [L] kg
    inertia: Any  # [L] kg m^2 about the COM
    com: Any  # [L, 2] m, link frame
    anchor: Any  # [L, 2] m, parent frame (zeros for roots)
    root_pose: Any  # [L, 3] x, y, angle of each root at rest (m, rad); fixed roots stay there
    contact: Any  # [C, 2] m, link frame
    contact_load: Any  # [C] N, normal load in the horizontal plane
    edge: Any  # [E, 2, 2] m, link frame: start and end of each drag edge
    gravity: Any  # [] m/s^2
    ground_k: Any  # [] N/m
    ground_c: Any  # [] N s/m
    mu: Any  # [L, 3] forward, backward, lateral friction coefficient per link
    slip: Any  # [] m/s
    water_k: Any  # [] N s/m^2, normal drag
    water_t: Any  # [] N s/m^2, tangential (skin) drag
    jspring: Any  # [L, 3] stiffness N m/rad, damping N m s/rad, rest rad
    limit: Any  # [L, 4] joint stop: min rad, max rad, stiffness N m/rad, damping N m s/rad
    act_min: Any  # [A] rad or m
    act_max: Any  # [A]
    act_ks: Any  # [A] N m/rad or N/m
    act_kd: Any  # [A] N m s/rad or N s/m
    act_pts: Any  # [A, 2, 2] linear actuators' attachment points (link frames); zeros if angular
    spr_pts: Any  # [N, 2, 2]
    spr: Any  # [N, 3] stiffness N/m, damping N s/m, rest m
    sens_min: Any  # [S] rad or m (touch: unused)
    sens_max: Any  # [S]
    sens_pts: Any  # [S, 2, 2] eye point / length end points, link frames
    terrain: Any  # [4] slope tan, hill height, hill half width, hill centre
    rough: Any  # [K, 3] amplitude m, wavenumber rad/m, phase rad
    follow: Any  # [F, 2] m, points equally spaced in arc length
    follow_ds: Any  # [] m, arc length between samples
    follow_speed: Any  # [] m/s
    q0: Any  # [D] initial generalised coordinates (centre of mass of each free tree, angles)
    dt: Any  # [] s


@dataclass(frozen=True)
class Model:
    """A compiled creature: ``structure`` is static, ``params`` are arrays (one creature, or
    with a leading batch axis on any leaf when tuning)."""

    structure: Structure
    params: Params
    spec: Creature
    dtype: Any

    def with_params(self, **changes) -> "Model":
        return replace(self, params=replace(self.params, **changes))


def _catmull_rom(points: np.ndarray, loop: bool, per_seg: int = 64) -> np.ndarray:
    pts = np.asarray(points, float)
    if loop:
        ext = np.vstack([pts[-1:], pts, pts[:2]])
    else:
        ext = np.vstack([2 * pts[:1] - pts[1:2], pts, 2 * pts[-1:] - pts[-2:-1]])
    out = []
    for i in range(1, len(ext) - 2):
        p0, p1, p2, p3 = ext[i - 1], ext[i], ext[i + 1], ext[i + 2]
        t = np.linspace(0, 1, per_seg, endpoint=False)[:, None]
        out.append(
            0.5
            * (
                2 * p1
                + (-p0 + p2) * t
                + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                + (-p0 + 3 * p1 - 3 * p2 + p3) * t**3
            )
        )
    out.append(ext[-2 if not loop else 1][None])
    return np.vstack(out)


def follow_table(points, loop: bool, n: int = FOLLOW_SAMPLES) -> tuple[np.ndarray, float]:
    """Resample a Catmull-Rom spline through ``points`` at ``n`` points equally spaced in arc
    length. Returns (table [n, 2], spacing in m)."""
    dense = _catmull_rom(np.asarray(points, float), loop)
    seg = np.linalg.norm(np.diff(dense, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = max(s[-1], 1e-9)
    target = np.linspace(0.0, total, n)
    table = np.stack([np.interp(target, s, dense[:, 0]), np.interp(target, s, dense[:, 1])], 1)
    return table, total / (n - 1)


def rough_terms(height: float, wavelength: float, seed: int) -> np.ndarray:
    """Amplitudes, wavenumbers and phases of rough terrain with RMS ``height``."""
    rng = np.random.default_rng(seed)
    lam = wavelength * 2.0 ** np.linspace(3.0, 0.0, ROUGH_TERMS)  # 8x down to the shortest
    k = 2 * np.pi / lam
    amp = lam * rng.uniform(0.5, 1.0, ROUGH_TERMS)  # longer waves are taller
    amp = amp * (height / math.sqrt(0.5 * float(np.sum(amp**2))))
    phase = rng.uniform(0, 2 * np.pi, ROUGH_TERMS)
    return np.stack([amp, k, phase], 1)


def drag_edges(spec: Creature) -> list[tuple[int, Vec2, Vec2]]:
    """(link index, start, end) of every edge that feels water drag: a segment link's segment,
    each side of a polygon link (none without water, or for point masses)."""
    out = []
    if spec.world.water_drag > 0:
        for i, l in enumerate(spec.links):
            if not l.drag or l.shape.kind == "point":
                continue
            pts = list(l.shape.points)
            pairs = [(pts[0], pts[1])] if l.shape.kind == "segment" else list(zip(pts, pts[1:] + pts[:1]))
            out += [(i, a, b) for a, b in pairs]
    return out


def articulated_supported(spec: Creature) -> bool:
    """Whether the articulated route can step ``spec``: trees of rigid links only (no point
    masses, no linear springs or actuators, which join two bodies)."""
    return not (any(l.is_point for l in spec.links) or spec.springs
                or any(a.kind == "linear" for a in spec.actuators))


def assemble(spec: Creature, dtype: Any = "float64", articulated: bool | None = None) -> Model:
    """Build the static structure and parameter arrays (NumPy) of ``spec``, bodies where the file
    puts them (:func:`sanlab.sim.compiler.compile_creature` then seats them on the ground).

    dtype: "float64" (default) or "float32": the numbers rounded to it, and the arithmetic the
    kernel steps the model in (float32: the kernel's float32 instantiation, float32 throughout).
    articulated: the step's linear algebra, O(n) articulated-body (True) or dense (False); None
    (default) leaves it to the kernel (articulated wherever it applies). Raises ValueError for
    another dtype, or for True on a creature the articulated route does not support (see
    :func:`articulated_supported`).
    """
    try:
        dt_np = np.dtype(dtype)
    except TypeError:
        dt_np = None
    if dt_np is None or dt_np.name not in ("float32", "float64"):
        raise ValueError(f"dtype: expected float32 or float64, got {dtype!r}")
    names = {l.name: i for i, l in enumerate(spec.links)}
    links, trees, q0 = _trees(spec, names)
    ndof = len(q0)
    if articulated and not articulated_supported(spec):
        raise ValueError(f"{spec.name}: the articulated route takes no point masses, linear springs or actuators")

    contacts, contact_pts, contact_load = [], [], []
    for i, l in enumerate(spec.links):
        for c in l.contacts:
            contacts.append(i)
            contact_pts.append(c)
            contact_load.append(l.mass * spec.world.gravity / max(1, len(l.contacts)))
    drag = drag_edges(spec)
    edges, edge_pts = [i for i, _, _ in drag], [(a, b) for _, a, b in drag]

    g = spec.world.ground
    mu, aniso = [], []
    for l in spec.links:
        if l.friction is None:
            mu.append((g.friction, g.friction, g.friction))
            aniso.append((0, -1, -1))
        else:
            f = l.friction
            mu.append((f.forward, f.backward, f.lateral))
            ax = (names[f.axis[0]], names[f.axis[1]]) if f.axis else (-1, -1)
            aniso.append((1, *ax))
    jspring, jsl, limit, lim = [], [], [], []
    for i, l in enumerate(spec.links):
        if l.spring is not None:
            jsl.append(i)
            jspring.append((l.spring.stiffness, l.spring.damping, l.spring.rest))
        else:
            jspring.append((0.0, 0.0, 0.0))
        if l.limit is not None:
            lim.append(i)
            limit.append((l.limit.min, l.limit.max, l.limit.stiffness, l.limit.damping))
        else:
            limit.append((0.0, 0.0, 0.0, 0.0))

    acts, lin_act, amin, amax, aks, akd, apts = [], [], [], [], [], [], []
    for a in spec.actuators:
        amin.append(a.min)
        amax.append(a.max)
        aks.append(a.ks)
        akd.append(a.kd)
        if a.kind == "angular":
            acts.append(("angular", names[a.joint]))
            apts.append(((0.0, 0.0), (0.0, 0.0)))
        else:
            acts.append(("linear", len(lin_act)))
            lin_act.append((names[a.a.link], names[a.b.link]))
            apts.append((a.a.at, a.b.at))

    springs, spts, spr = [], [], []
    for s in spec.springs:
        springs.append((names[s.a.link], names[s.b.link]))
        spts.append((s.a.at, s.b.at))
        spr.append((s.stiffness, s.damping, s.rest))

    sensors, smin, smax, spoints, eyes, lengths = [], [], [], [], [], []
    contact_index = {}
    k = 0
    for i, l in enumerate(spec.links):
        for j in range(len(l.contacts)):
            contact_index[(i, j)] = k
            k += 1
    for s in spec.sensors:
        if s.kind == "touch":
            sensors.append(("touch", names[s.link], contact_index[(names[s.link], s.contact)]))
            smin.append(0.0)
            smax.append(0.0)
            spoints.append(((0.0, 0.0), (0.0, 0.0)))
        elif isinstance(s, (AngleSensor, TiltSensor)):
            sensors.append((s.kind, names[s.link], -1))
            smin.append(s.min)
            smax.append(s.max)
            spoints.append(((0.0, 0.0), (0.0, 0.0)))
        elif s.kind == "eye":
            ax = (names[s.axis[0]], names[s.axis[1]]) if s.axis else (-1, -1)
            sensors.append(("eye", names[s.at.link], len(eyes)))
            eyes.append((names[s.at.link], *ax))
            smin.append(s.min)
            smax.append(s.max)
            spoints.append((s.at.at, (0.0, 0.0)))
        else:
            assert isinstance(s, LengthSensor)
            sensors.append(("length", -1, len(lengths)))
            lengths.append((names[s.a.link], names[s.b.link]))
            smin.append(s.min)
            smax.append(s.max)
            spoints.append((s.a.at, s.b.at))

    w = spec.world
    t = w.terrain
    follow = np.zeros((2, 2))
    follow_ds, follow_loop = 1.0, False
    if w.follow is not None:
        follow, follow_ds = follow_table(w.follow.points, w.follow.loop)
        follow_loop = w.follow.loop
    structure = Structure(
        name=spec.name,
        ndof=ndof,
        links=tuple(links),
        trees=tuple(trees),
        contacts=tuple(contacts),
        edges=tuple(edges),
        sensors=tuple(sensors),
        actuators=tuple(acts),
        lin_act=tuple(lin_act),
        springs=tuple(springs),
        joint_springs=tuple(jsl),
        limits=tuple(lim),
        aniso=tuple(aniso),
        eyes=tuple(eyes),
        lengths=tuple(lengths),
        plane=w.plane,
        terrain=t.kind if w.plane == "vertical" else "flat",
        water=bool(edges),
        follow=w.follow is not None,
        follow_loop=follow_loop,
        dt=spec.dt,
        articulated=None if articulated is None else bool(articulated),
    )

    def arr(x, shape=None):
        a = np.asarray(x, dtype=dt_np)
        if shape is not None:
            a = a.reshape(shape)
        return a

    L, C, E, A, S, N = len(links), len(contacts), len(edges), len(acts), len(sensors), len(springs)
    params = Params(
        mass=arr([l.mass for l in spec.links]),
        inertia=arr([l.inertia for l in spec.links]),
        com=arr([l.com for l in spec.links], (L, 2)),
        anchor=arr([l.anchor if l.parent else (0.0, 0.0) for l in spec.links], (L, 2)),
        root_pose=arr([(*l.position, l.angle) if l.parent is None else (0.0, 0.0, 0.0) for l in spec.links], (L, 3)),
        contact=arr(contact_pts, (C, 2)),
        contact_load=arr(contact_load, (C,)),
        edge=arr(edge_pts, (E, 2, 2)),
        gravity=arr(w.gravity),
        ground_k=arr(g.stiffness),
        ground_c=arr(g.damping),
        mu=arr(mu, (L, 3)),
        slip=arr(g.slip_speed),
        water_k=arr(w.water_drag),
        water_t=arr(w.water_drag * w.water_tangential),
        jspring=arr(jspring, (L, 3)),
        limit=arr(limit, (L, 4)),
        act_min=arr(amin, (A,)),
        act_max=arr(amax, (A,)),
        act_ks=arr(aks, (A,)),
        act_kd=arr(akd, (A,)),
        act_pts=arr(apts, (A, 2, 2)),
        spr_pts=arr(spts, (N, 2, 2)),
        spr=arr(spr, (N, 3)),
        sens_min=arr(smin, (S,)),
        sens_max=arr(smax, (S,)),
        sens_pts=arr(spoints, (S, 2, 2)),
        terrain=arr(
            [math.tan(t.angle), t.height, t.width / 2.0, t.center]
        ),
        rough=arr(
            rough_terms(t.height, t.wavelength, t.seed) if t.kind == "rough" else np.zeros((ROUGH_TERMS, 3))
        ),
        follow=arr(follow),
        follow_ds=arr(follow_ds),
        follow_speed=arr(w.follow.speed if w.follow else 0.0),
        q0=arr(q0, (ndof,)),
        dt=arr(spec.dt),
    )
    return Model(structure, params, spec, dt_np)


def _trees(spec: Creature, names: dict[str, int]) -> tuple[list[LinkS], list[TreeS], list[float]]:
    """Static link records, trees and the initial coordinates.

    Dofs are numbered in the file's link order (a root's x, y and angle where the root is
    listed, a joint's angle where its link is; ``Link.dofs``), as the MuJoCo exporter and the
    creature geometry number them; a free tree's x, y are its centre of mass in the file's start
    pose."""
    from sanlab.creature.geometry import initial_frames

    frames = initial_frames(spec)
    roots = [i for i, l in enumerate(spec.links) if l.parent is None]
    members: dict[int, list[int]] = {r: [] for r in roots}
    root_of: dict[int, int] = {}
    for i, l in enumerate(spec.links):
        root_of[i] = i if l.parent is None else root_of[names[l.parent]]
        members[root_of[i]].append(i)
    tree_of = {r: t for t, r in enumerate(roots)}
    q0: list[float] = []
    made: dict[int, LinkS] = {}
    for i, l in enumerate(spec.links):
        t = tree_of[root_of[i]]
        if l.parent is None:
            dx = dy = dof = -1
            if not l.fixed:
                dx, dy = len(q0), len(q0) + 1
                q0 += list(_tree_com(spec, members[i], frames))
                if not l.is_point:
                    dof = len(q0)
                    q0.append(l.angle)
            made[i] = LinkS(i, -1, l.is_point, dx, dy, dof, (i,), t)
        else:
            p = made[names[l.parent]]
            made[i] = LinkS(i, p.index, False, p.dof_x, p.dof_y, len(q0), p.chain + (i,), t)
            q0.append(l.angle)
    trees = []
    for r in roots:
        rot = tuple(i for i in members[r] if made[i].dof_rot >= 0)
        root = spec.links[r]
        trees.append(TreeS(r, tuple(members[r]), not root.fixed, root.is_point and len(members[r]) == 1, rot))
    return [made[i] for i in range(len(spec.links))], trees, q0


def _tree_com(spec: Creature, members: list[int], frames) -> tuple[float, float]:
    """Centre of mass (m, world) of the links ``members`` in the start pose ``frames``."""
    mass, com = 0.0, np.zeros(2)
    for i in members:
        link = spec.links[i]
        x, y, a = frames[link.name]
        c, s_ = math.cos(a), math.sin(a)
        cx, cy = link.com
        com += link.mass * np.array([x + c * cx - s_ * cy, y + s_ * cx + c * cy])
        mass += link.mass
    return float(com[0] / mass), float(com[1] / mass)
