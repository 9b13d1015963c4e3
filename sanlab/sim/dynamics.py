"""One time step of a planar articulated creature, written for a single creature.

Generalised coordinates q [D]: per tree (x, y, angle) of its root then one relative angle per
joint; per point mass (x, y). Equations of motion M(q) q'' = Q(q, q', u) - c(q, q') are built from
point Jacobians, unrolled at trace time over the creature's structure (see ``sparse``).

Integration is semi-implicit Euler in which every stiff term is linearised implicitly: each
spring-damper-like element with gradient g (a row over dofs), stiffness k and damping c adds
(h c + h^2 k) g g^T to the matrix and uses the predicted force F - h k (g . q') (PD servos,
passive springs, ground normal springs and dampers, regularised friction, water drag):

    (M + h D + h^2 K) dv = h (Q - c - h K q'),   q'_{n+1} = q'_n + dv,   q_{n+1} = q_n + h q'_{n+1}

so that dt = 1 ms is stable with stiff ground, strong servos and sticking friction.

Units: SI throughout.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from sanlab.sim.model import Model, Params, Structure
from sanlab.sim.sparse import SymMatrix, add, axpy, mul, neg, sub

Vec = tuple[Any, Any]


class State(NamedTuple):
    """Simulation state of one creature (add a leading batch axis for many)."""

    q: Any  # [D] generalised coordinates (m, rad)
    qd: Any  # [D] generalised velocities (m/s, rad/s)
    t: Any  # [] time (s)


class Frame(NamedTuple):
    """Kinematics of a state, computed once per step and shared by sensors and forces."""

    X: list  # per link origin (x, y), world
    V: list  # per link origin velocity
    cs: list  # per link (cos, sin) of the absolute angle
    th: list  # per link absolute angle
    w: list  # per link angular velocity
    cp: list  # per contact: world point
    cv: list  # per contact: world velocity
    depth: list  # per contact: penetration (m, > 0 when touching); horizontal plane: 1.0
    terrain: list  # per contact: (h, dh/dx) of the ground under it
    qd: list  # per dof velocity
    gate: Any = None  # unbatched runtime-true boolean that fences XLA fusion (see _barrier)


def initial_state(model: Model) -> State:
    p = model.params
    z = jnp.zeros_like(p.q0)
    return State(p.q0, z, jnp.zeros((), p.q0.dtype))


# ---------------------------------------------------------------- kinematics


def _rot(cs: Vec, r) -> Vec:
    c, s = cs
    return (c * r[0] - s * r[1], s * r[0] + c * r[1])


def _perp(v: Vec) -> Vec:
    return (neg(v[1]), v[0])


def _point(fr: Frame, i: int, r) -> Vec:
    rx, ry = _rot(fr.cs[i], r)
    return (fr.X[i][0] + rx, fr.X[i][1] + ry)


def _point_vel(fr: Frame, i: int, p: Vec) -> Vec:
    rx, ry = sub(p[0], fr.X[i][0]), sub(p[1], fr.X[i][1])
    w = fr.w[i]
    return (sub(fr.V[i][0], mul(w, ry)), add(fr.V[i][1], mul(w, rx)))


def jacobian(st: Structure, fr: Frame, i: int, p: Vec) -> dict:
    """Jacobian of world point ``p`` fixed on link ``i``: {dof: (dx/dq, dy/dq)}."""
    ls = st.links[i]
    J = {ls.dof_x: (1.0, 0.0), ls.dof_y: (0.0, 1.0)} if ls.dof_x >= 0 else {}
    if not ls.point:
        for k in ls.chain:
            if st.links[k].dof_rot >= 0:
                X = fr.X[k]
                J[st.links[k].dof_rot] = (neg(sub(p[1], X[1])), sub(p[0], X[0]))
    return J


def _rot_row(st: Structure, i: int) -> dict:
    """Row of ones over the rotational dofs that turn link i (its absolute angle's gradient)."""
    return {st.links[k].dof_rot: 1.0 for k in st.links[i].chain if st.links[k].dof_rot >= 0}


def _project(J: dict, n: Vec) -> dict:
    """Row g = J^T n (how each dof moves the point along n)."""
    out = {}
    for d, (jx, jy) in J.items():
        v = add(mul(jx, n[0]), mul(jy, n[1]))
        if not (isinstance(v, float) and v == 0.0):
            out[d] = v
    return out


def _bias_acc(st: Structure, fr: Frame, i: int, p: Vec) -> Vec:
    """Acceleration of point ``p`` on link ``i`` when q'' = 0 (centripetal terms)."""
    ls = st.links[i]
    if ls.point:
        return (0.0, 0.0)
    ax, ay = 0.0, 0.0
    chain = ls.chain
    for n, k in enumerate(chain):
        nxt = fr.X[chain[n + 1]] if n + 1 < len(chain) else p
        w2 = mul(fr.w[k], fr.w[k])
        ax = sub(ax, mul(w2, nxt[0] - fr.X[k][0]))
        ay = sub(ay, mul(w2, nxt[1] - fr.X[k][1]))
    return (ax, ay)


def terrain_height(st: Structure, p: Params, x) -> Vec:
    """Ground height h(x) and slope h'(x) (Python zeros for flat ground)."""
    kind = st.terrain
    if kind == "flat":
        return 0.0, 0.0
    if kind == "slope":
        return p.terrain[0] * x, p.terrain[0]
    if kind == "hill":
        H, hw, c = p.terrain[1], p.terrain[2], p.terrain[3]
        u = (x - c) * (math.pi / hw)
        inside = jnp.abs(x - c) < hw
        h = jnp.where(inside, 0.5 * H * (1.0 + jnp.cos(u)), 0.0)
        dh = jnp.where(inside, -0.5 * H * (math.pi / hw) * jnp.sin(u), 0.0)
        return h, dh
    h, dh = 0.0, 0.0
    for k in range(p.rough.shape[0]):
        a, w, ph = p.rough[k, 0], p.rough[k, 1], p.rough[k, 2]
        arg = w * x + ph
        h = add(h, a * jnp.sin(arg))
        dh = add(dh, a * w * jnp.cos(arg))
    return h, dh


def _ground_frame(h: Vec) -> tuple[Vec, Vec]:
    """Unit normal and tangent of the ground with slope h'."""
    dh = h[1]
    if isinstance(dh, float) and dh == 0.0:
        return (0.0, 1.0), (1.0, 0.0)
    inv = jax.lax.rsqrt(1.0 + dh * dh)
    return (-dh * inv, inv), (inv, dh * inv)


def sincos(a) -> Vec:
    """(cos a, sin a). float32: a branch-free polynomial (|error| < 2e-7) that vectorises;
    XLA's CPU sin/cos cost ~8 ns per element. float64: jnp.cos / jnp.sin."""
    if a.dtype != jnp.float32:
        return jnp.cos(a), jnp.sin(a)
    # reduce to r in [-pi/4, pi/4], a = r + k pi/2 (Cody-Waite split of pi/2)
    k = jnp.round(a * (2.0 / math.pi))
    r = a - k * 1.5707963705062866
    r = r + k * 4.37113900018624e-08
    r2 = r * r
    s = r + r * r2 * (-1.6666654611e-1 + r2 * (8.3321608736e-3 + r2 * -1.9515295891e-4))
    c = 1.0 - 0.5 * r2 + r2 * r2 * (4.166664568298827e-2 + r2 * (-1.388731625493765e-3 + r2 * 2.443315711809948e-5))
    ki = k.astype(jnp.int32) & 3
    sin = jnp.where(ki == 0, s, jnp.where(ki == 1, c, jnp.where(ki == 2, -s, -c)))
    cos = jnp.where(ki == 0, c, jnp.where(ki == 1, -s, jnp.where(ki == 2, -c, s)))
    return cos, sin


def prepare(model: Model, state: State, gate=None) -> Frame:
    """Forward kinematics of links and contact points.

    gate: optional traced boolean, true at run time and not batched, used to keep XLA from
    recomputing shared intermediates (see :func:`_barrier`); rollouts pass one.
    """
    st, p = model.structure, model.params
    q = [state.q[i] for i in range(st.ndof)]
    qd = [state.qd[i] for i in range(st.ndof)]
    # absolute angles and angular velocities, then their trig, computed once
    th, w = [], []
    for ls in st.links:
        if ls.parent < 0:
            if ls.dof_x < 0:
                th.append(p.root_pose[ls.index, 2])
                w.append(0.0)
            elif ls.point:
                th.append(0.0)
                w.append(0.0)
            else:
                th.append(q[ls.dof_rot])
                w.append(qd[ls.dof_rot])
        else:
            th.append(th[ls.parent] + q[ls.dof_rot])
            w.append(add(w[ls.parent], qd[ls.dof_rot]))
    cs = _barrier([(1.0, 0.0) if isinstance(a, float) else sincos(a) for a in th], gate)
    X, V = [], []
    for ls in st.links:
        if ls.parent < 0 and ls.dof_x < 0:
            X.append((p.root_pose[ls.index, 0], p.root_pose[ls.index, 1]))
            V.append((0.0, 0.0))
        elif ls.parent < 0:
            X.append((q[ls.dof_x], q[ls.dof_y]))
            V.append((qd[ls.dof_x], qd[ls.dof_y]))
        else:
            j = ls.parent
            r = _rot(cs[j], (p.anchor[ls.index, 0], p.anchor[ls.index, 1]))
            X.append((X[j][0] + r[0], X[j][1] + r[1]))
            V.append((sub(V[j][0], mul(w[j], r[1])), add(V[j][1], mul(w[j], r[0]))))
    X, V = _barrier((X, V), gate)
    fr = Frame(X, V, cs, th, w, [], [], [], [], qd, gate)
    for c, i in enumerate(st.contacts):
        pt = _point(fr, i, (p.contact[c, 0], p.contact[c, 1]))
        fr.cp.append(pt)
        fr.cv.append(_point_vel(fr, i, pt))
        if st.plane == "vertical":
            h = terrain_height(st, p, pt[0])
            n, _ = _ground_frame(h)
            fr.terrain.append(h)
            fr.depth.append(mul(sub(h[0], pt[1]), n[1]))
        else:
            fr.terrain.append((0.0, 0.0))
            fr.depth.append(1.0)
    cp, cv, depth, terrain = _barrier((fr.cp, fr.cv, fr.depth, fr.terrain), gate)
    return fr._replace(cp=cp, cv=cv, depth=depth, terrain=terrain)


def _barrier(tree, gate):
    """Force XLA to compute ``tree``'s traced leaves once and keep them in memory.

    XLA's CPU fusion otherwise re-derives shared intermediates (trig, kinematics) inside every
    consumer fusion. A conditional on an unbatched, runtime-unknown predicate is a boundary that
    fusion cannot cross. Python constants (structural zeros) pass through untouched.
    """
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    idx = [i for i, x in enumerate(leaves) if not isinstance(x, (int, float))]
    if idx:
        vals = [leaves[i] for i in idx]
        if gate is not None:
            vals = jax.lax.cond(gate, lambda v: v, lambda v: [x * 1 for x in v], vals)
        else:
            vals = jax.lax.optimization_barrier(vals)
        for i, x in zip(idx, vals):
            leaves[i] = x
    return jax.tree_util.tree_unflatten(treedef, leaves)


# ---------------------------------------------------------------- sensors


def _wrap(a):
    return a - (2 * math.pi) * jnp.floor((a + math.pi) * (0.5 / math.pi))


def follow_point(model: Model, t) -> Vec:
    """Position of the follow point at time t (m)."""
    p = model.params
    n = p.follow.shape[0]
    u = p.follow_speed * t / p.follow_ds
    if model.structure.follow_loop:
        u = jnp.mod(u, n - 1)
    u = jnp.clip(u, 0.0, n - 1)
    i0 = jnp.minimum(jnp.floor(u), n - 2).astype(jnp.int32)
    f = u - i0
    a, b = p.follow[i0], p.follow[i0 + 1]
    return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]))


