"""One time step of a planar articulated creature, written for a single creature.

Coordinates (see ``model``): per free tree the position of its centre of mass (COM), its root's
absolute angle and one relative angle per joint; per point mass its (x, y); a tree welded to the
world has only its joint angles. The state carries the generalised *momentum* p = M(q) q'
rather than the velocity, and every point Jacobian, the mass matrix M(q) and the inertial force
dT/dq are built from the creature's structure, unrolled at trace time (see ``sparse``).

The step is semi-implicit Euler in momentum form (the Lagrangian "symplectic Euler" with its
inertial force taken explicitly), with every stiff term linearised implicitly:

    q'_n = M_n^-1 p_n                                         (velocity of this configuration)
    (M_n + h D + h^2 K) dv = h (dT/dq(q_n, q'_n) + Q - h K q'_n)
    q'* = q'_n + dv,   p_{n+1} = M_n q'*,   q_{n+1} = q_n + h q'*

Each spring-damper-like element (PD servos, passive springs, joint stops, the ground's normal
and sticking-friction springs, sliding friction, water drag) with gradient row g, stiffness k
and damping c adds (h c + h^2 k) g g^T to the matrix and its predicted force F - h k (g . q') to
Q, so dt = 1 ms is stable with stiff ground, strong servos and sticking friction.

Why this form (each was a way for a search to cheat):

- *Momentum.* The translational rows are exactly m dv = h F_external (the COM coordinates make
  M block-diagonal there), so a creature on frictionless ground cannot move its COM along x, and
  a creature in flight keeps its linear momentum; its angular momentum about the COM (the root
  angle is a cyclic coordinate in flight) is conserved too, because dT/dq has no entry for it
  and p is what is carried from step to step. The velocity-form step (M_n dv = h (Q - c)) leaks
  both at O(dt), and searches learn to walk on ice with the leak.
- *Energy.* Taking the velocity of the new configuration from the carried momentum (rather than
  integrating a Coriolis force explicitly) makes the step dissipate a little where the
  velocity form gains: a passive, undamped chain released from rest does not gain energy.
- *Friction that holds.* Each touching contact keeps an anchor on the ground (``State.anchor``):
  while the tangential spring-damper to it needs no more than mu N, the contact sticks, with no
  creep however long the load lasts; beyond it, Coulomb sliding (an implicit damper that can stop
  a slip but never reverse it) and the anchor follows.

Units: SI throughout.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from sanlab.sim import articulated
from sanlab.sim.model import Model, Params, Structure
from sanlab.sim.sparse import SymMatrix, add, axpy, mul, neg, sub

Vec = tuple[Any, Any]
# A gradient row: {dof: coefficient}, or on the articulated route an articulated.BodyRow; the
# step's elements take either (``Any``: the union would need every consumer to say so)
Row = Any


from sanlab.sim.state import State  # noqa: E402  (one State for the kernel and this reference)


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
    qd: list  # per dof velocity q'_n = M_n^-1 p_n (state coordinates)
    # The fields below are None until the step has computed them (``Any``: every reader runs after
    # that, and pyright cannot follow it)
    gate: Any = None  # unbatched runtime-true boolean that fences XLA fusion (see _barrier)
    com: Any = None  # list, per link: centre of mass, world
    S: Any = None  # dict, per rotational link of a free tree: (sum over its subtree of m (c - X_k)) / m_tree
    M: Any = None  # mass matrix M(q_n), tree coordinates: a SymMatrix, or articulated.Bodies
    u: Any = None  # list, per dof velocity in tree coordinates (root origins, angle rates)


# ---------------------------------------------------------------- kinematics


def _rot(cs: Vec, r) -> Vec:
    c, s = cs
    return (c * r[0] - s * r[1], s * r[0] + c * r[1])


def _perp(v: Vec) -> Vec:
    return (neg(v[1]), v[0])


def _point_at(cs: Vec, X: Vec, r) -> Vec:
    rx, ry = _rot(cs, r)
    return (add(X[0], rx), add(X[1], ry))


def _point(fr: Frame, i: int, r) -> Vec:
    rx, ry = _rot(fr.cs[i], r)
    return (fr.X[i][0] + rx, fr.X[i][1] + ry)


def _point_vel(fr: Frame, i: int, p: Vec) -> Vec:
    rx, ry = sub(p[0], fr.X[i][0]), sub(p[1], fr.X[i][1])
    w = fr.w[i]
    return (sub(fr.V[i][0], mul(w, ry)), add(fr.V[i][1], mul(w, rx)))


def jacobian(st: Structure, fr: Frame, i: int, p: Vec) -> dict:
    """Jacobian of world point ``p`` fixed on link ``i`` in *tree* coordinates (the velocity of
    each free tree's root origin, then the angle rates): {dof: (dx/du, dy/du)}.

    Forces, the mass matrix and the linear solve of a step live in these coordinates, where a
    point depends only on the dofs of its own chain (no fill-in); the state's coordinates, a
    free tree's centre of mass, differ from them by a linear change of variables (see
    :func:`_to_tree` and friends). On the articulated route, the point on its body
    (:class:`articulated.BodyPoint`)."""
    if st.articulated:
        return fr.M.point(i, p)
    ls = st.links[i]
    J: dict = {ls.dof_x: (1.0, 0.0), ls.dof_y: (0.0, 1.0)} if ls.dof_x >= 0 else {}
    if not ls.point:
        for k in ls.chain:
            if st.links[k].dof_rot >= 0:
                X = fr.X[k]
                J[st.links[k].dof_rot] = (neg(sub(p[1], X[1])), sub(p[0], X[0]))
    return J


def _rot_row(st: Structure, i: int) -> Row:
    """Row of ones over the rotational dofs that turn link i (its absolute angle's gradient)."""
    if st.articulated:
        return articulated.rotation_row(i)
    return {st.links[k].dof_rot: 1.0 for k in st.links[i].chain if st.links[k].dof_rot >= 0}


def _project(J: dict, n: Vec) -> Row:
    """Row g = J^T n (how each dof moves the point along n)."""
    if isinstance(J, articulated.BodyPoint):
        return articulated.project(J, n)
    out = {}
    for d, (jx, jy) in J.items():
        v = add(mul(jx, n[0]), mul(jy, n[1]))
        if not (isinstance(v, float) and v == 0.0):
            out[d] = v
    return out


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
    ki = k.astype(jnp.int32)
    swap, flip = (ki & 1) == 1, (ki & 2) == 2  # quadrants 1 and 3 swap sin and cos; 2 and 3 negate
    sin = jnp.where(swap, c, s)
    cos = jnp.where(swap, -s, c)
    return jnp.where(flip, -cos, cos), jnp.where(flip, -sin, sin)


def _positions(model: Model, q, gate) -> Frame:
    """Positions only: link frames, centres of mass, subtree sums, contact points and depths."""
    st, p = model.structure, model.params
    q = [q[i] for i in range(st.ndof)]
    th = []
    for ls in st.links:
        if ls.parent < 0:
            if ls.dof_rot >= 0:
                th.append(q[ls.dof_rot])
            elif ls.dof_x < 0:
                th.append(p.root_pose[ls.index, 2])  # welded to the world
            else:
                th.append(0.0)  # a free point mass never turns
        else:
            th.append(th[ls.parent] + q[ls.dof_rot])
    cs = _barrier([(1.0, 0.0) if isinstance(a, float) else sincos(a) for a in th], gate)
    # link origins relative to their tree's root (a free tree's root at the origin)
    X: list = [None] * len(st.links)
    for ls in st.links:
        i = ls.index
        if ls.parent < 0:
            if ls.dof_x < 0:
                X[i] = (p.root_pose[i, 0], p.root_pose[i, 1])  # welded to the world
            elif ls.point:
                X[i] = (q[ls.dof_x], q[ls.dof_y])
            else:
                X[i] = (0.0, 0.0)
        else:
            j = ls.parent
            r = _rot(cs[j], (p.anchor[i, 0], p.anchor[i, 1]))
            X[i] = (add(X[j][0], r[0]), add(X[j][1], r[1]))
    com: list = [None] * len(st.links)
    for ls in st.links:
        i = ls.index
        if ls.point or (ls.parent < 0 and ls.dof_x < 0 and ls.dof_rot < 0):
            com[i] = X[i] if ls.point else _point_at(cs[i], X[i], (p.com[i, 0], p.com[i, 1]))
        else:
            r = _rot(cs[i], (p.com[i, 0], p.com[i, 1]))
            com[i] = (add(X[i][0], r[0]), add(X[i][1], r[1]))
    S: dict = {}
    for tree in st.trees:
        if not tree.free or tree.point:
            continue
        # subtree sums, leaves first: m_sub(k) and sum m c over the subtree of k
        msum: dict = {}
        mc: dict = {}
        for i in reversed(tree.links):
            m = p.mass[i]
            ms, mx, my = m, m * com[i][0], m * com[i][1]
            for j in tree.links:
                if st.links[j].parent == i:
                    ms, mx, my = ms + msum[j], mx + mc[j][0], my + mc[j][1]
            msum[i], mc[i] = ms, (mx, my)
        r = tree.root
        inv = 1.0 / msum[r]
        # place the tree so that its centre of mass is at (q_x, q_y)
        root = st.links[r]
        sx = q[root.dof_x] - mc[r][0] * inv
        sy = q[root.dof_y] - mc[r][1] * inv
        for i in tree.links:
            X[i] = (add(X[i][0], sx), add(X[i][1], sy))
            com[i] = (com[i][0] + sx, com[i][1] + sy)
        for k in tree.rot:
            # S_k = sum over the subtree of k of m (c - X_k), over the tree's mass (shift-free form)
            Xr = (sub(X[k][0], sx), sub(X[k][1], sy))
            S[k] = ((mc[k][0] - msum[k] * Xr[0]) * inv, (mc[k][1] - msum[k] * Xr[1]) * inv)
    X, com, S = _barrier((X, com, S), gate, 'pos')
    fr = Frame(X, [None] * len(X), cs, th, [None] * len(X), [], [], [], [], [], gate, com, S)
    for c, i in enumerate(st.contacts):
        pt = _point(fr, i, (p.contact[c, 0], p.contact[c, 1]))
        fr.cp.append(pt)
        if st.plane == "vertical":
            h = terrain_height(st, p, pt[0])
            n, _ = _ground_frame(h)
            fr.terrain.append(h)
            fr.depth.append(mul(sub(h[0], pt[1]), n[1]))
        else:
            fr.terrain.append((0.0, 0.0))
            fr.depth.append(1.0)
    cp, depth, terrain = _barrier((fr.cp, fr.depth, fr.terrain), gate, 'cp')
    return fr._replace(cp=cp, depth=depth, terrain=terrain)


def _mass_matrix(st: Structure, p: Params, fr: Frame) -> Any:
    """M(q) in tree coordinates: sum over links of m J_c^T J_c + I r r^T (a SymMatrix), or on
    the articulated route one spatial inertia per body (:class:`articulated.Bodies`)."""
    if st.articulated:
        B = articulated.Bodies(st, fr.X, fr.com, p.mass, p.inertia, lambda t, name: _barrier(t, fr.gate, name))
        B.a = _barrier(B.a, fr.gate, "M")
        return B
    terms = _Terms()
    for ls in st.links:
        i = ls.index
        if ls.parent < 0 and ls.dof_x < 0 and ls.dof_rot < 0:
            continue  # welded to the world
        J = jacobian(st, fr, i, fr.com[i])
        terms.outer(p.mass[i], {d: v[0] for d, v in J.items() if not _zero(v[0])})
        terms.outer(p.mass[i], {d: v[1] for d, v in J.items() if not _zero(v[1])})
        if not ls.point:
            terms.outer(p.inertia[i], _rot_row(st, i))
    M, _ = terms.assemble(_elimination_order(st), fr.gate)
    M.a = _barrier(M.a, fr.gate, "M")  # used by the velocity solve, the step's matrix and p's update
    return M


def _zero(v) -> bool:
    return isinstance(v, float) and v == 0.0


def _turn_rates(st: Structure, fr: Frame):
    """Per free tree (by root): [(dof of link k, T_k)], T_k = (S_ky, -S_kx) the velocity of the
    root origin relative to the centre of mass per unit rate of dof k (the tree turns about its
    centre of mass)."""
    out = {}
    for tree in st.trees:
        if tree.free and not tree.point:
            out[tree.root] = [(st.links[k].dof_rot, (fr.S[k][1], neg(fr.S[k][0]))) for k in tree.rot]
    return out


def _to_tree(st: Structure, fr: Frame, v: list) -> list:
    """Velocities: state coordinates -> tree coordinates, u = S v (root origin = centre of mass
    velocity + turning)."""
    u = list(v)
    for r, rows in _turn_rates(st, fr).items():
        ls = st.links[r]
        for d, (tx, ty) in rows:
            u[ls.dof_x] = add(u[ls.dof_x], mul(tx, v[d]))
            u[ls.dof_y] = add(u[ls.dof_y], mul(ty, v[d]))
    return u


def _from_tree(st: Structure, fr: Frame, u: list) -> list:
    """Velocities: tree coordinates -> state coordinates, v = S^-1 u."""
    v = list(u)
    for r, rows in _turn_rates(st, fr).items():
        ls = st.links[r]
        for d, (tx, ty) in rows:
            v[ls.dof_x] = sub(v[ls.dof_x], mul(tx, u[d]))
            v[ls.dof_y] = sub(v[ls.dof_y], mul(ty, u[d]))
    return v


def _force_to_tree(st: Structure, fr: Frame, f: list) -> list:
    """Generalised forces or momenta: state coordinates -> tree coordinates, S^-T f."""
    g = list(f)
    for r, rows in _turn_rates(st, fr).items():
        ls = st.links[r]
        for d, (tx, ty) in rows:
            g[d] = sub(g[d], add(mul(tx, f[ls.dof_x]), mul(ty, f[ls.dof_y])))
    return g


def _force_from_tree(st: Structure, fr: Frame, g: list) -> list:
    """Generalised forces or momenta: tree coordinates -> state coordinates, S^T g."""
    f = list(g)
    for r, rows in _turn_rates(st, fr).items():
        ls = st.links[r]
        for d, (tx, ty) in rows:
            f[d] = add(f[d], add(mul(tx, g[ls.dof_x]), mul(ty, g[ls.dof_y])))
    return f


def _velocities(model: Model, fr: Frame, u: list) -> Frame:
    """Link angular velocities, link origin and contact velocities for tree velocities ``u``;
    ``qd`` of the frame: the same velocities in state coordinates."""
    st = model.structure
    w: list = [None] * len(st.links)
    V: list = [None] * len(st.links)
    for ls in st.links:
        i = ls.index
        if ls.parent < 0:
            w[i] = u[ls.dof_rot] if ls.dof_rot >= 0 else 0.0
            V[i] = (u[ls.dof_x], u[ls.dof_y]) if ls.dof_x >= 0 else (0.0, 0.0)
        else:
            j = ls.parent
            w[i] = add(w[j], u[ls.dof_rot])
            rx, ry = sub(fr.X[i][0], fr.X[j][0]), sub(fr.X[i][1], fr.X[j][1])
            V[i] = (sub(V[j][0], mul(w[j], ry)), add(V[j][1], mul(w[j], rx)))
    w, V = _barrier((w, V), fr.gate, 'wv')
    fr = fr._replace(w=w, V=V, qd=_from_tree(st, fr, u), u=u)
    cv = [_point_vel(fr, i, fr.cp[c]) for c, i in enumerate(st.contacts)]
    return fr._replace(cv=_barrier(cv, fr.gate, 'cv'))


def prepare(model: Model, state: State, gate=None) -> Frame:
    """Kinematics of a state: positions, the mass matrix, the velocity M^-1 p and every velocity
    the forces need.

    gate: optional traced boolean, true at run time and not batched, used to keep XLA from
    recomputing shared intermediates (see :func:`_barrier`); rollouts pass one.
    """
    st = model.structure
    fr = _positions(model, state.q, gate)
    M = _mass_matrix(st, model.params, fr)
    pt = _force_to_tree(st, fr, [state.p[d] for d in range(st.ndof)])
    v = M.solve(dict(enumerate(pt))) if st.articulated else M.solve(dict(enumerate(pt)), _fence(gate, 'v-forward'))
    u = _barrier([v[d] for d in range(st.ndof)], gate, 'u')
    return _velocities(model, fr._replace(M=M), u)


def _fence(gate, name):
    """:func:`_barrier` as a one-argument callable (for the sparse solver), or None without a gate."""
    return None if gate is None else (lambda tree: _barrier(tree, gate, name))


def _barrier(tree, gate, name=""):
    """Force XLA to compute ``tree``'s traced leaves once and keep them in memory.

    XLA's CPU fusion otherwise re-derives shared intermediates (trig, kinematics) inside every
    consumer fusion. A conditional on an unbatched, runtime-unknown predicate is a boundary that
    fusion cannot cross. Python constants (structural zeros) pass through untouched. ``name``
    labels the fence for profiling.
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


# ---------------------------------------------------------------- states


def _dense(a, dtype) -> Any:
    return jnp.stack([x + jnp.zeros((), dtype) for x in a]) if a else jnp.zeros((0,), dtype)


def _contact_points(model: Model, fr: Frame) -> Any:
    dtype = model.params.q0.dtype
    C = len(model.structure.contacts)
    if not C:
        return jnp.zeros((0, 2), dtype)
    return jnp.stack([jnp.stack([pt[0] + jnp.zeros((), dtype), pt[1] + jnp.zeros((), dtype)]) for pt in fr.cp])


def _make_one(model: Model, q, qd, t) -> State:
    st = model.structure
    fr = _positions(model, q, None)
    M = _mass_matrix(st, model.params, fr)
    u = _to_tree(st, fr, [qd[d] for d in range(st.ndof)])
    Mu = M.matvec(dict(enumerate(u)))
    p = _force_from_tree(st, fr, [Mu.get(d, 0.0) for d in range(st.ndof)])
    return State(q, qd, t, _dense(p, q.dtype), _contact_points(model, fr))


def make_state(model: Model, q=None, qd=None, t=0.0) -> State:
    """A consistent state: coordinates ``q`` [D] or [B, D] (default: the creature's start pose),
    velocities ``qd`` (default: at rest), time ``t`` (s); momenta p = M(q) qd and friction anchors
    at the contacts (nothing held yet)."""
    dtype = model.params.q0.dtype
    q = jnp.asarray(model.params.q0 if q is None else q, dtype)
    qd = jnp.zeros_like(q) if qd is None else jnp.asarray(qd, dtype)
    t = jnp.broadcast_to(jnp.asarray(t, dtype), q.shape[:-1])
    if q.ndim == 1:
        return _make_one(model, q, qd, t)
    return jax.vmap(lambda a, b, c: _make_one(model, a, b, c))(q, qd, t)


def initial_state(model: Model) -> State:
    """The creature at rest in its start pose (one creature)."""
    return make_state(model)


def velocity(model: Model, state: State, gate=None) -> Any:
    """The velocity M(q)^-1 p [D] of one state (what ``qd`` holds outside a rollout's loop).
    gate: as for :func:`prepare` (a rollout passes its own, so that this last solve is fenced
    like every step's)."""
    st = model.structure
    fr = _positions(model, state.q, gate)
    M = _mass_matrix(st, model.params, fr)
    u = M.solve(dict(enumerate(_force_to_tree(st, fr, [state.p[d] for d in range(st.ndof)]))))
    return _dense(_from_tree(st, fr, [u[d] for d in range(st.ndof)]), state.q.dtype)


def seat_on_ground(model: Model, q0) -> Any:
    """q0 [D] with every free tree lifted just enough that none of its contact points starts
    below the ground (a body started inside the ground would be launched by the penalty spring).
    Vertical plane; trees already above the ground are left where they are."""
    st = model.structure
    fr = _positions(model, jnp.asarray(q0), None)
    out = jnp.asarray(q0)
    for tree in st.trees:
        if not tree.free:
            continue
        lift = jnp.zeros((), out.dtype)
        for c, i in enumerate(st.contacts):
            if st.links[i].tree == st.links[tree.root].tree:
                # vertical distance to the ground under the point
                h = terrain_height(st, model.params, fr.cp[c][0])[0]
                lift = jnp.maximum(lift, h - fr.cp[c][1])
        out = out.at[st.links[tree.root].dof_y].add(lift)
    return out


def _free_roots(st: Structure):
    return [st.links[t.root] for t in st.trees if t.free and not t.point]


def root_coordinates(model: Model, q, qd=None):
    """Convert one state's coordinates q [D] (and velocities qd) to root-origin form: each free
    tree's centre of mass (and its velocity) replaced by its root link's origin (and that point's
    velocity), the convention of MuJoCo's free joints and of the creature file's ``position``.
    Returns q_root, or (q_root, qd_root) when qd is given."""
    st = model.structure
    fr = _positions(model, q, None)
    qr = q
    for r in _free_roots(st):
        qr = qr.at[r.dof_x].set(fr.X[r.index][0]).at[r.dof_y].set(fr.X[r.index][1])
    if qd is None:
        return qr
    return qr, _dense(_to_tree(st, fr, [qd[d] for d in range(st.ndof)]), qd.dtype)


def from_root_coordinates(model: Model, q_root, qd_root=None):
    """Inverse of :func:`root_coordinates`."""
    st = model.structure
    q = q_root
    for r in _free_roots(st):
        q = q.at[r.dof_x].set(0.0).at[r.dof_y].set(0.0)
    fr = _positions(model, q, None)  # centre of mass at the origin: the root sits at -offset
    for r in _free_roots(st):
        q = q.at[r.dof_x].set(q_root[r.dof_x] - fr.X[r.index][0]).at[r.dof_y].set(q_root[r.dof_y] - fr.X[r.index][1])
    if qd_root is None:
        return q
    return q, _dense(_from_tree(st, fr, [qd_root[d] for d in range(st.ndof)]), qd_root.dtype)


# ---------------------------------------------------------------- sensors


def wrap_angle(a):
    """a wrapped to [-pi, pi)."""
    return a - (2 * math.pi) * jnp.floor((a + math.pi) * (0.5 / math.pi))


_wrap = wrap_angle


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
    """Binary sensor values [S] (0.0 / 1.0) of a prepared frame (positions only)."""
    st, p = model.structure, model.params
    dtype = p.q0.dtype
    out = []
    # None only without a follow path, and then there is no eye sensor to read it (the loader
    # demands a path of a creature with eyes)
    target: Any = follow_point(model, t) if st.follow else None
    for s, (kind, link, idx) in enumerate(st.sensors):
        if kind == "touch":
            on = fr.depth[idx] > 0 if st.plane == "vertical" else True
        elif kind in ("angle", "tilt"):
            ls = st.links[link]
            ang = fr.th[link] if ls.parent < 0 or kind == "tilt" else fr.th[link] - fr.th[ls.parent]
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
    """Leaves first, roots last: L D L^T of a tree then has no fill-in within a fixed tree; a free
    tree's rotational block is dense (it turns about its centre of mass) and small."""
    return list(range(st.ndof))[::-1]


def _inertial_force(st: Structure, p: Params, fr: Frame, T: "_Terms") -> None:
    """dT/dq at fixed velocities, the inertial generalised force of the momentum form.

    For link i with centre of mass c_i, T_i = m_i |v_ci|^2 / 2 + I_i w_i^2 / 2. Turning joint k at
    fixed velocities turns every segment below k on the chain to c_i, so d v_ci / dq_k =
    -sum_{j on the chain, j >= k} w_j s_j, s_j the segment of link j towards c_i, and (in a free
    tree, whose centre of mass velocity v_c is fixed) dT/dq_k = sum_i m_i (v_ci - v_c) . d v_ci /
    dq_k. Translations and a free root's angle are cyclic: no entry at all."""
    for tree in st.trees:
        if tree.point:
            continue
        root = st.links[tree.root]
        vc = (fr.qd[root.dof_x], fr.qd[root.dof_y]) if tree.free else (0.0, 0.0)
        for i in tree.links:
            ls = st.links[i]
            if ls.parent < 0 and not tree.free:
                continue
            chain = [k for k in ls.chain]
            rot_on_chain = [n for n, k in enumerate(chain) if st.links[k].dof_rot >= 0
                            and not (tree.free and st.links[k].parent < 0)]
            if not rot_on_chain:
                continue
            v = _point_vel(fr, i, fr.com[i])
            ux, uy = mul(p.mass[i], sub(v[0], vc[0])), mul(p.mass[i], sub(v[1], vc[1]))
            # suffix sums P_n = sum_{m >= n} w_{chain[m]} s_{chain[m]}
            Px: Any = 0.0
            Py: Any = 0.0
            suffix = {}
            for n in range(len(chain) - 1, -1, -1):
                k = chain[n]
                nxt = fr.X[chain[n + 1]] if n + 1 < len(chain) else fr.com[i]
                sx, sy = sub(nxt[0], fr.X[k][0]), sub(nxt[1], fr.X[k][1])
                Px, Py = add(Px, mul(fr.w[k], sx)), add(Py, mul(fr.w[k], sy))
                suffix[n] = (Px, Py)
            for n in rot_on_chain:
                Pn = suffix[n]
                T.force(neg(add(mul(ux, Pn[0]), mul(uy, Pn[1]))), {st.links[chain[n]].dof_rot: 1.0})


def _inertial_force_linear(st: Structure, p: Params, fr: Frame, T: "_Terms") -> None:
    """dT/dq of :func:`_inertial_force` in O(n): for joint k, dT/dq_k = -sum over its subtree of
    u_i x (v_ci - V_k), with u_i = m_i (v_ci - v_c) and V_k the velocity of joint k's origin
    (the chain's suffix sums there are the relative velocity v_ci - V_k turned by 90 degrees), so
    two subtree sums, sum u_i x v_ci and sum u_i, give every joint's entry."""
    kids = articulated.children(st)
    for tree in st.trees:
        if tree.point:
            continue
        root = st.links[tree.root]
        vc = (fr.qd[root.dof_x], fr.qd[root.dof_y]) if tree.free else (0.0, 0.0)
        A: dict = {}
        B: dict = {}
        for i in reversed(tree.links):
            ls = st.links[i]
            if ls.parent < 0 and not tree.free:
                continue  # welded to the world
            v = _point_vel(fr, i, fr.com[i])
            ux, uy = mul(p.mass[i], sub(v[0], vc[0])), mul(p.mass[i], sub(v[1], vc[1]))
            a, bx, by = sub(mul(ux, v[1]), mul(uy, v[0])), ux, uy
            for c in kids[i]:
                a, bx, by = add(a, A[c]), add(bx, B[c][0]), add(by, B[c][1])
            A[i], B[i] = a, (bx, by)
            if ls.dof_rot >= 0 and ls.parent >= 0:
                Vk = fr.V[i]
                T.force(add(neg(a), sub(mul(bx, Vk[1]), mul(by, Vk[0]))), {ls.dof_rot: 1.0})


def advance(model: Model, fr: Frame, state: State, u) -> tuple[State, Any]:
    """Integrate one step from a prepared frame with actuator activations ``u`` [A] in [0, 1].

    Returns (next state, largest penetration over contacts (m) at this step). The next state's
    ``qd`` is the velocity q'* of this step's position update (see the module docstring).
    """
    st, p = model.structure, model.params
    h = p.dt
    T = _Terms()
    qd = fr.u  # element rates are taken in tree coordinates, like their rows

    def element(g: dict, force, k, c, rate):
        """Spring-damper-like element along row g (see :func:`_element`)."""
        coef, f = _element(h, force, k, c, rate)
        T.outer(coef, g)
        T.force(f, g)

    (_inertial_force_linear if st.articulated else _inertial_force)(st, p, fr, T)

    # gravity: on a free tree's centre of mass (mapped to tree coordinates); link by link in a
    # welded tree
    if st.plane == "vertical":
        weight = [0.0] * st.ndof
        for tree in st.trees:
            r = st.links[tree.root]
            if tree.free:
                mt = 0.0
                for i in tree.links:
                    mt = add(mt, p.mass[i])
                weight[r.dof_y] = neg(mt * p.gravity)
                continue
            for i in tree.links:
                ls = st.links[i]
                if ls.parent < 0:
                    continue
                T.force(neg(p.mass[i] * p.gravity), _project(jacobian(st, fr, i, fr.com[i]), (0.0, 1.0)))
        for d, f in enumerate(_force_to_tree(st, fr, weight)):
            T.force(f, {d: 1.0})

    # passive joint springs
    for i in st.joint_springs:
        d = st.links[i].dof_rot
        k, c, rest = p.jspring[i, 0], p.jspring[i, 1], p.jspring[i, 2]
        phi = fr.th[i] - fr.th[st.links[i].parent]
        element({d: 1.0}, -k * (phi - rest) - c * qd[d], k, c, qd[d])

    # joint stops: a one-sided spring-damper that only ever pushes the joint back into range
    for i in st.limits:
        d = st.links[i].dof_rot
        lo, hi, k, c = p.limit[i, 0], p.limit[i, 1], p.limit[i, 2], p.limit[i, 3]
        phi = fr.th[i] - fr.th[st.links[i].parent]
        below = jnp.maximum(k * (lo - phi) - c * qd[d], 0.0)
        above = jnp.minimum(k * (hi - phi) - c * qd[d], 0.0)
        on = jnp.where(((phi < lo) & (below > 0)) | ((phi > hi) & (above < 0)), 1.0, 0.0)
        torque = jnp.where(phi < lo, below, jnp.where(phi > hi, above, 0.0))
        element({d: 1.0}, torque, on * k, on * c, qd[d])

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

    # ground contact and friction: first every contact's force laws (fenced, so that the
    # stick-slip decisions are computed once), then their elements
    laws, deepest = (_ground_laws if st.plane == "vertical" else _plane_laws)(st, p, fr, state)
    laws = _barrier(laws, fr.gate, "contacts")
    anchors = [a for _, a in laws]
    for rows, _ in laws:
        for g, coef, force in rows:
            T.outer(coef, g)
            T.force(force, g)

    # water drag on each edge, exact for a rigid edge: normal -k ∫ (v.N) N ds, tangential
    # (skin) -k_t ∫ (v.T) T ds (uniform along the edge, along its own line: no moment)
    for e, i in enumerate(st.edges):
        a0 = _point(fr, i, (p.edge[e, 0, 0], p.edge[e, 0, 1]))
        a1 = _point(fr, i, (p.edge[e, 1, 0], p.edge[e, 1, 1]))
        dx, dy = a1[0] - a0[0], a1[1] - a0[1]
        L = jnp.sqrt(dx * dx + dy * dy)
        tan = (dx / L, dy / L)
        nrm = (-tan[1], tan[0])
        va = _point_vel(fr, i, a0)
        vn = va[0] * nrm[0] + va[1] * nrm[1]
        w = fr.w[i]
        Ja = jacobian(st, fr, i, a0)
        gn = _project(Ja, nrm)
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
        vt = va[0] * tan[0] + va[1] * tan[1]
        ct = p.water_t * L
        element(_project(Ja, tan), -ct * vt, 0.0, ct, vt)

    if st.articulated:
        mat, vec = _barrier((T.mat, T.vec), fr.gate, 'terms')
        S = _barrier(articulated.gather(mat, vec), fr.gate, 'A')
        F = {b: tuple(mul(h, x) for x in f) for b, f in S.F.items()}
        du = _barrier(fr.M.solve({d: mul(h, v) for d, v in S.tau.items()}, S.arm, S.E, F), fr.gate, 'du')
    else:
        A, Q = T.assemble(_elimination_order(st), fr.gate, base=fr.M)
        rhs = {d: mul(h, v) for d, v in Q.items()}
        A.a, rhs = _barrier((A.a, rhs), fr.gate, 'A')
        du = _barrier(A.solve(rhs, _fence(fr.gate, 'du-forward')), fr.gate, 'du')
    ustar = [add(qd[d], du[d]) for d in range(st.ndof)]
    # p_{n+1} = M v* in state coordinates = S^T (M_tree u*) = p_n + S^T M_tree du
    Mdu = fr.M.matvec(du)
    dp = _force_from_tree(st, fr, [Mdu.get(d, 0.0) for d in range(st.ndof)])
    vstar = _from_tree(st, fr, ustar)
    # fenced before stacking: a fused stack would re-derive every entry for every element (q'*
    # is not: each of its entries is a few operations on du, which is fenced)
    dp, anchors = _barrier((dp, anchors), fr.gate, "update")
    dtype = state.q.dtype
    qd_new = _dense(vstar, dtype)
    p_new = state.p + _dense(dp, dtype)
    q_new = state.q + h * qd_new
    if deepest is None:
        deepest = jnp.zeros((), q_new.dtype)
    anchor = jnp.stack([jnp.stack([a[0] + jnp.zeros((), dtype), a[1] + jnp.zeros((), dtype)]) for a in anchors]) \
        if anchors else state.anchor
    return State(q_new, qd_new, state.t + h, p_new, anchor), deepest


def _element(h, force, k, c, rate) -> tuple:
    """A spring-damper-like element of the step (force F, stiffness k, damping c along a row g,
    rate g.q'; see the module docstring): its matrix coefficient h c + h^2 k and its predicted
    force F - h k rate."""
    return add(mul(h, c), mul(h * h, k)), sub(force, mul(mul(h, k), rate))


def _plane_laws(st: Structure, p: Params, fr: Frame, state: State) -> tuple[list, None]:
    """Horizontal plane: every contact's friction against the ground under its constant load,
    as elements of the step: per contact [(row, matrix coefficient, force)] and its next anchor
    (see ``advance``); nothing penetrates (None)."""
    laws = []
    for c, i in enumerate(st.contacts):
        pt, v = fr.cp[c], fr.cv[c]
        J = jacobian(st, fr, i, pt)
        mu_f, mu_b, mu_l = p.mu[i, 0], p.mu[i, 1], p.mu[i, 2]
        aniso, frm, to = st.aniso[i]
        anchor = (state.anchor[c, 0], state.anchor[c, 1])
        N = p.contact_load[c]
        d = (sub(pt[0], anchor[0]), sub(pt[1], anchor[1]))
        if aniso:
            ax = _axis(fr, i, frm, to)
            inv = jax.lax.rsqrt(ax[0] * ax[0] + ax[1] * ax[1] + 1e-12)
            e1 = (ax[0] * inv, ax[1] * inv)
            e2 = _perp(e1)
            va = v[0] * e1[0] + v[1] * e1[1]
            vl = v[0] * e2[0] + v[1] * e2[1]
            s1 = d[0] * e1[0] + d[1] * e1[1]
            s2 = d[0] * e2[0] + d[1] * e2[1]
            mu = jnp.where(p.ground_k * s1 + va > 0, mu_f, mu_b)
            r1, h1 = _stick_element(_stick_law(s1, va, mu * N, p, fr.gate), va, p)
            r2, h2 = _stick_element(_stick_law(s2, vl, mu_l * N, p, fr.gate), vl, p)
            laws.append(([(_project(J, e1), *r1), (_project(J, e2), *r2)],
                         (pt[0] - h1 * e1[0] - h2 * e2[0], pt[1] - h1 * e1[1] - h2 * e2[1])))
        else:
            rows, held = _stick_disc(J, d, v, mu_f * N, p)
            laws.append((rows, (sub(pt[0], held[0]), sub(pt[1], held[1]))))
    return laws, None


def _ground_laws(st: Structure, p: Params, fr: Frame, state: State) -> tuple[list, Any]:
    """Vertical plane: every contact's normal force and stick-slip friction against the ground,
    as elements of the step (see ``advance``): per contact [(normal row, matrix coefficient,
    force), (tangent row, coefficient, force)] and its next anchor; and the deepest penetration.

    In three passes, each fenced once for all contacts: the normal laws (and the friction limit
    mu N), the stick-slip decisions (:func:`_stick_law`), then the elements. A normal row's is the
    one :func:`_element` gives (force, stiffness, damping) = (N, k, c), or nothing off the
    ground, written out on each branch of the contact's state; a tangent row's comes from
    :func:`_stick_element`. The same arithmetic (bit for bit: a factor 1.0 or 0.0 is exact), two
    values kept per row instead of five."""
    h, k, c = p.dt, p.ground_k, p.ground_c
    pre, ground = [], []
    deepest = None
    for ci, i in enumerate(st.contacts):
        pt, v = fr.cp[ci], fr.cv[ci]
        n, t = _ground_frame(fr.terrain[ci])
        ground.append((n, t))
        depth = fr.depth[ci]
        deepest = depth if deepest is None else jnp.maximum(deepest, depth)
        vn = add(mul(v[0], n[0]), mul(v[1], n[1]))
        vt = add(mul(v[0], t[0]), mul(v[1], t[1]))
        fn = k * depth - c * vn
        on = (depth > 0) & (fn > 0)
        N = jnp.where(on, fn, 0.0)
        anchor = (state.anchor[ci, 0], state.anchor[ci, 1])
        stretch = add(mul(sub(pt[0], anchor[0]), t[0]), mul(sub(pt[1], anchor[1]), t[1]))
        aniso, frm, to = st.aniso[i]
        if aniso:
            # the limit depends on the way the contact is pushed to slip
            ax = _axis(fr, i, frm, to)
            along = add(mul(ax[0], t[0]), mul(ax[1], t[1]))
            fwd = along * (k * stretch + vt) > 0
            mu = jnp.where(fwd, p.mu[i, 0], p.mu[i, 1])
        else:
            mu = p.mu[i, 0]
        normal = (jnp.where(on, h * c + (h * h) * k, 0.0), jnp.where(on, fn - (h * k) * vn, 0.0))
        pre.append((normal, vt, stretch, mu * N))
    pre = _barrier(pre, fr.gate, "normal")
    decisions = _barrier([_stick_law(stretch, vt, limit, p) for _, vt, stretch, limit in pre], fr.gate, "stick")
    laws = []
    for ci, i in enumerate(st.contacts):
        normal, vt, _, _ = pre[ci]
        tangent, held = _stick_element(decisions[ci], vt, p)
        pt, (n, t) = fr.cp[ci], ground[ci]
        J = jacobian(st, fr, i, pt)
        laws.append(([(_project(J, n), *normal), (_project(J, t), *tangent)],
                     (sub(pt[0], mul(held, t[0])), sub(pt[1], mul(held, t[1])))))
    return laws, deepest


def _stick_law(stretch, v, limit, p: Params, gate=None) -> tuple:
    """Friction along one tangent direction (slip velocity v, anchor ``stretch`` m behind the
    contact, force limit ``limit`` = mu N): sticks while the spring-damper to the anchor (the
    ground's stiffness k, and a damper mu N / slip_speed) needs at most the limit, else slides
    with Coulomb friction. The damper bounds how fast the spring can push the contact back (by
    k s <= mu N: at most the slip speed), so a stopped slip does not rebound.

    Returns the decision: (1.0 where it sticks else 0.0, the anchor's stretch s kept, the
    sticking damping c, the sticking force -k s - c v, the sliding damping mu N / max(|v|, slip
    speed)), fenced together when ``gate`` is given (as for :func:`prepare`); see
    :func:`_stick_element`."""
    k = p.ground_k
    c = limit / p.slip  # as stiff as Coulomb friction at the slip speed: springs back at most that fast
    s = jnp.clip(stretch, -limit / k, limit / k)
    trial = -k * s - c * v
    stick = (limit > 0) & (jnp.abs(trial) <= limit)
    slide = limit / jnp.maximum(jnp.abs(v), p.slip)  # Coulomb as an implicit damper
    on = jnp.where(stick, 1.0, 0.0).astype(s.dtype)
    if gate is not None:  # the decision once: each result of it would otherwise re-derive it
        on, s, c, trial, slide = _barrier((on, s, c, trial, slide), gate, "stick")
    return on, s, c, trial, slide


def _stick_element(law: tuple, v, p: Params) -> tuple:
    """The step's element of a :func:`_stick_law` decision ``law`` at slip velocity v: when it
    sticks the spring-damper to the anchor (force -k s - c v, stiffness k, damping c), when it
    slides the Coulomb damper (force -slide v, damping slide), written out on each branch as
    :func:`_element` would compute it (the same arithmetic, bit for bit).

    Returns ((matrix coefficient h c + h^2 k, force F - h k v), how far behind the contact its
    anchor stays: 0 when sliding or free, so that a contact that stops sliding holds from where
    it stopped)."""
    h, k = p.dt, p.ground_k
    on, s, c, trial, slide = law
    stick = on > 0
    return ((jnp.where(stick, h * c + (h * h) * k, h * slide), jnp.where(stick, trial - (h * k) * v, -slide * v)),
            jnp.where(stick, s, 0.0))


def _stick_disc(J: dict, d: Vec, v: Vec, limit, p: Params) -> tuple:
    """Isotropic friction in the horizontal plane: as :func:`_stick_law`, with the force limited to a
    disc (the spring to the anchor ``d`` m behind the contact, 2-D). Returns the two elements
    (row, matrix coefficient, force) and the anchor's offset behind the contact."""
    k = p.ground_k
    c = limit / p.slip
    r = jnp.sqrt(d[0] * d[0] + d[1] * d[1])
    scale = jnp.minimum(1.0, (limit / k) / jnp.maximum(r, 1e-30))
    s = (d[0] * scale, d[1] * scale)
    trial = (-k * s[0] - c * v[0], -k * s[1] - c * v[1])
    stick = (limit > 0) & (trial[0] * trial[0] + trial[1] * trial[1] <= limit * limit)
    speed = jnp.sqrt(v[0] * v[0] + v[1] * v[1])
    slide = limit / jnp.maximum(speed, p.slip)
    ks = jnp.where(stick, k, 0.0)
    damp = jnp.where(stick, c, slide)
    rows = [(_project(J, e), *_element(p.dt, jnp.where(stick, trial[a], -slide * ve), ks, damp, ve))
            for a, (e, ve) in enumerate((((1.0, 0.0), v[0]), ((0.0, 1.0), v[1])))]
    return rows, (jnp.where(stick, s[0], 0.0), jnp.where(stick, s[1], 0.0))


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

    def assemble(self, order: list[int], gate, base: SymMatrix | None = None) -> tuple[SymMatrix, dict]:
        mat, vec = _barrier((self.mat, self.vec), gate, 'terms' if base is not None else 'mterms')
        M = SymMatrix(order)
        if base is not None:
            M.a = dict(base.a)
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


def step(model: Model, state: State, u) -> State:
    """Advance one creature by dt with actuator activations u [A] in [0, 1]; the returned state's
    ``qd`` is the velocity M^-1 p of the new configuration."""
    nxt, _ = advance(model, prepare(model, state), state, u)
    return nxt._replace(qd=velocity(model, nxt))


def energy(model: Model, state: State, fr: Frame | None = None) -> dict:
    """Mechanical energy of one creature (J): kinetic (of the velocity M^-1 p), gravitational
    (m g y of each centre of mass), and elastic (passive joint and linear springs; actuators,
    joint stops and the ground excluded). fr: ``state``'s prepared frame when at hand (an
    observer's ``update`` has it), else it is prepared here."""
    st, p = model.structure, model.params
    if fr is None:
        fr = prepare(model, state)
    kin, grav, elastic = 0.0, 0.0, 0.0
    for ls in st.links:
        i = ls.index
        if ls.parent < 0 and ls.dof_x < 0 and ls.dof_rot < 0:
            continue
        v = _point_vel(fr, i, fr.com[i])
        kin = kin + 0.5 * p.mass[i] * (v[0] * v[0] + v[1] * v[1]) + 0.5 * p.inertia[i] * fr.w[i] * fr.w[i]
        if st.plane == "vertical":
            grav = grav + p.mass[i] * p.gravity * fr.com[i][1]
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
    """Whole-creature centre of mass and its velocity from a prepared frame (m, m/s).

    Links welded to the world are part of the world and do not count."""
    st, p = model.structure, model.params
    mx = my = vx = vy = 0.0
    total = 0.0
    for ls in st.links:
        i = ls.index
        if ls.parent < 0 and ls.dof_x < 0 and ls.dof_rot < 0:
            continue
        m = p.mass[i]
        c = fr.com[i]
        mx, my = mx + m * c[0], my + m * c[1]
        if fr.w[i] is not None:
            v = _point_vel(fr, i, c)
            vx, vy = add(vx, mul(m, v[0])), add(vy, mul(m, v[1]))
        total = total + m
    inv = 1.0 / total
    return (mx * inv, my * inv), (mul(vx, inv), mul(vy, inv))


def poses(model: Model, q) -> dict:
    """World placement of one configuration q [D] (for drawing and analysis): ``links`` [L, 3]
    (origin x, y and absolute angle of each link frame), ``contacts`` [C, 2] (contact points),
    ``depth`` [C] (penetration, > 0 when touching; horizontal plane: 1), ``com`` [2]."""
    fr = _positions(model, q, None)
    z = jnp.zeros((), q.dtype)
    links = jnp.stack([jnp.stack([x[0] + z, x[1] + z, a + z]) for x, a in zip(fr.X, fr.th)])
    C = len(model.structure.contacts)
    contacts = jnp.stack([jnp.stack([p[0] + z, p[1] + z]) for p in fr.cp]) if C else jnp.zeros((0, 2), q.dtype)
    depth = jnp.stack([d + z for d in fr.depth]) if C else jnp.zeros((0,), q.dtype)
    com, _ = centre_of_mass(model, fr)
    return {"links": links, "contacts": contacts, "depth": depth, "com": jnp.stack([com[0] + z, com[1] + z])}
