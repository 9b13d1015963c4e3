"""O(n) linear algebra of a step for larger creatures: the articulated-body algorithm.

The step (``dynamics``) solves (M + sum_e c_e g_e g_e^T) x = b twice per step and multiplies by M
once. The dense route (``sparse.SymMatrix``) assembles M from point Jacobians and factorises it:
for an n-link chain that is O(n^3) scalar operations, all unrolled into the compiled program.
Here the same matrices are never formed. Each body's mass, and each element that acts on one
body (a contact's normal and friction rows, water drag on an edge, gravity, a rotation row),
is a planar spatial inertia, a symmetric 3 x 3 over the body's spatial velocity; joint-space
elements (PD servos, joint springs, joint stops) add to their joint's diagonal ("armature").
Featherstone's articulated-body recursion then solves with that matrix in O(n) operations and
the composite-body recursion multiplies by M in O(n) (R. Featherstone, *Rigid Body Dynamics
Algorithms*, 2008, ch. 7; the paper's own simulator used an O(n) recursive formulation).

Spatial vectors are planar (w, vx, vy): a body's angular rate and the velocity of the body-fixed
point that is at its tree's *reference point* (the tree's root origin, so that all lever arms are
small numbers whatever the creature's position); forces are (moment about the reference point,
fx, fy). In these terms a free tree's three root dofs (root origin velocity, root angle rate;
the step's tree coordinates) are the identity, and a revolute joint at X has the motion subspace
(1, (X - ref)_y, -(X - ref)_x).

Supported: trees of rigid links, free or welded to the world (no point masses and no element
that joins two bodies, such as a linear spring or actuator); ``model.assemble`` falls back to
the dense route otherwise. Same scalar algebra as ``sparse``: Python floats are structural
constants and vanish at trace time.
"""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

from sanlab.sim.sparse import SymMatrix, add, mul, neg, sub

Vec = tuple[Any, Any]
Sym3 = tuple  # (a00, a01, a02, a11, a12, a22) of a symmetric 3 x 3, index order (w, x, y)
_IDX = {(0, 0): 0, (0, 1): 1, (0, 2): 2, (1, 1): 3, (1, 2): 4, (2, 2): 5}


class BodyPoint(NamedTuple):
    """A point fixed on body ``link``, ``r`` m from its tree's reference point (the articulated
    form of a point Jacobian)."""

    link: int
    r: Vec


class BodyRow(NamedTuple):
    """A row g of the step's system acting through one body: g . u = a . V_link, with V_link the
    body's spatial velocity (w, vx, vy) about its tree's reference point."""

    link: int
    a: tuple


def project(J: BodyPoint, n: Vec) -> BodyRow:
    """Row of the velocity of point ``J`` along direction n: (r x n, n_x, n_y)."""
    r = J.r
    return BodyRow(J.link, (sub(mul(r[0], n[1]), mul(r[1], n[0])), n[0], n[1]))


def rotation_row(link: int) -> BodyRow:
    """Row of body ``link``'s absolute angular rate."""
    return BodyRow(link, (1.0, 0.0, 0.0))


def _sym_add(A: Sym3, B: Sym3) -> Sym3:
    return tuple(add(a, b) for a, b in zip(A, B))


def _sym_outer(c, a: tuple, b: tuple | None = None) -> Sym3:
    """c a a^T, or c (a b^T + b a^T)."""
    out = []
    for (i, j) in _IDX:
        if b is None:
            v = mul(mul(c, a[i]), a[j])
        else:
            v = add(mul(mul(c, a[i]), b[j]), mul(mul(c, b[i]), a[j]))
        out.append(v)
    return tuple(out)


def _sym_vec(A: Sym3, x: tuple) -> tuple:
    """A x."""
    e = lambda i, j: A[_IDX[(min(i, j), max(i, j))]]
    return tuple(add(add(mul(e(i, 0), x[0]), mul(e(i, 1), x[1])), mul(e(i, 2), x[2])) for i in range(3))


def _dot(a: tuple, b: tuple) -> Any:
    return add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))


def _axpy(y: tuple, c, x: tuple) -> tuple:
    return tuple(add(yi, mul(c, xi)) for yi, xi in zip(y, x))


_ZERO3 = (0.0, 0.0, 0.0)
_ZERO6 = (0.0,) * 6


@functools.lru_cache(maxsize=256)
def children(structure) -> dict[int, tuple[int, ...]]:
    """Each link's children (link indices), per structure (computed once, at trace time)."""
    return {ls.index: tuple(k.index for k in structure.links if k.parent == ls.index) for ls in structure.links}


