"""Engine benchmark: issue 46's goals for the kernel that reads the creature as data, one run.

The simulator's kernel (``sanlab.sim.kernel``, C++ in sanlab/sim/_kernel, built once per
install) steps random closed-loop SANs (dt = 1 ms; the SAN evaluated every step inside the
kernel, float64, and in float32 where said). Every figure is printed beside a reference timed in the same run, as a ratio:
these machines vary 2x from run to run, so a figure alone says little. The references: MuJoCo's
C step and C rollout loop (``mujoco.rollout`` on the same creature converted to MJCF, open-loop
servo targets: no network in its loop; benchmarks/mujoco_route.py), MuJoCo stepping with the
same SAN in NumPy, and the kernel itself (a creature's second call, a batch with one shared
table).

Printed, in order:
- build: the kernel's one-time compile (``setup.py build_ext`` into a temporary folder);
- first call (no per-creature compile): a fresh process meets chains no process has seen
  (benchmarks/chains.py ``random_chain``, a new seed each run unless ``--seed``): the seconds
  from its file to the final states of 8 SANs after 1 s (pack, start, run), the first and the
  second time, for a 9-link then a 16-link chain (the process's first creature also pays the
  first-time costs of the library and of lazy imports; the second creature's first/second ratio
  is the "nothing compiled" figure); then, through the CLI in fresh processes,
  ``sanlab search FILE -n 8 --seconds 1`` and ``sanlab check FILE --simulate`` on a never-seen
  9-link chain, first and second run;
- latency: µs per bounder step at batch 1 and 32, and batch 1 against MuJoCo's C step on one
  thread;
- throughput: the bounder at ``--batch`` (2048) in float64 and in float32 (a model compiled with
  ``dtype="float32"``: the kernel's float32 form, 16 lanes a tile where float64 has 8; the two
  timed in turn, the ratio float32 / float64), against MuJoCo's C rollout loop at the same batch
  (one thread per core) and the MuJoCo + NumPy route;
- growth: ns per creature-step of N-link chains (``--growth 2,4,8,16,32``) on the kernel with
  their random SANs and with the physics alone (activations held), and on MuJoCo's C loop at the
  same batch; cost(longest) / cost(shortest) of each (a chain's SAN grows as N^2 by construction);
- mixed batches: the bounder at ``--batch`` with every row carrying its own numbers (every float
  table of ``kernel.ROW_TABLES``, each number jittered by up to 2 %: ``run_san(..., rows=)``)
  against one shared table, same batch, steps and SANs;
- the GPU (``sanlab.sim.gpu``, NVRTC's build of the same kernel): on a machine with one, the
  bounder's best rate over a few batches in float64 and float32, each against the CPU's tiles of
  the same arithmetic in the same run (``benchmarks/gpu.py``'s ``rates``; that script adds the
  first call and the bit-for-bit check); without one, "unmeasured" and why;
- with ``--replay``, a 6 s bounder replay at batch 1 through ``sim.rollout`` in fresh processes.

The XLA engine the kernel replaced was this benchmark's reference until it was removed; its
figures are in docs/engine-history.md, and the tests keep its numbers
(tests/sim/test_kernel_reference.py).

Compared calls alternate (``bench_kernels.best``), so that a change in the machine's load falls
on both. Then the goals, each with its figure and whether this run met it, and one last line of
``key=value`` pairs (nan where a part was skipped).

    python benchmarks/engine.py [--batch 2048] [--steps 2000] [--growth 2,4,8,16,32]
                                [--no-cli] [--no-build] [--seed N]
                                [--repeats 5] [--mujoco-seconds 2] [--replay]

Needs MuJoCo (``pip install -e '.[bench]'``). About two minutes on 2 shared cores; ``--steps``,
``--batch-steps``, ``--growth-steps`` and ``--repeats`` make it longer and steadier.
"""

from __future__ import annotations

import argparse
import math
import os
import secrets
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
NAN = float("nan")

