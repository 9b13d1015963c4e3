"""Where a step's time goes: the compiled rollout profiled kernel by kernel, each kernel
attributed to the line of sanlab that made it.

The engine traces one creature's step as scalar arithmetic unrolled over its links, contacts and
dofs, batched with ``vmap`` (see sanlab/sim/dynamics.py). XLA's CPU backend turns that into a few
hundred small kernels per step, each a loop over the batch that reads its inputs from memory and
writes its output back. This script counts them and says which lines of the step they come from:
the profile behind the engine's limits (README, "Benchmarks").

How: the rollout is compiled with XLA's optimised HLO dumped (its kernels carry the Python stack
of the op at their root), run once untraced (the rate), then once under ``jax.profiler`` (one
event per kernel and step), and each kernel's time is summed by the innermost line of sanlab's
step on its stack (``--depth`` lines of context) and by the phase of the step it belongs to
(``prepare``: kinematics, mass matrix and the velocity solve; ``advance``: forces, the step's
matrix and solve, the update; ``sense``; the SAN; the observer). The profiler's own cost per kernel
inflates small kernels: read the shares as a map, the untraced rate as the figure.

    python benchmarks/profile.py [--creature bounder] [--batch 2048] [--steps 200] [--depth 1]
"""

from __future__ import annotations

import argparse
import collections
import glob
import linecache
import os
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

OURS = ("dynamics.py", "array_step.py", "articulated.py", "san.py", "metrics.py")


def _section(text: str, head: str) -> list[str]:
    part = text.split("\n" + head + "\n", 1)
    return part[1].split("\n\n", 1)[0].splitlines() if len(part) == 2 else []


def kernel_stacks(hlo: str) -> dict[str, list[tuple[str, str, int]]]:
    """Kernel name -> the Python stack of its root op, innermost first: [(path, function, line)],
    from the stack-frame tables of XLA's HLO text dump."""
    num = lambda key, line: int(re.search(key + r"=(\d+)", line).group(1))  # type: ignore[union-attr]
    files = {int(x.split()[0]): x.split(None, 1)[1].strip('"') for x in _section(hlo, "FileNames")}
    funcs = {int(x.split()[0]): x.split(None, 1)[1].strip('"') for x in _section(hlo, "FunctionNames")}
    locs = {int(x.split()[0]): (files[num("file_name_id", x)], funcs[num("function_name_id", x)], num("line", x))
            for x in _section(hlo, "FileLocations")}
    # parent_frame_id counts from 1 over the frame list (0: none), so frame i's parent is that - 1
    frames = {int(x.split()[0]): (num("file_location_id", x), num("parent_frame_id", x) - 1)
              for x in _section(hlo, "StackFrames")}

    def stack(fid: int) -> list[tuple[str, str, int]]:
        out, seen = [], set()
        while fid in frames and fid not in seen:
            seen.add(fid)
            loc, fid = frames[fid]
            out.append(locs[loc])
        return out

    kernels = {}
    for m in re.finditer(r"^\s*(?:ROOT )?%(\S+) = .*?metadata=\{([^}]*)\}", hlo, re.M):
        s = re.search(r"stack_frame_id=(\d+)", m.group(2))
        kernels[m.group(1)] = stack(int(s.group(1))) if s else []
    return kernels