class Bodies:
    """The mass matrix M(q) of a creature in tree coordinates, held as one spatial inertia per
    body (no n x n matrix is formed). Duck-compatible with ``sparse.SymMatrix`` where the step
    uses it: ``solve`` and ``matvec`` over dof-keyed dicts.

    structure: the model's ``Structure``; ``X`` / ``com``: per link origin and centre of mass,
    world (m); mass (kg) and inertia about the centre of mass (kg m^2) as indexable arrays;
    fence: ``fence(tree, name) -> tree``, keeps XLA from re-deriving intermediates (see
    ``dynamics._barrier``; default: none).
    """

    def __init__(self, structure, X: list, com: list, mass, inertia, fence=None):
        st = self.st = structure
        self.fence = fence or (lambda tree, name: tree)
        self.children = children(st)
        self.I: dict[int, Sym3] = {}
        self.s: dict[int, tuple] = {}  # motion subspace of each joint (non-root link)
        self.ref: dict[int, Vec] = {}  # per tree (by root): reference point, world
        for tree in st.trees:
            if tree.point:
                raise ValueError("the articulated route has no point masses (use the dense route)")
            ref = self.ref[tree.root] = X[tree.root]
            for i in tree.links:
                ls = st.links[i]
                if ls.parent < 0 and not tree.free:
                    continue  # welded to the world: part of the world
                m = mass[i]
                cx, cy = sub(com[i][0], ref[0]), sub(com[i][1], ref[1])
                mcx, mcy = mul(m, cx), mul(m, cy)
                self.I[i] = (add(inertia[i], add(mul(mcx, cx), mul(mcy, cy))), neg(mcy), mcx, m, 0.0, m)
                if ls.parent >= 0:
                    rx, ry = sub(X[i][0], ref[0]), sub(X[i][1], ref[1])
                    self.s[i] = (1.0, ry, neg(rx))

    @property
    def a(self) -> dict:
        """The arrays that define M (what a fence keeps in memory)."""
        return {"I": self.I, "s": self.s}

    @a.setter
    def a(self, v: dict) -> None:
        self.I, self.s = v["I"], v["s"]

    def point(self, link: int, p: Vec) -> BodyPoint:
        """The articulated Jacobian of world point p fixed on body ``link``."""
        ref = self.ref[self.st.trees[self.st.links[link].tree].root]
        return BodyPoint(link, (sub(p[0], ref[0]), sub(p[1], ref[1])))

    # ------------------------------------------------------------ M x

    def matvec(self, x: dict) -> dict:
        """M x for tree-coordinate velocities x (absent entries are zero): the composite-body
        recursion, body momenta I V summed leaves first and projected on each joint."""
        st = self.st
        out: dict = {}
        for tree in st.trees:
            root = st.links[tree.root]
            V: dict = {}
            for i in tree.links:
                ls = st.links[i]
                if ls.parent < 0:
                    V[i] = (x.get(root.dof_rot, 0.0), x.get(root.dof_x, 0.0), x.get(root.dof_y, 0.0)) \
                        if tree.free else _ZERO3
                else:
                    V[i] = _axpy(V[ls.parent], x.get(ls.dof_rot, 0.0), self.s[i])
            H: dict = {}
            for i in reversed(tree.links):
                ls = st.links[i]
                if ls.parent < 0 and not tree.free:
                    continue
                h = _sym_vec(self.I[i], V[i])
                for c in self.children[i]:
                    h = tuple(add(a, b) for a, b in zip(h, H[c]))
                H[i] = h
                if ls.parent >= 0:
                    out[ls.dof_rot] = _dot(self.s[i], h)
                else:
                    out[ls.dof_rot], out[ls.dof_x], out[ls.dof_y] = h
        return {d: v for d, v in out.items() if not (isinstance(v, float) and v == 0.0)}

    # ------------------------------------------------------------ solve

    def solve(self, b: dict, arm: dict | None = None, E: dict | None = None, F: dict | None = None) -> dict:
        """Solve (M + sum_bodies J_b^T E_b J_b + diag(arm)) x = b + sum_bodies J_b^T F_b.

        b: joint-space forces by dof; arm: extra diagonal by dof; E: extra spatial inertia (Sym3)
        by body; F: spatial force (w, x, y) by body. Returns x for every dof (a dense dict).
        Featherstone's articulated-body recursion with zero velocity-product terms."""
        st = self.st
        arm, E, F = arm or {}, E or {}, F or {}
        x: dict = {}
        for tree in st.trees:
            root = st.links[tree.root]
            welded = not tree.free
            IA: dict = {}
            pA: dict = {}
            for i in tree.links:
                if i == tree.root and welded:
                    continue
                IA[i] = _sym_add(self.I[i], E[i]) if i in E else self.I[i]
                pA[i] = tuple(neg(v) for v in F[i]) if i in F else _ZERO3
            U, invD, uu = {}, {}, {}
            for i in reversed(tree.links):
                ls = st.links[i]
                if ls.parent < 0:
                    continue
                s, d = self.s[i], ls.dof_rot
                Ui = _sym_vec(IA[i], s)
                D = add(_dot(s, Ui), arm.get(d, 0.0))
                inv = 1.0 / D
                ui = sub(b.get(d, 0.0), _dot(s, pA[i]))
                U[i], invD[i], uu[i] = Ui, inv, ui
                if ls.parent == tree.root and welded:
                    continue  # the world takes it
                Uinv = tuple(mul(v, inv) for v in Ui)
                Ia = tuple(sub(IA[i][k], mul(Uinv[p], Ui[q])) for k, (p, q) in enumerate(_IDX))
                pa = _axpy(pA[i], ui, Uinv)
                j = ls.parent
                IA[j] = _sym_add(IA[j], Ia)
                pA[j] = tuple(add(a, c) for a, c in zip(pA[j], pa))
                # fenced link by link: left to itself, XLA's fusion re-derives the whole subtree's
                # recursion inside every consumer (the bounder ran 2x slower unfenced)
                IA[j], pA[j], U[i], invD[i], uu[i] = self.fence((IA[j], pA[j], Ui, inv, ui), "aba")
            a: dict = {}
            if welded:
                a[tree.root] = _ZERO3
            else:
                # the free root: a 3 x 3 system over (w, vx, vy) = (root angle rate, root origin velocity)
                dofs = (root.dof_rot, root.dof_x, root.dof_y)
                K = SymMatrix([2, 1, 0])
                for (p, q), k in _IDX.items():
                    v = IA[tree.root][k]
                    if p == q:
                        v = add(v, arm.get(dofs[p], 0.0))
                    K.add(p, q, v)
                rhs = {k: sub(b.get(dofs[k], 0.0), pA[tree.root][k]) for k in range(3)}
                sol = K.solve(rhs)
                a[tree.root] = (sol[0], sol[1], sol[2])
                for k in range(3):
                    x[dofs[k]] = sol[k]
            for i in tree.links:
                ls = st.links[i]
                if ls.parent < 0:
                    continue
                ap = a[ls.parent]
                xi = mul(sub(uu[i], _dot(U[i], ap)), invD[i])
                x[ls.dof_rot] = xi
                if self.children[i]:
                    a[i] = _axpy(ap, xi, self.s[i])
                    a[i], x[ls.dof_rot] = self.fence((a[i], xi), "aba")
        return x


