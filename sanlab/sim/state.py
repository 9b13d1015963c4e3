"""A creature's state and what can be read off it, computed by the kernel (:mod:`sanlab.sim.kernel`).

    state = make_state(model)                  # at rest in the start pose
    frame = poses(model, state.q)              # link frames, contact points, depth, centre of mass
    e = energy(model, state)                   # kinetic, gravitational, elastic (J)

Every function takes one creature ([D] arrays) or a batch ([B, D]) and returns NumPy float64
arrays of the same leading shape. Nothing here compiles a creature: the model's tables are
packed once per model (:func:`packed`) and read by the kernel.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from sanlab.sim import kernel
from sanlab.sim.model import Model


class State(NamedTuple):
    """Simulation state of one creature (a leading batch axis for many).

    ``p`` is what the integrator carries; ``qd`` is the velocity M(q)^-1 p of this state. Build
    states with :func:`make_state`.
    """

    q: Any  # [D] generalised coordinates (m, rad)
    qd: Any  # [D] generalised velocities (m/s, rad/s)
    t: Any  # [] time (s)
    p: Any  # [D] generalised momenta (kg m/s, kg m^2/s)
    anchor: Any  # [C, 2] m, world: where each contact's friction holds it (the contact itself when free)


class SanState(NamedTuple):
    """A SAN's state (paper §4; ``sanlab.san``): one network, or a leading batch axis for many."""

    istate: Any  # [N] integrator state in [0, 1]
    out: Any  # [N] binary outputs


def packed(model: Model, hidden: int = 0) -> kernel.Packed:
    """The kernel's tables of ``model`` for a SAN of ``hidden`` hidden nodes, built once per
    model object (a model is immutable: ``with_params`` makes a new one)."""
    cache = model.__dict__.get("_packed")
    if cache is None:
        cache = {}
        object.__setattr__(model, "_packed", cache)
    if hidden not in cache:
        cache[hidden] = kernel.pack(model, hidden)
    return cache[hidden]


def row_tables(model: Model, B: int) -> dict:
    """The kernel's float tables (``kernel.ROW_TABLES``) that differ between the rows of a model
    whose parameters all carry a leading axis of B rows (a tuned, ensemble or design batch); the
    tables every row shares are left out (the kernel then reads one copy). Raises ValueError for
    a model without that axis."""
    lead = np.shape(model.params.q0)[:-1]
    if lead != (B,):
        raise ValueError(f"params_batched: expected every parameter with a leading axis of {B} rows, q0 has {lead}")
    return {name: x for name, x in kernel.numbers(model.structure, model.params, (B,)).items()
            if not np.all(x == x[:1])}


def first_row(model: Model) -> Model:
    """Row 0 of a model whose parameters carry a leading batch axis."""
    import dataclasses

    p = model.params
    return model.with_params(**{f.name: np.asarray(getattr(p, f.name))[0] for f in dataclasses.fields(p)})


def start_states(model: Model, q: Any, seat: Any = True, params_batched: bool = False) -> State:
    """States at rest for coordinates q [B, D]: each row seated on the ground where ``seat`` ([B]
    or one bool; vertical plane: every free tree lifted just clear of it, as ``compile_creature``
    seats the start pose) and its friction anchors at its contact points. params_batched: the
    model's parameters carry the B rows (each row seated on its own body)."""
    qq = np.asarray(q, np.float64)
    B = qq.shape[0]
    pk = packed(first_row(model) if params_batched else model)
    rows = row_tables(model, B) if params_batched else None
    qs, anchor = kernel.start(pk, qq, seat=seat, rows=rows)
    z = np.zeros_like(qs)
    return State(qs, z, np.zeros(B), z.copy(), anchor)


def _rows(x: Any, D: int, name: str = "q") -> tuple[np.ndarray, bool]:
    """x [D] or [B, D] -> ([B, D] float64, whether it was one); ValueError naming ``name``
    otherwise."""
    a = np.asarray(x, np.float64)
    if a.ndim not in (1, 2) or a.shape[-1] != D or (a.ndim == 2 and a.shape[0] < 1):
        raise ValueError(f"{name}: expected shape ({D},) or (B, {D}) (the creature's coordinates), got {a.shape}")
    return (a[None], True) if a.ndim == 1 else (a, False)


def _back(x: np.ndarray, single: bool) -> np.ndarray:
    return x[0] if single else x


