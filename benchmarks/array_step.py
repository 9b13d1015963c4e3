"""Experiment (issue 29): the step of ``sanlab.sim.dynamics`` written over arrays, batch axis
last, timed against the engine in one process. Not used by sanlab: it is the measured record of
why the engine keeps its form (docs/engine-history.md, "Round 3").

    python benchmarks/array_step.py [--creature bounder] [--batches 1,32,2048] [--steps 1000]

prints the float64 agreement of one step with ``dynamics`` on every supported built-in, then per
batch size the microseconds per step of both (a random SAN closed loop, best of 3, the two
alternated) and their ratio.

``dynamics`` traces one creature's step as scalar code unrolled over its links, contacts and
dofs (structural zeros vanish at trace time); batched with ``vmap``, every scalar becomes a
``[B]`` vector and XLA's CPU backend makes a kernel of nearly every few of them. Here the same
equations (the module docstring of ``dynamics``) are written once per phase over ``[L, B]``,
``[C, B]``, ``[D, B]`` and ``[D, D, B]`` arrays, the creature's structure as static numpy tables
(ancestor masks, dof maps), so that each phase is a few wide kernels whose inner loop runs over
the batch. Planar vectors are (x, y) pairs of such arrays. Every operation is a map over the
batch axis: a controller steps bit for bit the same alone or anywhere in a batch.

The arithmetic differs from ``dynamics`` in order only (sums over masks instead of chains):
float64 runs agree to round-off.

Supported: trees of rigid links, free or welded, in the vertical plane on any terrain, with
angular servos, joint springs and stops, isotropic and anisotropic friction, on the dense route
(:func:`supported`).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from sanlab.sim import dynamics as dyn
from sanlab.sim.model import Structure


def supported(st: Structure) -> bool:
    """Whether this module can step creatures of structure ``st``."""
    return (st.plane == "vertical" and not st.edges and not st.springs and not st.lin_act
            and not any(ls.point for ls in st.links) and not st.articulated)


@dataclass(frozen=True)
class Tables:
    """Static index tables of one structure (numpy; trace-time constants)."""

    anc: np.ndarray  # [L, L] 1.0 where column k is on row i's chain (root .. i)
    par: np.ndarray  # [L] parent index (self for roots)
    is_root: np.ndarray  # [L] bool
    welded: np.ndarray  # [L] bool: root welded to the world
    rot_dof: np.ndarray  # [L] own rotational dof, D (a zero slot) when none
    moves: np.ndarray  # [L] bool: link has dofs (not a welded root)
    tree: np.ndarray  # [L] tree index
    tree_free: np.ndarray  # [T] bool
    tree_dx: np.ndarray  # [T] dof_x (D when welded)
    tree_dy: np.ndarray  # [T]
    tree_mask: np.ndarray  # [T, L]
    dof_tree_mask: np.ndarray  # [T, D]
    turning: np.ndarray  # [L] bool: owns a rot dof of a free tree (the tree turns about its COM)
    dof_link: np.ndarray  # [D] link whose rot dof this is (0 for translational)
    dof_turning: np.ndarray  # [D] bool: rot dof of a turning link
    dof_tree: np.ndarray  # [D] tree of the dof
    rot_rows: np.ndarray  # [L, D] 1.0 on the rot dofs of a link's chain (gradient of its angle)
    joint: np.ndarray  # [L] bool: a joint (non-root link with a rot dof)
    welded_tree: np.ndarray  # [L] bool: a moving link of a welded tree
    jac_on: np.ndarray  # [L, D] bool: rot dof d turns link l
    jac_tx: np.ndarray  # [L, D] 1.0 where d is the x translation of link l's tree
    jac_ty: np.ndarray  # [L, D]
    contact_link: np.ndarray  # [C]
    aniso: np.ndarray  # [C] bool
    aniso_axis: np.ndarray  # [C] bool: axis between two link origins
    aniso_frm: np.ndarray  # [C]
    aniso_to: np.ndarray  # [C]
    act_link: np.ndarray  # [A]
    act_dof: np.ndarray  # [A]
    spring_link: np.ndarray  # [Js]
    limit_link: np.ndarray  # [Jl]


@lru_cache(maxsize=64)
def tables(st: Structure) -> Tables:
    L, D = len(st.links), st.ndof
    anc = np.zeros((L, L))
    par = np.arange(L)
    rot_dof = np.full(L, D)
    rot_rows = np.zeros((L, D))
    for ls in st.links:
        for k in ls.chain:
            anc[ls.index, k] = 1.0
            if st.links[k].dof_rot >= 0:
                rot_rows[ls.index, st.links[k].dof_rot] = 1.0
        if ls.parent >= 0:
            par[ls.index] = ls.parent
        if ls.dof_rot >= 0:
            rot_dof[ls.index] = ls.dof_rot
    is_root = np.array([ls.parent < 0 for ls in st.links])
    welded = np.array([ls.parent < 0 and ls.dof_x < 0 for ls in st.links])
    T = len(st.trees)
    tree = np.array([ls.tree for ls in st.links])
    tree_free = np.array([t.free for t in st.trees])
    tree_dx = np.array([st.links[t.root].dof_x if t.free else D for t in st.trees])
    tree_dy = np.array([st.links[t.root].dof_y if t.free else D for t in st.trees])
    tree_mask = np.zeros((T, L))
    for ti, t in enumerate(st.trees):
        tree_mask[ti, list(t.links)] = 1.0
    turning = np.array([ls.dof_rot >= 0 and bool(tree_free[ls.tree]) for ls in st.links])
    dof_link = np.zeros(D, int)
    dof_rot = np.zeros(D, bool)
    dof_tree = np.zeros(D, int)
    dof_is_x = np.zeros(D, bool)
    dof_is_y = np.zeros(D, bool)
    for ls in st.links:
        if ls.dof_rot >= 0:
            dof_link[ls.dof_rot] = ls.index
            dof_rot[ls.dof_rot] = True
            dof_tree[ls.dof_rot] = ls.tree
        if ls.dof_x >= 0:
            dof_is_x[ls.dof_x] = True
            dof_is_y[ls.dof_y] = True
            dof_tree[ls.dof_x] = dof_tree[ls.dof_y] = ls.tree
    dof_tree_mask = (dof_tree[None, :] == np.arange(T)[:, None]).astype(float)
    joint = np.array([ls.parent >= 0 and ls.dof_rot >= 0 for ls in st.links])
    welded_tree = ~tree_free[tree] & ~is_root
    jac_on = (rot_rows > 0) & dof_rot[None, :]
    same = dof_tree[None, :] == tree[:, None]
    jac_tx = (dof_is_x[None, :] & same).astype(float)
    jac_ty = (dof_is_y[None, :] & same).astype(float)
    cl = np.array(st.contacts, int)
    aniso = np.array([bool(st.aniso[i][0]) for i in st.contacts], bool)
    frm = np.array([max(st.aniso[i][1], 0) for i in st.contacts], int)
    to = np.array([max(st.aniso[i][2], 0) for i in st.contacts], int)
    axis2 = np.array([st.aniso[i][1] >= 0 for i in st.contacts], bool)
    act_link = np.array([ref for _, ref in st.actuators], int)
    act_dof = np.array([st.links[ref].dof_rot for _, ref in st.actuators], int)
    return Tables(anc, par, is_root, welded, rot_dof, ~welded, tree, tree_free, tree_dx, tree_dy, tree_mask,
                  dof_tree_mask, turning, dof_link, dof_rot & turning[dof_link], dof_tree, rot_rows, joint,
                  welded_tree, jac_on, jac_tx, jac_ty, cl, aniso, axis2, frm, to, act_link, act_dof,
                  np.array(st.joint_springs, int), np.array(st.limits, int))


# ---------------------------------------------------------------- array helpers (axis 0 static)


def _take(x, idx):
    """x[idx] along axis 0 for a static index array: slices (XLA fuses a slice into its consumer;
    a gather is a kernel of its own)."""
    idx = [int(i) for i in np.asarray(idx).reshape(-1)]
    if not idx:
        return x[:0]
    runs, start = [], 0
    for n in range(1, len(idx) + 1):
        if n == len(idx) or idx[n] != idx[n - 1] + 1:
            runs.append(x[idx[start]:idx[n - 1] + 1])
            start = n
    return runs[0] if len(runs) == 1 else jnp.concatenate(runs)


def _usum(x, axis: int = 0):
    """The sum over a small static axis as adds in a fixed order (a reduction over a tiny axis is
    several times slower on XLA's CPU backend)."""
    parts = [jax.lax.index_in_dim(x, i, axis, keepdims=False) for i in range(x.shape[axis])]
    out = parts[0]
    for y in parts[1:]:
        out = out + y
    return out


def _mv(mask: np.ndarray, x):
    """mask [N, K] (static) times x [K, ...]: adds in a fixed order over the columns that are not
    all zero (structural zeros vanish at trace time); a factor 1 is dropped."""
    shape = (mask.shape[0],) + tuple(x.shape[1:])
    out = None
    for k in range(mask.shape[1]):
        col = mask[:, k]
        if not col.any():
            continue
        xk = x[k][None]
        term = xk if np.all(col == 1.0) else jnp.asarray(col, x.dtype).reshape((-1,) + (1,) * (x.ndim - 1)) * xk
        out = term if out is None else out + term
    if out is None:
        return jnp.zeros(shape, x.dtype)
    return jnp.broadcast_to(out, shape)


def _scatter_add(n: int, idx, vals):
    """[n, ...] holding vals [K, ...] added at static indices idx (repeats add; >= n dropped)."""
    P = np.zeros((n, len(idx)))
    for j, i in enumerate(np.asarray(idx).reshape(-1)):
        if i < n:
            P[i, j] = 1.0
    return _mv(P, vals)


def _pad(x):
    """x [D, ...] with a zero slot appended (index D)."""
    return jnp.concatenate([x, jnp.zeros((1,) + x.shape[1:], x.dtype)])


def _fence(tree, gate):
    """dynamics._barrier: materialise a phase's arrays once (XLA's fusion would otherwise
    recompute them inside every consumer, element by element)."""
    return tree if gate is None else dyn._barrier(tree, gate)


def _rot(cs, r):
    c, s = cs
    return (c * r[0] - s * r[1], s * r[0] + c * r[1])


def _where(mask: np.ndarray, a, b):
    """jnp.where with a static mask over axis 0 (and any further static axes)."""
    m = mask.reshape(mask.shape + (1,) * (max(jnp.ndim(a), jnp.ndim(b)) - mask.ndim))
    return jnp.where(m, a, b)


def batch_last(x, batched: bool):
    """A parameter as this module holds it: [..., B] (batched model) or [..., 1]."""
    return jnp.moveaxis(x, 0, -1) if batched else x[..., None]


# ---------------------------------------------------------------- the step


class Kin(NamedTuple):
    """Kinematics of a batch of states, batch axis last (planar vectors as (x, y) pairs)."""

    th: Any  # [L, B]
    cs: Any  # ([L, B], [L, B])
    X: Any  # link origins
    com: Any  # centres of mass
    S: Any  # per turning link (sum over its subtree of m (c - X_k)) / m_tree
    cp: Any  # contact points
    depth: Any  # [C, B]
    terrain: Any  # (h, dh/dx) under each contact
    M: Any  # [D, D, B] tree coordinates
    Jcom: Any  # ([L, D, B], [L, D, B]) centre-of-mass Jacobians
    JX: Any  # link-origin Jacobians
    Jc: Any  # contact Jacobians
    u: Any  # [D, B] tree-coordinate velocity
    qd: Any  # [D, B] state-coordinate velocity
    V: Any  # link origin velocities
    w: Any  # [L, B]
    cv: Any  # contact velocities


def _jac(tb: Tables, X, P, links):
    """Jacobians in tree coordinates (x, y), each [N, D, B], of points P ([N, B] pairs) fixed on
    static ``links`` [N] (dynamics.jacobian)."""
    Xd = (_take(X[0], tb.dof_link), _take(X[1], tb.dof_link))  # origin of the link owning each rot dof
    on = tb.jac_on[links]
    jx = _where(on, -(P[1][:, None] - Xd[1][None]), jnp.asarray(tb.jac_tx[links][..., None], P[0].dtype))
    jy = _where(on, P[0][:, None] - Xd[0][None], jnp.asarray(tb.jac_ty[links][..., None], P[0].dtype))
    return jx, jy


def _jv(J, u):
    """Point velocities J u: ([N, B], [N, B])."""
    return _usum(J[0] * u[None], 1), _usum(J[1] * u[None], 1)


def _solve(A, b, gate=None):
    """Solve A x = b, A [D, D, B] symmetric positive definite, by L D L^T eliminating the last row
    first (dynamics' elimination order: leaves before roots), one rank-1 update per row."""
    D = b.shape[0]
    cols, invs = [None] * D, [None] * D
    for k in range(D - 1, -1, -1):
        inv = 1.0 / A[k, k]
        col = A[:k, k] * inv
        A = A[:k, :k] - col[:, None] * A[k, :k][None]
        cols[k], invs[k] = col, inv
    cols, invs = _fence((cols, invs), gate)
    y = b
    for k in range(D - 1, 0, -1):
        y = jnp.concatenate([y[:k] - cols[k] * y[k][None], y[k:]])
    y = _fence(y, gate) * jnp.stack(invs)
    for k in range(1, D):
        y = jnp.concatenate([y[:k], (y[k] - _usum(cols[k] * y[:k]))[None], y[k + 1:]])
    return y


def _turn(tb: Tables, S):
    """Per dof: T_k = (S_ky, -S_kx) of a turning link's rot dof, else 0 ([D, B] pair)."""
    Sx, Sy = _take(S[0], tb.dof_link), _take(S[1], tb.dof_link)
    return _where(tb.dof_turning, Sy, 0.0), _where(tb.dof_turning, -Sx, 0.0)


def _place(tb: Tables, xy, D):
    return _scatter_add(D, tb.tree_dx, xy[0]) + _scatter_add(D, tb.tree_dy, xy[1])


def _tree_xy(tb: Tables, f):
    fp = _pad(f)
    return _take(fp, tb.tree_dx), _take(fp, tb.tree_dy)  # [T, B]


def from_tree(tb, S, u):
    T = _turn(tb, S)
    return u - _place(tb, (_mv(tb.dof_tree_mask, T[0] * u), _mv(tb.dof_tree_mask, T[1] * u)), u.shape[0])


def force_to_tree(tb, S, f):
    T = _turn(tb, S)
    fx, fy = _tree_xy(tb, f)
    return f - (T[0] * _take(fx, tb.dof_tree) + T[1] * _take(fy, tb.dof_tree))


def force_from_tree(tb, S, g):
    T = _turn(tb, S)
    gx, gy = _tree_xy(tb, g)
    return g + (T[0] * _take(gx, tb.dof_tree) + T[1] * _take(gy, tb.dof_tree))


def prepare(st: Structure, p, q, mom, gate=None) -> Kin:
    """Kinematics, mass matrix and velocity of a batch: q, mom [D, B]; p: parameters batch-last
    (:func:`batch_last`)."""
    tb = tables(st)
    dt = q.dtype
    qp = _pad(q)
    inc = _where(tb.welded, p.root_pose[:, 2], _take(qp, tb.rot_dof))
    th = _mv(tb.anc, inc)
    cs = _fence(dyn.sincos(th), gate)
    r = _rot((_take(cs[0], tb.par), _take(cs[1], tb.par)), (p.anchor[:, 0], p.anchor[:, 1]))
    r = (_where(tb.is_root, _where(tb.welded, p.root_pose[:, 0], 0.0), r[0]),
         _where(tb.is_root, _where(tb.welded, p.root_pose[:, 1], 0.0), r[1]))
    Xr = (_mv(tb.anc, r[0]), _mv(tb.anc, r[1]))
    rc = _rot(cs, (p.com[:, 0], p.com[:, 1]))
    comr = (Xr[0] + rc[0], Xr[1] + rc[1])
    m = _where(tb.moves, p.mass, 0.0)
    mt = _mv(tb.tree_mask, m)
    mct = (_mv(tb.tree_mask, m * comr[0]), _mv(tb.tree_mask, m * comr[1]))
    qx, qy = _take(qp, tb.tree_dx), _take(qp, tb.tree_dy)
    sx = _where(tb.tree_free, qx - mct[0] / mt, 0.0)
    sy = _where(tb.tree_free, qy - mct[1] / mt, 0.0)
    sx, sy = _take(sx, tb.tree), _take(sy, tb.tree)
    X = (Xr[0] + sx, Xr[1] + sy)
    com = (comr[0] + sx, comr[1] + sy)
    desc = tb.anc.T
    msub = _mv(desc, m)
    mcsub = (_mv(desc, m * comr[0]), _mv(desc, m * comr[1]))
    mtl = _take(mt, tb.tree)
    S = (_where(tb.turning, (mcsub[0] - msub * Xr[0]) / mtl, 0.0),
         _where(tb.turning, (mcsub[1] - msub * Xr[1]) / mtl, 0.0))
    X, com, S = _fence((X, com, S), gate)
    lc = tb.contact_link
    if len(lc):
        cc = _rot((_take(cs[0], lc), _take(cs[1], lc)), (p.contact[:, 0], p.contact[:, 1]))
        cp = (_take(X[0], lc) + cc[0], _take(X[1], lc) + cc[1])
        h, dh = dyn.terrain_height(st, p, cp[0])
        h, dh = h + jnp.zeros_like(cp[0]), dh + jnp.zeros_like(cp[0])
        depth = (h - cp[1]) * jax.lax.rsqrt(1.0 + dh * dh)
    else:
        cp = (jnp.zeros((0,) + q.shape[1:], dt),) * 2
        h = dh = depth = cp[0]
    links = np.arange(len(st.links))
    Jcom = _jac(tb, X, com, links)
    JX = _jac(tb, X, X, links)
    Jc = _jac(tb, X, cp, lc)
    cp, depth, h, dh, Jcom, JX, Jc = _fence((cp, depth, h, dh, Jcom, JX, Jc), gate)
    M = None
    for i in range(len(st.links)):
        if not tb.moves[i]:
            continue
        jx, jy = Jcom[0][i], Jcom[1][i]
        term = m[i][None, None] * (jx[:, None] * jx[None] + jy[:, None] * jy[None])
        RR = np.outer(tb.rot_rows[i], tb.rot_rows[i])
        if RR.any():
            term = term + jnp.asarray(RR[..., None], dt) * p.inertia[i][None, None]
        M = term if M is None else M + term
    M = _fence(M, gate)
    u = _fence(_solve(M, force_to_tree(tb, S, mom), gate), gate)
    V, w, qd, cv = _fence((_jv(JX, u), _mv(tb.rot_rows, u), from_tree(tb, S, u), _jv(Jc, u)), gate)
    return Kin(th, cs, X, com, S, cp, depth, (h, dh), M, Jcom, JX, Jc, u, qd, V, w, cv)


def advance(st: Structure, p, k: Kin, q, mom, anchor, t, u, gate=None):
    """One step of a batch from its kinematics ``k``: q, mom [D, B], anchor ([C, B], [C, B]),
    activations u [A, B]. Returns (q, qd, t, p, anchor) of the next state and the deepest
    penetration [B]."""
    tb = tables(st)
    h = p.dt
    D = st.ndof
    dt = q.dtype
    qd = k.u
    m = _where(tb.moves, p.mass, 0.0)
    # inertial force dT/dq (dynamics._inertial_force_linear)
    vci = _jv(k.Jcom, qd)
    vcx, vcy = _tree_xy(tb, k.qd)
    vcx, vcy = _take(_where(tb.tree_free, vcx, 0.0), tb.tree), _take(_where(tb.tree_free, vcy, 0.0), tb.tree)
    Ux, Uy = m * (vci[0] - vcx), m * (vci[1] - vcy)
    a = Ux * vci[1] - Uy * vci[0]
    desc = tb.anc.T
    Bx, By = _mv(desc, Ux), _mv(desc, Uy)
    fin = -_mv(desc, a) + (Bx * k.V[1] - By * k.V[0])
    Q = _scatter_add(D, tb.rot_dof, _where(tb.joint, fin, 0.0))
    # gravity: on a free tree's centre of mass, link by link in a welded tree
    g = p.gravity
    wt = _where(tb.tree_free, _mv(tb.tree_mask, m), 0.0)
    Q = Q + force_to_tree(tb, k.S, _place(tb, (jnp.zeros_like(wt), -wt * g), D))
    for i in np.flatnonzero(tb.welded_tree):
        Q = Q - (m[i] * g)[None] * k.Jcom[1][i]
    # unit-row elements on joint dofs
    coefs, forces, dofs = [], [], []
    phi_all = k.th - _take(k.th, tb.par)
    if len(tb.spring_link):
        i = tb.spring_link
        d = tb.rot_dof[i]
        js = _take(p.jspring, i)
        kk, c, rest = js[:, 0], js[:, 1], js[:, 2]
        rate = _take(qd, d)
        coef, f = dyn._element(h, -kk * (_take(phi_all, i) - rest) - c * rate, kk, c, rate)
        coefs.append(coef)
        forces.append(f)
        dofs.append(d)
    if len(tb.limit_link):
        i = tb.limit_link
        d = tb.rot_dof[i]
        lim = _take(p.limit, i)
        lo, hi, kk, c = lim[:, 0], lim[:, 1], lim[:, 2], lim[:, 3]
        phi = _take(phi_all, i)
        rate = _take(qd, d)
        below = jnp.maximum(kk * (lo - phi) - c * rate, 0.0)
        above = jnp.minimum(kk * (hi - phi) - c * rate, 0.0)
        on = jnp.where(((phi < lo) & (below > 0)) | ((phi > hi) & (above < 0)), 1.0, 0.0)
        torque = jnp.where(phi < lo, below, jnp.where(phi > hi, above, 0.0))
        coef, f = dyn._element(h, torque, on * kk, on * c, rate)
        coefs.append(coef)
        forces.append(f)
        dofs.append(d)
    if len(tb.act_link):
        i = tb.act_link
        d = tb.act_dof
        target = p.act_min + u * (p.act_max - p.act_min)
        rate = _take(qd, d)
        coef, f = dyn._element(h, p.act_ks * (target - _take(phi_all, i)) - p.act_kd * rate, p.act_ks, p.act_kd, rate)
        coefs.append(coef)
        forces.append(f)
        dofs.append(d)
    A = k.M
    if dofs:
        d = np.concatenate(dofs)
        diag = _scatter_add(D, d, jnp.concatenate(coefs))
        A = A + jnp.asarray(np.eye(D)[..., None], dt) * diag[:, None]
        Q = Q + _scatter_add(D, d, jnp.concatenate(forces))
    lc = tb.contact_link
    deepest = jnp.zeros(q.shape[1:], dt)
    if len(lc):
        kg, cg = p.ground_k, p.ground_c
        _, dh = k.terrain
        inv = jax.lax.rsqrt(1.0 + dh * dh)
        n = (-dh * inv, inv)
        tt = (inv, dh * inv)
        depth = k.depth
        deepest = jnp.max(depth, axis=0)
        vn = k.cv[0] * n[0] + k.cv[1] * n[1]
        vt = k.cv[0] * tt[0] + k.cv[1] * tt[1]
        fn = kg * depth - cg * vn
        on = (depth > 0) & (fn > 0)
        N = jnp.where(on, fn, 0.0)
        stretch = (k.cp[0] - anchor[0]) * tt[0] + (k.cp[1] - anchor[1]) * tt[1]
        mus = _take(p.mu, lc)
        mu = mus[:, 0]
        if tb.aniso.any():
            ax = (_where(tb.aniso_axis, _take(k.X[0], tb.aniso_to) - _take(k.X[0], tb.aniso_frm), _take(k.cs[0], lc)),
                  _where(tb.aniso_axis, _take(k.X[1], tb.aniso_to) - _take(k.X[1], tb.aniso_frm), _take(k.cs[1], lc)))
            along = ax[0] * tt[0] + ax[1] * tt[1]
            fwd = along * (kg * stretch + vt) > 0
            mu = _where(tb.aniso, jnp.where(fwd, mus[:, 0], mus[:, 1]), mu)
        ncoef = jnp.where(on, h * cg + (h * h) * kg, 0.0)
        nforce = jnp.where(on, fn - (h * kg) * vn, 0.0)
        law = dyn._stick_law(stretch, vt, mu * N, p)
        (tcoef, tforce), held = dyn._stick_element(law, vt, p)
        n, tt, ncoef, nforce, tcoef, tforce, held = _fence((n, tt, ncoef, nforce, tcoef, tforce, held), gate)
        Jc = k.Jc
        G = jnp.concatenate([Jc[0] * n[0][:, None] + Jc[1] * n[1][:, None],
                             Jc[0] * tt[0][:, None] + Jc[1] * tt[1][:, None]])  # [2C, D, B]
        coef = jnp.concatenate([ncoef, tcoef])
        force = jnp.concatenate([nforce, tforce])
        G = _fence(G, gate)
        for e in range(G.shape[0]):
            A = A + coef[e][None, None] * G[e][:, None] * G[e][None]
            Q = Q + force[e][None] * G[e]
        anchor = (k.cp[0] - held * tt[0], k.cp[1] - held * tt[1])
    A, Q = _fence((A, Q), gate)
    du = _fence(_solve(A, h * Q, gate), gate)
    ustar = qd + du
    Mdu = _usum(k.M * du[None], 1)
    dp = force_from_tree(tb, k.S, Mdu)
    vstar = from_tree(tb, k.S, ustar)
    dp, anchor = _fence((dp, anchor), gate)
    return (q + h * vstar, vstar, t + h, mom + dp, anchor), deepest


def frame(k: Kin) -> dyn.Frame:
    """The batch-first view of ``k`` that sensors and observers read (one creature per row under
    ``vmap``): per link X, cs, com, V [B, L, 2], th, w [B, L]; contacts cp, cv [B, C, 2], depth
    [B, C], terrain [B, C, 2]; qd [B, D]."""
    two = lambda v: jnp.stack([v[0].T, v[1].T], -1)
    fields: list[Any] = [two(k.X), two(k.V), two(k.cs), k.th.T, k.w.T, two(k.cp), two(k.cv), k.depth.T,
                         two(k.terrain), k.qd.T, None, two(k.com), None, None, None]
    return dyn.Frame(*fields)


# ---------------------------------------------------------------- measurement


def _rollouts(model, san):
    """Two jitted closed loops (params, cparams, state, steps) -> final q: the engine's vmapped
    step, and this module's batch-last one."""
    st = model.structure

    def control(m, c, state, fr, cstate):
        bits = dyn.sense(m, fr, state.t)
        return san.apply(c, cstate, bits, m.params.dt)

    def engine(cp, state, cstate, steps):
        def one(c, carry):
            state, cstate = carry
            fr = dyn.prepare(model, state, gate)
            cstate, u = control(model, c, state, fr, cstate)
            nxt, _ = dyn.advance(model, fr, state, u)
            return nxt, cstate

        gate = steps > 0
        step = jax.vmap(one, in_axes=(0, 0))
        return jax.lax.fori_loop(0, steps, lambda _, c: step(cp, c), (state, cstate))[0].q

    def arrays(cp, state, cstate, steps):
        pb = jax.tree_util.tree_map(lambda x: batch_last(x, False), model.params)
        gate = steps > 0

        def body(_, carry):
            state, cstate = carry
            k = prepare(st, pb, state.q.T, state.p.T, gate)
            fr = frame(k)
            cstate, u = jax.vmap(lambda c, s, f, cs: control(model, c, s, f, cs))(cp, state, fr, cstate)
            anchor = (state.anchor[:, :, 0].T, state.anchor[:, :, 1].T)
            (q, qd, t, p, anc), _ = advance(st, pb, k, state.q.T, state.p.T, anchor, state.t, u.T, gate)
            return dyn.State(q.T, qd.T, t, p.T, jnp.stack([anc[0].T, anc[1].T], -1)), cstate

        return jax.lax.fori_loop(0, steps, body, (state, cstate))[0].q

    return jax.jit(engine), jax.jit(arrays)


def agreement(names) -> None:
    """Float64: one step from random states, max relative difference of q, qd, p, anchor."""
    from sanlab import creature, sim

    for name in names:
        m = sim.compile_creature(creature.load(name), dtype="float64")
        st = m.structure
        if not supported(st):
            print(f"  {name}: not supported")
            continue
        rng = np.random.default_rng(0)
        B = 8
        q = np.asarray(m.params.q0)[None] + rng.normal(0, 0.05, (B, st.ndof))
        s = dyn.make_state(m, q, rng.normal(0, 0.5, (B, st.ndof)))
        s = s._replace(anchor=s.anchor + rng.normal(0, 0.002, s.anchor.shape))
        u = rng.uniform(0, 1, (B, st.n_actuators))
        ref = jax.vmap(lambda s, u, m=m: dyn.advance(m, dyn.prepare(m, s), s, u)[0])(s, u)
        pb = jax.tree_util.tree_map(lambda x: batch_last(x, False), m.params)
        k = prepare(st, pb, s.q.T, s.p.T)
        (q1, qd1, _, p1, anc), _ = advance(st, pb, k, s.q.T, s.p.T, (s.anchor[:, :, 0].T, s.anchor[:, :, 1].T), s.t, u.T)
        got = (q1.T, qd1.T, p1.T, jnp.stack([anc[0].T, anc[1].T], -1))
        worst = max(float(np.max(np.abs(np.asarray(a) - np.asarray(b)) / (1 + np.abs(np.asarray(a)))))
                    for a, b in zip((ref.q, ref.qd, ref.p, ref.anchor), got))
        print(f"  {name}: max relative difference {worst:.1e}")


def main() -> None:
    import argparse
    import time

    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--creature", default="bounder")
    ap.add_argument("--batches", default="1,32,2048")
    ap.add_argument("--steps", type=int, default=1000)
    a = ap.parse_args()
    import sanlab

    sanlab.configure()
    from sanlab import creature, sim
    from sanlab.engine_report import random_san_params

    spec = creature.load(a.creature)
    model = sim.compile_creature(spec)
    print(f"float32, one CPU device ({jax.devices()[0].device_kind}), a random SAN closed loop, best of 3:")
    for B in [int(b) for b in a.batches.split(",")]:
        san, cp = random_san_params(spec, B, seed=0)
        state = jax.vmap(lambda _: dyn.make_state(model))(jnp.arange(B))
        cstate = jax.vmap(lambda c, san=san: san.init(c, model))(cp)
        engine, arrays = _rollouts(model, san)
        best = {}
        first = {}
        for name, f in (("engine", engine), ("arrays", arrays)):
            t0 = time.perf_counter()
            jax.block_until_ready(f(cp, state, cstate, 10))
            first[name] = time.perf_counter() - t0
        for _ in range(3):
            for name, f in (("engine", engine), ("arrays", arrays)):
                t0 = time.perf_counter()
                jax.block_until_ready(f(cp, state, cstate, a.steps))
                best[name] = min(best.get(name, 1e9), (time.perf_counter() - t0) / a.steps * 1e6)
        print(f"{a.creature} batch {B}: engine {best['engine']:.1f} us/step, arrays {best['arrays']:.1f} us/step, "
              f"arrays/engine speed {best['engine'] / best['arrays']:.2f} x; first call (trace + compile) "
              f"engine {first['engine']:.1f} s, arrays {first['arrays']:.1f} s")
    jax.config.update("jax_enable_x64", True)
    print("float64, one step against sanlab.sim.dynamics:")
    agreement(["bounder", "cart", "walker", "luxo", "twolink", "threelink", "fourlink", "star"])


if __name__ == "__main__":
    main()
