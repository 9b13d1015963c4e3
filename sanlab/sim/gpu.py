"""The simulator's kernel on an NVIDIA GPU: the scalar forms of the same C++ template the CPU runs
(``sanlab/sim/_kernel``, ``Lanes<double>`` or ``Lanes<float>``: one creature per thread, in the
arithmetic of the model's dtype as on the CPU), compiled at run time by
NVRTC from NVIDIA's pip wheel (``pip install 'sanlab[gpu]'``: ``nvidia-cuda-nvrtc-cu12``; no
CUDA toolkit), cached on disk, and launched through the CUDA driver API (``libcuda``, which comes
with the GPU's driver) by ctypes.

Why ctypes and not ``cuda-python``/``cuda.core``: NVRTC's C API needs six functions and the
driver's a dozen; ctypes reaches both with nothing to install beyond the NVRTC wheel, where
``cuda-bindings`` would add a compiled package whose major version must match the driver's.

What is built (docs/gpu.md): ``gpu.cu``'s entry points (one per controller kind and arithmetic,
kernel.cpp's ``sanlab_rollout`` with W = 1: ``sanlab_gpu_san`` in float64, ``sanlab_gpu_san_f32``
in float32, ...), compiled with :data:`OPTIONS`: ``-default-device`` (every function a device
function), ``--fmad=false`` (no fused multiply-adds: every multiply and add rounded apart, as the
CPU's ``-ffp-contract=off``), IEEE division and square root without flushing denormals, and
``-std=c++17``. Each thread's scratch is lane-innermost in blocks of a warp (:data:`WARP`). Without
a GPU, :func:`compile_ptx`, :func:`report` and :func:`resources` still work (CI checks them);
:func:`device` says in one line why there is none.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from sanlab.sim import layout
from sanlab.sim.native import _dims, _tables
from sanlab.sim.tables import ROW_TABLES, TABLES, Packed

KERNEL = Path(__file__).parent / "_kernel"
DTYPES = ("float64", "float32")  # the arithmetics, as the CPU's (a model's dtype)
# gpu.cu's entry points, by (controller kind, dtype)
ENTRIES = {(kind, dtype): f"sanlab_gpu_{kind}{'_f32' if dtype == 'float32' else ''}"
           for dtype in DTYPES for kind in layout.KINDS}
# IEEE division and square root, denormals kept: NVRTC's defaults, stated because float32's bits
# rest on them (CUDA's fast float division, sqrt and flush to zero would part from the CPU's)
OPTIONS = ("-default-device", "--fmad=false", "--prec-div=true", "--prec-sqrt=true", "--ftz=false", "-std=c++17")
# NVRTC has no C++ standard library: the two headers the kernel's tables include (layout.h,
# tables.h), as the few typedefs they need (LP64, as the CPU build)
HEADERS = {
    "cstdint": "#pragma once\ntypedef signed char int8_t;\ntypedef short int16_t;\ntypedef int int32_t;\n"
               "typedef long int64_t;\ntypedef unsigned int uint32_t;\ntypedef unsigned long uint64_t;\n",
    "cstddef": "#pragma once\ntypedef unsigned long size_t;\n",
}
ARCH = "sm_90"  # H100, H200: the devices this is written for
# the scratch's layout (gpu.cu, tables.h: Strided): lane-innermost in blocks of a warp, value k of
# thread b at (b // WARP) * WARP * per_thread + k * WARP + b % WARP; NVRTC is given it as SANLAB_WARP
WARP = 32


class GpuUnavailable(RuntimeError):
    """No NVRTC (the ``gpu`` extra is not installed) or no GPU with a driver: its message is one line."""


# ------------------------------------------------------------------ NVRTC: the kernel's source to PTX or CUBIN


def _nvrtc_path() -> Path:
    """libnvrtc.so.12 from the ``nvidia-cuda-nvrtc-cu12`` wheel; GpuUnavailable if not installed."""
    try:
        import nvidia.cuda_nvrtc as wheel  # type: ignore[import-not-found]
    except ImportError:
        raise GpuUnavailable("NVRTC is not installed: pip install 'sanlab[gpu]' (nvidia-cuda-nvrtc-cu12)") from None
    for root in wheel.__path__:
        for p in sorted((Path(root) / "lib").glob("libnvrtc.so.*")):
            return p
    raise GpuUnavailable(f"NVRTC's wheel holds no libnvrtc.so.* in {list(wheel.__path__)}")


_NVRTC: Any = None


def _nvrtc():
    global _NVRTC
    if _NVRTC is None:
        lib = ctypes.CDLL(str(_nvrtc_path()))
        lib.nvrtcGetErrorString.restype = ctypes.c_char_p
        _NVRTC = lib
    return _NVRTC


def nvrtc_version() -> tuple[int, int]:
    """NVRTC's (major, minor). Raises GpuUnavailable without the wheel."""
    major, minor = ctypes.c_int(), ctypes.c_int()
    _nvrtc().nvrtcVersion(ctypes.byref(major), ctypes.byref(minor))
    return major.value, minor.value