FIRST_KERNEL = """
import sys, time; t0 = time.perf_counter()
sys.path.insert(0, {bench!r})
import bench_kernels as bk
from chains import random_chain
out = [time.perf_counter() - t0]
for n, seed in ((9, {seed}), (16, {seed} + 1)):
    for _ in range(2):
        t = time.perf_counter()
        bk.new_creature(random_chain(n, seed))
        out.append(time.perf_counter() - t)
print(*out)
"""

REPLAY = """
import time
from sanlab import creature, sim
from sanlab.random_sans import random_san_params
t0 = time.perf_counter()
spec = creature.load("bounder")
m = sim.compile_creature(spec)
san, p = random_san_params(spec, 1, 0)
r = sim.rollout(m, san, p, seconds=6.0, record_fps=30)
assert r.frames.q.shape[1] == 181
print(time.perf_counter() - t0)
"""


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=str(ROOT))


def _python(code: str, env: dict) -> list[float]:
    """The numbers the last line of ``code`` prints, run in a fresh interpreter."""
    out = subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True, text=True)
    return [float(x) for x in out.stdout.strip().splitlines()[-1].split()]


def build() -> float:
    """Seconds of the kernel's one-time build (``setup.py build_ext``, as an install runs it) into
    a temporary folder; nan if it fails."""
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "-b", f"{tmp}/lib", "-t", f"{tmp}/tmp"],
                           cwd=ROOT, capture_output=True, text=True)
        s = time.perf_counter() - t0
    if r.returncode != 0:
        print(f"build: failed ({r.stderr.strip().splitlines()[-1:]})")
        return NAN
    from sanlab.sim import kernel

    print(f"build: the kernel's one-time compile {s:.1f} s (setup.py build_ext; {kernel.lanes()} float64 or "
          f"{kernel.lanes('float32')} float32 lanes a tile)")
    return s


def first_calls(seed: int) -> dict:
    """A fresh process's first calls of never-seen chains."""
    r: dict = {}
    bench = str(ROOT / "benchmarks")
    imp, a1, a2, b1, b2 = _python(FIRST_KERNEL.format(bench=bench, seed=seed), _env())
    r.update(first_s=a1, first_second_s=a2, first16_s=b1, first16_second_s=b2)
    print(f"first call (chains of seed {seed}, never seen: file -> pack -> start -> 8 SANs x 1 s; fresh process, "
          f"import {imp:.2f} s first):")
    print(f"  kernel: 9-link chain {a1:.3f} s, again {a2:.3f} s (first/second {a1 / a2:.2f}); then a 16-link chain "
          f"{b1:.3f} s, again {b2:.3f} s ({b1 / b2:.2f})")
    return r


def _cli(args: list[str], cwd: str) -> float:
    """Wall seconds of ``python -m sanlab ARGS`` in a fresh process; nan if it fails."""
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "sanlab", *args], cwd=cwd, env=_env(),
                       capture_output=True, text=True)
    s = time.perf_counter() - t0
    if p.returncode != 0:
        tail = (p.stderr or p.stdout).strip().splitlines()[-1:]
        print(f"  `sanlab {' '.join(args)}` failed (exit {p.returncode}): {tail}")
        return NAN
    return s


def cli(seed: int) -> dict:
    """The commands' wall times on never-seen 9-link chains, first and second run."""
    from chains import random_chain_toml

    print("first call through the CLI (fresh processes, first and second run):")
    r: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for what, s, args in (("search", seed + 2, ["-n", "8", "--seconds", "1", "--db", "gaits.db"]),
                              ("check", seed + 3, ["--simulate"])):
            path = Path(tmp) / f"chain9_{s}.toml"
            path.write_text(random_chain_toml(9, s))
            argv = [what, path.name, *args]
            first, second = _cli(argv, tmp), _cli(argv, tmp)
            r[f"{what}_first_s"], r[f"{what}_second_s"] = first, second
            print(f"  `sanlab {' '.join(argv)}`: {first:.2f} s, again {second:.2f} s (first/second "
                  f"{first / second:.2f})", flush=True)
    return r


