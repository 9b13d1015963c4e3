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

Every entry point steps in the arithmetic of its tables' ``Packed.dtype`` (the model's dtype):
float64, or float32 (the same template over float lanes: 16 per tile where float64 has 8; its
scalar form plain float). Arrays in and out are float64 either way; a float32 run reads them
rounded to float32 and returns its float32 values exactly.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sanlab.sim import layout
from sanlab.sim.native import ENTRY_POINTS, _call, _dims, _pointers, _tables, _tile, _untile, is_f32, lanes, source_hash
from sanlab.sim.observe import ACC, EVENTS, METRIC_KINDS, Observe
from sanlab.sim.tables import (
    F_MASS,
    F_MU,
    L_PARENT,
    ROW_TABLES,
    SENSORS,
    TABLES,
    TERRAINS,
    W_ARTICULATED,
    W_DT,
    W_HIDDEN,
    W_PLANE,
    Packed,
    _check_rows,
    check,
    numbers,
    pack,
)

__all__ = [  # the kernel's calls, and what they take from the modules it is split into
    "ACC", "ENTRY_POINTS", "EVENTS", "F_MASS", "F_MU", "INSPECT", "KINDS", "L_PARENT", "METRIC_KINDS", "ROW_TABLES",
    "SENSORS", "TABLES", "TERRAINS", "W_ARTICULATED", "W_DT", "Observe", "Packed", "centre_of_mass", "check",
    "check_count", "energy", "follow_point", "lanes", "momenta", "numbers", "pack", "poses", "run_open", "run_san",
    "sense", "source_hash", "start", "velocity",
]


def start(pk: Packed, q, seat: Any = True, rows: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Start states at rest for coordinates q [B, D]: (q [B, D] with every free tree lifted just
    clear of the ground where ``seat`` ([B] or one bool; vertical plane), the friction anchors
    [B, C, 2] at the contact points). The momenta of a state at rest are zero."""
    W = _lanes_of(pk, False)
    q = _rows_of("q", q, pk.ndof)
    B = q.shape[0]
    tables, per_row, _keep = _tables(pk, B, rows, W)
    vertical = pk.wi[W_PLANE] == 0
    on = np.broadcast_to(np.asarray(seat, bool) & vertical, (B,)).astype(np.float64)
    qt, st = _tile(q, W), _tile(on, W)
    anchor = np.zeros((qt.shape[0], pk.ci.shape[0], 2, W))
    _call("sanlab_start", f32=is_f32(pk.dtype), dims=_dims(pk, 0).ctypes.data, tables=tables, per_row=per_row.ctypes.data, q=qt.ctypes.data,
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

    W = _lanes_of(pk, scalar)
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


def _lanes_of(pk: Packed, scalar: bool) -> int:
    """Rows per tile for ``pk``'s arithmetic (1: the scalar form), or a ValueError naming the
    tables' dtype when the kernel has no arithmetic for it."""
    if getattr(pk, "dtype", None) not in ("float64", "float32"):
        raise ValueError(f"tables.dtype: expected float64 or float32, got {getattr(pk, 'dtype', None)!r}")
    return 1 if scalar else lanes(pk.dtype)


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
    W = _lanes_of(pk, scalar)
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
    _call("sanlab_rollout", kind=kind, scalar=int(scalar), f32=is_f32(pk.dtype), dims=dims.ctypes.data, tables=tables,
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
    W = _lanes_of(pk, scalar)
    B = x.shape[0]
    tables, per_row, _keep = _tables(pk, B, rows, W)
    xt = _tile(x, W)
    out = np.zeros((xt.shape[0], n_out, W))
    _call("sanlab_inspect", kind=INSPECT.index(kind), scalar=int(scalar), f32=is_f32(pk.dtype), dims=_dims(pk, 0).ctypes.data, tables=tables,
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