def make_state(model: Model, q: Any = None, qd: Any = None, t: float = 0.0) -> State:
    """A consistent state: coordinates ``q`` [D] or [B, D] (default: the creature's start pose),
    velocities ``qd`` (default: at rest), time ``t`` (s); momenta p = M(q) qd and friction anchors
    at the contacts (nothing held yet)."""
    pk = packed(model)
    qq, single = _rows(model.params.q0 if q is None else q, pk.ndof)
    _, anchor = kernel.start(pk, qq, seat=False)
    if qd is None:
        v = np.zeros_like(qq)
        p = np.zeros_like(qq)
    else:
        v, _ = _rows(qd, pk.ndof, "qd")
        v = np.broadcast_to(v, qq.shape).copy()
        p = kernel.momenta(pk, qq, v)
    tt = np.full(qq.shape[0], float(t))
    return State(*(_back(x, single) for x in (qq, v, tt, p, anchor)))


def initial_state(model: Model) -> State:
    """The creature at rest in its start pose (one creature)."""
    return make_state(model)


def velocity(model: Model, state: State) -> np.ndarray:
    """The velocity M(q)^-1 p [..., D] of a state."""
    pk = packed(model)
    q, single = _rows(state.q, pk.ndof)
    p, _ = _rows(state.p, pk.ndof, "p")
    return _back(kernel.velocity(pk, q, p), single)


def poses(model: Model, q: Any, params_batched: bool = False) -> dict:
    """World placement of configurations q [..., D] (for drawing and analysis): ``links``
    [..., L, 3] (origin x, y and absolute angle of each link frame), ``contacts`` [..., C, 2]
    (contact points), ``depth`` [..., C] (penetration, > 0 when touching; horizontal plane: 1),
    ``com`` [..., 2] (the centre of mass of the links not welded to the world).
    params_batched: the model's parameters carry a leading axis of B rows (a design or tuning
    batch) and q is [B, D], row b placed on body b. Raises ValueError for q of the wrong shape."""
    pk = packed(first_row(model) if params_batched else model)
    a = np.asarray(q, np.float64)
    if a.ndim < 1 or a.shape[-1] != pk.ndof or a.size == 0 or (params_batched and a.ndim != 2):
        want = f"(B, {pk.ndof})" if params_batched else f"(..., {pk.ndof})"
        raise ValueError(f"q: expected shape {want} (the creature's coordinates), got {a.shape}")
    lead = a.shape[:-1]
    rows = row_tables(model, a.shape[0]) if params_batched else None
    out = kernel.poses(pk, a.reshape(-1, pk.ndof), rows=rows)
    return {k: v.reshape(*lead, *v.shape[1:]) for k, v in out.items()}


def energy(model: Model, state: State) -> dict:
    """Mechanical energy (J) of a state: kinetic (of the velocity M^-1 p), gravitational (m g y of
    each centre of mass) and elastic (passive joint and linear springs; actuators, joint stops and
    the ground excluded), each [...]."""
    pk = packed(model)
    q, single = _rows(state.q, pk.ndof)
    p, _ = _rows(state.p, pk.ndof)
    return {k: _back(v, single) for k, v in kernel.energy(pk, q, p).items()}


def sense(model: Model, q: Any, t: Any = 0.0) -> np.ndarray:
    """Binary sensor values [..., S] (0.0 / 1.0) of configurations q [..., D] at time t (s; the
    follow point moves with it)."""
    pk = packed(model)
    qq, single = _rows(q, pk.ndof)
    return _back(kernel.sense(pk, qq, np.broadcast_to(np.asarray(t, np.float64), qq.shape[:1])), single)


def follow_point(model: Model, t: Any) -> np.ndarray:
    """Position of the follow point at time(s) t (m): [2] or [B, 2]."""
    tt = np.asarray(t, np.float64)
    out = kernel.follow_point(packed(model), tt.reshape(-1))
    return out[0] if tt.ndim == 0 else out


def centre_of_mass(model: Model, q: Any) -> np.ndarray:
    """The centre of mass [..., 2] (m) of configurations q [..., D] (links welded to the world are
    part of the world and do not count)."""
    return poses(model, q)["com"]


def step(model: Model, state: State, u: Any) -> State:
    """One step of one creature (or a batch) under activations u [..., A] in [0, 1]."""
    pk = packed(model)
    q, single = _rows(state.q, pk.ndof)
    p, _ = _rows(state.p, pk.ndof)
    anchor = np.asarray(state.anchor, np.float64).reshape(q.shape[0], -1, 2)
    uu = np.broadcast_to(np.asarray(u, np.float64), (q.shape[0], pk.ai.shape[0]))
    t = float(np.asarray(state.t, np.float64).reshape(-1)[0])
    r = kernel.run_open(pk, "hold", uu, q, p, anchor, 1, t0=t)
    return State(*(_back(x, single) for x in (r["q"], r["qd"], r["t"], r["p"], r["anchor"])))


