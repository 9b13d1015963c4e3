# ruff: noqa: RUF059
"""The step as one compiled kernel that reads the creature as data (engine round 4, in progress).

Today's engine (``sanlab.sim.dynamics``) unrolls each creature's structure into its own XLA
program at trace time, so every new creature is a compile and a small batch pays ~510 kernel
dispatches per step. Here the structure is *data*: integer tables (parents, dofs, contacts,
sensors, actuators) and float tables (masses, lengths, gains, ranges), read by one Numba kernel
that is compiled once per install (``cache=True``) and serves every creature, as MuJoCo's C
engine and MuJoCo Warp read their models.

The kernel follows ``dynamics`` term for term (the same coordinates, the same momentum-form
semi-implicit step with its implicitly linearised elements, the same stick-slip contact laws,
the same elimination order of the L D L^T solve), so that in float64 the two agree to round-off.
Structural zeros are no longer dropped at trace time; they are carried as exact zeros, which
changes no value (x + 0 = x exactly), and the scalar code skips the contacts that do not touch.

Coverage so far (the spike of issue 46): the vertical plane, trees of rigid links (free or welded
to the world), angular servos, joint springs and stops, isotropic and anisotropic ground friction
on flat, sloped, hill and rough terrain, touch, angle and tilt sensors, the SAN controller, and
the dense route of the linear algebra. Not yet: the horizontal plane and water drag, point masses,
linear actuators and springs, eye and length sensors, observers (metrics) and recording, the
articulated O(n) route. :func:`supported` says whether a model is covered.

Layout (see :func:`pack`): ``li`` int32 [L, LI] and ``lf`` float64 [L, LF] per link; ``ti``
int32 [T, 3] per tree; ``ci`` int32 [C] and ``cf`` [C, 2] per contact; ``si`` int32 [S, 2] and
``sf`` [S, 2] per sensor; ``ai`` int32 [A] and ``af`` [A, 4] per actuator; ``wf`` float64 [WF]
and ``wi`` int32 [WI] for the world; ``rough`` [K, 3].
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange

# li columns
L_PARENT, L_POINT, L_DX, L_DY, L_ROT, L_TREE, L_WELDED, L_ANISO, L_AX_FROM, L_AX_TO, L_SPRING, L_LIMIT = range(12)
LI = 12
# lf columns
F_MASS, F_INERTIA, F_COMX, F_COMY, F_ANCX, F_ANCY, F_POSEX, F_POSEY, F_POSEA = range(9)
F_MU = 9  # 3: forward, backward, lateral
F_JSPRING = 12  # 3: stiffness, damping, rest
F_LIMIT = 15  # 4: min, max, stiffness, damping
LF = 19
# wf entries
W_GRAVITY, W_GK, W_GC, W_SLIP, W_DT, W_SLOPE, W_HILL_H, W_HILL_W, W_HILL_C = range(9)
WF = 9
# wi entries
W_TERRAIN, W_HIDDEN = range(2)
WI = 2
TERRAINS = {"flat": 0, "slope": 1, "hill": 2, "rough": 3}
SENSORS = {"touch": 0, "angle": 1, "tilt": 2}


class Packed(NamedTuple):
    """A creature as arrays (see the module docstring)."""

    li: Any
    lf: Any
    ri: Any  # [L, R] int32: the dofs of each link's chain (translation, then joints from the root)
    rl: Any  # [L, R] int32: what each of them is: -1 / -2 the tree's x / y, -3 a dof the link
    # does not depend on, else the link whose joint it is (its origin is the pivot)
    rn: Any  # [L] int32: how many
    ti: Any
    ci: Any
    cf: Any
    si: Any
    sf: Any
    ai: Any
    af: Any
    wf: Any
    wi: Any
    rough: Any
    q0: Any  # [D]
    ndof: int


def supported(model) -> str | None:
    """None when the kernel covers ``model`` (a ``sim.Model``), else what it lacks."""
    st = model.structure
    if st.plane != "vertical":
        return "the horizontal plane"
    if st.water:
        return "water drag"
    if any(ls.point for ls in st.links):
        return "point masses"
    if st.lin_act or st.springs:
        return "linear actuators or springs"
    if any(kind not in SENSORS for kind, _, _ in st.sensors):
        return "eye or length sensors"
    return None


def pack(model, hidden: int) -> Packed:
    """The arrays of ``model`` (a ``sim.Model``, any dtype: the kernel runs in float64) and the
    SAN's hidden node count. Raises ValueError for what the kernel does not cover yet."""
    why = supported(model)
    if why is not None:
        raise ValueError(f"the kernel does not cover {why} yet")
    st, p = model.structure, model.params
    f = lambda x: np.asarray(x, np.float64)
    L = len(st.links)
    li = np.full((L, LI), -1, np.int32)
    lf = np.zeros((L, LF), np.float64)
    mass, inertia, com, anchor, pose = f(p.mass), f(p.inertia), f(p.com), f(p.anchor), f(p.root_pose)
    mu, jspring, limit = f(p.mu), f(p.jspring), f(p.limit)
    for ls in st.links:
        i = ls.index
        aniso = st.aniso[i]
        welded = ls.parent < 0 and ls.dof_x < 0 and ls.dof_rot < 0
        li[i] = (ls.parent, int(ls.point), ls.dof_x, ls.dof_y, ls.dof_rot, ls.tree, int(welded), aniso[0], aniso[1],
                 aniso[2], int(i in st.joint_springs), int(i in st.limits))
        lf[i, :F_MU] = (mass[i], inertia[i], com[i, 0], com[i, 1], anchor[i, 0], anchor[i, 1], *pose[i])
        lf[i, F_MU:F_MU + 3] = mu[i]
        lf[i, F_JSPRING:F_JSPRING + 3] = jspring[i]
        lf[i, F_LIMIT:F_LIMIT + 4] = limit[i]
    R = 2 + max(len(ls.chain) for ls in st.links)
    ri = np.zeros((L, R), np.int32)
    rl = np.full((L, R), -3, np.int32)
    rn = np.zeros(L, np.int32)
    for ls in st.links:
        row = [(ls.dof_x, -1), (ls.dof_y, -2)] if ls.dof_x >= 0 else []
        row += [(st.links[k].dof_rot, k) for k in ls.chain if st.links[k].dof_rot >= 0]
        assert [d for d, _ in row] == sorted(d for d, _ in row), "dofs along a chain increase"
        rn[ls.index] = len(row)
        for a, (d, k) in enumerate(row):
            ri[ls.index, a], rl[ls.index, a] = d, k
    ti = np.array([(t.root, int(t.free), int(t.point)) for t in st.trees], np.int32).reshape(-1, 3)
    ci = np.array(st.contacts, np.int32)
    cf = f(p.contact).reshape(-1, 2)
    si = np.array([(SENSORS[k], idx if k == "touch" else link) for k, link, idx in st.sensors], np.int32).reshape(-1, 2)
    sf = np.stack([f(p.sens_min), f(p.sens_max)], 1).reshape(-1, 2)
    ai = np.array([ref for _, ref in st.actuators], np.int32)
    af = np.stack([f(p.act_min), f(p.act_max), f(p.act_ks), f(p.act_kd)], 1).reshape(-1, 4)
    terrain = f(p.terrain)
    wf = np.array([f(p.gravity), f(p.ground_k), f(p.ground_c), f(p.slip), f(p.dt), terrain[0], terrain[1], terrain[2],
                   terrain[3]], np.float64)
    wi = np.array([TERRAINS[st.terrain], hidden], np.int32)
    return Packed(li, lf, ri, rl, rn, ti, ci, cf, si, sf, ai, af, wf, wi, f(p.rough).reshape(-1, 3), f(p.q0), st.ndof)


