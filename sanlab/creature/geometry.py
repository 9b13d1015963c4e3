"""Plane geometry of creatures, in plain Python floats (SI units): mass properties of the link
shapes and the kinematics of link frames.

The loader takes a link's default centre of mass and inertia from :func:`mass_properties` and a
spring's default rest length from :func:`link_frames`; the MuJoCo exporter
(``sanlab.interop.mjcf``) takes its forward kinematics from :func:`link_frames` too. The simulator
(``sanlab.sim``) has its own, compiled kinematics.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from .spec import Creature, Link, PointRef, Vec2

Frame = tuple[float, float, float]  # a link frame in the world: origin x (m), y (m), angle (rad)


def transform(frame: Frame, p: Vec2) -> Vec2:
    """World position (m) of point ``p`` given in ``frame`` (m)."""
    x, y, a = frame
    c, s = math.cos(a), math.sin(a)
    return (x + c * p[0] - s * p[1], y + s * p[0] + c * p[1])


def polygon_moments(pts: Sequence[Vec2]) -> tuple[float, Vec2, float]:
    """Shoelace: signed area (m^2), area centroid (m), and polar second moment of area about the
    origin (m^4, with the sign of the area); all zero for a degenerate polygon."""
    a = cx = cy = j = 0.0
    pts = tuple(pts)
    for (x0, y0), (x1, y1) in zip(pts, pts[1:] + pts[:1], strict=True):
        c = x0 * y1 - x1 * y0
        a += c
        cx += (x0 + x1) * c
        cy += (y0 + y1) * c
        j += c * (x0 * x0 + x0 * x1 + x1 * x1 + y0 * y0 + y0 * y1 + y1 * y1)
    a /= 2
    if abs(a) < 1e-12:
        return 0.0, (0.0, 0.0), 0.0
    return a, (cx / (6 * a), cy / (6 * a)), j / 12


def mass_properties(kind: str, pts: Sequence[Vec2], mass: float) -> tuple[Vec2, float]:
    """Centre of mass (m, link frame) and inertia about it (kg m^2) of a uniform ``kind`` shape
    ("segment": a thin rod, "polygon": a lamina, "point": a point mass) of ``mass`` (kg)."""
    if kind == "segment":
        (x0, y0), (x1, y1) = pts
        return ((x0 + x1) / 2, (y0 + y1) / 2), mass * ((x1 - x0) ** 2 + (y1 - y0) ** 2) / 12
    if kind == "polygon":
        a, (cx, cy), j = polygon_moments(pts)
        return (cx, cy), mass * (j / a - cx * cx - cy * cy)
    return (0.0, 0.0), 0.0


def link_frames(links: Iterable[Link], q: Sequence[float] | None = None) -> dict[str, Frame]:
    """The world frame of every link (parents come before children in a creature).

    q: generalised coordinates in the creature's dof order (each link's :attr:`Link.dofs`: a free
    root's x, y (m) and angle (rad), a jointed link's joint angle (rad)); None: the initial pose
    of the file (roots at ``position`` and ``angle``, joints at ``angle``).
    """
    frames: dict[str, Frame] = {}
    k = 0
    for link in links:
        own = [float(v) for v in q[k : k + link.dofs]] if q is not None else None
        k += link.dofs
        if link.parent is None:
            if own:  # a free root: x, y and, unless a point mass, its angle
                frames[link.name] = (own[0], own[1], own[2] if len(own) == 3 else 0.0)
            else:  # the initial pose, or a fixed root
                frames[link.name] = (link.position[0], link.position[1], link.angle)
        else:
            parent = frames[link.parent]
            x, y = transform(parent, link.anchor)
            frames[link.name] = (x, y, parent[2] + (own[0] if own is not None else link.angle))
    return frames


def initial_frames(creature: Creature) -> dict[str, Frame]:
    """World pose (x m, y m, angle rad) of every link's frame in the initial configuration."""
    return link_frames(creature.links)


def world_point(creature: Creature, link: str, at: Vec2 = (0.0, 0.0)) -> Vec2:
    """Initial world position (m) of point ``at`` (link frame, m) of ``link``."""
    return transform(initial_frames(creature)[link], at)


def size(creature: Creature) -> float:
    """The creature's size (m) at its start pose: the larger of the width and the height of all
    its outline and contact points (and link origins, for point masses)."""
    frames = initial_frames(creature)
    pts = []
    for link in creature.links:
        f = frames[link.name]
        pts += [transform(f, p) for p in (*link.shape.points, *link.contacts, (0.0, 0.0))]
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    return max(max(xs) - min(xs), max(ys) - min(ys))


def _dofs(creature: Creature) -> tuple[list[str], dict[str, list[int]]]:
    """(the link owning each dof, each link's dofs), in ``Link.dofs`` order."""
    owner: list[str] = []
    dof_of: dict[str, list[int]] = {}
    for link in creature.links:
        dof_of[link.name] = list(range(len(owner), len(owner) + link.dofs))
        owner += [link.name] * link.dofs
    return owner, dof_of