def terrain_height(model: Model, x: Any) -> tuple[np.ndarray, np.ndarray]:
    """The ground's height h(x) and slope h'(x) (m, and m/m) at x [...] (m) in the vertical
    plane: the kernel's ground (``_kernel/terrain.h``), for drawing and checks."""
    st, p = model.structure, model.params
    x = np.asarray(x, np.float64)
    zero = np.zeros_like(x)
    terrain = np.asarray(p.terrain, np.float64)
    if st.terrain == "flat":
        return zero, zero.copy()
    if st.terrain == "slope":
        return terrain[0] * x, zero + terrain[0]
    if st.terrain == "hill":
        H, hw, c = terrain[1], terrain[2], terrain[3]
        u = (x - c) * (np.pi / hw)
        inside = np.abs(x - c) < hw
        return (np.where(inside, 0.5 * H * (1.0 + np.cos(u)), 0.0),
                np.where(inside, -0.5 * H * (np.pi / hw) * np.sin(u), 0.0))
    h, dh = zero.copy(), zero.copy()
    for a, w, ph in np.asarray(p.rough, np.float64):
        h += a * np.sin(w * x + ph)
        dh += a * w * np.cos(w * x + ph)
    return h, dh


def wrap_angle(a: Any) -> np.ndarray:
    """a wrapped to [-pi, pi)."""
    a = np.asarray(a, np.float64)
    return a - (2 * np.pi) * np.floor((a + np.pi) * (0.5 / np.pi))


def _turn_rates(model: Model, q: np.ndarray) -> dict[int, tuple[np.ndarray, list[tuple[int, np.ndarray]]]]:
    """For each free tree of links (root link index -> (its root link's origin minus the tree's
    centre of mass [2], [(rotational dof d, d(origin - centre of mass)/dq_d [2])])) at one
    configuration q [D]: turning a joint swings its subtree about the joint and so moves the
    centre of mass under a root that stays; turning the root swings the whole tree."""
    st, p = model.structure, model.params
    links = poses(model, q)["links"]
    mass, com = np.asarray(p.mass, np.float64), np.asarray(p.com, np.float64)
    c, s = np.cos(links[:, 2]), np.sin(links[:, 2])
    centre = links[:, :2] + np.stack([c * com[:, 0] - s * com[:, 1], s * com[:, 0] + c * com[:, 1]], 1)
    perp = lambda v: np.array([-v[1], v[0]])
    out = {}
    for t in st.trees:
        if not t.free or t.point:
            continue
        members = list(t.links)
        M = mass[members].sum()
        cm = (mass[members, None] * centre[members]).sum(0) / M
        root = links[t.root, :2]
        rows = []
        for k in t.rot:
            d = st.links[k].dof_rot
            if k == t.root:
                rows.append((d, perp(root - cm)))
                continue
            sub = [i for i in members if k in st.links[i].chain]
            Ms = mass[sub].sum()
            cs = (mass[sub, None] * centre[sub]).sum(0) / Ms
            rows.append((d, -(Ms / M) * perp(cs - links[k, :2])))
        out[t.root] = (root - cm, rows)
    return out


def root_coordinates(model: Model, q: Any, qd: Any = None):
    """One state's coordinates q [D] (and velocities qd) in root-origin form: each free tree's
    centre of mass (and its velocity) replaced by its root link's origin (and that point's
    velocity), the convention of MuJoCo's free joints and of the creature file's ``position``.
    Returns q_root, or (q_root, qd_root) when qd is given."""
    st = model.structure
    qr = np.array(q, np.float64)
    vr = None if qd is None else np.array(qd, np.float64)
    for r, (offset, rows) in _turn_rates(model, qr).items():
        ls = st.links[r]
        if vr is not None:
            turn = sum((T * vr[d] for d, T in rows), np.zeros(2))
            vr[ls.dof_x] += turn[0]
            vr[ls.dof_y] += turn[1]
        qr[ls.dof_x] += offset[0]
        qr[ls.dof_y] += offset[1]
    return qr if vr is None else (qr, vr)


def from_root_coordinates(model: Model, q_root: Any, qd_root: Any = None):
    """Inverse of :func:`root_coordinates`."""
    st = model.structure
    q = np.array(q_root, np.float64)
    v = None if qd_root is None else np.array(qd_root, np.float64)
    for r, (offset, rows) in _turn_rates(model, q).items():  # the offset depends on the angles only
        ls = st.links[r]
        q[ls.dof_x] -= offset[0]
        q[ls.dof_y] -= offset[1]
        if v is not None:
            turn = sum((T * v[d] for d, T in rows), np.zeros(2))
            v[ls.dof_x] -= turn[0]
            v[ls.dof_y] -= turn[1]
    return q if v is None else (q, v)