# ------------------------------------------------------------------ the step, one creature


@njit(cache=True, error_model="numpy", inline="always")
def _terrain(wi, wf, rough, x):
    """(h, dh/dx) of the ground at x."""
    kind = wi[W_TERRAIN]
    if kind == 0:
        return 0.0, 0.0
    if kind == 1:
        return wf[W_SLOPE] * x, wf[W_SLOPE]
    if kind == 2:
        H, hw, c = wf[W_HILL_H], wf[W_HILL_W], wf[W_HILL_C]
        u = (x - c) * (math.pi / hw)
        if abs(x - c) < hw:
            return 0.5 * H * (1.0 + math.cos(u)), -0.5 * H * (math.pi / hw) * math.sin(u)
        return 0.0, 0.0
    h = 0.0
    dh = 0.0
    for k in range(rough.shape[0]):
        a, w, ph = rough[k, 0], rough[k, 1], rough[k, 2]
        arg = w * x + ph
        h = h + a * math.sin(arg)
        dh = dh + a * w * math.cos(arg)
    return h, dh


@njit(cache=True, error_model="numpy")
def _positions(li, lf, ti, ci, cf, wi, wf, rough, q, th, cs, X, com, msum, mc, S, cp, depth, gn):
    """Positions: absolute angles th [L], (cos, sin) cs [L, 2], link origins X [L, 2], centres
    of mass com [L, 2], per free tree's rotational link S [L, 2]; contact points cp [C, 2],
    depths [C] and ground normals gn [C, 4] (n, t)."""
    L = li.shape[0]
    for i in range(L):
        par, rot = li[i, L_PARENT], li[i, L_ROT]
        if par < 0:
            if rot >= 0:
                th[i] = q[rot]
            elif li[i, L_DX] < 0:
                th[i] = lf[i, F_POSEA]
            else:
                th[i] = 0.0
        else:
            th[i] = th[par] + q[rot]
        cs[i, 0] = math.cos(th[i])
        cs[i, 1] = math.sin(th[i])
    for i in range(L):
        par = li[i, L_PARENT]
        if par < 0:
            if li[i, L_DX] < 0:
                X[i, 0] = lf[i, F_POSEX]
                X[i, 1] = lf[i, F_POSEY]
            else:
                X[i, 0] = 0.0
                X[i, 1] = 0.0
        else:
            c, s = cs[par, 0], cs[par, 1]
            ax, ay = lf[i, F_ANCX], lf[i, F_ANCY]
            X[i, 0] = X[par, 0] + (c * ax - s * ay)
            X[i, 1] = X[par, 1] + (s * ax + c * ay)
    for i in range(L):
        c, s = cs[i, 0], cs[i, 1]
        rx, ry = lf[i, F_COMX], lf[i, F_COMY]
        com[i, 0] = X[i, 0] + (c * rx - s * ry)
        com[i, 1] = X[i, 1] + (s * rx + c * ry)
    for t in range(ti.shape[0]):
        if ti[t, 1] == 0 or ti[t, 2] == 1:
            continue
        r = ti[t, 0]
        for i in range(L - 1, -1, -1):
            if li[i, L_TREE] != t:
                continue
            m = lf[i, F_MASS]
            ms, mx, my = m, m * com[i, 0], m * com[i, 1]
            for j in range(L):
                if li[j, L_PARENT] == i:
                    ms, mx, my = ms + msum[j], mx + mc[j, 0], my + mc[j, 1]
            msum[i], mc[i, 0], mc[i, 1] = ms, mx, my
        inv = 1.0 / msum[r]
        sx = q[li[r, L_DX]] - mc[r, 0] * inv
        sy = q[li[r, L_DY]] - mc[r, 1] * inv
        for k in range(L):
            if li[k, L_TREE] != t:
                continue
            if li[k, L_ROT] >= 0:
                # S_k from the unshifted origin (X still relative to the tree's root)
                S[k, 0] = (mc[k, 0] - msum[k] * X[k, 0]) * inv
                S[k, 1] = (mc[k, 1] - msum[k] * X[k, 1]) * inv
            X[k, 0] = X[k, 0] + sx
            X[k, 1] = X[k, 1] + sy
            com[k, 0] = com[k, 0] + sx
            com[k, 1] = com[k, 1] + sy
    for c in range(ci.shape[0]):
        i = ci[c]
        cc, ss = cs[i, 0], cs[i, 1]
        rx, ry = cf[c, 0], cf[c, 1]
        px = X[i, 0] + (cc * rx - ss * ry)
        py = X[i, 1] + (ss * rx + cc * ry)
        cp[c, 0], cp[c, 1] = px, py
        h, dh = _terrain(wi, wf, rough, px)
        if dh == 0.0 and wi[W_TERRAIN] == 0:
            nx, ny, tx, ty = 0.0, 1.0, 1.0, 0.0
        else:
            inv = 1.0 / math.sqrt(1.0 + dh * dh)
            nx, ny, tx, ty = -dh * inv, inv, inv, dh * inv
        gn[c, 0], gn[c, 1], gn[c, 2], gn[c, 3] = nx, ny, tx, ty
        depth[c] = (h - py) * ny