def _jacobian(creature: Creature, frames: dict[str, Frame], dof_of: dict[str, list[int]], link: Link,
              p: Vec2) -> tuple[list[float], list[float], list[float]]:
    """(dx/dq, dy/dq, dangle/dq) [n] of world point ``p`` fixed on ``link``, at ``frames``."""
    by_name = {k.name: k for k in creature.links}
    n = sum(len(d) for d in dof_of.values())
    chain, k = [], link
    while True:
        chain.append(k)
        if k.parent is None:
            break
        k = by_name[k.parent]
    root = chain[-1]
    jx, jy, rot = [0.0] * n, [0.0] * n, [0.0] * n
    if not root.fixed:
        jx[dof_of[root.name][0]], jy[dof_of[root.name][1]] = 1.0, 1.0
    for k in chain:
        d = dof_of[k.name]
        if k.is_point or (k is root and (root.fixed or len(d) < 3)):
            continue
        i = d[-1]  # the link's own rotation: a joint angle, or a free root's angle
        X, Y, _ = frames[k.name]
        jx[i], jy[i], rot[i] = -(p[1] - Y), p[0] - X, 1.0
    return jx, jy, rot


def mass_matrix(creature: Creature) -> tuple[list[list[float]], list[str]]:
    """The mass matrix M (kg, kg m, kg m^2) at the file's start pose, in root coordinates (a free
    root's x, y, angle; each joint's angle, in ``Link.dofs`` order), and the name of the link
    that owns each dof: M = sum over links of m J_c^T J_c + I r r^T, J_c the Jacobian of the
    link's centre of mass and r the row of the joints that turn it."""
    frames = initial_frames(creature)
    owner, dof_of = _dofs(creature)
    n = len(owner)
    M = [[0.0] * n for _ in range(n)]
    by_name = {link.name: link for link in creature.links}
    for link in creature.links:
        root = link
        while root.parent is not None:
            root = by_name[root.parent]
        if root.fixed and link is root:
            continue
        jx, jy, rot = _jacobian(creature, frames, dof_of, link, transform(frames[link.name], link.com))
        for a in range(n):
            for b in range(n):
                M[a][b] += link.mass * (jx[a] * jx[b] + jy[a] * jy[b]) + link.inertia * rot[a] * rot[b]
    return M, owner


def line_masses(creature: Creature, lines: Sequence[tuple[PointRef, PointRef]]) -> list[float]:
    """The effective mass (kg) each line between two points meets at the file's start pose:
    1 / (J M^-1 J^T), J the rate of the line's length in the dofs (:func:`mass_matrix`), every
    dof free to move. A spring of stiffness k along it oscillates at sqrt(k / m) rad/s. inf for
    a line no dof with mass changes (both points on one link, or on the world)."""
    import numpy as np

    M, owner = mass_matrix(creature)
    frames = initial_frames(creature)
    _, dof_of = _dofs(creature)
    by_name = {link.name: link for link in creature.links}
    A = np.asarray(M, float).reshape(len(owner), len(owner))
    keep = np.flatnonzero(np.diag(A) > 0) if len(owner) else np.zeros(0, int)
    inv = np.linalg.pinv(A[np.ix_(keep, keep)]) if len(keep) else np.zeros((0, 0))
    out = []
    for a, b in lines:
        pa, pb = transform(frames[a.link], a.at), transform(frames[b.link], b.at)
        d = np.subtract(pb, pa)
        length = float(np.hypot(*d))
        if length == 0.0:
            out.append(math.inf)
            continue
        u = d / length
        ja = _jacobian(creature, frames, dof_of, by_name[a.link], pa)
        jb = _jacobian(creature, frames, dof_of, by_name[b.link], pb)
        J = u[0] * (np.subtract(jb[0], ja[0])) + u[1] * (np.subtract(jb[1], ja[1]))
        w = float(J[keep] @ inv @ J[keep]) if len(keep) else 0.0
        out.append(1.0 / w if w > 1e-300 else math.inf)
    return out


def joint_inertias(creature: Creature) -> dict[str, float]:
    """Each joint's effective inertia at the file's start pose (kg m^2), by the name of the
    link it turns: 1 / (M^-1)_jj, the inertia a torque at that joint meets when every other
    dof is free to move (:func:`mass_matrix`). A servo of stiffness ks there oscillates at
    sqrt(ks / I) rad/s. Joints of a tree welded to the world count the same way."""
    import numpy as np

    M, owner = mass_matrix(creature)
    if not owner:
        return {}
    A = np.asarray(M, float)
    keep = np.flatnonzero(np.diag(A) > 0)  # a dof no mass moves (a massless chain) has no inertia
    inv = np.linalg.pinv(A[np.ix_(keep, keep)])
    out: dict[str, float] = {}
    for row, dof in enumerate(keep):
        name = owner[dof]
        link = next(link for link in creature.links if link.name == name)
        if link.parent is not None and dof == max(i for i, o in enumerate(owner) if o == name):
            out[name] = 1.0 / inv[row, row] if inv[row, row] > 0 else math.inf
    return out