def source() -> str:
    """The GPU translation unit: gpu.cu, which includes the kernel's headers (passed by -I)."""
    return (KERNEL / "gpu.cu").read_text()


def source_hash() -> str:
    """The hash of every kernel source (as setup.py's), the NVRTC version, the options and the
    headers given to NVRTC: the cache's key (with the arch and the kinds built)."""
    h = hashlib.sha256()
    for f in sorted(KERNEL.glob("*.[hc]*")):
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    h.update(repr((nvrtc_version(), OPTIONS, HEADERS, WARP)).encode())
    return h.hexdigest()[:16]


class CompileError(RuntimeError):
    """NVRTC refused the kernel: the message holds its log (every line it rejected)."""


def _kinds(kinds) -> tuple[str, ...]:
    kinds = tuple(layout.KINDS) if kinds is None else tuple(kinds)
    bad = [k for k in kinds if k not in layout.KINDS]
    if bad or not kinds:
        raise ValueError(f"kinds: expected some of {list(layout.KINDS)}, got {list(kinds)}")
    return tuple(k for k in layout.KINDS if k in kinds)


def _dtype(dtype) -> str:
    if dtype not in DTYPES:
        raise ValueError(f"dtype: expected one of {list(DTYPES)}, got {dtype!r}")
    return dtype


def _compile(arch: str, extra: tuple[str, ...] = (), kinds=None, dtype: str = "float64") -> tuple[bytes, str, str]:
    """NVRTC on gpu.cu for ``arch`` ("sm_90": a CUBIN; "compute_90": PTX) with the entry points of
    ``kinds`` (controller kinds, layout.KINDS; None: all) in ``dtype``'s arithmetic: (the binary,
    the log, the PTX). Raises CompileError with NVRTC's log where it fails."""
    lib = _nvrtc()
    prog = ctypes.c_void_p()
    src = source().encode()

    def check(rc: int, what: str) -> None:
        if rc:
            raise CompileError(f"NVRTC {what}: {lib.nvrtcGetErrorString(rc).decode()}")

    names = (ctypes.c_char_p * len(HEADERS))(*[n.encode() for n in HEADERS])
    texts = (ctypes.c_char_p * len(HEADERS))(*[t.encode() for t in HEADERS.values()])
    check(lib.nvrtcCreateProgram(ctypes.byref(prog), src, b"gpu.cu", len(HEADERS), texts, names), "nvrtcCreateProgram")
    try:
        opts = [*OPTIONS, f"-arch={arch}", f"-I{KERNEL}", *(f"-DSANLAB_GPU_{k.upper()}" for k in _kinds(kinds)),
                f"-DSANLAB_GPU_F{'32' if _dtype(dtype) == 'float32' else '64'}", f"-DSANLAB_WARP={WARP}", *extra]
        argv = (ctypes.c_char_p * len(opts))(*[o.encode() for o in opts])
        rc = lib.nvrtcCompileProgram(prog, len(opts), argv)
        n = ctypes.c_size_t()
        lib.nvrtcGetProgramLogSize(prog, ctypes.byref(n))
        log = ctypes.create_string_buffer(n.value)
        lib.nvrtcGetProgramLog(prog, log)
        text = log.value.decode(errors="replace")
        if rc:
            raise CompileError(f"NVRTC could not compile sanlab/sim/_kernel/gpu.cu for {arch}:\n{text}")

        def get(size, data, what: str) -> bytes:
            check(size(prog, ctypes.byref(n)), what)
            out = ctypes.create_string_buffer(n.value)
            check(data(prog, out), what)
            return out.raw

        ptx = get(lib.nvrtcGetPTXSize, lib.nvrtcGetPTX, "PTX")  # kept for a real arch too
        binary = get(lib.nvrtcGetCUBINSize, lib.nvrtcGetCUBIN, "CUBIN") if arch.startswith("sm_") else ptx
        return binary, text, ptx.rstrip(b"\0").decode(errors="replace")
    finally:
        lib.nvrtcDestroyProgram(ctypes.byref(prog))


