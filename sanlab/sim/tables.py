"""The creature as the kernel's tables (:func:`pack`), each as :mod:`sanlab.sim.layout` declares it,
and what the kernel may read without checking (:func:`check`). Part of the kernel's calls
(:mod:`sanlab.sim.kernel`), private to ``sanlab.sim``."""

from __future__ import annotations

from collections import OrderedDict
from typing import Any, NamedTuple

import numpy as np

from sanlab.sim import layout

# offsets of the columns the host reads (layout.py declares every table; these are its offsets)
_LI, _WI, _WF, _LF = (layout.TABLE[n] for n in ("li", "wi", "wf", "lf"))
L_PARENT, L_DX, L_DY, L_ROT, L_TREE = (_LI.at(c) for c in ("parent", "dof_x", "dof_y", "dof_rot", "tree"))
L_AX_FROM, L_AX_TO, L_SPRING, L_LIMIT = (_LI.at(c) for c in ("axis_from", "axis_to", "spring", "limit"))
LI, LF, W_COUNT = _LI.width, _LF.width, _WF.width
F_MASS, F_MU = _LF.at("mass"), _LF.at("mu")
W_DT = _WF.at("dt")
W_TERRAIN, W_HIDDEN, W_PLANE, W_FOLLOW, W_FOLLOW_LOOP, W_ARTICULATED = (
    _WI.at(c) for c in ("terrain", "hidden", "plane", "follow", "follow_loop", "articulated"))
TERRAINS = {name: k for k, name in enumerate(layout.TERRAINS)}
SENSORS = {name: k for k, name in enumerate(layout.SENSORS)}
TABLES = layout.ORDER  # the order of the tables in the kernel's call
ROW_TABLES = layout.ROW_TABLES  # the numbers a row may carry its own of


class Packed(NamedTuple):
    """A creature as tables for the kernel, each [rows, columns] as :mod:`sanlab.sim.layout`
    declares them (names, widths, units; the int32 ``li ti ci si ai pi ei wi`` and the float64
    ``lf cf sf af pf ef wf rough follow``), and each link's chain: ``ri``, ``rl`` [L, R] and
    ``rn`` [L], the dofs a point on it depends on (the tree's translation, then each joint from
    the root, in increasing order), what each is (-1 / -2 the tree's x / y, else the link whose
    joint it is), and how many. Units SI. ``dtype``: the arithmetic the kernel steps these tables
    in, "float64" or "float32" (the model's dtype; the tables stay float64, holding a float32
    model's numbers exactly)."""

    li: Any
    ri: Any
    rl: Any
    rn: Any
    ti: Any
    ci: Any
    si: Any
    ai: Any
    pi: Any
    ei: Any
    wi: Any
    lf: Any
    cf: Any
    sf: Any
    af: Any
    pf: Any
    ef: Any
    wf: Any
    rough: Any
    follow: Any
    q0: Any  # [D] the start pose
    ndof: int
    dtype: str = "float64"