@njit(cache=True, error_model="numpy", inline="always")
def _outer(A, coef, idx, val, n):
    """A += coef g g^T for the row g with entries val[:n] at dofs idx[:n] (increasing), both
    halves, each entry's product formed as the sparse matrix forms it: (coef g_i) g_j, i >= j."""
    for a in range(n):
        i = idx[a]
        cgi = coef * val[a]
        for b in range(a + 1):
            j = idx[b]
            v = cgi * val[b]
            A[i, j] += v
            if i != j:
                A[j, i] += v


@njit(cache=True, error_model="numpy", inline="always")
def _force(Q, f, idx, val, n):
    for a in range(n):
        Q[idx[a]] += f * val[a]


@njit(cache=True, error_model="numpy", inline="always")
def _point_row(rl, rn, X, i, px, py, nx, ny, val):
    """The row g = J^T n of world point (px, py) on link i along n: its entries in val, at the
    dofs ``ri[i]`` (the link's chain: the tree's translation, then each joint from the root);
    returns their count. Entries the point does not depend on are exact zeros."""
    n = rn[i]
    for a in range(n):
        k = rl[i, a]
        if k == -1:
            val[a] = nx
        elif k == -2:
            val[a] = ny
        elif k == -3:
            val[a] = 0.0
        else:
            val[a] = (-(py - X[k, 1])) * nx + (px - X[k, 0]) * ny
    return n