def cache_dir() -> Path:
    """Where built kernels are kept: $SANLAB_CACHE or $XDG_CACHE_HOME/sanlab (~/.cache/sanlab), /gpu."""
    base = os.environ.get("SANLAB_CACHE") or os.path.join(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache",
                                                          "sanlab")
    return Path(base) / "gpu"


def build(arch: str = ARCH, kinds=None, dtype: str = "float64") -> bytes:
    """The kernel built for ``arch`` ("sm_90": a CUBIN the driver loads as it is; "compute_90":
    PTX the driver compiles on load) with the entry points of ``kinds`` (None: every controller
    kind) in ``dtype``'s arithmetic ("float64" or "float32"), from the disk cache when these
    sources, this NVRTC and these options built it before. Raises GpuUnavailable without NVRTC,
    CompileError where it fails, ValueError for an unknown kind or dtype."""
    ks = _kinds(kinds)
    tag = ("all" if len(ks) == len(layout.KINDS) else "+".join(ks)) + ("-f32" if _dtype(dtype) == "float32" else "")
    path = cache_dir() / f"{source_hash()}-{arch}-{tag}.{'cubin' if arch.startswith('sm_') else 'ptx'}"
    if path.exists():
        return path.read_bytes()
    binary, _, _ = _compile(arch, kinds=ks, dtype=dtype)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_bytes(binary)
    tmp.replace(path)  # whole or not at all: another process may be building the same
    return binary


def compile_ptx(arch: str = "compute_90", kinds=None, dtype: str = "float64") -> str:
    """The kernel's PTX for a virtual ``arch`` (text), cached as :func:`build`."""
    return build(arch, kinds, dtype).rstrip(b"\0").decode()


def resources(arch: str = ARCH, dtype: str = "float64") -> dict[str, dict[str, int]]:
    """What ptxas reports for each entry point of the kernel built for ``arch`` in ``dtype``'s
    arithmetic (NVRTC runs ptxas itself for a real arch; ``-Xptxas -v`` puts its report in the
    log): per entry (a controller kind, layout.KINDS), ``registers``, ``spill_stores`` and
    ``spill_loads`` (bytes), ``stack`` (bytes of stack frame). Not cached: it is the check CI
    runs (about 40 s for the five entries of one dtype)."""
    return report(arch, dtype)[0]


def report(arch: str = ARCH, dtype: str = "float64") -> tuple[dict[str, dict[str, int]], str]:
    """:func:`resources`, and the PTX that ptxas compiled, from one NVRTC run (CI checks both)."""
    _, log, ptx = _compile(arch, ("-Xptxas", "-v"), dtype=dtype)
    names = {e: k for (k, d), e in ENTRIES.items() if d == dtype}
    out: dict[str, dict[str, int]] = {}
    entry = None
    for line in log.splitlines():
        m = re.search(r"Compiling entry function '(\w+)'", line)
        if m:
            entry = names.get(m.group(1), m.group(1))
            out[entry] = {}
            continue
        if entry is None:
            continue
        m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
        if m:
            out[entry].update(stack=int(m.group(1)), spill_stores=int(m.group(2)), spill_loads=int(m.group(3)))
        m = re.search(r"Used (\d+) registers", line)
        if m:
            out[entry]["registers"] = int(m.group(1))
    if set(out) != set(layout.KINDS) or any(len(v) != 4 for v in out.values()):
        raise CompileError(f"ptxas's report did not name every entry point with its registers and spills:\n{log}")
    return out, ptx


# ------------------------------------------------------------------ the driver: a device, a launch


_CUDA: Any = None


def _driver():
    """libcuda (the GPU driver's), initialised; GpuUnavailable in one line where there is none."""
    global _CUDA
    if _CUDA is None:
        try:
            lib = ctypes.CDLL("libcuda.so.1")
        except OSError:
            raise GpuUnavailable("no GPU: the CUDA driver (libcuda.so.1) is not installed on this machine") from None
        _signatures(lib)
        rc = lib.cuInit(0)
        count = ctypes.c_int()
        if rc or lib.cuDeviceGetCount(ctypes.byref(count)) or count.value < 1:
            raise GpuUnavailable(f"no GPU: the CUDA driver found no device (cuInit returned {rc})")
        _CUDA = lib
    return _CUDA