def _axis(fr: Frame, i: int, frm: int, to: int) -> Vec:
    if frm >= 0:
        return (fr.X[to][0] - fr.X[frm][0], fr.X[to][1] - fr.X[frm][1])
    return fr.cs[i]


def sense(model: Model, fr: Frame, t) -> Any:
    """Binary sensor values [S] (0.0 / 1.0) of a prepared frame."""
    st, p = model.structure, model.params
    dtype = p.q0.dtype
    out = []
    target = follow_point(model, t) if st.follow else None
    for s, (kind, link, idx) in enumerate(st.sensors):
        if kind == "touch":
            on = fr.depth[idx] > 0 if st.plane == "vertical" else True
        elif kind == "angle":
            ls = st.links[link]
            ang = fr.th[link] if ls.parent < 0 else fr.th[link] - fr.th[ls.parent]
            a = _wrap(ang)
            on = (a >= p.sens_min[s]) & (a <= p.sens_max[s])
        elif kind == "eye":
            li, frm, to = st.eyes[idx]
            e = _point(fr, li, (p.sens_pts[s, 0, 0], p.sens_pts[s, 0, 1]))
            ax = _axis(fr, li, frm, to)
            dx, dy = target[0] - e[0], target[1] - e[1]
            a = jnp.arctan2(ax[0] * dy - ax[1] * dx, ax[0] * dx + ax[1] * dy)
            on = (a >= p.sens_min[s]) & (a <= p.sens_max[s])
        else:
            la, lb = st.lengths[idx]
            pa = _point(fr, la, (p.sens_pts[s, 0, 0], p.sens_pts[s, 0, 1]))
            pb = _point(fr, lb, (p.sens_pts[s, 1, 0], p.sens_pts[s, 1, 1]))
            L = jnp.sqrt((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2)
            on = (L >= p.sens_min[s]) & (L <= p.sens_max[s])
        out.append(jnp.asarray(on, dtype))
    if not out:
        return jnp.zeros((0,), dtype)
    return jnp.stack(out)


# ---------------------------------------------------------------- forces and integration


def _elimination_order(st: Structure) -> list[int]:
    """Leaves first, roots last: L D L^T of a tree then has no fill-in."""
    return list(range(st.ndof))[::-1]


def advance(model: Model, fr: Frame, state: State, u) -> tuple[State, Any]:
    """Integrate one step from a prepared frame with actuator activations ``u`` [A] in [0, 1].

    Returns (next state, largest penetration over contacts (m) at this step).
    """
    st, p = model.structure, model.params
    h = p.dt
    T = _Terms()
    qd = fr.qd

    def element(g: dict, force, k, c, rate):
        """Spring-damper-like element along row g: force F, stiffness k, damping c, rate g.q'."""
        T.outer(add(mul(h, c), mul(h * h, k)), g)
        T.force(sub(force, mul(mul(h, k), rate)), g)

    # inertia, gravity and centripetal terms
    for ls in st.links:
        i = ls.index
        m = p.mass[i]
        if ls.dof_x < 0 and ls.parent < 0:
            continue  # welded to the world
        if ls.point:
            T.outer(m, {ls.dof_x: 1.0})
            T.outer(m, {ls.dof_y: 1.0})
            if st.plane == "vertical":
                T.force(-m * p.gravity, {ls.dof_y: 1.0})
            continue
        com = _point(fr, i, (p.com[i, 0], p.com[i, 1]))
        J = jacobian(st, fr, i, com)
        gx = {d: v[0] for d, v in J.items() if not (isinstance(v[0], float) and v[0] == 0.0)}
        gy = {d: v[1] for d, v in J.items() if not (isinstance(v[1], float) and v[1] == 0.0)}
        T.outer(m, gx)
        T.outer(m, gy)
        T.outer(p.inertia[i], _rot_row(st, i))
        a = _bias_acc(st, fr, i, com)
        fx = neg(mul(m, a[0]))
        fy = neg(mul(m, a[1]))
        if st.plane == "vertical":
            fy = sub(fy, m * p.gravity)
        T.force(fx, gx)
        T.force(fy, gy)

    # passive joint springs
    for i in st.joint_springs:
        d = st.links[i].dof_rot
        k, c, rest = p.jspring[i, 0], p.jspring[i, 1], p.jspring[i, 2]
        phi = fr.th[i] - fr.th[st.links[i].parent]
        element({d: 1.0}, -k * (phi - rest) - c * qd[d], k, c, qd[d])

    # actuators
    for a, (kind, ref) in enumerate(st.actuators):
        target = p.act_min[a] + u[a] * (p.act_max[a] - p.act_min[a])
        ks, kd = p.act_ks[a], p.act_kd[a]
        if kind == "angular":
            d = st.links[ref].dof_rot
            phi = fr.th[ref] - fr.th[st.links[ref].parent]
            element({d: 1.0}, ks * (target - phi) - kd * qd[d], ks, kd, qd[d])
        else:
            la, lb = st.lin_act[ref]
            _linear(st, fr, p.act_pts[a], la, lb, target, ks, kd, element)

    for n, (la, lb) in enumerate(st.springs):
        _linear(st, fr, p.spr_pts[n], la, lb, p.spr[n, 2], p.spr[n, 0], p.spr[n, 1], element)

    # ground contact and friction
    deepest = None
    for c, i in enumerate(st.contacts):
        pt, v = fr.cp[c], fr.cv[c]
        J = jacobian(st, fr, i, pt)
        mu_f, mu_b, mu_l = p.mu[i, 0], p.mu[i, 1], p.mu[i, 2]
        aniso, frm, to = st.aniso[i]
        eps = p.slip
        if st.plane == "vertical":
            n, t = _ground_frame(fr.terrain[c])
            depth = fr.depth[c]
            deepest = depth if deepest is None else jnp.maximum(deepest, depth)
            vn = add(mul(v[0], n[0]), mul(v[1], n[1]))
            vt = add(mul(v[0], t[0]), mul(v[1], t[1]))
            gn, gt = _project(J, n), _project(J, t)
            touching = depth > 0
            fn = p.ground_k * depth - p.ground_c * vn
            N = jnp.where(touching & (fn > 0), fn, 0.0)
            on = jnp.where(touching & (fn > 0), 1.0, 0.0)
            element(gn, N, on * p.ground_k, on * p.ground_c, vn)
            if aniso:
                ax = _axis(fr, i, frm, to)
                fwd = (add(mul(ax[0], t[0]), mul(ax[1], t[1])) * vt) > 0
                mu = jnp.where(fwd, mu_f, mu_b)
            else:
                mu = mu_f
            _friction(element, gt, vt, mu * N, eps)
        else:
            N = p.contact_load[c]
            if aniso:
                ax = _axis(fr, i, frm, to)
                inv = jax.lax.rsqrt(ax[0] * ax[0] + ax[1] * ax[1] + 1e-12)
                e1 = (ax[0] * inv, ax[1] * inv)
                e2 = _perp(e1)
                va = v[0] * e1[0] + v[1] * e1[1]
                vl = v[0] * e2[0] + v[1] * e2[1]
                _friction(element, _project(J, e1), va, jnp.where(va > 0, mu_f, mu_b) * N, eps)
                _friction(element, _project(J, e2), vl, mu_l * N, eps)
            else:
                # isotropic Coulomb: the force opposes the slip velocity, |F| = mu N (implicit
                # damper, as in _friction)
                speed = jnp.sqrt(v[0] * v[0] + v[1] * v[1])
                gamma = mu_f * N / jnp.maximum(speed, eps)
                for e, ve in (((1.0, 0.0), v[0]), ((0.0, 1.0), v[1])):
                    element(_project(J, e), -gamma * ve, 0.0, gamma, ve)

    # water drag on each edge: F = -k ∫ (v.N) N ds, exact for a rigid edge
    for e, i in enumerate(st.edges):
        a0 = _point(fr, i, (p.edge[e, 0, 0], p.edge[e, 0, 1]))
        a1 = _point(fr, i, (p.edge[e, 1, 0], p.edge[e, 1, 1]))
        dx, dy = a1[0] - a0[0], a1[1] - a0[1]
        L = jnp.sqrt(dx * dx + dy * dy)
        nrm = (-dy / L, dx / L)
        va = _point_vel(fr, i, a0)
        vn = va[0] * nrm[0] + va[1] * nrm[1]
        w = fr.w[i]
        gn = _project(jacobian(st, fr, i, a0), nrm)
        k = p.water_k
        if st.links[i].point:
            gw, w = {}, 0.0
        else:
            gw = _rot_row(st, i)
        c1, c2, c3 = k * L, k * L * L / 2, k * L * L * L / 3
        T.outer(h * c1, gn)
        T.outer(h * c2, gn, gw)
        T.outer(h * c3, gw)
        T.force(neg(add(mul(c1, vn), mul(c2, w))), gn)
        T.force(neg(add(mul(c2, vn), mul(c3, w))), gw)

    M, Q = T.assemble(_elimination_order(st), fr.gate)
    rhs = {d: mul(h, v) for d, v in Q.items()}
    M.a, rhs = _barrier((M.a, rhs), fr.gate)
    dv = _barrier(M.solve(rhs), fr.gate)
    qd_new = jnp.stack([add(qd[d], dv[d]) for d in range(st.ndof)])
    q_new = state.q + h * qd_new
    if deepest is None:
        deepest = jnp.zeros((), q_new.dtype)
    return State(q_new, qd_new, state.t + h), deepest


class _Terms:
    """Contributions to the step's matrix (coef g g^T, or coef (g h^T + h g^T)) and generalised
    force (f g), collected first and materialised once before assembly, so that XLA does not
    re-derive each shared Jacobian inside every matrix entry."""

    def __init__(self):
        self.mat: list = []
        self.vec: list = []

    def outer(self, coef, g: dict, h: dict | None = None) -> None:
        if not (isinstance(coef, float) and coef == 0.0) and g:
            self.mat.append((coef, g, h))

    def force(self, f, g: dict) -> None:
        if not (isinstance(f, float) and f == 0.0) and g:
            self.vec.append((f, g))

    def assemble(self, order: list[int], gate) -> tuple[SymMatrix, dict]:
        mat, vec = _barrier((self.mat, self.vec), gate)
        M = SymMatrix(order)
        for coef, g, h in mat:
            M.add_outer(coef, g, h)
        Q: dict = {}
        for f, g in vec:
            axpy(Q, f, g)
        return M, Q


def _linear(st, fr, pts, la, lb, target, ks, kd, element) -> None:
    """Spring-damper between a point on link la and one on link lb: F = ks (target - L) - kd L'."""
    pa = _point(fr, la, (pts[0, 0], pts[0, 1]))
    pb = _point(fr, lb, (pts[1, 0], pts[1, 1]))
    dx, dy = pb[0] - pa[0], pb[1] - pa[1]
    L = jnp.sqrt(dx * dx + dy * dy)
    e = (dx / L, dy / L)
    g = _project(jacobian(st, fr, lb, pb), e)
    axpy(g, -1.0, _project(jacobian(st, fr, la, pa), e))
    va, vb = _point_vel(fr, la, pa), _point_vel(fr, lb, pb)
    rate = (vb[0] - va[0]) * e[0] + (vb[1] - va[1]) * e[1]
    element(g, ks * (target - L) - kd * rate, ks, kd, rate)


def _friction(element, g: dict, v, muN, eps) -> None:
    """Coulomb friction along row g as a damper c = muN / max(|v|, eps), treated implicitly: the
    force is muN against the slip (viscous below slip speed eps), and being implicit it can stop
    a slip within a step but never reverse it, however large muN dt is (hard landings)."""
    c = muN / jnp.maximum(jnp.abs(v), eps)
    element(g, -c * v, 0.0, c, v)


def step(model: Model, state: State, u) -> State:
    """Advance one creature by dt with actuator activations u [A] in [0, 1]."""
    return advance(model, prepare(model, state), state, u)[0]


def energy(model: Model, state: State) -> dict:
    """Mechanical energy of one creature (J): kinetic, gravitational (m g y of each centre of
    mass), and elastic (passive joint and linear springs; actuators and ground excluded)."""
    st, p = model.structure, model.params
    fr = prepare(model, state)
    kin, grav, elastic = 0.0, 0.0, 0.0
    for ls in st.links:
        i = ls.index
        if ls.parent < 0 and ls.dof_x < 0:
            continue
        com = _point(fr, i, (p.com[i, 0], p.com[i, 1]))
        v = _point_vel(fr, i, com)
        kin = kin + 0.5 * p.mass[i] * (v[0] * v[0] + v[1] * v[1]) + 0.5 * p.inertia[i] * fr.w[i] * fr.w[i]
        if st.plane == "vertical":
            grav = grav + p.mass[i] * p.gravity * com[1]
    for i in st.joint_springs:
        phi = fr.th[i] - fr.th[st.links[i].parent]
        elastic = elastic + 0.5 * p.jspring[i, 0] * (phi - p.jspring[i, 2]) ** 2
    for n, (la, lb) in enumerate(st.springs):
        pa = _point(fr, la, (p.spr_pts[n, 0, 0], p.spr_pts[n, 0, 1]))
        pb = _point(fr, lb, (p.spr_pts[n, 1, 0], p.spr_pts[n, 1, 1]))
        L = jnp.sqrt((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2)
        elastic = elastic + 0.5 * p.spr[n, 0] * (L - p.spr[n, 2]) ** 2
    z = jnp.zeros((), p.q0.dtype)
    return {"kinetic": kin + z, "gravity": grav + z, "elastic": elastic + z}


def centre_of_mass(model: Model, fr: Frame) -> tuple[Vec, Vec]:
    """Whole-creature centre of mass and its velocity from a prepared frame (m, m/s)."""
    st, p = model.structure, model.params
    mx = my = vx = vy = 0.0
    total = 0.0
    for ls in st.links:
        i = ls.index
        if ls.parent < 0 and ls.dof_x < 0:
            continue  # a fixed base is part of the world
        m = p.mass[i]
        c = _point(fr, i, (p.com[i, 0], p.com[i, 1]))
        v = _point_vel(fr, i, c)
        mx, my = mx + m * c[0], my + m * c[1]
        vx, vy = add(vx, mul(m, v[0])), add(vy, mul(m, v[1]))
        total = total + m
    inv = 1.0 / total
    return (mx * inv, my * inv), (mul(vx, inv), mul(vy, inv))


def poses(model: Model, q) -> dict:
    """World placement of one configuration q [D] (for drawing and analysis): ``links`` [L, 3]
    (origin x, y and absolute angle of each link frame), ``contacts`` [C, 2] (contact points),
    ``depth`` [C] (penetration, > 0 when touching; horizontal plane: 1), ``com`` [2]."""
    state = State(q, jnp.zeros_like(q), jnp.zeros((), q.dtype))
    fr = prepare(model, state)
    z = jnp.zeros((), q.dtype)
    links = jnp.stack([jnp.stack([x[0] + z, x[1] + z, a + z]) for x, a in zip(fr.X, fr.th)])
    C = len(model.structure.contacts)
    contacts = jnp.stack([jnp.stack([p[0] + z, p[1] + z]) for p in fr.cp]) if C else jnp.zeros((0, 2), q.dtype)
    depth = jnp.stack([d + z for d in fr.depth]) if C else jnp.zeros((0,), q.dtype)
    com, _ = centre_of_mass(model, fr)
    return {"links": links, "contacts": contacts, "depth": depth, "com": jnp.stack([com[0] + z, com[1] + z])}
