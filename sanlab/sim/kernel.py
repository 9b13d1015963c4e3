"""The calls of the simulator's kernel: one compiled C++ kernel (``sanlab/sim/_kernel``) that
reads the creature as data and serves every creature, as MuJoCo's C engine and MuJoCo Warp read
their models. Private to ``sanlab.sim``: the layers above use its API (``tests/test_layers.py``).

The creature goes down as tables (:func:`pack`: integer tables of its structure, float tables of
its numbers, each declared once in :mod:`sanlab.sim.layout`), which the package's install
compiles nothing for. The kernel steps a tile of :func:`lanes` creatures per thread, one SIMD
register per value; ``_kernel/step.h``'s ``step()`` names the stages of a step, each in a header
of its own (``docs/simulator.md`` walks them). It covers every element of a creature file (both
planes, every terrain, point masses, angular and linear servos, joint springs and stops, linear
springs, iso- and anisotropic friction, water drag, every sensor kind, the follow point), both
routes of the linear algebra (the dense L D L^T and the articulated O(n) recursion, see
:func:`pack`), the observers (:class:`Observe`) and recording (``every=``). It replaced an XLA
engine in issue 46 and agreed with it to round-off (``tests/sim/test_kernel_reference.py`` holds
that engine's numbers; ``docs/engine-history.md``).

Entry points, each over a batch of B rows (rows may carry their own numbers: ``rows=``), each
checking what it is given before the kernel reads it (:func:`check`, step counts, shapes):

- rollouts: :func:`run_san` (SANs) and :func:`run_open` (held activations, sines, reflexes,
  patterns), one loop for every kind of controller; :func:`start` for states at rest, seated on
  the ground;
- inspectors of single configurations: :func:`poses`, :func:`energy`, :func:`momenta`,
  :func:`velocity`, :func:`sense`, :func:`follow_point`, :func:`centre_of_mass` (what
  ``sim.poses``, ``sim.energy``, ``sim.make_state``, ``sim.velocity``, ``sim.sense``,
  ``sim.follow_point`` and ``sim.centre_of_mass`` compute with them).

Every entry point but :func:`start` also runs in the GPU's form (``scalar=True``: plain double,
one row per thread), bit for bit as the SIMD tiles.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
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


class Packed(NamedTuple):
    """A creature as tables for the kernel, each [rows, columns] as :mod:`sanlab.sim.layout`
    declares them (names, widths, units; the int32 ``li ti ci si ai pi ei wi`` and the float64
    ``lf cf sf af pf ef wf rough follow``), and each link's chain: ``ri``, ``rl`` [L, R] and
    ``rn`` [L], the dofs a point on it depends on (the tree's translation, then each joint from
    the root, in increasing order), what each is (-1 / -2 the tree's x / y, else the link whose
    joint it is), and how many. Units SI."""

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


def pack(model, hidden: int, articulated: bool | None = None) -> Packed:
    """The tables of ``model`` (a ``sim.Model`` of any dtype: the kernel runs in float64) for a
    SAN with ``hidden`` hidden nodes.

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
                  x["wf"], x["rough"], f(p.follow).reshape(-1, 2), f(p.q0), st.ndof)


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
        if (here / "_kernel").is_dir():  # installed with its sources: the build must be of them
            lib.sanlab_kernel_source.restype = ctypes.c_char_p
            built, now = lib.sanlab_kernel_source().decode(), source_hash(here / "_kernel")
            if built != now:
                raise RuntimeError(f"sanlab's simulator kernel {path.name} was built from other sources ({built}, "
                                   f"these are {now}): rebuild it with `pip install -e .`")
        for name, args in ENTRY_POINTS.items():
            fn = getattr(lib, name)
            fn.restype = None
            fn.argtypes = [_CTYPES.get(c, ctypes.c_void_p) for _, c in args]
        lib.sanlab_kernel_lanes.restype = ctypes.c_int
        _LIB = lib
    return _LIB


_LIB = None
ENTRY_POINTS = {"sanlab_rollout": layout.ROLLOUT_ARGS, "sanlab_inspect": layout.INSPECT_ARGS,
                "sanlab_start": layout.START_ARGS}