class System(NamedTuple):
    """The step's matrix M + sum c g g^T and generalised force, gathered per body and per joint
    for :meth:`Bodies.solve`."""

    arm: dict  # dof -> extra diagonal
    E: dict  # body -> Sym3
    tau: dict  # dof -> joint-space force
    F: dict  # body -> spatial force (w, x, y)


def gather(mat: list, vec: list) -> System:
    """Sort the step's terms (see ``dynamics._Terms``): ``mat`` [(coef, g, h)], ``vec``
    [(force, g)], each row g a ``BodyRow`` or a one-entry dof dict (a joint-space element)."""
    arm: dict = {}
    E: dict = {}
    tau: dict = {}
    F: dict = {}
    for coef, g, h in mat:
        if isinstance(g, dict):
            if h is not None or len(g) != 1:
                raise ValueError("the articulated route takes joint rows with one entry")
            (d, v), = g.items()
            arm[d] = add(arm.get(d, 0.0), mul(coef, mul(v, v)))
            continue
        if h is not None and h.link != g.link:
            raise ValueError("the articulated route takes no element that joins two bodies")
        term = _sym_outer(coef, g.a, None if h is None else h.a)
        E[g.link] = _sym_add(E[g.link], term) if g.link in E else term
    for f, g in vec:
        if isinstance(g, dict):
            for d, v in g.items():
                tau[d] = add(tau.get(d, 0.0), mul(f, v))
            continue
        F[g.link] = _axpy(F.get(g.link, _ZERO3), f, g.a)
    return System(arm, E, tau, F)
