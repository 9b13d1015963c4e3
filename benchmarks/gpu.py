"""GPU benchmark: the kernel's scalar forms on one NVIDIA GPU (sanlab/sim/gpu.py), issue 58 §3.

On a machine with a GPU (and the ``gpu`` extra: ``pip install -e '.[gpu]'``), prints, in order,
for each arithmetic of ``--dtypes`` (float64, the default and the audit's reference, and float32,
the ``_f32`` entry points; the model's dtype chooses, as on the CPU):
- the device and NVRTC's version;
- first call: the SAN entry's NVRTC build for the device's arch from an empty cache (seconds),
  then the first rollout in this process (module load included: one bounder, one step), then the
  same call again (the launch and copies alone);
- bit for bit: for every built-in creature (``--creatures``), ``--check`` random SANs for
  ``--check-steps`` steps on the GPU against the CPU's scalar form of the same dtype
  (``kernel.run_san(..., scalar=True)``, which the tests hold to the SIMD tiles): "same bits" or
  how many creatures differ and by how much;
- rate: bounder creature-steps/s at each of ``--batches`` and ``--threads`` a block for
  ``--steps`` steps (dt = 1 ms, closed-loop SANs), beside the CPU's SIMD tiles of the same dtype
  at ``--cpu-batch`` in the same run, as a ratio; the goal (issue 58) is 10^9 on one H100.
The last line holds every figure as key=value for a log. On a machine without a GPU it prints
``unmeasured: no GPU (<why>)`` and exits 0; ``--build`` then still times NVRTC's builds (they
need no GPU).

    python benchmarks/gpu.py [--dtypes float64,float32] [--batches 16384,131072,1048576]
                             [--steps 1000] [--threads 64,128] [--check 64] [--check-steps 2000]
                             [--creatures all] [--cpu-batch 2048] [--build]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from sanlab.sim import gpu  # noqa: E402


def timed_build(arch: str, dtype: str = "float64") -> float:
    """Seconds of NVRTC's build of the kernel's SAN entry point in ``dtype`` for ``arch`` from an
    empty cache (what a search's first call on a new install waits for)."""
    old = os.environ.get("SANLAB_CACHE")
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["SANLAB_CACHE"] = tmp
        try:
            t = time.perf_counter()
            gpu.build(arch, ("san",), dtype)
            return time.perf_counter() - t
        finally:
            if old is None:
                os.environ.pop("SANLAB_CACHE")
            else:
                os.environ["SANLAB_CACHE"] = old


def inputs(name: str, B: int, seed: int, distinct: int | None = None, dtype: str = "float64") -> tuple:
    """The bounder's (or ``name``'s) packed tables in ``dtype`` and run_san's arrays for B random
    SANs; with ``distinct``, only that many SANs drawn and repeated to B rows (drawing a million is
    slow): (packed tables, run_san's arrays by name)."""
    import bench_kernels as bk

    from sanlab import creature

    n = min(B, distinct) if distinct else B
    _, _, sp, pk, (q, p, anchor, istate, out), _ = bk._start(creature.load(name), n, seed, dtype=dtype)
    rep = lambda a: np.resize(np.asarray(a), (B, *np.shape(a)[1:]))
    arrays = (sp.weights, sp.k1, sp.k2, q, p, anchor, istate, out)
    args: dict[str, Any] = {k: rep(a) for k, a in zip(("weights", "k1", "k2", "q", "p", "anchor", "istate", "out"), arrays)}
    return pk, args


def check(names: list[str], B: int, steps: int, dtype: str = "float64") -> dict:
    """How many of B creatures of each name end ``steps`` steps with other bits on the GPU than
    on the CPU's scalar form, both in ``dtype``."""
    from sanlab.sim import kernel

    bad = {}
    for name in names:
        pk, args = inputs(name, B, 7, dtype=dtype)
        g = gpu.run_san(pk, **args, steps=steps)
        c = kernel.run_san(pk, **args, steps=steps, scalar=True)
        differ = np.zeros(B, bool)
        worst = 0.0
        for key in g:
            a, b = np.asarray(g[key]).reshape(B, -1), np.asarray(c[key]).reshape(B, -1)
            same = (a == b) | (np.isnan(a) & np.isnan(b))
            differ |= ~same.all(1)
            with np.errstate(invalid="ignore"):
                if key == "q":
                    worst = max(worst, float(np.nanmax(np.abs(a - b), initial=0.0)))
        bad[name] = int(differ.sum())
        print(f"  {name:10s} " + ("same bits" if not differ.any() else
                                   f"{differ.sum()} of {B} differ (largest |q_gpu - q_cpu| {worst:.3g})"))
    return bad


def rates(dtype: str, a: argparse.Namespace) -> tuple[float, float]:
    """The CPU tiles' rate at ``--cpu-batch`` and the GPU's best over ``--batches`` x ``--threads``
    (bounder creature-steps/s, closed-loop SANs in ``dtype``), each line printed."""
    from sanlab.sim import kernel

    pk, cargs = inputs("bounder", a.cpu_batch, 0, dtype=dtype)
    kernel.run_san(pk, **cargs, steps=10)
    cpu_s = float("inf")
    for _ in range(3):  # the best of three: the CPU's figure is the reference, the noisier side
        t = time.perf_counter()
        kernel.run_san(pk, **cargs, steps=a.steps)
        cpu_s = min(cpu_s, time.perf_counter() - t)
    cpu_rate = a.cpu_batch * a.steps / cpu_s
    print(f"rate, {dtype}: bounder, {a.steps} steps, closed-loop SANs; CPU tiles at batch {a.cpu_batch}: "
          f"{cpu_rate / 1e6:.1f} M creature-steps/s")
    best = 0.0
    for B in (int(x) for x in a.batches.split(",")):
        pk, gargs = inputs("bounder", B, 0, distinct=4096, dtype=dtype)
        N = gargs["istate"].shape[1]
        values = gpu.scratch_values(gpu._dims(pk, N), 2 * N, 2 * N, 0)
        total, per = gpu.scratch_bytes(B, values, dtype), values * np.dtype(dtype).itemsize
        s_ = 0.0
        for threads in (int(x) for x in a.threads.split(",")):
            gpu.run_san(pk, **gargs, steps=1, threads=threads)  # allocations and first touch outside the timing
            t = time.perf_counter()
            gpu.run_san(pk, **gargs, steps=a.steps, threads=threads)
            s_ = time.perf_counter() - t
            rate = B * a.steps / s_
            best = max(best, rate)
            print(f"  batch {B:>8d}, {threads:>3d} threads a block: {rate / 1e6:9.1f} M creature-steps/s "
                  f"({rate / cpu_rate:.1f}x the CPU), {s_:.2f} s, scratch {total / 2**30:.2f} GiB ({per} B a thread)")
        if s_ > 120:
            print("  (larger batches skipped: this one took over 2 minutes)")
            break
    return cpu_rate, best


def main() -> None:
    ap = argparse.ArgumentParser(description="GPU benchmark: the kernel's scalar forms on one NVIDIA GPU")
    ap.add_argument("--dtypes", default="float64,float32", help="the arithmetics to run, in order")
    ap.add_argument("--batches", default="16384,131072,1048576")
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--check", type=int, default=64)
    ap.add_argument("--check-steps", type=int, default=2000)
    ap.add_argument("--creatures", default="all")
    ap.add_argument("--cpu-batch", type=int, default=2048)
    ap.add_argument("--threads", default="64,128", help="threads a block to time (about 250 registers a thread: at most 256)")
    ap.add_argument("--build", action="store_true", help="without a GPU: time NVRTC's builds for sm_90 anyway")
    a = ap.parse_args()
    dtypes = a.dtypes.split(",")
    for d in dtypes:
        if d not in gpu.DTYPES:
            ap.error(f"--dtypes: expected some of {','.join(gpu.DTYPES)}, got {d!r}")
    try:
        name = gpu.device()
    except gpu.GpuUnavailable as e:
        print(f"unmeasured: {e}")
        if a.build:
            try:
                print(f"build: NVRTC {'.'.join(map(str, gpu.nvrtc_version()))}, the SAN's entry for sm_90: " +
                      ", ".join(f"{d} {timed_build('sm_90', d):.1f} s" for d in dtypes) + " (no GPU needed)")
            except gpu.GpuUnavailable as e2:
                print(f"build: unmeasured: {e2}")
        return
    from sanlab import creature

    s = gpu._session()  # the context on the device
    print(f"device: {name} ({s.arch}), NVRTC {'.'.join(map(str, gpu.nvrtc_version()))}")
    builtin = sorted(p.stem for p in (Path(creature.__file__).parent / "builtin").glob("*.toml"))
    names = builtin if a.creatures == "all" else a.creatures.split(",")
    log: dict[str, str] = {}
    for dtype in dtypes:
        build_s = timed_build(s.arch, dtype)
        pk, args = inputs("bounder", 1, 0, dtype=dtype)
        t = time.perf_counter()
        gpu.run_san(pk, **args, steps=1)
        first = time.perf_counter() - t
        t = time.perf_counter()
        gpu.run_san(pk, **args, steps=1)
        again = time.perf_counter() - t
        print(f"first call, {dtype}: NVRTC's build of the SAN's entry {build_s:.1f} s from an empty cache; the first "
              f"rollout (the build read from the cache, the module loaded) {first * 1e3:.1f} ms, again "
              f"{again * 1e3:.2f} ms")
        print(f"bit for bit, {dtype}, against the CPU's scalar form ({a.check} random SANs x {a.check_steps} steps "
              "each):")
        bad = check(names, a.check, a.check_steps, dtype)
        cpu_rate, best = rates(dtype, a)
        print(f"goal, {dtype}: 10^9 bounder creature-steps/s on one H100: {best / 1e9:.3f}e9 "
              f"({'met' if best >= 1e9 else 'not met'}); bit for bit on every creature: "
              f"{'yes' if not any(bad.values()) else 'no: ' + ', '.join(k for k, v in bad.items() if v)}")
        log.update({f"gpu_rate_{dtype}": f"{best:.4g}", f"cpu_rate_{dtype}": f"{cpu_rate:.4g}",
                    f"build_s_{dtype}": f"{build_s:.3g}", f"first_ms_{dtype}": f"{first * 1e3:.3g}",
                    f"bits_differ_{dtype}": str(sum(bad.values()))})
    print(" ".join(f"{k}={v}" for k, v in log.items()))


if __name__ == "__main__":
    main()
