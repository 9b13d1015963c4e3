"""The step as one compiled kernel that reads the creature as data (engine round 4, in progress).

Today's engine (``sanlab.sim.dynamics``) unrolls each creature's structure into its own XLA
program at trace time, so every new creature is a compile and a small batch pays ~510 kernel
dispatches per step. Here the structure is *data*: integer tables (parents, dofs, contacts,
sensors, actuators) and float tables (masses, lengths, gains, ranges), read by one C++ kernel
(``sanlab/sim/_kernel``) that the package's install compiles once and that serves every
creature, as MuJoCo's C engine and MuJoCo Warp read their models. It steps a tile of
:func:`lanes` creatures per thread, one SIMD register per value (see ``_kernel/step.h``).

The kernel follows ``dynamics`` term for term (the same coordinates, the same momentum-form
semi-implicit step with its implicitly linearised elements, the same stick-slip contact laws,
the same elimination order of the L D L^T solve), in float64, so that the two agree to
round-off. Structural zeros are no longer dropped at trace time; they are carried as exact
zeros, which changes no value (x + 0 = x exactly), and a contact no creature of a tile touches
is skipped.

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

from typing import Any, NamedTuple

import numpy as np

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