def _signatures(lib) -> None:
    """The driver functions' C signatures (ctypes would pass a bare int as a 32-bit one: a size over
    2 GiB would not fit)."""
    P, I, U, S = ctypes.c_void_p, ctypes.c_int, ctypes.c_uint, ctypes.c_size_t
    D = ctypes.c_uint64  # CUdeviceptr
    for name, args in {
        "cuInit": [U], "cuDeviceGetCount": [P], "cuDeviceGet": [P, I], "cuDeviceGetName": [P, I, I],
        "cuDeviceGetAttribute": [P, I, I], "cuDevicePrimaryCtxRetain": [P, I], "cuCtxSetCurrent": [P],
        "cuModuleLoadData": [P, ctypes.c_char_p], "cuModuleGetFunction": [P, P, ctypes.c_char_p],
        "cuMemAlloc_v2": [P, S], "cuMemFree_v2": [D], "cuMemcpyHtoD_v2": [D, P, S], "cuMemcpyDtoH_v2": [P, D, S],
        "cuLaunchKernel": [P, U, U, U, U, U, U, U, P, P, P], "cuCtxSynchronize": [], "cuGetErrorString": [I, P],
    }.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = I, args


def device() -> str:
    """The first GPU's name, or GpuUnavailable saying in one line why there is none."""
    lib = _driver()
    dev = ctypes.c_int()
    _check(lib.cuDeviceGet(ctypes.byref(dev), 0), "cuDeviceGet")
    name = ctypes.create_string_buffer(256)
    _check(lib.cuDeviceGetName(name, 256, dev), "cuDeviceGetName")
    return name.value.decode()


def _check(rc: int, what: str) -> None:
    if rc:
        msg = ctypes.c_char_p()
        if _CUDA is not None:
            _CUDA.cuGetErrorString(rc, ctypes.byref(msg))
        raise RuntimeError(f"CUDA {what} failed: {rc} {(msg.value or b'').decode()}")


class _Session:
    """A context on device 0 and the kernel's module loaded in it (once per process)."""

    def __init__(self) -> None:
        lib = _driver()
        dev = ctypes.c_int()
        _check(lib.cuDeviceGet(ctypes.byref(dev), 0), "cuDeviceGet")
        major, minor = ctypes.c_int(), ctypes.c_int()
        _check(lib.cuDeviceGetAttribute(ctypes.byref(major), 75, dev), "compute capability")  # MAJOR
        _check(lib.cuDeviceGetAttribute(ctypes.byref(minor), 76, dev), "compute capability")  # MINOR
        self.arch = f"sm_{major.value}{minor.value}"
        self.ctx = ctypes.c_void_p()
        _check(lib.cuDevicePrimaryCtxRetain(ctypes.byref(self.ctx), dev), "cuDevicePrimaryCtxRetain")
        _check(lib.cuCtxSetCurrent(self.ctx), "cuCtxSetCurrent")
        self.functions: dict[str, ctypes.c_void_p] = {}
        self.modules: list[ctypes.c_void_p] = []
        self.lib = lib

    def function(self, name: str) -> ctypes.c_void_p:
        """The entry point ``name`` (one of :data:`ENTRIES`), built (one module per controller kind
        and dtype: a first call waits for its own entry's build alone) and loaded on first use. The
        image is a CUBIN for this device's arch: the driver JITs nothing, and any driver of NVRTC's
        major version or later loads it."""
        if name not in self.functions:
            kind, dtype = next(k for k, e in ENTRIES.items() if e == name)
            module = ctypes.c_void_p()
            _check(self.lib.cuModuleLoadData(ctypes.byref(module), build(self.arch, (kind,), dtype)),
                   "cuModuleLoadData")
            self.modules.append(module)
            f = ctypes.c_void_p()
            _check(self.lib.cuModuleGetFunction(ctypes.byref(f), module, name.encode()), "cuModuleGetFunction")
            self.functions[name] = f
        return self.functions[name]

    def alloc(self, nbytes: int) -> ctypes.c_uint64:
        p = ctypes.c_uint64()
        _check(self.lib.cuMemAlloc_v2(ctypes.byref(p), max(int(nbytes), 8)), f"cuMemAlloc of {int(nbytes)} bytes")
        return p

    def put(self, a: np.ndarray) -> ctypes.c_uint64:
        a = np.ascontiguousarray(a)
        p = self.alloc(a.nbytes)
        _check(self.lib.cuMemcpyHtoD_v2(p, a.ctypes.data, a.nbytes), "cuMemcpyHtoD")
        return p

    def get(self, p: ctypes.c_uint64, a: np.ndarray) -> None:
        _check(self.lib.cuMemcpyDtoH_v2(a.ctypes.data, p, a.nbytes), "cuMemcpyDtoH")

    def free(self, p: ctypes.c_uint64) -> None:
        self.lib.cuMemFree_v2(p)

    def launch(self, name: str, args: list, blocks: int, threads: int) -> None:
        """gpu.cu's entry point ``name`` (:data:`ENTRIES`) over blocks x threads threads, waited for."""
        argv = (ctypes.c_void_p * len(args))(*[ctypes.cast(ctypes.byref(a), ctypes.c_void_p) for a in args])
        _check(self.lib.cuLaunchKernel(self.function(name), blocks, 1, 1, threads, 1, 1, 0, None, argv, None),
               "cuLaunchKernel")
        _check(self.lib.cuCtxSynchronize(), "the rollout")