@njit(cache=True, error_model="numpy", inline="always")
def _rot_row(rl, rn, i, val):
    """The row of link i's absolute angle: ones at its chain's joints (see :func:`_point_row`)."""
    n = rn[i]
    for a in range(n):
        val[a] = 1.0 if rl[i, a] >= 0 else 0.0
    return n


@njit(cache=True, error_model="numpy")
def _mass_matrix(li, lf, ri, rl, rn, X, com, M, g, D):
    for a in range(D):
        for b in range(D):
            M[a, b] = 0.0
    for i in range(li.shape[0]):
        if li[i, L_WELDED] == 1:
            continue
        n = _point_row(rl, rn, X, i, com[i, 0], com[i, 1], 1.0, 0.0, g)
        _outer(M, lf[i, F_MASS], ri[i], g, n)
        n = _point_row(rl, rn, X, i, com[i, 0], com[i, 1], 0.0, 1.0, g)
        _outer(M, lf[i, F_MASS], ri[i], g, n)
        n = _rot_row(rl, rn, i, g)
        _outer(M, lf[i, F_INERTIA], ri[i], g, n)


@njit(cache=True, error_model="numpy")
def _solve(A, b, x, F, Lf, D):
    """x = A^-1 b by L D L^T in the elimination order D-1, ..., 0 (leaves first), as
    ``sparse.SymMatrix.solve`` (structural zeros carried as exact zeros); F [D, D] and Lf [D, D]
    are scratch: the working matrix and the factor's columns (Lf[k, i] = l_ik, Lf[k, k] = 1/d_k)."""
    for a in range(D):
        for c in range(D):
            F[a, c] = A[a, c]
    for k in range(D - 1, -1, -1):
        inv = 1.0 / F[k, k]
        Lf[k, k] = inv
        for i in range(k):
            Lf[k, i] = F[i, k] * inv
        for i in range(k - 1, -1, -1):
            l = Lf[k, i]
            for j in range(k - 1, i - 1, -1):
                v = F[i, j] - l * F[j, k]
                F[i, j] = v
                F[j, i] = v
    for a in range(D):
        x[a] = b[a]
    for k in range(D - 1, -1, -1):
        for i in range(k - 1, -1, -1):
            x[i] = x[i] - Lf[k, i] * x[k]
    for k in range(D):
        x[k] = x[k] * Lf[k, k]
    for k in range(D):
        for i in range(k - 1, -1, -1):
            x[k] = x[k] - Lf[k, i] * x[i]


@njit(cache=True, error_model="numpy")
def _turn(li, ti, S, v, sign, force, D):
    """The change between state and tree coordinates of each free tree (see ``dynamics._to_tree``
    and friends): velocities when ``force`` is 0 (u = S v for sign +1, v = S^-1 u for -1),
    generalised forces when 1 (S^T g for +1, S^-T f for -1). In place on v [D]."""
    for t in range(ti.shape[0]):
        if ti[t, 1] == 0 or ti[t, 2] == 1:
            continue
        r = ti[t, 0]
        dx, dy = li[r, L_DX], li[r, L_DY]
        fx, fy = v[dx], v[dy]
        for k in range(li.shape[0]):
            if li[k, L_TREE] != t or li[k, L_ROT] < 0:
                continue
            d = li[k, L_ROT]
            tx, ty = S[k, 1], -S[k, 0]
            if force == 0:
                if sign > 0:
                    v[dx] = v[dx] + tx * v[d]
                    v[dy] = v[dy] + ty * v[d]
                else:
                    v[dx] = v[dx] - tx * v[d]
                    v[dy] = v[dy] - ty * v[d]
            else:
                if sign > 0:
                    v[d] = v[d] + (tx * fx + ty * fy)
                else:
                    v[d] = v[d] - (tx * fx + ty * fy)