def latency(spec, steps: int, repeats: int) -> dict:
    """µs per bounder step at batch 1 and 32, and against MuJoCo's C step."""
    import bench_kernels as bk
    from mujoco_route import mujoco_c_loop_steps_per_s

    r: dict = {}
    print(f"latency: bounder, µs per step ({steps} steps a call, best of {repeats}):")
    for B in (1, 32):
        (t,) = bk.best([bk.prepared(spec, B, steps, 0)], repeats)
        r[f"b{B}_us"] = k = t / steps * 1e6
        print(f"  batch {B}: kernel {k:.2f} µs", flush=True)
    mj = 1e6 / mujoco_c_loop_steps_per_s(spec, batch=1, steps=max(steps, 1000), repeats=repeats, threads=1)
    r["b1_mujoco_us"] = mj
    print(f"  batch 1: MuJoCo's C step {mj:.2f} µs on one thread, open loop (kernel {mj / r['b1_us']:.1f} x faster, "
          "its SAN included)")
    return r


def throughput(spec, batch: int, steps: int, repeats: int, mujoco_seconds: float) -> dict:
    """Creature-steps per second of the bounder at ``batch``, against MuJoCo."""
    import bench_kernels as bk
    from mujoco_route import mujoco_c_loop_steps_per_s, mujoco_steps_per_s

    r: dict = {}
    t, t32 = bk.best([bk.prepared(spec, batch, steps, 0), bk.prepared(spec, batch, steps, 0, dtype="float32")], repeats)
    r["rate"] = k = batch * steps / t
    r["rate_f32"] = k32 = batch * steps / t32
    print(f"throughput: bounder, batch {batch} x {steps} steps, best of {repeats}:")
    print(f"  kernel (float64): {k / 1e6:.2f} M creature-steps/s ({1e9 / k:.0f} ns per creature-step)")
    print(f"  kernel (float32): {k32 / 1e6:.2f} M creature-steps/s ({1e9 / k32:.0f} ns per creature-step; "
          f"{k32 / k:.2f} x float64)")
    mjc = mujoco_c_loop_steps_per_s(spec, batch=batch, steps=100, repeats=repeats)
    r["rate_mujoco_c"] = mjc
    print(f"  MuJoCo's C rollout loop: {mjc / 1e6:.3f} M/s, open loop, one thread per core (kernel {k / mjc:.1f} x, "
          f"float32 {k32 / mjc:.1f} x)")
    if mujoco_seconds > 0:
        try:
            mjn, info = mujoco_steps_per_s(seconds_budget=mujoco_seconds, details=True)
        except RuntimeError as e:  # MuJoCo went unstable: the route timed a different job
            r["mujoco_numpy_invalid"] = True
            print(f"  MuJoCo with the SAN in NumPy: {e}; not timed")
        else:
            r["rate_mujoco_numpy"] = mjn
            print(f"  MuJoCo with the SAN in NumPy: {mjn / 1e6:.3f} M/s, one process per core, "
                  f"{info['creatures']} creatures each (kernel {k / mjn:.0f} x; no instabilities)")
    return r