_SESSION: _Session | None = None


def _session() -> _Session:
    global _SESSION
    if _SESSION is None:
        _SESSION = _Session()
    return _SESSION


def derived(pk: Packed) -> np.ndarray:
    """The tables kernel.cpp's Tables derives on the CPU, for the GPU: dense_idx [D] (0 .. D - 1),
    kid_start [L + 1] and kids (each link's children in link order; one 0 past them), int32."""
    parents = pk.li[:, layout.TABLE["li"].at("parent")]
    L = pk.li.shape[0]
    kids = [j for i in range(L) for j in range(L) if parents[j] == i]
    start = np.cumsum([0] + [int(np.sum(parents == i)) for i in range(L)])
    return np.concatenate([np.arange(pk.ndof), start, kids, [0]]).astype(np.int32)


def scratch_values(dims: np.ndarray, n_param: int, n_state: int, n_acc: int) -> int:
    """Values of scratch (float64 or float32: the arithmetic's) one thread needs: its tile (tables.h: tile_layout, asked of the
    CPU build: sanlab_tile_values) and the state, parameters, controller state, accumulators and
    velocity gpu.cu copies in."""
    from sanlab.sim.native import _library

    fn = _library().sanlab_tile_values
    fn.restype, fn.argtypes = ctypes.c_int64, [ctypes.c_void_p]
    d = {name: int(dims[k]) for k, (name, _, _) in enumerate(layout.DIMS)}
    state = 2 * d["dofs"] + 2 * d["contacts"] + 2
    return int(fn(dims.ctypes.data)) + state + n_param + n_state + n_acc + d["dofs"]