def loop_body_cost(hlo: str) -> dict[str, int]:
    """Static size of the step's compiled loop body, from XLA's optimised HLO text: its fusions
    (kernels), the operands they read and the operations inside them (parameters, constants,
    broadcasts, slices and other data movement not counted). Every kernel is a loop over the
    batch, so ``fusions + operands + ops`` counts the vector instructions of one creature-step;
    unlike a timing it does not vary with the load on a shared machine."""
    comps: dict[str, list[str]] = {}
    cur = None
    for line in hlo.splitlines():
        head = re.match(r"^(?:ENTRY )?%?([\w.\-]+) .*\{\s*$", line)
        if head:
            cur = head.group(1)
            comps[cur] = []
        elif line.startswith("}"):
            cur = None
        elif cur is not None and "=" in line:
            comps[cur].append(line.strip())
    callees = {c: {n.strip().lstrip("%") for l in lines
                   for m in re.finditer(r"(?:body|calls|branch_computations|to_apply)=\{?([%\w.\-, ]+)\}?", l)
                   for n in m.group(1).split(",")} for c, lines in comps.items()}

    def reach(c: str, seen: set) -> set:
        if c not in seen:
            seen.add(c)
            for d in callees.get(c, ()):
                reach(d, seen)
        return seen

    bodies = [m.group(1) for lines in comps.values() for l in lines for m in [re.search(r" while\(.*body=%?([\w.\-]+)", l)] if m]
    inside = max((reach(b, set()) for b in bodies), key=len, default=set())
    out = {"fusions": 0, "operands": 0, "ops": 0}
    moves = re.compile(r" (parameter|constant|broadcast|bitcast|slice|reshape|tuple|get-tuple-element)\(")
    for c in inside:
        for l in comps.get(c, []):
            f = re.search(r"= [^=]+ fusion\((.*?)\), kind=\w+, calls=%?([\w.\-]+)", l)
            if f:
                out["fusions"] += 1
                out["operands"] += len([o for o in f.group(1).split(", ") if o])
                out["ops"] += sum(1 for b in comps.get(f.group(2), []) if not moves.search(b))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--creature", default="bounder")
    ap.add_argument("--batch", type=int, default=2048)
    ap.add_argument("--steps", type=int, default=200, help="steps of the traced rollout")
    ap.add_argument("--depth", type=int, default=1, help="lines of sanlab's stack that name a kernel's source")
    ap.add_argument("--top", type=int, default=30)
    a = ap.parse_args()
    dump = tempfile.mkdtemp(prefix="sanlab-hlo-")
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") +
                               f" --xla_dump_to={dump} --xla_dump_hlo_as_text --xla_dump_hlo_module_re=jit_local")
    os.environ["SANLAB_NO_COMPILE_CACHE"] = "1"  # compile here, so that the dump is written
    import sanlab

    sanlab.configure()
    import jax

    from sanlab import creature, sim
    from sanlab.engine_report import random_san_params

    spec = creature.load(a.creature)
    model = sim.compile_creature(spec)
    san, params = random_san_params(spec, a.batch, seed=0)
    run = lambda n: jax.block_until_ready(sim.rollout(model, san, params, steps=n).state.q)
    run(a.steps)  # compiles (the number of steps is an input of the program: one compilation)
    best = float("inf")
    timed = max(a.steps, 2000)  # long enough that the call's fixed cost does not count
    for _ in range(3):
        t0 = time.perf_counter()
        run(timed)
        best = min(best, time.perf_counter() - t0)
    devices = len(jax.devices())
    print(f"{a.creature}, batch {a.batch} on {devices} x {jax.devices()[0].platform}: {best / timed * 1e6:.1f} us "
          f"per step untraced ({a.batch * timed / best / 1e6:.2f} M creature-steps/s)")

    with tempfile.TemporaryDirectory() as trace:
        with jax.profiler.trace(trace):
            run(a.steps)
        data = jax.profiler.ProfileData.from_file(glob.glob(f"{trace}/**/*.xplane.pb", recursive=True)[0])
    spent: dict[str, float] = collections.defaultdict(float)  # per step and device, below
    calls: dict[str, float] = collections.defaultdict(float)
    for plane in data.planes:
        for line in plane.lines:
            if not line.name.startswith("tf_XLAEigen"):
                continue
            for ev in line.events:  # XLA's worker threads: every kernel of every device's share
                if not ev.name.startswith(("ThunkExecutor", "end: ")):
                    spent[ev.name] += ev.duration_ns / devices
                    calls[ev.name] += 1 / devices
    hlo_files = sorted(glob.glob(f"{dump}/*jit_local*after_optimizations.txt"))
    hlo = Path(hlo_files[-1]).read_text() if hlo_files else ""
    stacks = kernel_stacks(hlo)
    size = loop_body_cost(hlo)
    print(f"compiled loop body (static): {size['fusions']} fusions reading {size['operands']} operands, {size['ops']} "
          f"operations in them; sum {sum(size.values())}")
    total = sum(spent.values())
    n = sum(calls.values()) / a.steps
    print(f"{n:.0f} kernels per step and device ({len(spent)} distinct), {total / 1e3 / a.steps:.0f} us of them per "
          f"step and device traced; by source line (innermost {a.depth} of sanlab's step):")
    by_line: dict[str, float] = collections.defaultdict(float)
    by_phase: dict[str, float] = collections.defaultdict(float)
    line_calls: dict[str, float] = collections.defaultdict(float)
    phase_calls: dict[str, float] = collections.defaultdict(float)
    for name, ns in spent.items():
        ours = [f for f in stacks.get(name, []) if Path(f[0]).name in OURS and f[1] != "_barrier"]
        where = " < ".join(f"{Path(f[0]).stem}.{f[1]}:{f[2]}" for f in ours[:a.depth]) or "(loop, copies, conditionals)"
        if ours:
            where += "  " + linecache.getline(ours[0][0], ours[0][2]).strip()[:70]
        phase = next((f[1] for f in reversed(ours) if Path(f[0]).name == "dynamics.py"), ours[-1][1] if ours else "(other)")
        by_line[where] += ns
        line_calls[where] += calls[name]
        by_phase[phase] += ns
        phase_calls[phase] += calls[name]
    print(f"{'share':>6} {'kernels/step':>13}  source")
    for where, ns in sorted(by_line.items(), key=lambda kv: -kv[1])[:a.top]:
        print(f"{100 * ns / total:5.1f}% {line_calls[where] / a.steps:13.1f}  {where}")
    if os.environ.get("SANLAB_PROFILE_KERNELS"):
        for name, ns in sorted(spent.items(), key=lambda kv: -kv[1])[:15]:
            print(f"  kernel {name}: {100 * ns / total:.1f}% {calls[name] / a.steps:.1f}/step")
    print("by phase of the step:")
    for phase, ns in sorted(by_phase.items(), key=lambda kv: -kv[1]):
        print(f"{100 * ns / total:5.1f}% {phase_calls[phase] / a.steps:13.1f}  {phase}")


if __name__ == "__main__":
    main()