def growth(links: list[int], batch: int, steps: int, repeats: int) -> dict:
    """ns per creature-step of N-link chains on the kernel, with their random SANs and with the
    physics alone (activations held: no network), and on MuJoCo's C loop (open loop), same batch.
    A chain's SAN grows quadratically with it (2 N touch and angle sensors, as many hidden nodes,
    N - 1 actuators: its weights grow as N^2), so the growth of the physics is printed apart. The
    kernel's calls are short, so they go round the sizes ``repeats`` times (a change in the
    machine's load falls on every size) and each size keeps its best."""
    import bench_kernels as bk
    from chains import chain_creature
    from mujoco_route import mujoco_c_loop_steps_per_s

    calls = [bk.prepared(chain_creature(n), batch, steps, 0) for n in links]
    calls += [bk.prepared_open(chain_creature(n), batch, steps, 0) for n in links]
    best = bk.best(calls, repeats)
    ns = lambda t: t / (batch * steps) * 1e9
    san = {n: ns(t) for n, t in zip(links, best[:len(links)])}
    phys = {n: ns(t) for n, t in zip(links, best[len(links):])}
    print(f"growth: N-link chains, batch {batch} x {steps} steps, ns per creature-step (the kernel's best of {repeats} "
          "rounds; 'physics': activations held, no network):")
    print(f"  {'links':>5} {'with SAN':>9} {'vs first':>9} {'physics':>8} {'vs first':>9} {'MuJoCo C':>9} {'vs first':>9} "
          f"{'SAN ahead':>10}")
    mj, vs = {}, {}
    for n in links:
        mj[n] = 1e9 / mujoco_c_loop_steps_per_s(chain_creature(n), batch=batch, steps=steps, repeats=repeats)
        vs[n] = mj[n] / san[n]
        lo = links[0]
        print(f"  {n:>5} {san[n]:>9.0f} {san[n] / san[lo]:>8.1f}x {phys[n]:>8.0f} {phys[n] / phys[lo]:>8.1f}x "
              f"{mj[n]:>9.0f} {mj[n] / mj[lo]:>8.1f}x {vs[n]:>9.1f}x", flush=True)
    lo, hi = links[0], links[-1]
    print(f"  cost({hi})/cost({lo}) for {hi / lo:.0f} x the links: with the SAN {san[hi] / san[lo]:.1f}, physics alone "
          f"{phys[hi] / phys[lo]:.1f}, MuJoCo's C loop {mj[hi] / mj[lo]:.1f}")
    return dict(growth_ratio=san[hi] / san[lo], growth_physics_ratio=phys[hi] / phys[lo],
                growth_mujoco_ratio=mj[hi] / mj[lo], growth_min_vs_mujoco=min(vs.values()), growth_lo=lo, growth_hi=hi)


def jittered_rows(batch: int, seed: int = 0, names: list | None = None):
    """For :func:`bench_kernels.prepared`'s ``rows``: every non-empty float table of
    ``kernel.ROW_TABLES`` given per row, each number times 1 + U(-0.02, 0.02); their names are
    appended to ``names``."""
    from sanlab.sim import kernel

    def rows(pk) -> dict:
        rng = np.random.default_rng(seed)
        out = {}
        for name in kernel.ROW_TABLES:
            x = np.asarray(getattr(pk, name), np.float64)
            if x.size:
                out[name] = x[None] * (1 + rng.uniform(-0.02, 0.02, (batch, *x.shape)))
        if names is not None:
            names[:] = list(out)
        return out

    return rows


def mixed(spec, batch: int, steps: int, repeats: int) -> dict:
    """The cost of a batch whose rows carry their own numbers against one with a shared table."""
    import bench_kernels as bk

    names: list = []
    shared_f = bk.prepared(spec, batch, steps, 0)
    rows_f = bk.prepared(spec, batch, steps, 0, rows=jittered_rows(batch, 0, names))
    shared, per_row = bk.best([shared_f, rows_f], repeats)
    ns = lambda t: 1e9 * t / (batch * steps)
    print(f"mixed batch: bounder, batch {batch} x {steps} steps, rows with their own {', '.join(names)} (each number "
          f"jittered 2 %): {per_row / shared:.2f} x the cost of one shared table ({ns(per_row):.0f} against "
          f"{ns(shared):.0f} ns per creature-step, best of {repeats} alternated)")
    return dict(mixed_ratio=per_row / shared)


def replay() -> float:
    """Seconds of one 6 s bounder replay at batch 1 recorded at 30 fps through ``sim.rollout``
    (render, the studio's playback), in fresh processes: the best of three (after import)."""
    best = min(_python(REPLAY, _env())[0] for _ in range(3))
    print(f"replay (sim.rollout): bounder, 6 s at batch 1, 30 fps: {best:.2f} s (after import, best of 3 processes)")
    return best