@njit(cache=True, error_model="numpy")
def _velocities(li, ci, X, cp, u, w, V, cv):
    for i in range(li.shape[0]):
        par, rot = li[i, L_PARENT], li[i, L_ROT]
        if par < 0:
            w[i] = u[rot] if rot >= 0 else 0.0
            if li[i, L_DX] >= 0:
                V[i, 0], V[i, 1] = u[li[i, L_DX]], u[li[i, L_DY]]
            else:
                V[i, 0], V[i, 1] = 0.0, 0.0
        else:
            w[i] = w[par] + u[rot]
            rx, ry = X[i, 0] - X[par, 0], X[i, 1] - X[par, 1]
            V[i, 0] = V[par, 0] - w[par] * ry
            V[i, 1] = V[par, 1] + w[par] * rx
    for c in range(ci.shape[0]):
        i = ci[c]
        rx, ry = cp[c, 0] - X[i, 0], cp[c, 1] - X[i, 1]
        cv[c, 0] = V[i, 0] - w[i] * ry
        cv[c, 1] = V[i, 1] + w[i] * rx


@njit(cache=True, error_model="numpy", inline="always")
def _wrap(a):
    return a - (2 * math.pi) * math.floor((a + math.pi) * (0.5 / math.pi))


@njit(cache=True, error_model="numpy")
def _element_joint(A, Q, d, h, force, k, c, rate):
    A[d, d] += h * c + (h * h) * k
    Q[d] += force - (h * k) * rate


class Scratch(NamedTuple):
    th: Any
    cs: Any
    X: Any
    com: Any
    msum: Any
    mc: Any
    S: Any
    cp: Any
    depth: Any
    gn: Any
    w: Any
    V: Any
    cv: Any
    M: Any
    A: Any
    F: Any
    Q: Any
    u: Any
    qd: Any
    g: Any
    x: Any
    Lf: Any


@njit(cache=True, error_model="numpy")
def _scratch(L, C, D):
    return (np.zeros(L), np.zeros((L, 2)), np.zeros((L, 2)), np.zeros((L, 2)), np.zeros(L), np.zeros((L, 2)),
            np.zeros((L, 2)), np.zeros((C, 2)), np.zeros(C), np.zeros((C, 4)), np.zeros(L), np.zeros((L, 2)),
            np.zeros((C, 2)), np.zeros((D, D)), np.zeros((D, D)), np.zeros((D, D)), np.zeros(D), np.zeros(D),
            np.zeros(D), np.zeros(D), np.zeros(D), np.zeros((D, D)))


@njit(cache=True, error_model="numpy")
def _prepare(li, lf, ri, rl, rn, ti, ci, cf, wi, wf, rough, q, p, sc):
    """Kinematics of (q, p): positions, M, the velocity u = M^-1 p (tree coordinates, in sc.u),
    qd (state coordinates, in sc.qd), link and contact velocities."""
    th, cs, X, com, msum, mc, S, cp, depth, gn, w, V, cv, M, A, F, Q, u, qd, g, x, Lf = sc
    D = q.shape[0]
    _positions(li, lf, ti, ci, cf, wi, wf, rough, q, th, cs, X, com, msum, mc, S, cp, depth, gn)
    _mass_matrix(li, lf, ri, rl, rn, X, com, M, g, D)
    for d in range(D):
        x[d] = p[d]
    _turn(li, ti, S, x, -1, 1, D)
    _solve(M, x, u, F, Lf, D)
    for d in range(D):
        qd[d] = u[d]
    _turn(li, ti, S, qd, -1, 0, D)
    _velocities(li, ci, X, cp, u, w, V, cv)