def scratch_bytes(B: int, per_thread: int, dtype: Any = "float64") -> int:
    """Bytes of scratch B threads of ``per_thread`` values of ``dtype`` take: whole warps (the
    layout's blocks, :data:`WARP`)."""
    return -(-B // WARP) * WARP * per_thread * np.dtype(dtype).itemsize


def run_san(pk: Packed, weights, k1, k2, q, p, anchor, istate, out, steps: int, t0: Any = 0.0,
            rows: dict | None = None, threads: int = 128, on: Any = None) -> dict:
    """``steps`` steps of B creatures under SANs on the GPU, one creature per thread: arguments and
    result as :func:`sanlab.sim.kernel.run_san` (``rows``: per-row tables, as there) without
    observers or frames (the keys q, p, anchor, istate, out, t, dmax, qd). The arithmetic is the
    tables' ``pk.dtype``, as on the CPU: float64, or float32 (the ``_f32`` entry points; arrays in
    and out float64 either way, a float32 run's rounded on the way in and its float32 values
    returned exactly). ``threads`` per block. ``on``: where to run (None: the GPU; the tests pass a
    host emulation of the same entry points). Raises GpuUnavailable without a GPU or NVRTC,
    ValueError for tables of another dtype, arrays or per-row tables of the wrong shape (as the
    CPU's)."""
    from sanlab.sim import kernel

    kernel._lanes_of(pk, True)  # the CPU's check of the tables' dtype: float64 or float32
    dtype = str(pk.dtype)
    real = np.float32 if dtype == "float32" else np.float64
    B = np.shape(q)[0] if np.ndim(q) else 0
    if B < 1:
        raise ValueError(f"q: expected at least one row [B, {pk.ndof}], got shape {np.shape(q)}")
    N = np.shape(istate)[1] if np.ndim(istate) == 2 else -1
    D, C, S = pk.ndof, pk.ci.shape[0], pk.si.shape[0]
    H = int(pk.wi[layout.TABLE["wi"].at("hidden")])
    if N != H + pk.ai.shape[0]:
        raise ValueError(f"istate: expected {H + pk.ai.shape[0]} nodes per row (the tables' {H} hidden and "
                         f"{pk.ai.shape[0]} actuator nodes), got shape {np.shape(istate)}")
    w = np.asarray(weights)
    if w.shape != (B, N, S + N) or np.any(w != np.round(w)) or np.abs(w).max(initial=0) > 2:
        raise ValueError(f"weights: expected integers in [-2, 2] of shape {(B, N, S + N)}, got {w.shape}")
    NP = -(-N // 32) * 32
    w16 = np.zeros((B, S + N, NP), np.int16)
    w16[:, :, :N] = np.swapaxes(w, 1, 2)
    par = np.concatenate([kernel._shaped("k1", k1, (B, N)), kernel._shaped("k2", k2, (B, N))], 1)
    cst = np.concatenate([kernel._shaped("istate", istate, (B, N)), kernel._shaped("out", out, (B, N))], 1)
    t0 = np.asarray(t0, np.float64)
    if t0.shape not in ((), (B,)):
        raise ValueError(f"t0: expected a number or shape {(B,)}, got {t0.shape}")
    st = [kernel._shaped("q", q, (B, D)), kernel._shaped("p", p, (B, D)), kernel._shaped("anchor", anchor, (B, C, 2)),
          np.broadcast_to(t0, (B,)), np.full(B, -np.inf)]
    steps = kernel.check_count("steps", steps)
    s = _session() if on is None else on
    dims = _dims(pk, N)
    _, per_row, arrays = _tables(pk, B, rows, 1)
    held: list = []

    def put(a) -> ctypes.c_uint64:
        held.append(s.put(np.asarray(a)))
        return held[-1]

    try:
        table_ptrs = [put(a).value for a in arrays]
        tables = put(np.array(table_ptrs, np.uint64))
        # the numbers a step reads, in its arithmetic: float64's are the tables themselves, float32's
        # rounded once per call (as the CPU's float tiles round them as a tile starts)
        first = TABLES.index(ROW_TABLES[0])
        row_ptrs = table_ptrs[first:first + len(ROW_TABLES)] if real is np.float64 else \
            [put(np.asarray(a, np.float32)).value for a in arrays[first:first + len(ROW_TABLES)]]
        numbers = put(np.array(row_ptrs, np.uint64))
        state = [put(a) for a in st]
        cst_d, qd_d = put(cst), put(np.zeros((B, D)))
        per_thread = scratch_values(dims, par.shape[1], cst.shape[1], 0)
        scratch = s.alloc(scratch_bytes(B, per_thread, real))
        held.append(scratch)
        null = ctypes.c_uint64(0)
        i32, i64 = ctypes.c_int32, ctypes.c_int64
        args = [put(dims), tables, numbers, put(per_row), put(np.array([x.value for x in state], np.uint64)),
                put(par), cst_d, put(w16), i32(NP), null, null, i32(1), null, qd_d, null, i64(1), i64(0),
                put(derived(pk)), scratch, i64(per_thread), i64(B), i64(steps)]
        s.launch(ENTRIES["san", dtype], args, -(-B // threads), threads)
        res = {}
        for name, a, d in zip(("q", "p", "anchor", "t", "dmax"), st, state):
            res[name] = np.empty(a.shape)
            s.get(d, res[name])
        c = np.empty_like(cst)
        s.get(cst_d, c)
        res["istate"], res["out"] = np.split(c, [N], axis=1)
        res["qd"] = np.empty((B, D))
        s.get(qd_d, res["qd"])
        return res
    finally:
        for x in held:
            s.free(x)


__all__ = ["ARCH", "DTYPES", "ENTRIES", "WARP", "CompileError", "GpuUnavailable", "build", "cache_dir", "compile_ptx",
           "derived", "device", "nvrtc_version", "report", "resources", "run_san", "scratch_bytes", "scratch_values",
           "source"]