def goals(r: dict) -> None:
    """Issues 46's and 58's goals against this run's figures."""
    g = lambda k: r.get(k, NAN)

    def line(goal: str, figure: str, ok) -> None:
        verdict = "unmeasured" if ok is None else ("met" if ok else "not met")
        print(f"  {goal:<52} {figure:<44} {verdict}")

    fine = lambda *xs: all(math.isfinite(x) for x in xs)
    print("goals (issues 46 and 58):")
    line("kernel build once per install <= 60 s", f"{g('build_s'):.1f} s", g("build_s") <= 60 if fine(g("build_s")) else None)
    line("never-seen creature's first result <= 1 s", f"9-link {g('first_s'):.3f} s, 16-link {g('first16_s'):.3f} s",
         max(g("first_s"), g("first16_s")) <= 1.0)
    line("  ... within 1.5 x its second (no compile)", f"{g('first_s') / g('first_second_s'):.2f}, "
         f"{g('first16_s') / g('first16_second_s'):.2f}", g("first16_s") <= 1.5 * g("first16_second_s"))
    s1, s2 = g("search_first_s"), g("search_second_s")
    line("`search -n 8 --seconds 1` new creature, 1.5 x 2nd", f"{s1:.2f} s, {s1 / s2:.2f} x its second",
         s1 <= 1.5 * s2 if fine(s1, s2) else None)
    c1 = g("check_first_s")
    line("9-link `check --simulate` < 5 s", f"{c1:.2f} s", c1 < 5 if fine(c1) else None)
    line("batch 32 <= 15 µs per bounder step", f"{g('b32_us'):.2f} µs", g("b32_us") <= 15)
    line("batch 1 at least as fast as MuJoCo's C step", f"{g('b1_mujoco_us') / g('b1_us'):.2f} x",
         g("b1_us") <= g("b1_mujoco_us"))
    line("batch 2048 no slower than the XLA engine", "removed: docs/engine-history.md", None)
    line("batch 2048 >= 40 x MuJoCo's C rollout loop", f"{g('rate') / g('rate_mujoco_c'):.1f} x",
         g("rate") >= 40 * g("rate_mujoco_c"))
    line("float32 >= 1.7 x float64 at batch 2048", f"{g('rate_f32') / g('rate'):.2f} x", g("rate_f32") >= 1.7 * g("rate"))
    line("  ... and float32 >= 40 x MuJoCo's C rollout loop", f"{g('rate_f32') / g('rate_mujoco_c'):.1f} x",
         g("rate_f32") >= 40 * g("rate_mujoco_c"))
    if "growth_ratio" in r:
        lo, hi = r["growth_lo"], r["growth_hi"]
        line(f"physics alone: cost({hi})/cost({lo}) <= {hi // lo} (linear)", f"{g('growth_physics_ratio'):.1f}",
             g("growth_physics_ratio") <= hi / lo)
        line(f"with the SAN: cost({hi})/cost({lo}) below MuJoCo's", f"{g('growth_ratio'):.1f} against "
             f"{g('growth_mujoco_ratio'):.1f}", g("growth_ratio") <= g("growth_mujoco_ratio"))
        line("ahead of MuJoCo's C loop at every size", f"at least {g('growth_min_vs_mujoco'):.1f} x",
             g("growth_min_vs_mujoco") >= 1)
    line("rows with their own numbers (a mixed batch)", f"{g('mixed_ratio'):.2f} x a shared table's cost", True)
    gr = max(g("gpu_rate"), g("gpu_rate_f32")) if fine(g("gpu_rate"), g("gpu_rate_f32")) else NAN
    line(">= 1 G bounder creature-steps/s on one GPU", f"{gr / 1e9:.3f} G (float64 {g('gpu_rate') / 1e9:.3f}, "
         f"float32 {g('gpu_rate_f32') / 1e9:.3f})" if fine(gr) else "no GPU on this machine", gr >= 1e9 if fine(gr) else None)