def pack(model, hidden: int, articulated: bool | None = None) -> Packed:
    """The tables of ``model`` (a ``sim.Model``) for a SAN with ``hidden`` hidden nodes, to be
    stepped in the model's dtype: float64 arithmetic, or float32 (``Packed.dtype``).

    articulated: the step's linear algebra, the O(n) articulated-body recursion (True) or the
    dense L D L^T (False), the same step to round-off. None (default): the model's own choice
    (``compile_creature(spec, articulated=...)``), else articulated wherever it applies (trees of
    rigid links: no point masses, nothing joining two bodies), which measured as fast or faster
    at every size (bounder at batch 2048: 156 against 215 ns per creature-step; a 32-link chain
    2.3x). Raises ValueError for True where it does not apply."""
    from sanlab.sim.model import articulated_supported

    st, p = model.structure, model.params
    if articulated is None:
        articulated = getattr(st, "articulated", None)
    can = articulated_supported(model.spec)
    if articulated and not can:
        raise ValueError("the articulated route takes trees of rigid links only (no point masses, linear springs "
                         "or linear actuators)")
    art = can if articulated is None else articulated
    f = lambda x: np.asarray(x, np.float64)
    i32 = lambda x, *shape: np.asarray(x, np.int32).reshape(*shape)
    L = len(st.links)
    links = st.links
    li = layout.TABLE["li"].build((), L, parent=[ls.parent for ls in links], point=[int(ls.point) for ls in links],
                                  dof=[(ls.dof_x, ls.dof_y, ls.dof_rot) for ls in links], tree=[ls.tree for ls in links],
                                  welded=[int(ls.parent < 0 and ls.dof_x < 0 and ls.dof_rot < 0) for ls in links],
                                  aniso=[st.aniso[ls.index][0] for ls in links],
                                  axis=[st.aniso[ls.index][1:] for ls in links],
                                  spring=[int(ls.index in st.joint_springs) for ls in links],
                                  limit=[int(ls.index in st.limits) for ls in links])
    assert [ls.index for ls in links] == list(range(L))
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
    T, S, A = len(st.trees), len(st.sensors), len(st.actuators)
    ti = layout.TABLE["ti"].build((), T, root=[t.root for t in st.trees], free=[int(t.free) for t in st.trees],
                                  point=[int(t.point) for t in st.trees])
    ci = i32(st.contacts, -1)
    reads = []  # per sensor: (on, second, third)
    for kind, link, idx in st.sensors:
        if kind == "touch":
            reads.append((idx, -1, -1))
        elif kind == "eye":
            reads.append(tuple(st.eyes[idx]))
        elif kind == "length":
            reads.append((*st.lengths[idx], -1))
        else:
            reads.append((link, -1, -1))
    reads = np.array(reads, np.int32).reshape(S, 3)
    si = layout.TABLE["si"].build((), S, kind=[SENSORS[k] for k, _, _ in st.sensors], on=reads[:, 0],
                                  second=reads[:, 1], third=reads[:, 2])
    ends = np.array([(ref, -1) if kind == "angular" else st.lin_act[ref] for kind, ref in st.actuators],
                    np.int32).reshape(A, 2)
    ai = layout.TABLE["ai"].build((), A, kind=[layout.ACTUATORS.index(k) for k, _ in st.actuators], link=ends[:, 0],
                                  link_b=ends[:, 1])
    pi = i32(st.springs, -1, 2)
    ei = i32(st.edges, -1)
    wi = layout.TABLE["wi"].build((), 1, terrain=TERRAINS[st.terrain], hidden=hidden,
                                  plane=layout.PLANES.index(st.plane), follow=int(st.follow),
                                  follow_loop=int(st.follow_loop), articulated=int(art))
    x = numbers(model.structure, p)
    return Packed(li, ri, rl, rn, ti, ci, si, ai, pi, ei, wi, x["lf"], x["cf"], x["sf"], x["af"], x["pf"], x["ef"],
                  x["wf"], x["rough"], f(p.follow).reshape(-1, 2), f(p.q0), st.ndof,
                  np.dtype(getattr(model, "dtype", "float64")).name)


