"""The GPU build of the kernel (sanlab/sim/gpu.py, sanlab/sim/_kernel/gpu.cu), checked without a GPU:

- gpu.cu's entry points, compiled for the host by the system's C++ compiler with __CUDACC_RTC__
  defined (the headers' GPU side: no vector types, the scalar SAN, CUDA's spelling of the maths)
  and run thread by thread through gpu.run_san's own argument packing, step every built-in
  creature bit for bit as the CPU's scalar form and its SIMD tiles do, in float64 and in float32;
- NVRTC (the ``gpu`` extra) compiles gpu.cu to sm_90, and ptxas (run by NVRTC, ``-Xptxas -v``)
  reports no spills and registers within the budget below (the float32 entries:
  tests/sim/test_float32.py);
- without a GPU, asking for one fails in one line that says why.
What needs a device (the CUDA maths' bits, the rate) is benchmarks/gpu.py's.
"""

from __future__ import annotations

import ctypes
import importlib.util
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.random_sans import random_san_params
from sanlab.sim import gpu, kernel, layout
from sanlab.sim.native import _dims

BUILTIN = sorted(p.stem for p in (Path(creature.__file__).parent / "builtin").glob("*.toml"))
HAVE_NVRTC = importlib.util.find_spec("nvidia") is not None and importlib.util.find_spec("nvidia.cuda_nvrtc") is not None
needs_nvrtc = pytest.mark.skipif(not HAVE_NVRTC, reason="NVRTC is not installed (pip install 'sanlab[gpu]': "
                                                         "nvidia-cuda-nvrtc-cu12)")
# ptxas's registers per thread for each entry point: the whole rollout inlined into one function
# (SANLAB_INLINE) takes nearly all 255 a thread may have (measured 240-248 in float64, 230-240 in
# float32 with NVRTC 12.9 for sm_90) without spilling; the budget holds it there, so a change that
# spills, or needs a bigger stack (a stage called rather than inlined: its tile on the stack,
# about 800 bytes), fails here
REGISTERS = 255
STACK = 256  # bytes: the small local arrays of gpu_rollout and the stages (measured 64 and 32)

SHIM = """
#include <cmath>
struct sanlab_dim3 { unsigned x, y, z; };
static sanlab_dim3 blockIdx, threadIdx, blockDim;
#define __global__
#define __forceinline__ inline __attribute__((always_inline))
extern "C" void sanlab_host_thread(unsigned block, unsigned thread, unsigned threads) {
  blockIdx.x = block; threadIdx.x = thread; blockDim.x = threads;
}
"""


GUARD = 8  # float64s past each block, which no thread may write (a layout that overran its block)