def _ctypes_of() -> dict:
    import ctypes

    return {"int32_t": ctypes.c_int32, "int64_t": ctypes.c_int64}  # every pointer: c_void_p


_CTYPES = _ctypes_of()


def _call(name: str, **args) -> None:
    """The kernel's entry point ``name`` with its arguments by name (layout.py declares them)."""
    names = [a for a, _ in ENTRY_POINTS[name]]
    if sorted(args) != sorted(names):
        raise TypeError(f"{name}: expected arguments {names}, got {sorted(args)}")
    getattr(_library(), name)(*(args[a] for a in names))


def source_hash(folder) -> str:
    """The hash of the kernel's sources in ``folder``, as setup.py stamps it into the build."""
    import hashlib
    from pathlib import Path

    h = hashlib.sha256()
    for f in sorted(Path(folder).glob("*.[hc]*")):
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def lanes() -> int:
    """Creatures per tile (the SIMD width the kernel was built for)."""
    return int(_library().sanlab_kernel_lanes())


def _tile(x: np.ndarray, W: int) -> np.ndarray:
    """[B, ...] -> [T, ..., W], the batch padded with copies of its last row; always a new array:
    the kernel writes its state back in place, and a view (W = 1, or a 1-D array) would hand it
    the caller's own memory."""
    B, rest = x.shape[0], x.shape[1:]
    T, full = -(-B // W), B // W
    n = math.prod(rest)
    out = np.empty((T, n, W), np.float64)
    # written through a [T, W, n] view of the tile layout: no padded copy of x in between (a
    # Gymnasium step tiles nine small arrays per call, where each allocation shows)
    view = out.transpose(0, 2, 1)
    flat = x.reshape(B, n)
    if full:
        view[:full] = flat[: full * W].reshape(full, W, n)
    if full < T:
        r = B - full * W
        view[full, :r] = flat[full * W :]
        view[full, r:] = flat[B - 1]
    return out.reshape(T, *rest, W)


def _untile(x: np.ndarray, B: int) -> np.ndarray:
    T, W = x.shape[0], x.shape[-1]
    rest = x.shape[1:-1]
    return x.reshape(T, -1, W).transpose(0, 2, 1).reshape(T * W, *rest)[:B]


ROW_TABLES = layout.ROW_TABLES  # the numbers a row may carry its own of
ACC = layout.ACC  # what the observers accumulate per row (layout.py says what each is)
EVENTS = layout.EVENTS
METRIC_KINDS = layout.METRIC_KINDS


@dataclass(frozen=True)
class Observe:
    """What a rollout accumulates besides the state: the ingredients of a metric (paper §5.1; see
    ``sanlab.metrics``) and the behaviour descriptors (``sanlab.descriptors``). Link, dof and sensor
    numbers index the model's; angles in rad, heights in m above the ground."""

    kind: str = "distance"  # one of METRIC_KINDS: which integral to keep (hopping's, pursuit's, tracking's)
    fell_links: tuple[int, ...] = ()  # fallen once one turns past fell_angle from upright
    fell_angle: float = math.pi / 2
    fell_com_height: float | None = None  # fallen once the centre of mass comes closer to the ground
    fell_link_height: float | None = None  # or a fell link's centre of mass
    depth: bool = False  # keep the deepest contact
    root: int = -1  # the descriptors' rotating root link (-1: none)
    sensors: int = 0  # sensors in the descriptors' word (0: no word; at most 30)
    joints: tuple[int, ...] = ()  # dofs of the joints whose mean speed is kept
    touch: tuple[int, ...] = ()  # sensor indices whose duty is kept

    @property
    def size(self) -> int:
        """Accumulator values per row."""
        return len(ACC) + len(self.touch) + 2 * EVENTS

    def check(self, pk: Packed) -> None:
        """Raise ValueError unless every index it names is one of ``pk``'s (the kernel reads and
        writes by them: an index past a table would be read or written past it)."""
        L, S, D = pk.li.shape[0], pk.si.shape[0], pk.ndof
        if self.kind not in METRIC_KINDS:
            raise ValueError(f"observe.kind: expected one of {METRIC_KINDS}, got {self.kind!r}")
        if self.kind in ("pursuit", "tracking") and not pk.wi[W_FOLLOW]:
            raise ValueError(f"observe.kind: {self.kind} needs a follow path (the model has none)")
        for name, values, n in (("fell_links", self.fell_links, L), ("joints", self.joints, D),
                                ("touch", self.touch, S), ("root", () if self.root == -1 else (self.root,), L)):
            bad = [v for v in values if not (isinstance(v, (int, np.integer)) and 0 <= v < n)]
            if bad:
                raise ValueError(f"observe.{name}: expected indices in [0, {n}), got {bad[0]!r}")
        if not (isinstance(self.sensors, (int, np.integer)) and 0 <= self.sensors <= min(30, S)):
            raise ValueError(f"observe.sensors: expected 0 to {min(30, S)} (the creature's sensors, at most 30), "
                             f"got {self.sensors!r}")

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(oi int32, of float64), the kernel's config (_kernel/observe.h)."""
        oi = [METRIC_KINDS.index(self.kind), self.fell_com_height is not None, self.fell_link_height is not None,
              self.depth, self.root, self.sensors, len(self.fell_links), len(self.joints), len(self.touch),
              *self.fell_links, *self.joints, *self.touch]
        of = [self.fell_angle, self.fell_com_height or 0.0, self.fell_link_height or 0.0]
        return np.array(oi, np.int32), np.array(of, np.float64)


def _dims(pk: Packed, N: int) -> np.ndarray:
    """The kernel's counts (layout.DIMS) of ``pk`` with a SAN of N nodes (0: another controller)."""
    S = pk.si.shape[0]
    counts = {"links": pk.li.shape[0], "contacts": pk.ci.shape[0], "trees": pk.ti.shape[0], "dofs": pk.ndof,
              "sensors": S, "actuators": pk.ai.shape[0], "chain": pk.ri.shape[1], "rough": pk.rough.shape[0],
              "nodes": N, "inputs": S + N, "springs": pk.pi.shape[0], "edges": pk.ei.shape[0],
              "follow": pk.follow.shape[0]}
    return np.array([counts[name] for name, _, _ in layout.DIMS], np.int32)


def _tables(pk: Packed, B: int, rows: dict | None, W: int) -> tuple[Any, np.ndarray, list]:
    """The kernel's tables for a call of B rows in tiles of W (``rows``: per-row ones, see
    :func:`run_san`): (their addresses, the per-row flags, the arrays, which must outlive the
    call). Without per-row tables the answer is kept for the last few creatures: a Gymnasium
    step or a studio chunk calls the kernel thousands of times on one creature."""
    if not rows:
        hit = _SHARED.get(id(pk))
        if hit is not None and hit[0] is pk:  # the creature itself is held, so its id is its own
            _SHARED.move_to_end(id(pk))
            return hit[1]
    _checked(pk)
    rows = _check_rows(pk, B, rows)
    T = -(-B // W)
    tables = []
    for name in TABLES:
        shared = np.ascontiguousarray(getattr(pk, name))
        if name not in rows:
            tables.append(shared)
            continue
        x = rows[name]
        if T * W != B:  # padded like the state: copies of the last row
            x = np.concatenate([x, np.repeat(x[-1:], T * W - B, 0)])
        tables.append(np.ascontiguousarray(x))
    answer = (_pointers(tables), np.array([name in rows for name in ROW_TABLES], np.int32), tables)
    if not rows:
        _SHARED[id(pk)] = (pk, answer)
        while len(_SHARED) > 8:
            _SHARED.popitem(last=False)
    return answer


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
    R = np.shape(pk.ri)[1] if np.ndim(pk.ri) == 2 else -1
    li = shaped("li", (L, LI), np.int32)
    ri, rl, rn = shaped("ri", (L, R), np.int32), shaped("rl", (L, R), np.int32), shaped("rn", (L,), np.int32)
    ti, ci = shaped("ti", (T, 3), np.int32), shaped("ci", (C,), np.int32)
    si, ai = shaped("si", (S, 4), np.int32), shaped("ai", (A, 3), np.int32)
    pi, ei, wi = shaped("pi", (P, 2), np.int32), shaped("ei", (E,), np.int32), shaped("wi", (6,), np.int32)
    K, F = np.shape(pk.rough)[0], np.shape(pk.follow)[0]
    for name, shape in (("lf", (L, LF)), ("cf", (C, 3)), ("sf", (S, 6)), ("af", (A, 8)), ("pf", (P, 7)),
                        ("ef", (E, 4)), ("wf", (W_COUNT,)), ("rough", (K, 3)), ("follow", (F, 2)), ("q0", (D,))):
        shaped(name, shape, np.float64)
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
_SHARED: OrderedDict = OrderedDict()  # id(pk) -> (pk, _tables' answer) for the last creatures called


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


def _pointers(arrays: list):
    import ctypes

    return (ctypes.c_void_p * len(arrays))(*[a.__array_interface__["data"][0] for a in arrays])


def start(pk: Packed, q, seat: Any = True, rows: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Start states at rest for coordinates q [B, D]: (q [B, D] with every free tree lifted just
    clear of the ground where ``seat`` ([B] or one bool; vertical plane), the friction anchors
    [B, C, 2] at the contact points). The momenta of a state at rest are zero."""
    W = lanes()
    q = _rows_of("q", q, pk.ndof)
    B = q.shape[0]
    tables, per_row, _keep = _tables(pk, B, rows, W)
    vertical = pk.wi[W_PLANE] == 0
    on = np.broadcast_to(np.asarray(seat, bool) & vertical, (B,)).astype(np.float64)
    qt, st = _tile(q, W), _tile(on, W)
    anchor = np.zeros((qt.shape[0], pk.ci.shape[0], 2, W))
    _call("sanlab_start", dims=_dims(pk, 0).ctypes.data, tables=tables, per_row=per_row.ctypes.data, q=qt.ctypes.data,
          seat_rows=st.ctypes.data, anchor=anchor.ctypes.data, T=qt.shape[0])
    return _untile(qt, B), _untile(anchor, B)


def run_san(pk: Packed, weights, k1, k2, q, p, anchor, istate, out, steps: int, t0: Any = 0.0,
            rows: dict | None = None, observe: Observe | None = None, acc=None, every: int = 0,
            scalar: bool = False) -> dict:
    """``steps`` steps of B creatures under SANs on the kernel. weights [B, N, I], k1, k2 [B, N]
    (1/s), q, p [B, D], anchor [B, C, 2], istate, out [B, N]; t0 the time at the start (s), one
    for every row or one per row [B] (a continued run: the previous call's ``t``).
    rows: tables of :data:`ROW_TABLES` given per row ([B, *shape of pk's]) where rows differ
    (mixed batches: tuning, ensembles, designs); the others are ``pk``'s, shared.
    observe: what to accumulate along the way (None: nothing); acc [B, observe.size] the
    accumulators to go on from (None: started from the first state). every: record a frame every
    ``every`` steps from the first (0: none). scalar: one creature per thread in plain double, the
    form a GPU thread runs (tests compare it with the SIMD tiles, bit for bit).
    Returns the state after them: q, p, anchor, istate, out, t (s), qd [B, D] the velocity
    M(q)^-1 p (state coordinates), the deepest penetration dmax [B] (m; -inf without contacts),
    and with ``observe`` the accumulators ``acc`` [B, observe.size] (columns: :data:`ACC`, then
    duty, the words and their times); with ``every`` the frames: ``frames_q``, ``frames_qd`` [B, F, D]
    (each the state before that step and its velocity), ``frames_bits`` [B, F, S], ``frames_u`` [B, F, A]
    (the activations that step took), ``frames_istate``, ``frames_out`` [B, F, N] (the SAN's state
    before that step), F = steps // every. Raises ValueError for a per-row table of the wrong shape,
    weights that are not integers in [-2, 2], state arrays (q, p, anchor, istate, out, k1, k2, acc,
    t0) of the wrong shape, or a negative ``steps`` or ``every``."""

    W = 1 if scalar else lanes()
    B = np.shape(q)[0]
    N = np.shape(istate)[1]
    T = -(-B // W)
    rows = _check_rows(pk, B, rows)  # first: a bad table is reported before bad weights, as it always was
    if N != pk.wi[W_HIDDEN] + pk.ai.shape[0]:
        raise ValueError(f"istate: expected {pk.wi[W_HIDDEN] + pk.ai.shape[0]} nodes per row (the tables' "
                         f"{pk.wi[W_HIDDEN]} hidden and {pk.ai.shape[0]} actuator nodes), got {N}")
    w = np.asarray(weights)
    if w.shape != (B, N, pk.si.shape[0] + N) or np.any(w != np.round(w)) or np.abs(w).max(initial=0) > 2:
        raise ValueError(f"weights: expected integers in [-2, 2] of shape {(B, N, pk.si.shape[0] + N)}, got {w.shape}")
    NP = -(-N // 32) * 32
    if NP > 256:
        raise ValueError(f"the kernel's SAN takes at most 256 nodes, got {N}")
    w16 = np.zeros((T * W, w.shape[2], NP), np.int16)  # per creature, one row of nodes per input
    w16[:B, :, :N] = np.swapaxes(w, 1, 2)
    w16[B:] = w16[B - 1] if B else 0
    par = np.concatenate([_shaped("k1", k1, (B, N)), _shaped("k2", k2, (B, N))], 1)
    cst = np.concatenate([_shaped("istate", istate, (B, N)), _shaped("out", out, (B, N))], 1)
    res = _rollout(pk, KINDS["san"], N, par, cst, w16, NP, q, p, anchor, steps, t0, rows, observe, acc, every, scalar)
    res["istate"], res["out"] = np.split(res.pop("cstate"), [N], axis=1)
    if "frames_cstate" in res:
        res["frames_istate"], res["frames_out"] = np.split(res.pop("frames_cstate"), [N], axis=2)
    return res


KINDS = {name: k for k, name in enumerate(layout.KINDS)}  # the kernel's controllers (kernel.cpp)


def run_open(pk: Packed, kind: str, params, q, p, anchor, steps: int, t0: Any = 0.0, rows: dict | None = None,
             observe: Observe | None = None, acc=None, every: int = 0, scalar: bool = False) -> dict:
    """``steps`` steps of B creatures under open-loop or reflex controllers on the kernel, one
    ``kind`` per call (the controllers of ``sim.rollout``):

    - ``"hold"``: params u [B, A], activations in [0, 1] held for every step of the call
      (``sim.ConstantController``; external actions: a Gymnasium step, the studio);
    - ``"sine"``: params [B, A + 1] = (phases (rad)..., f (Hz)): u_a = 0.5 + 0.5 sin(2 pi f t +
      phase_a), t the row's time before the step (s, from ``t0``; ``sim.SineController`` from 0);
    - ``"reflex"``: params (W [B, A, S], b [B, A]): u = clip(W bits + b, 0, 1) of the step's
      sensor values (``sim.ReflexController``);
    - ``"pattern"``: params [B, 4 A + 1] = per actuator (phase, duty, low, high), then the period
      T (s): u_a = high_a while frac(t / T - phase_a) < duty_a, else low_a (a square wave;
      ``sim.PatternController``); phase and duty are fractions of the period, the levels
      activations in [0, 1], T > 0.

    q, p [B, D], anchor [B, C, 2]; t0, rows, observe, acc, every and scalar as for
    :func:`run_san`. Returns what :func:`run_san` returns but the SAN's state: q, p, anchor, t,
    dmax, qd, with ``observe`` acc, with ``every`` frames_q, frames_qd [B, F, D], frames_bits
    [B, F, S], frames_u [B, F, A]. Raises ValueError naming the argument for an unknown kind,
    parameters of the wrong shape, not finite, (hold) outside [0, 1] or (pattern) with a period <= 0 or levels outside [0, 1], state arrays of the
    wrong shape, a negative ``steps`` or ``every``, or a per-row table of the wrong shape."""
    if kind not in ("hold", "sine", "reflex", "pattern"):
        raise ValueError(f"kind: expected 'hold', 'sine', 'reflex' or 'pattern', got {kind!r}")
    B = np.shape(q)[0]
    A, S = pk.ai.shape[0], pk.si.shape[0]
    if kind == "hold":
        par = _shaped("params", params, (B, A))
        if not np.all((par >= 0.0) & (par <= 1.0)):
            raise ValueError("params: hold's activations must lie in [0, 1]")
    elif kind == "sine":
        par = _shaped("params", params, (B, A + 1))
    elif kind == "pattern":
        par = _shaped("params", params, (B, 4 * A + 1))
        levels = par[:, :4 * A].reshape(B, A, 4)[:, :, 2:]
        if not (np.all(par[:, -1] > 0) and np.all((levels >= 0.0) & (levels <= 1.0))):
            raise ValueError("params: a pattern's period must be > 0 and its levels lie in [0, 1]")
    else:
        if not isinstance(params, (tuple, list)) or len(params) != 2:
            raise ValueError("params: reflex takes (W [B, A, S], b [B, A])")
        Wr, b = _shaped("params[0] (W)", params[0], (B, A, S)), _shaped("params[1] (b)", params[1], (B, A))
        par = np.concatenate([Wr.reshape(B, A * S), b], 1)
    if not np.all(np.isfinite(par)):
        raise ValueError("params: expected finite numbers")
    res = _rollout(pk, KINDS[kind], 0, par, np.zeros((B, 0)), None, 0, q, p, anchor, steps, t0, rows, observe, acc,
                   every, scalar)
    res.pop("cstate")
    res.pop("frames_cstate", None)
    return res


COUNT_MAX = 2**63 - 1  # the kernel's counts are int64: a larger one would wrap


def check_count(name: str, x) -> int:
    """x as a whole number in [0, COUNT_MAX], or a ValueError naming it."""
    n, whole = -1, False
    try:
        n = int(x)
        whole = n == x and not isinstance(x, bool)
    except (TypeError, ValueError, OverflowError):
        pass
    if not whole or not 0 <= n <= COUNT_MAX:
        raise ValueError(f"{name}: expected a whole number in [0, 2**63 - 1], got {x!r}")
    return n


def _shaped(name: str, x, shape: tuple) -> np.ndarray:
    """x as float64 of ``shape``, or a ValueError naming it."""
    a = np.asarray(x, np.float64)
    if a.shape != tuple(shape):
        raise ValueError(f"{name}: expected shape {tuple(shape)}, got {a.shape}")
    return a


def _rollout(pk: Packed, kind: int, N: int, par: np.ndarray, cst: np.ndarray, w16, NP: int, q, p, anchor, steps: int,
             t0: Any, rows: dict | None, observe: Observe | None, acc, every: int, scalar: bool) -> dict:
    """The kernel's rollout under controller ``kind`` (:data:`KINDS`) with N SAN nodes (0 for the
    others): parameters par [B, n_param] and state cst [B, n_state] per row, a SAN's weights w16
    (see :func:`run_san`). Returns q, p, anchor, t, dmax, qd, cstate [, acc] [, frames_*]."""
    W = 1 if scalar else lanes()
    B = np.shape(q)[0] if np.ndim(q) else 0
    if B < 1:
        raise ValueError(f"q: expected at least one row [B, {pk.ndof}], got shape {np.shape(q)}")
    D, C, S, A = pk.ndof, pk.ci.shape[0], pk.si.shape[0], pk.ai.shape[0]
    if observe is not None:
        observe.check(pk)
    steps, every = check_count("steps", steps), check_count("every", every)
    tables, per_row, _keep = _tables(pk, B, rows, W)
    q, p = _shaped("q", q, (B, D)), _shaped("p", p, (B, D))
    anchor = _shaped("anchor", anchor, (B, C, 2))
    if observe is not None and acc is not None:
        acc = _shaped("acc", acc, (B, observe.size))
        changes = acc[:, ACC.index("changes")]
        if not np.all(np.isfinite(acc[:, :len(ACC)])) or np.any(changes < 0) or np.any(changes != np.round(changes)):
            raise ValueError("acc: expected accumulators a rollout returned (finite, a whole count of changes >= 0)")
    dims = _dims(pk, N)
    T = -(-B // W)
    t0 = np.asarray(t0, np.float64)
    if t0.shape not in ((), (B,)):
        raise ValueError(f"t0: expected a number or shape {(B,)}, got {t0.shape}")
    st = [_tile(a, W) for a in (q, p, anchor, np.broadcast_to(t0, (B,)), np.full(B, -np.inf))]
    par_t, cst_t = _tile(par, W), _tile(cst, W)
    qd = np.zeros((T, D, W))
    oi = of = acc_t = None
    if observe is not None:
        oi, of = observe.arrays()
        acc_t = _tile(np.zeros((B, observe.size)) if acc is None else acc, W)
    addr = lambda a: None if a is None else a.ctypes.data
    n_frames = int(steps) // every if every > 0 else 0  # as sim.rollout: whole frames only
    ns = cst.shape[1]
    frames = np.zeros((T, n_frames, 2 * D + S + A + ns, W)) if every > 0 else None
    _call("sanlab_rollout", kind=kind, scalar=int(scalar), dims=dims.ctypes.data, tables=tables,
          per_row=per_row.ctypes.data, state=_pointers(st), par=par_t.ctypes.data, cst=cst_t.ctypes.data,
          weights=addr(w16), NP=NP, oi=addr(oi), of=addr(of), init=int(acc is None), acc=addr(acc_t),
          qd=qd.ctypes.data, frames=addr(frames), every=int(every), n_frames=n_frames, T=T, steps=int(steps))
    res = {n: _untile(a, B) for n, a in zip(("q", "p", "anchor", "t", "dmax"), st)}
    res["cstate"] = _untile(cst_t, B)
    res["qd"] = _untile(qd, B)
    if acc_t is not None:
        res["acc"] = _untile(acc_t, B)
    if frames is not None:
        fr = _untile(frames, B)  # [B, F, values]
        for name, part in zip(("q", "qd", "bits", "u", "cstate"), np.split(fr, np.cumsum([D, D, S, A]), axis=2)):
            res["frames_" + name] = part
    return res


# ------------------------------------------------------------------ inspectors: single configurations


INSPECT = layout.INSPECT  # the inspectors, in kernel.cpp's order


def _inspect(pk: Packed, kind: str, x: np.ndarray, n_out: int, rows: dict | None, scalar: bool) -> np.ndarray:
    """The kernel's inspector ``kind`` over rows x [B, n_in] -> [B, n_out]."""
    W = 1 if scalar else lanes()
    B = x.shape[0]
    tables, per_row, _keep = _tables(pk, B, rows, W)
    xt = _tile(x, W)
    out = np.zeros((xt.shape[0], n_out, W))
    _call("sanlab_inspect", kind=INSPECT.index(kind), scalar=int(scalar), dims=_dims(pk, 0).ctypes.data, tables=tables,
          per_row=per_row.ctypes.data, **{"in": xt.ctypes.data}, out=out.ctypes.data, T=xt.shape[0])
    return _untile(out, B)


def _rows_of(name: str, x, width: int) -> np.ndarray:
    """x as float64 [B, width], or a ValueError naming it."""
    a = np.asarray(x, np.float64)
    if a.ndim != 2 or a.shape[1] != width or a.shape[0] < 1:
        raise ValueError(f"{name}: expected shape (B, {width}) with B >= 1, got {a.shape}")
    return a


def _times(t, B: int) -> np.ndarray:
    """t (s) as [B, 1]: one number for every row or one per row, or a ValueError naming it."""
    a = np.asarray(t, np.float64)
    if a.shape not in ((), (B,)):
        raise ValueError(f"t: expected a number or shape {(B,)}, got {a.shape}")
    return np.broadcast_to(a, (B,))[:, None]


def poses(pk: Packed, q, rows: dict | None = None, scalar: bool = False) -> dict:
    """World placement of configurations q [B, D] (for drawing and analysis):
    ``links`` [B, L, 3] (origin x, y (m) and absolute angle (rad) of each link frame),
    ``contacts`` [B, C, 2] (contact points, m), ``depth`` [B, C] (penetration, m, > 0 when
    touching; horizontal plane: 1), ``com`` [B, 2] (the centre of mass of the links not welded to
    the world, m). rows: per-row tables as for :func:`run_san`; scalar: the GPU's form (plain
    double, one row per thread). Raises ValueError for q or a per-row table of the wrong shape."""
    q = _rows_of("q", q, pk.ndof)
    B, L, C = q.shape[0], pk.li.shape[0], pk.ci.shape[0]
    out = _inspect(pk, "poses", q, 3 * L + 3 * C + 2, rows, scalar)
    links, contacts, depth, com = np.split(out, np.cumsum([3 * L, 2 * C, C]), axis=1)
    return {"links": links.reshape(B, L, 3), "contacts": contacts.reshape(B, C, 2), "depth": depth, "com": com}


def energy(pk: Packed, q, p, rows: dict | None = None, scalar: bool = False) -> dict:
    """Mechanical energy of states (q, p) [B, D] (J): ``kinetic`` [B] (of the
    velocity M(q)^-1 p), ``gravity`` [B] (m g y of each centre of mass; 0 in the horizontal
    plane) and ``elastic`` [B] (passive joint and linear springs; actuators, joint stops and the
    ground excluded). Links welded to the world do not count. rows, scalar as for :func:`poses`.
    Raises ValueError for q, p or a per-row table of the wrong shape."""
    D = pk.ndof
    q = _rows_of("q", q, D)
    p = _shaped("p", p, q.shape)
    out = _inspect(pk, "energy", np.concatenate([q, p], 1), 3, rows, scalar)
    return {"kinetic": out[:, 0], "gravity": out[:, 1], "elastic": out[:, 2]}


def momenta(pk: Packed, q, qd, rows: dict | None = None, scalar: bool = False) -> np.ndarray:
    """The momenta p = M(q) qd [B, D] of configurations q [B, D] moving at velocities qd [B, D]
    (state coordinates; what ``sim.make_state`` carries). rows, scalar as for :func:`poses`.
    Raises ValueError for q, qd or a per-row table of the wrong shape."""
    D = pk.ndof
    q = _rows_of("q", q, D)
    qd = _shaped("qd", qd, q.shape)
    return _inspect(pk, "momenta", np.concatenate([q, qd], 1), D, rows, scalar)


def velocity(pk: Packed, q, p, rows: dict | None = None, scalar: bool = False) -> np.ndarray:
    """The velocities qd = M(q)^-1 p [B, D] of states (q, p) [B, D] (what a
    rollout returns as ``qd``). rows, scalar as for :func:`poses`. Raises ValueError for q, p or
    a per-row table of the wrong shape."""
    D = pk.ndof
    q = _rows_of("q", q, D)
    p = _shaped("p", p, q.shape)
    return _inspect(pk, "velocity", np.concatenate([q, p], 1), D, rows, scalar)


def sense(pk: Packed, q, t, rows: dict | None = None, scalar: bool = False) -> np.ndarray:
    """Binary sensor values bits [B, S] (0.0 / 1.0) of configurations q
    [B, D] at time t (s: one number or [B]; the eyes see the follow point of that time). rows,
    scalar as for :func:`poses`. Raises ValueError for q, t or a per-row table of the wrong
    shape."""
    q = _rows_of("q", q, pk.ndof)
    return _inspect(pk, "sense", np.concatenate([q, _times(t, q.shape[0])], 1), pk.si.shape[0], rows, scalar)


def follow_point(pk: Packed, t, rows: dict | None = None, scalar: bool = False) -> np.ndarray:
    """The follow point [B, 2] (m) at times t [B] (s). rows, scalar as
    for :func:`poses` (a row's own ``wf`` carries its own speed). Raises ValueError for t not 1-D
    or a per-row table of the wrong shape."""
    t = np.asarray(t, np.float64)
    if t.ndim != 1:
        raise ValueError(f"t: expected shape (B,), got {t.shape}")
    return _inspect(pk, "follow_point", t[:, None], 2, rows, scalar)


def centre_of_mass(pk: Packed, q, p, rows: dict | None = None, scalar: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The centre of mass [B, 2] (m) of states (q, p) [B, D] and its velocity [B, 2] (m/s; the
    links welded to the world do not count). rows, scalar as for
    :func:`poses`. Raises ValueError for q, p or a per-row table of the wrong shape."""
    D = pk.ndof
    q = _rows_of("q", q, D)
    p = _shaped("p", p, q.shape)
    out = _inspect(pk, "centre_of_mass", np.concatenate([q, p], 1), 4, rows, scalar)
    return out[:, :2], out[:, 2:]