def numbers(structure, params, batch: tuple[int, ...] = ()) -> dict[str, np.ndarray]:
    """The float tables of :data:`ROW_TABLES` (float64) of ``params`` (a ``sim.Params``) whose
    leaves carry the leading axes ``batch`` (``()``: one creature; ``(B,)``: B rows, as a tuned or
    ensemble model's) -> {name: [*batch, *the table's shape]}. See :class:`Packed` for the
    columns."""
    p, st = params, structure
    L, C, S, A = len(st.links), len(st.contacts), len(st.sensors), len(st.actuators)
    P, E, K = len(st.springs), len(st.edges), np.shape(p.rough)[-2]
    f = lambda x, *shape: np.broadcast_to(np.asarray(x, np.float64), (*batch, *shape)) if shape else \
        np.broadcast_to(np.asarray(x, np.float64), batch)
    tab = lambda name, n, **cols: layout.TABLE[name].build(batch, n, **cols)
    lf = tab("lf", L, mass=f(p.mass, L), inertia=f(p.inertia, L), com=f(p.com, L, 2), anchor=f(p.anchor, L, 2),
             pose=f(p.root_pose, L, 3), mu=f(p.mu, L, 3), jspring=f(p.jspring, L, 3), limit=f(p.limit, L, 4))
    cf = tab("cf", C, point=f(p.contact, C, 2), load=f(p.contact_load, C))
    pts = f(p.sens_pts, S, 2, 2)
    sf = tab("sf", S, min=f(p.sens_min, S), max=f(p.sens_max, S), point=pts[..., 0, :], point_b=pts[..., 1, :])
    pts = f(p.act_pts, A, 2, 2)
    af = tab("af", A, min=f(p.act_min, A), max=f(p.act_max, A), ks=f(p.act_ks, A), kd=f(p.act_kd, A),
             point_a=pts[..., 0, :], point_b=pts[..., 1, :])
    pts, spr = f(p.spr_pts, P, 2, 2), f(p.spr, P, 3)
    pf = tab("pf", P, point_a=pts[..., 0, :], point_b=pts[..., 1, :], ks=spr[..., 0], kd=spr[..., 1], rest=spr[..., 2])
    pts = f(p.edge, E, 2, 2)
    ef = tab("ef", E, a=pts[..., 0, :], b=pts[..., 1, :])
    terrain = f(p.terrain, 4)
    wf = tab("wf", 1, gravity=f(p.gravity), ground_k=f(p.ground_k), ground_c=f(p.ground_c), slip=f(p.slip),
             dt=f(p.dt), slope=terrain[..., 0], hill=terrain[..., 1:], water_k=f(p.water_k), water_t=f(p.water_t),
             follow_ds=f(p.follow_ds), follow_speed=f(p.follow_speed))
    rough = f(p.rough, K, 3)
    rough = tab("rough", K, amplitude=rough[..., 0], wavenumber=rough[..., 1], phase=rough[..., 2])
    out = {"lf": lf, "cf": cf, "sf": sf, "af": af, "pf": pf, "ef": ef, "wf": wf, "rough": rough}
    return {k: np.ascontiguousarray(v) for k, v in out.items()}