def on_gpu(cpu_batch: int) -> dict:
    """The GPU's bounder rate in float64 and float32 beside the CPU tiles' (benchmarks/gpu.py's
    ``rates``, batches 16384 and 131072, 500 steps), or an "unmeasured" line without a GPU (or
    without the ``gpu`` extra): {} then."""
    import gpu as gpu_bench  # benchmarks/gpu.py

    from sanlab.sim import gpu

    try:
        name = gpu.device()
    except gpu.GpuUnavailable as e:
        print(f"GPU: unmeasured: {e} (python benchmarks/gpu.py on a machine with one)")
        return {}
    print(f"GPU: {name}")
    a = argparse.Namespace(cpu_batch=cpu_batch, steps=500, batches="16384,131072", threads="128")
    out = {}
    for dtype, tag in (("float64", ""), ("float32", "_f32")):
        cpu_rate, best = gpu_bench.rates(dtype, a)
        out[f"gpu_cpu_rate{tag}"], out[f"gpu_rate{tag}"] = cpu_rate, best
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--batch", type=int, default=2048, help="the throughput and mixed batches")
    ap.add_argument("--batch-steps", type=int, default=250, help="steps a call at --batch")
    ap.add_argument("--steps", type=int, default=2000, help="steps a call at batch 1 and 32")
    ap.add_argument("--repeats", type=int, default=5, help="timed calls of each (the best counts)")
    ap.add_argument("--growth", default="2,4,8,16,32", help="chain lengths of the growth table ('' skips it)")
    ap.add_argument("--growth-batch", type=int, default=256)
    ap.add_argument("--growth-steps", type=int, default=200)
    ap.add_argument("--mujoco-seconds", type=float, default=2.0,
                    help="seconds of the MuJoCo + NumPy route's workers (0 skips it)")
    ap.add_argument("--seed", type=int, default=None, help="the never-seen chains' seed (default: a new one)")
    ap.add_argument("--no-cli", action="store_true", help="leave out the CLI's first calls")
    ap.add_argument("--no-build", action="store_true", help="leave out the kernel's build")
    ap.add_argument("--replay", action="store_true", help="also a 6 s replay through sim.rollout, fresh processes")
    a = ap.parse_args()
    t0 = time.perf_counter()
    seed = secrets.randbelow(10**6) if a.seed is None else a.seed

    from sanlab import creature

    spec = creature.load("bounder")
    r: dict = {}
    if not a.no_build:
        r["build_s"] = build()
    r.update(first_calls(seed))
    if not a.no_cli:
        r.update(cli(seed))
    r.update(latency(spec, a.steps, a.repeats))
    r.update(throughput(spec, a.batch, a.batch_steps, a.repeats, a.mujoco_seconds))
    if a.growth:
        r.update(growth([int(n) for n in a.growth.split(",")], a.growth_batch, a.growth_steps, a.repeats))
    r.update(mixed(spec, a.batch, a.batch_steps, a.repeats))
    r.update(on_gpu(a.batch))
    replay_s = replay() if a.replay else NAN
    goals(r)
    print(f"({time.perf_counter() - t0:.0f} s)")
    g = lambda k: r.get(k, NAN)
    summary = dict(
        build_s=g("build_s"), first_s=g("first_s"), first_vs_second=g("first16_s") / g("first16_second_s"),
        search_first_s=g("search_first_s"),
        search_first_vs_second=g("search_first_s") / g("search_second_s"), check_simulate_s=g("check_first_s"),
        b32_us=g("b32_us"), b1_vs_mujoco=g("b1_mujoco_us") / g("b1_us"),
        steps_per_s=g("rate"), vs_mujoco_c_loop=g("rate") / g("rate_mujoco_c"), f32_steps_per_s=g("rate_f32"),
        f32_vs_f64=g("rate_f32") / g("rate"), f32_vs_mujoco_c_loop=g("rate_f32") / g("rate_mujoco_c"),
        vs_mujoco=g("rate") / g("rate_mujoco_numpy"), growth_ratio=g("growth_ratio"),
        growth_physics_ratio=g("growth_physics_ratio"), growth_mujoco_ratio=g("growth_mujoco_ratio"),
        growth_vs_mujoco_min=g("growth_min_vs_mujoco"), mixed_ratio=g("mixed_ratio"), replay_warm_s=replay_s,
        gpu_steps_per_s=g("gpu_rate"), gpu_vs_cpu=g("gpu_rate") / g("gpu_cpu_rate"),
        gpu_f32_steps_per_s=g("gpu_rate_f32"), gpu_f32_vs_cpu=g("gpu_rate_f32") / g("gpu_cpu_rate_f32"),
    )
    print(" ".join(f"{k}={v:.4g}" for k, v in summary.items()))
    if r.get("mujoco_numpy_invalid"):
        sys.exit("INVALID: MuJoCo with the SAN in NumPy went unstable (see above)")


if __name__ == "__main__":
    main()