@njit(cache=True, error_model="numpy")
def _advance(li, lf, ri, rl, rn, ti, ci, cf, ai, af, wi, wf, rough, q, p, anchor, act, sc):
    """One step from a prepared scratch with activations act [A]: q, p, anchor updated in place.
    Returns the deepest penetration (m)."""
    th, cs, X, com, msum, mc, S, cp, depth, gn, w, V, cv, M, A, F, Q, u, qd, g, x, Lf = sc
    D = q.shape[0]
    L = li.shape[0]
    h = wf[W_DT]
    for a in range(D):
        Q[a] = 0.0
        for b in range(D):
            A[a, b] = M[a, b]
    # inertial force dT/dq at fixed velocities (dynamics._inertial_force)
    for t in range(ti.shape[0]):
        if ti[t, 2] == 1:
            continue
        free = ti[t, 1] == 1
        r = ti[t, 0]
        vcx = qd[li[r, L_DX]] if free else 0.0
        vcy = qd[li[r, L_DY]] if free else 0.0
        for i in range(L):
            if li[i, L_TREE] != t or (li[i, L_PARENT] < 0 and not free):
                continue
            rx, ry = com[i, 0] - X[i, 0], com[i, 1] - X[i, 1]
            vx, vy = V[i, 0] - w[i] * ry, V[i, 1] + w[i] * rx
            m = lf[i, F_MASS]
            ux, uy = m * (vx - vcx), m * (vy - vcy)
            # suffix sums from link i up its chain: P_k = sum over chain links at or below k of w s
            Px, Py = 0.0, 0.0
            nxt_x, nxt_y = com[i, 0], com[i, 1]
            k = i
            while k >= 0:
                Px = Px + w[k] * (nxt_x - X[k, 0])
                Py = Py + w[k] * (nxt_y - X[k, 1])
                nxt_x, nxt_y = X[k, 0], X[k, 1]
                rot = li[k, L_ROT]
                if rot >= 0 and not (free and li[k, L_PARENT] < 0):
                    Q[rot] += -(ux * Px + uy * Py)
                k = li[k, L_PARENT]
    # gravity
    grav = wf[W_GRAVITY]
    for a in range(D):
        x[a] = 0.0
    for t in range(ti.shape[0]):
        r = ti[t, 0]
        if ti[t, 1] == 1:
            mt = 0.0
            for i in range(L):
                if li[i, L_TREE] == t:
                    mt = mt + lf[i, F_MASS]
            x[li[r, L_DY]] = -(mt * grav)
            continue
        for i in range(L):
            if li[i, L_TREE] != t or li[i, L_PARENT] < 0:
                continue
            n = _point_row(rl, rn, X, i, com[i, 0], com[i, 1], 0.0, 1.0, g)
            _force(Q, -(lf[i, F_MASS] * grav), ri[i], g, n)
    _turn(li, ti, S, x, -1, 1, D)
    for a in range(D):
        Q[a] += x[a]
    # passive joint springs, then stops
    for i in range(L):
        if li[i, L_SPRING] == 1:
            d = li[i, L_ROT]
            k, c, rest = lf[i, F_JSPRING], lf[i, F_JSPRING + 1], lf[i, F_JSPRING + 2]
            phi = th[i] - th[li[i, L_PARENT]]
            _element_joint(A, Q, d, h, -k * (phi - rest) - c * u[d], k, c, u[d])
    for i in range(L):
        if li[i, L_LIMIT] == 1:
            d = li[i, L_ROT]
            lo, hi, k, c = lf[i, F_LIMIT], lf[i, F_LIMIT + 1], lf[i, F_LIMIT + 2], lf[i, F_LIMIT + 3]
            phi = th[i] - th[li[i, L_PARENT]]
            below = max(k * (lo - phi) - c * u[d], 0.0)
            above = min(k * (hi - phi) - c * u[d], 0.0)
            on = 1.0 if ((phi < lo) and (below > 0)) or ((phi > hi) and (above < 0)) else 0.0
            torque = below if phi < lo else (above if phi > hi else 0.0)
            _element_joint(A, Q, d, h, torque, on * k, on * c, u[d])
    # actuators (angular servos)
    for a in range(ai.shape[0]):
        j = ai[a]
        d = li[j, L_ROT]
        target = af[a, 0] + act[a] * (af[a, 1] - af[a, 0])
        ks, kd = af[a, 2], af[a, 3]
        phi = th[j] - th[li[j, L_PARENT]]
        _element_joint(A, Q, d, h, ks * (target - phi) - kd * u[d], ks, kd, u[d])
    # ground contact and stick-slip friction (dynamics._ground_laws)
    gk, gc, slip = wf[W_GK], wf[W_GC], wf[W_SLIP]
    deepest = -math.inf
    for c in range(ci.shape[0]):
        i = ci[c]
        nx, ny, tx, ty = gn[c, 0], gn[c, 1], gn[c, 2], gn[c, 3]
        dep = depth[c]
        deepest = max(deepest, dep)
        vx, vy = cv[c, 0], cv[c, 1]
        vn = vx * nx + vy * ny
        vt = vx * tx + vy * ty
        fn = gk * dep - gc * vn
        on = dep > 0 and fn > 0
        N = fn if on else 0.0
        stretch = (cp[c, 0] - anchor[c, 0]) * tx + (cp[c, 1] - anchor[c, 1]) * ty
        if li[i, L_ANISO] == 1:
            frm, to = li[i, L_AX_FROM], li[i, L_AX_TO]
            if frm >= 0:
                axx, axy = X[to, 0] - X[frm, 0], X[to, 1] - X[frm, 1]
            else:
                axx, axy = cs[i, 0], cs[i, 1]
            along = axx * tx + axy * ty
            mu = lf[i, F_MU] if along * (gk * stretch + vt) > 0 else lf[i, F_MU + 1]
        else:
            mu = lf[i, F_MU]
        limit = mu * N
        held = 0.0
        if on:
            n = _point_row(rl, rn, X, i, cp[c, 0], cp[c, 1], nx, ny, g)
            _outer(A, h * gc + (h * h) * gk, ri[i], g, n)
            _force(Q, fn - (h * gk) * vn, ri[i], g, n)
        if limit > 0:
            # the stick-slip decision (dynamics._stick_law); no limit: no friction element at all
            cs_ = limit / slip
            s = min(max(stretch, -limit / gk), limit / gk)
            trial = -gk * s - cs_ * vt
            slide = limit / max(abs(vt), slip)
            n = _point_row(rl, rn, X, i, cp[c, 0], cp[c, 1], tx, ty, g)
            if abs(trial) <= limit:
                _outer(A, h * cs_ + (h * h) * gk, ri[i], g, n)
                _force(Q, trial - (h * gk) * vt, ri[i], g, n)
                held = s
            else:
                _outer(A, h * slide, ri[i], g, n)
                _force(Q, -slide * vt, ri[i], g, n)
        anchor[c, 0] = cp[c, 0] - held * tx
        anchor[c, 1] = cp[c, 1] - held * ty
    # the step: A du = h Q; p += S^T M du; q += h v*
    for a in range(D):
        Q[a] = h * Q[a]
    _solve(A, Q, x, F, Lf, D)  # x = du
    for a in range(D):
        acc = 0.0
        for b in range(D):
            acc += M[a, b] * x[b]
        g[a] = acc
    _turn(li, ti, S, g, 1, 1, D)
    for a in range(D):
        p[a] = p[a] + g[a]
        x[a] = u[a] + x[a]  # u* in tree coordinates
    _turn(li, ti, S, x, -1, 0, D)
    for a in range(D):
        qd[a] = x[a]
        q[a] = q[a] + h * x[a]
    return deepest