def check(pk: Packed) -> None:
    """Raise ValueError naming the table unless ``pk``'s tables are what the kernel may read
    without checking: each of the shape its counts imply, every index inside the table it
    indexes (a parent before its child, a joint's link with a parent and a rotation), each kind
    one the kernel knows, and a follow path of at least two samples (the kernel interpolates
    between neighbours). :func:`pack` makes such tables; every entry point checks them once
    per call, before the kernel reads them."""
    L, C, T, D = pk.li.shape[0] if np.ndim(pk.li) == 2 else -1, np.size(pk.ci), np.shape(pk.ti)[0], int(pk.ndof)
    S, A, P, E = np.shape(pk.si)[0], np.shape(pk.ai)[0], np.shape(pk.pi)[0], np.size(pk.ei)

    def need(ok: bool, name: str, what: str) -> None:
        if not ok:
            raise ValueError(f"tables.{name}: expected {what}")

    def shaped(name: str, shape: tuple, dtype) -> np.ndarray:
        a = np.asarray(getattr(pk, name))
        need(a.shape == shape and a.dtype == dtype, name, f"{np.dtype(dtype).name} of shape {shape}, got "
             f"{a.dtype.name} of shape {a.shape}")
        return a

    def within(name: str, x: np.ndarray, lo: int, hi: int) -> None:
        need(bool(np.all((x >= lo) & (x < hi))), name, f"indices in [{lo}, {hi}), got {x[(x < lo) | (x >= hi)][:1]}")

    need(L >= 1 and D >= 0, "li", "at least one link")
    need(getattr(pk, "dtype", None) in ("float64", "float32"), "dtype", f"float64 or float32, got {pk.dtype!r}")
    R = np.shape(pk.ri)[1] if np.ndim(pk.ri) == 2 else -1
    K, F = np.shape(pk.rough)[0], np.shape(pk.follow)[0]
    rows = {"links": L, "trees": T, "contacts": C, "sensors": S, "actuators": A, "springs": P, "edges": E, "rough": K,
            "follow": F}
    got = {}
    for t in layout.TABLES:  # each of the declared shape: [rows, width], one column 1-D, the world one row
        shape = (t.width,) if t.rows == "world" else (rows[t.rows],) if t.name in ("ci", "ei") else (rows[t.rows], t.width)
        got[t.name] = shaped(t.name, shape, np.dtype(t.dtype))
    li, ti, ci, si, ai, pi, ei, wi = (got[n] for n in ("li", "ti", "ci", "si", "ai", "pi", "ei", "wi"))
    ri, rl, rn = shaped("ri", (L, R), np.int32), shaped("rl", (L, R), np.int32), shaped("rn", (L,), np.int32)
    shaped("q0", (D,), np.float64)
    need(F >= 2, "follow", f"a path of at least 2 samples, got {F}")
    parent = li[:, L_PARENT]
    need(bool(np.all((parent >= -1) & (parent < np.arange(L)))), "li", "each link's parent before it (or -1)")
    for col in (L_DX, L_DY, L_ROT):
        within("li (dofs)", li[:, col], -1, D)
    within("li (trees)", li[:, L_TREE], 0, T)
    within("li (axes)", li[:, [L_AX_FROM, L_AX_TO]], -1, L)
    jointed = (parent >= 0) & (li[:, L_ROT] >= 0)
    need(bool(np.all(jointed[(li[:, L_SPRING] != 0) | (li[:, L_LIMIT] != 0)])), "li", "springs and stops at joints")
    within("ri", ri, 0, max(D, 1))
    within("rl", rl, -3, L)
    within("rn", rn, 0, R + 1)
    within("ti", ti[:, 0], 0, L)
    within("ci", ci, 0, L)
    within("pi", pi, 0, L)
    within("ei", ei, 0, L)
    kinds = si[:, 0]
    within("si (kinds)", kinds, 0, len(SENSORS))
    for kind, cols, lo, hi in ((SENSORS["touch"], [1], 0, C), (SENSORS["angle"], [1], 0, L), (SENSORS["tilt"], [1], 0, L),
                               (SENSORS["eye"], [1], 0, L), (SENSORS["eye"], [2, 3], -1, L),
                               (SENSORS["length"], [1, 2], 0, L)):
        within("si", si[kinds == kind][:, cols], lo, hi)
    within("ai (kinds)", ai[:, 0], 0, 2)
    angular = ai[ai[:, 0] == 0, 1]
    within("ai", angular, 0, L)
    need(bool(np.all(jointed[angular])), "ai", "angular actuators at joints")
    within("ai", ai[ai[:, 0] == 1][:, 1:], 0, L)
    within("wi (terrain)", wi[W_TERRAIN:W_TERRAIN + 1], 0, len(TERRAINS))
    need(wi[W_HIDDEN] >= 0 and all(wi[k] in (0, 1) for k in (W_PLANE, W_FOLLOW, W_FOLLOW_LOOP, W_ARTICULATED)),
         "wi", "hidden nodes >= 0 and flags 0 or 1")


def _checked(pk: Packed) -> None:
    """:func:`check` once per tables: the last few checked are remembered (an ensemble or a
    tuning run calls the kernel with the same tables and rows of its own, thousands of times)."""
    hit = _CHECKED.get(id(pk))
    if hit is not None and hit is pk:  # held, so its id is its own
        _CHECKED.move_to_end(id(pk))
        return
    check(pk)
    _CHECKED[id(pk)] = pk
    while len(_CHECKED) > 64:
        _CHECKED.popitem(last=False)


_CHECKED: OrderedDict = OrderedDict()  # id(pk) -> pk, the tables check() passed


def _check_rows(pk: Packed, B: int, rows: dict | None) -> dict:
    """``rows`` (see :func:`run_san`) as float64 arrays, or a ValueError naming the one that is
    not a table a row may carry, or not of its shape."""
    rows = rows or {}
    unknown = sorted(set(rows) - set(ROW_TABLES))
    if unknown:
        raise ValueError(f"rows: expected tables among {ROW_TABLES}, got {unknown}")
    out = {}
    for name, x in rows.items():
        shape = (B, *getattr(pk, name).shape)
        out[name] = np.asarray(x, np.float64)
        if out[name].shape != shape:
            raise ValueError(f"rows[{name!r}]: expected shape {shape}, got {out[name].shape}")
    return out
