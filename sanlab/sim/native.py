"""The compiled kernel as a library: loading it (built by the package's install, setup.py), its
entry points called by argument name (:mod:`sanlab.sim.layout` declares them), and the tiles of
SIMD lanes a batch is laid out in. Part of the kernel's calls (:mod:`sanlab.sim.kernel`), private
to ``sanlab.sim``."""

from __future__ import annotations

import math
from collections import OrderedDict
from typing import Any

import numpy as np

from sanlab.sim import layout
from sanlab.sim.tables import ROW_TABLES, TABLES, Packed, _check_rows, _checked


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
        _LIB = use(lib)
    return _LIB


def use(lib):
    """``lib`` (a ``ctypes.CDLL`` of a kernel build) with its entry points' signatures, as the
    library every call goes to from now on (the tests load a sanitizer's build this way)."""
    import ctypes

    global _LIB
    for name, args in ENTRY_POINTS.items():
        fn = getattr(lib, name)
        fn.restype = None
        fn.argtypes = [_CTYPES.get(c, ctypes.c_void_p) for _, c in args]
    lib.sanlab_kernel_lanes.restype = ctypes.c_int
    lib.sanlab_kernel_lanes.argtypes = [ctypes.c_int32]
    _LIB = lib
    return lib


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


def lanes(dtype: Any = "float64") -> int:
    """Creatures per tile in ``dtype``'s arithmetic ("float64" or "float32"): the SIMD width the
    kernel was built for, in that type (8 float64 or 16 float32 lanes in the same 64 bytes).
    Raises ValueError for another dtype."""
    return int(_library().sanlab_kernel_lanes(is_f32(dtype)))


def is_f32(dtype: Any) -> int:
    """1 for float32 arithmetic, 0 for float64; ValueError naming ``dtype`` for anything else."""
    try:
        name = np.dtype(dtype).name
    except TypeError:
        name = None
    if name not in ("float32", "float64"):
        raise ValueError(f"dtype: expected float32 or float64, got {dtype!r}")
    return int(name == "float32")


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


_SHARED: OrderedDict = OrderedDict()  # id(pk) -> (pk, _tables' answer) for the last creatures called


def _pointers(arrays: list):
    import ctypes

    return (ctypes.c_void_p * len(arrays))(*[a.__array_interface__["data"][0] for a in arrays])