@njit(cache=True, error_model="numpy")
def _sense(li, si, sf, wi, depth, th, bits):
    for s in range(si.shape[0]):
        kind, link = si[s, 0], si[s, 1]
        if kind == 0:
            bits[s] = 1.0 if depth[link] > 0 else 0.0  # touch: link holds the contact index
        else:
            par = li[link, L_PARENT]
            ang = th[link] if (par < 0 or kind == 2) else th[link] - th[par]
            a = _wrap(ang)
            bits[s] = 1.0 if (a >= sf[s, 0] and a <= sf[s, 1]) else 0.0


@njit(cache=True, error_model="numpy")
def _san(WT, k1, k2, bits, istate, out, total, act, dt, H):
    """The SAN's node update (``sanlab.san.San.apply``): WT [I, N] the weights transposed, inputs
    the sensor bits then the nodes' previous outputs; act [A] the activations of the actuator
    nodes. Every input is 0 or 1, so a node's sum is the sum of its weights from the inputs that
    are on (exact: small integers)."""
    N = WT.shape[1]
    S = bits.shape[0]
    for n in range(N):
        total[n] = 0.0
    for i in range(S):
        if bits[i] != 0.0:
            for n in range(N):
                total[n] += WT[i, n]
    for i in range(N):
        if out[i] != 0.0:
            for n in range(N):
                total[n] += WT[S + i, n]
    for n in range(N):
        rate = k1[n] if total[n] > 0 else k2[n]
        s = min(max(istate[n] + rate * dt, 0.0), 1.0)
        istate[n] = s
        if n >= H:
            act[n - H] = (min(max(total[n], -2.0), 2.0) + 2.0) * 0.25
        if out[n] == 1.0 and s == 0.0:
            out[n] = 0.0
        elif out[n] == 0.0 and s == 1.0:
            out[n] = 1.0