class HostEmulation:
    """gpu.run_san's `on`: device memory as host memory, a launch as its threads one by one."""

    def __init__(self, lib: ctypes.CDLL) -> None:
        self.lib, self.blocks, self.launched = lib, {}, []

    def _block(self, nbytes: int) -> ctypes.c_uint64:
        n = -(-max(int(nbytes), 8) // 8)
        a = np.zeros(n + GUARD)
        a[n:] = 1234.5
        p = ctypes.c_uint64(a.ctypes.data)
        self.blocks[p.value] = (a, n)
        return p

    def alloc(self, nbytes: int) -> ctypes.c_uint64:  # gpu.run_san's scratch
        return self._block(nbytes)

    def put(self, a: np.ndarray) -> ctypes.c_uint64:
        a = np.ascontiguousarray(a)
        p = self._block(a.nbytes)
        ctypes.memmove(p.value, a.ctypes.data, a.nbytes)
        return p

    def get(self, p: ctypes.c_uint64, a: np.ndarray) -> None:
        ctypes.memmove(a.ctypes.data, p.value, a.nbytes)

    def free(self, p: ctypes.c_uint64) -> None:
        a, n = self.blocks.pop(p.value)
        assert np.all(a[n:] == 1234.5), "a thread wrote past the end of a block"

    def launch(self, name: str, args: list, blocks: int, threads: int) -> None:
        fn = getattr(self.lib, name)
        fn.restype, fn.argtypes = None, [type(a) for a in args]
        self.launched.append(name)
        for b in range(blocks):
            for t in range(threads):
                self.lib.sanlab_host_thread(b, t, threads)
                fn(*args)


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> HostEmulation:
    cxx = shutil.which("g++") or shutil.which("c++")
    if cxx is None:
        pytest.skip("no C++ compiler to build gpu.cu for the host")
    d = tmp_path_factory.mktemp("gpu_host")
    (d / "shim.h").write_text(SHIM)
    lib = d / "gpu_host.so"
    # the CPU build's flags (setup.py), and its pragma's no-SLP (kernel.cpp) on the command line
    subprocess.run([cxx, "-std=c++17", "-O2", "-march=native", "-ffp-contract=off", "-fno-math-errno",
                    "-fno-tree-slp-vectorize", "-D__CUDACC_RTC__", *(f"-DSANLAB_GPU_{k.upper()}" for k in layout.KINDS),
                    "-DSANLAB_GPU_F64", "-DSANLAB_GPU_F32", f"-DSANLAB_WARP={gpu.WARP}",
                    "-include", str(d / "shim.h"), "-I", str(gpu.KERNEL),
                    "-x", "c++", str(gpu.KERNEL / "gpu.cu"), "-shared", "-fPIC", "-o", str(lib)], check=True)
    return HostEmulation(ctypes.CDLL(str(lib)))


def _case(name: str, B: int = 7, seed: int = 3, dtype: str = "float64"):
    spec = creature.load(name)
    m = sim.compile_creature(spec, dtype=dtype)
    san, sp = random_san_params(spec, B, seed, dtype="float64")
    s0 = sim.make_state(m)
    tile = lambda x: np.tile(np.asarray(x), (B,) + (1,) * np.ndim(x))
    N = san.n_nodes
    args = (np.asarray(sp.weights), np.asarray(sp.k1), np.asarray(sp.k2), tile(s0.q), tile(s0.p), tile(s0.anchor),
            np.zeros((B, N)), np.zeros((B, N)))
    return kernel.pack(m, san.n_hidden), args


@pytest.mark.parametrize("dtype", gpu.DTYPES)
@pytest.mark.parametrize("name", BUILTIN)
def test_gpu_entry_points_step_every_creature_bit_for_bit_as_the_cpus_scalar_form_and_tiles(host, name, dtype):
    # float32: the _f32 entry points against the CPU's float scalar form and its tiles of 16
    # float lanes (7 creatures: a ragged tile), the model's dtype choosing as on the CPU
    pk, args = _case(name, dtype=dtype)
    assert pk.dtype == dtype
    got = gpu.run_san(pk, *args, 300, t0=0.25, threads=4, on=host)  # 7 creatures: two blocks, one thread idle
    assert host.launched[-1] == gpu.ENTRIES["san", dtype]
    for scalar in (True, False):
        want = kernel.run_san(pk, *args, 300, t0=0.25, scalar=scalar)
        for key in got:
            assert np.array_equal(got[key], want[key], equal_nan=True), (key, scalar)
    if dtype == "float32":  # float32 arithmetic: every value a float32, and not float64's run
        f64 = kernel.run_san(_case(name)[0], *args, 300, t0=0.25)
        assert np.array_equal(got["q"], got["q"].astype(np.float32).astype(np.float64))
        assert not np.array_equal(got["q"], f64["q"])
    assert host.blocks == {}  # every block it allocated was given back


@pytest.mark.parametrize("dtype", gpu.DTYPES)
def test_gpu_rows_that_carry_their_own_numbers_step_as_on_the_cpu(host, dtype):
    # a per-row table is each thread's own row; a shared one, one address every thread reads (in
    # float32, both rounded once per call)
    pk, args = _case("bounder", B=6, dtype=dtype)
    scale = np.linspace(0.8, 1.25, 6)
    lf = np.repeat(pk.lf[None], 6, 0)
    lf[:, :, kernel.F_MASS] *= scale[:, None]
    wf = np.repeat(pk.wf[None], 6, 0)
    wf[:, kernel.W_DT] *= np.where(np.arange(6) % 2, 0.5, 1.0)
    rows = {"lf": lf, "wf": wf}
    got = gpu.run_san(pk, *args, 200, rows=rows, threads=4, on=host)
    want = kernel.run_san(pk, *args, 200, rows=rows, scalar=True)
    for key in got:
        assert np.array_equal(got[key], want[key]), key
    assert len({got["q"][i].tobytes() for i in range(6)}) == 6  # the rows did differ
    with pytest.raises(ValueError, match="lf"):
        gpu.run_san(pk, *args, 10, rows={"lf": lf[:3]}, on=host)


def test_a_continued_gpu_run_goes_on_from_the_state_it_is_given(host):
    pk, args = _case("walker", B=3)
    first = gpu.run_san(pk, *args, 150, on=host)
    keys = ("q", "p", "anchor", "istate", "out")
    again = gpu.run_san(pk, *args[:3], first["q"], first["p"], first["anchor"], first["istate"], first["out"], 150,
                        t0=first["t"], on=host)
    whole = kernel.run_san(pk, *args, 300, scalar=True)
    for key in (*keys, "t", "qd"):
        assert np.array_equal(again[key], whole[key]), key


def test_the_gpu_rollout_refuses_arrays_of_the_wrong_shape_before_touching_a_device(host):
    pk, (w, k1, k2, q, p, a, ist, out) = _case("bounder", B=2)
    launched = len(host.launched)
    with pytest.raises(ValueError, match="weights: expected integers in"):
        gpu.run_san(pk, w * 3, k1, k2, q, p, a, ist, out, 10, on=host)
    with pytest.raises(ValueError, match="istate: expected"):
        gpu.run_san(pk, w, k1, k2, q, p, a, ist[:, :-1], out, 10, on=host)
    with pytest.raises(ValueError, match="anchor: expected shape"):
        gpu.run_san(pk, w, k1, k2, q, p, a[:, :1], ist, out, 10, on=host)
    with pytest.raises(ValueError, match="t0: expected"):
        gpu.run_san(pk, w, k1, k2, q, p, a, ist, out, 10, t0=np.zeros(3), on=host)
    with pytest.raises(ValueError, match=r"^tables\.dtype: expected float64 or float32, got 'float16'$"):
        gpu.run_san(pk._replace(dtype="float16"), w, k1, k2, q, p, a, ist, out, 10, on=host)
    assert host.blocks == {} and len(host.launched) == launched


class Keeping(HostEmulation):
    """The host emulation keeping a copy of the scratch as the rollout left it."""

    scratch: np.ndarray

    def alloc(self, nbytes: int) -> ctypes.c_uint64:
        p = super().alloc(nbytes)
        self.at, self.nbytes = p.value, int(nbytes)
        return p

    def free(self, p: ctypes.c_uint64) -> None:
        if p.value == self.at:
            self.scratch = self.blocks[p.value][0][: self.nbytes // 8].copy()
        super().free(p)


@pytest.mark.parametrize("dtype", gpu.DTYPES)
def test_the_scratch_is_lane_innermost_in_blocks_of_a_warp(host, dtype):
    # value k of thread b at (b // 32) * 32 * per_thread + k * 32 + b % 32: threads b and b + 1 of a
    # warp keep each value in neighbouring elements, so a warp reads one value of its 32 creatures
    # from 32 neighbouring addresses. Read back from where the rollout left its values: the state
    # (after the tile), the parameters, the SAN's state and the final velocity, and a value of the
    # tile itself (each link's angle, after the tile's room for the numbers)
    B, W = 40, gpu.WARP  # a warp and a part of one, in blocks of 8 threads
    pk, args = _case("bounder", B=B, dtype=dtype)
    keep = Keeping(host.lib)
    got = gpu.run_san(pk, *args, 50, threads=8, on=keep)
    D, C, N = pk.ndof, pk.ci.shape[0], args[-1].shape[1]
    dims = _dims(pk, N)
    per = gpu.scratch_values(dims, 2 * N, 2 * N, 0)
    assert keep.nbytes == gpu.scratch_bytes(B, per, dtype) == 2 * W * per * np.dtype(dtype).itemsize
    mem = keep.scratch.view(np.float32 if dtype == "float32" else np.float64).astype(np.float64)
    assert mem.size == 2 * W * per
    lanes = mem.reshape(2, per, W)  # [warp, value, lane]
    values = lanes.transpose(0, 2, 1).reshape(2 * W, per)[:B]  # [thread, value]
    tile = per - (2 * D + 2 * C + 2) - 4 * N - D
    want = np.concatenate([got["q"], got["p"], got["anchor"].reshape(B, -1), got["t"][:, None], got["dmax"][:, None],
                           args[1], args[2], got["istate"], got["out"], got["qd"]], 1).astype(dtype)  # k1, k2 rounded
    assert np.array_equal(values[:, tile:], want)
    numbers = sum(getattr(pk, name).size for name in kernel.ROW_TABLES)  # room kept unused on the GPU
    assert not values[:, :numbers].any()
    th = kernel.poses(pk, got["q"])["links"][:, :, 2]  # the last step's link angles, as the CPU puts them
    assert np.array_equal(values[:, numbers : numbers + th.shape[1]], th)
    assert not lanes[1, :, B - W :].any()  # the second warp's idle lanes: untouched
    # so the address of value k for thread b + 1 is one element past thread b's
    k, b = tile + 1, 5
    at = lambda b, k: (b // W) * W * per + k * W + b % W
    assert at(b + 1, k) - at(b, k) == 1 and mem[at(b, k)] == got["q"][b, 1] and mem[at(b + 1, k)] == got["q"][b + 1, 1]


def test_the_derived_tables_list_each_links_children_in_link_order():
    pk, _ = _case("star", B=1)
    d = gpu.derived(pk)
    L, D = pk.li.shape[0], pk.ndof
    parent = pk.li[:, layout.TABLE["li"].at("parent")]
    assert list(d[:D]) == list(range(D))
    start, kids = d[D : D + L + 1], d[D + L + 1 :]
    for i in range(L):
        assert list(kids[start[i] : start[i + 1]]) == [j for j in range(L) if parent[j] == i]
    assert start[-1] == L - int(np.sum(parent < 0))


def test_without_a_gpu_asking_for_one_says_why_in_one_line():
    try:
        ctypes.CDLL("libcuda.so.1")
        pytest.skip("this machine has a CUDA driver: benchmarks/gpu.py is its check")
    except OSError:
        pass
    with pytest.raises(gpu.GpuUnavailable) as e:
        gpu.device()
    assert "\n" not in str(e.value) and str(e.value).startswith("no GPU: ")


@needs_nvrtc
@pytest.mark.slow
def test_the_kernel_compiles_through_nvrtc_to_sm_90_without_spills_within_the_register_budget():
    report, ptx = gpu.report("sm_90")  # about 40 s: ptxas on five whole rollouts
    assert set(report) == set(layout.KINDS)
    assert re.findall(r"\bdiv\.rn\.f64\b", ptx) and not re.search(r"\.(?:approx|full|ftz)\b", ptx)  # IEEE, as the CPU
    for kind, r in report.items():
        assert r["spill_stores"] == 0 and r["spill_loads"] == 0, (kind, r)
        assert 0 < r["registers"] <= REGISTERS, (kind, r)
        assert r["stack"] <= STACK, (kind, r)


@needs_nvrtc
@pytest.mark.slow
def test_the_ptx_is_built_once_and_then_read_from_the_disk_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SANLAB_CACHE", str(tmp_path))
    ptx = gpu.compile_ptx("compute_90", ("san",))  # the SAN's entry alone: what a first search builds
    assert ".target sm_90" in ptx and ".entry sanlab_gpu_san(" in ptx and ".entry sanlab_gpu_hold(" not in ptx
    files = list((tmp_path / "gpu").iterdir())
    assert len(files) == 1 and files[0].name.endswith("-compute_90-san.ptx")
    files[0].write_bytes(b"marker\0")  # the second call reads the cache, not NVRTC
    assert gpu.compile_ptx("compute_90", ("san",)) == "marker"
    # a float32 model's first search builds the float entry alone, cached apart
    ptx = gpu.compile_ptx("compute_90", ("san",), "float32")
    assert ".entry sanlab_gpu_san_f32(" in ptx and ".entry sanlab_gpu_san(" not in ptx
    assert sorted(f.name.split("-", 1)[1] for f in (tmp_path / "gpu").iterdir()) == ["compute_90-san-f32.ptx",
                                                                                     "compute_90-san.ptx"]
    with pytest.raises(ValueError, match="kinds: expected some of"):
        gpu.build("compute_90", ("walk",))
    with pytest.raises(ValueError, match="dtype: expected one of"):
        gpu.build("compute_90", ("san",), "float16")


@needs_nvrtc
def test_nvrtc_rejects_a_kernel_that_uses_what_the_gpu_lacks_and_says_where(monkeypatch):
    # the guards matter: a header that reached a GCC vector type outside them is refused, with the
    # file and line in the message
    src = '#include "lanes.h"\ntypedef double v4 __attribute__((vector_size(32)));\nv4 f(v4 a) { return a[0] + a; }\n'
    monkeypatch.setattr(gpu, "source", lambda: src)
    with pytest.raises(gpu.CompileError, match=r"gpu\.cu\(\d+\)"):
        gpu._compile("compute_90")