@njit(cache=True, error_model="numpy", parallel=True)
def rollout_san(li, lf, ri, rl, rn, ti, ci, cf, si, sf, ai, af, wf, wi, rough, WT, k1, k2, q, p, anchor, istate, out, t, steps):
    """Run ``steps`` steps of B creatures under SANs, in place on the state: q, p [B, D], anchor
    [B, C, 2], the SAN's istate and out [B, N], t [B]. WT [B, I, N] weights, transposed (float64), k1, k2 [B, N].
    Returns the deepest penetration per creature [B] (m)."""
    B = q.shape[0]
    D = q.shape[1]
    L, C = li.shape[0], ci.shape[0]
    deepest = np.full(B, -np.inf)
    h = wf[W_DT]
    H = wi[W_HIDDEN]
    for b in prange(B):
        sc = _scratch(L, C, D)
        bits = np.zeros(si.shape[0])
        act = np.zeros(ai.shape[0])
        total = np.zeros(WT.shape[2])
        qb, pb, ab = q[b], p[b], anchor[b]
        dmax = -np.inf
        for _ in range(steps):
            _prepare(li, lf, ri, rl, rn, ti, ci, cf, wi, wf, rough, qb, pb, sc)
            _sense(li, si, sf, wi, sc[8], sc[0], bits)
            _san(WT[b], k1[b], k2[b], bits, istate[b], out[b], total, act, h, H)
            dmax = max(dmax, _advance(li, lf, ri, rl, rn, ti, ci, cf, ai, af, wi, wf, rough, qb, pb, ab, act, sc))
            t[b] += h
        deepest[b] = dmax
    return deepest


# ------------------------------------------------------------------ the C++ kernel (sanlab/sim/_kernel)


def _library():
    """The compiled kernel (built by the package's install: setup.py), loaded once."""
    global _LIB
    if _LIB is None:
        import ctypes
        import importlib.machinery
        from pathlib import Path

        here = Path(__file__).parent
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = here / f"_kernel_lib{suffix}"
            if path.exists():
                break
        else:
            raise RuntimeError(f"sanlab's simulator kernel is not built in {here}: reinstall with `pip install -e .`")
        lib = ctypes.CDLL(str(path))
        P = ctypes.c_void_p
        lib.sanlab_rollout_san.restype = ctypes.c_int
        lib.sanlab_rollout_san.argtypes = [P] * 26 + [ctypes.c_int64, ctypes.c_int64]
        lib.sanlab_kernel_lanes.restype = ctypes.c_int
        _LIB = lib
    return _LIB


_LIB = None


def lanes() -> int:
    """Creatures per tile (the SIMD width the kernel was built for)."""
    return int(_library().sanlab_kernel_lanes())


def _tile(x: np.ndarray, W: int) -> np.ndarray:
    """[B, ...] -> [T, ..., W], the batch padded with copies of its last row."""
    B = x.shape[0]
    T = -(-B // W)
    if T * W != B:
        x = np.concatenate([x, np.repeat(x[-1:], T * W - B, 0)])
    return np.ascontiguousarray(np.moveaxis(x.reshape(T, W, *x.shape[1:]), 1, -1), np.float64)


def _untile(x: np.ndarray, B: int) -> np.ndarray:
    return np.moveaxis(x, -1, 1).reshape(-1, *x.shape[1:-1])[:B]


def run_san(pk: Packed, weights, k1, k2, q, p, anchor, istate, out, steps: int) -> dict:
    """``steps`` steps of B creatures under SANs on the C++ kernel. weights [B, N, I], k1, k2
    [B, N] (1/s), q, p [B, D], anchor [B, C, 2], istate, out [B, N]. Returns the state after
    them: q, p, anchor, istate, out, t (s since the call), and the deepest penetration dmax [B]
    (m; -inf without contacts)."""
    W = lanes()
    B = q.shape[0]
    N = istate.shape[1]
    dims = np.array([pk.li.shape[0], pk.ci.shape[0], pk.ti.shape[0], pk.ndof, pk.si.shape[0], pk.ai.shape[0],
                     pk.ri.shape[1], pk.rough.shape[0], N, pk.si.shape[0] + N], np.int32)
    st = [_tile(np.asarray(a, np.float64), W) for a in (q, p, anchor, istate, out, np.zeros(B), np.full(B, -np.inf))]
    ctrl = [_tile(np.swapaxes(np.asarray(weights, np.float64), 1, 2), W), _tile(np.asarray(k1, np.float64), W),
            _tile(np.asarray(k2, np.float64), W)]
    tables = [dims, pk.li, pk.ri, pk.rl, pk.rn, pk.ti, pk.ci, pk.si, pk.ai, pk.wi, pk.lf, pk.cf, pk.sf, pk.af, pk.wf,
              pk.rough]
    tables = [np.ascontiguousarray(a) for a in tables]
    rc = _library().sanlab_rollout_san(*[a.ctypes.data for a in tables + st + ctrl], st[0].shape[0], int(steps))
    if rc != 0:
        raise ValueError("the creature is larger than the kernel's scratch")
    names = ("q", "p", "anchor", "istate", "out", "t", "dmax")
    return {n: _untile(a, B) for n, a in zip(names, st)}
