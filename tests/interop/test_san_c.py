"""The C99 header of ``sanlab export GAIT --c`` against the simulator's SAN.

Compiled with the system's C compiler and fed the sensor trace of a recorded rollout (a frame
every step), the header's ``san_step`` switches every node on the same step as the rollout did,
with the same integrator states, activations and actuator targets, bit for bit: both do the same
float64 operations on the same float64 constants, each multiply-add rounded twice (the kernel is
built with ``-ffp-contract=off``; the header keeps any compiler from fusing them). Figure 7 step
by step in plain Python is the reference for any sensor trace and step. The C is compiled as ISO
C99 with every warning an error, and in a GNU mode for this CPU, which fuses multiply-adds
wherever it may."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.creature import load, read_source
from sanlab.gait import Gait, check_params
from sanlab.interop import san_c
from sanlab.library import Library
from sanlab.san import San
from sanlab.sim import kernel
from tests.helpers import ROOT

CC = shutil.which("cc")
CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic"]  # ISO C99: no contraction
# GNU C for this CPU: GCC contracts a * b + c into an FMA here, even across statements, where the
# CPU has one (x86-64 since 2013, ARMv8)
GNU_FLAGS = ["-std=gnu99", "-O3", "-march=native", "-Wall", "-Wextra", "-Werror"]
SECONDS = 3.0  # of each recorded rollout: 3000 steps at the creatures' dt of 1 ms
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc) on this machine")
runner = CliRunner()

# The test's C program: argv[1] is dt (a C99 hexadecimal float: exact); each line of stdin is one
# step's sensor bytes; each line of stdout the state after that step: the node outputs, then the
# bit patterns of the nodes' istate, the activations u and the targets.
DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "san.h"

static unsigned long long bits_of(double x)
{
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return (unsigned long long)b;
}

int main(int argc, char **argv)
{
    char line[4096];
    san_state s;
    double dt;
    if (argc != 2)
        return 2;
    dt = strtod(argv[1], NULL);
    san_init(&s);
    while (fgets(line, sizeof line, stdin)) {
        uint8_t sensors[SAN_N_SENSORS];
        double targets[SAN_N_ACTUATORS];
        char *p = line;
        int i;
        for (i = 0; i < SAN_N_SENSORS; i++)
            sensors[i] = (uint8_t)strtol(p, &p, 10);
        san_step(&s, sensors, dt, targets);
        for (i = 0; i < SAN_N_NODES; i++)
            printf("%d ", s.out[i]);
        for (i = 0; i < SAN_N_NODES; i++)
            printf("%016llx ", bits_of(s.istate[i]));
        for (i = 0; i < SAN_N_ACTUATORS; i++)
            printf("%016llx ", bits_of(s.u[i]));
        for (i = 0; i < SAN_N_ACTUATORS; i++)
            printf("%016llx ", bits_of(targets[i]));
        printf("\n");
    }
    return 0;
}
"""


def compile_c(folder, text: str | None, sources: dict[str, str], flags=CFLAGS) -> str:
    """``text`` as folder/san.h (unless None) and ``sources`` beside it, compiled and linked (not
    even a warning allowed); the program's path."""
    if text is not None:
        (folder / "san.h").write_text(text)
    for name, src in sources.items():
        (folder / name).write_text(src)
    exe = str(folder / "prog")
    r = subprocess.run([str(CC), *flags, "-I", str(folder), *(str(folder / n) for n in sources), "-o", exe],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and not r.stderr, r.stderr
    return exe


def run_c(exe: str, sensors, dt: float, n_nodes: int, n_actuators: int) -> dict[str, np.ndarray]:
    """The compiled SAN fed ``sensors`` [T, S] (bytes) with step ``dt`` (s): its outputs [T, N],
    istate [T, N], u [T, A] and targets [T, A] (float64) after each step."""
    stdin = "".join(" ".join(map(str, row)) + "\n" for row in np.asarray(sensors, int).tolist())
    r = subprocess.run([exe, float(dt).hex()], input=stdin, capture_output=True, text=True, timeout=120, check=True)
    rows = [line.split() for line in r.stdout.splitlines()]
    assert len(rows) == len(sensors)
    N, A = n_nodes, n_actuators
    f64 = lambda a, b: np.array([[int(x, 16) for x in row[a:b]] for row in rows], np.uint64).view(np.float64)
    return {"out": np.array([[int(x) for x in row[:N]] for row in rows]), "istate": f64(N, 2 * N),
            "u": f64(2 * N, 2 * N + A), "targets": f64(2 * N + A, 2 * N + 2 * A)}


def gait_numbers(gait: Gait) -> dict[str, np.ndarray]:
    """The gait's own numbers (float64): its per-node rates k1, k2 [N] (tuned, or from its or the
    creature file's delays), and its model's act_min, act_max [A] and dt."""
    k1, k2 = gait.params.rates(gait.san.n_nodes, gait.spec.san.delay_on, gait.spec.san.delay_off)
    p = gait.model().params
    return {name: np.asarray(x, np.float64) for name, x in
            (("k1", k1), ("k2", k2), ("act_min", p.act_min), ("act_max", p.act_max), ("dt", p.dt))}


def kernel_numbers(gait: Gait) -> dict[str, np.ndarray]:
    """The numbers the kernel steps the gait's SAN with, as its replay hands them over: k1, k2
    [N], the actuators' act_min, act_max [A] (its actuator table) and dt (its world table)."""
    pk = kernel.pack(gait.model(), gait.san.n_hidden)
    sp = gait.san_params()
    return {"k1": np.asarray(sp.k1, np.float64)[0], "k2": np.asarray(sp.k2, np.float64)[0],
            "act_min": pk.af[:, 0], "act_max": pk.af[:, 1], "dt": pk.wf[kernel.W_DT]}


def targets_of(numbers: dict, u) -> np.ndarray:
    """The actuator targets [T, A] of activations u as the kernel computes them from ``numbers``'
    act_min, act_max (step.h: ``f[0] + act (f[1] - f[0])``, float64, each operation rounded)."""
    span = [(float(a), float(b) - float(a)) for a, b in zip(numbers["act_min"], numbers["act_max"])]
    return np.array([[a + float(v) * d for (a, d), v in zip(span, row)] for row in np.asarray(u)]).reshape(np.shape(u))


def figure7(gait: Gait, on, dt: float) -> dict[str, np.ndarray]:
    """Figure 7 step by step in plain Python floats (IEEE double, each operation rounded) with the
    gait's numbers: the reference for any sensor trace ``on`` [T, S] and step ``dt``."""
    w = np.asarray(gait.weights, int).tolist()
    k = gait_numbers(gait)
    k1, k2 = k["k1"].tolist(), k["k2"].tolist()
    H, N = gait.san.n_hidden, gait.san.n_nodes
    istate, out = [0.0] * N, [0] * N
    rows: dict[str, list] = {"out": [], "istate": [], "u": []}
    for bits in np.asarray(on, bool).tolist():
        inputs = [int(b) for b in bits] + out
        total = [sum(wi * x for wi, x in zip(row, inputs)) for row in w]
        for n in range(N):
            x = istate[n] + (k1[n] if total[n] > 0 else k2[n]) * dt
            istate[n] = min(max(x, 0.0), 1.0)
            out[n] = 0 if out[n] == 1 and istate[n] == 0.0 else 1 if out[n] == 0 and istate[n] == 1.0 else out[n]
        rows["out"].append(list(out))
        rows["istate"].append(list(istate))
        rows["u"].append([(min(max(t, -2), 2) + 2) * 0.25 for t in total[H:]])
    res = {key: np.array(v) for key, v in rows.items()}
    res["out"] = res["out"].astype(int)
    res["targets"] = targets_of(k, res["u"])
    return res


def assert_identical(got: dict, want: dict) -> None:
    for key in ("out", "istate", "u", "targets"):
        a, b = np.asarray(got[key]), np.asarray(want[key])
        assert a.shape == b.shape, key
        if key != "out":  # bit for bit: compare the bit patterns
            a, b = a.view(np.uint64), np.asarray(b, np.float64).view(np.uint64)
        bad = np.argwhere(a != b)
        assert bad.size == 0, (f"{key} differs first at [step, node] {bad[0].tolist()}: "
                               f"{got[key][tuple(bad[0])]!r} vs {want[key][tuple(bad[0])]!r}")


# ---- the gaits: stored in a library as a search or tuning stores them, read as the CLI reads them

def _rates(n: int) -> dict:
    """Per-node rates as a tuning writes them: each node its own delays in [0.07, 0.15] s."""
    t_on, t_off = np.linspace(0.07, 0.15, n), np.linspace(0.15, 0.07, n)
    return {"k1": (1.0 / t_on).tolist(), "k2": (-1.0 / t_off).tolist()}


@pytest.fixture(scope="module")
def gaits(tmp_path_factory) -> tuple[str, dict[str, str]]:
    """(library, {case: gait id}): a phase-1 cart gait (the file's delays), a tuned cart gait
    (per-node rates, tuned actuator and sensor ranges) and a crawler gait (linear actuators: its
    targets are lengths in metres), each checked as the library's import checks a gait. Weights:
    random streams picked for lively traces (several activation levels, nodes switching both
    ways, chattering contacts)."""
    db = str(tmp_path_factory.mktemp("san_c") / "gaits.db")
    ids = {}
    with Library(db) as lib:
        for creature, kind, idx, params in (
            ("cart", "search", 8, {"delay_on": 0.1, "delay_off": 0.1}),
            ("cart", "tune", 34, {**_rates(6), "model": {"act_min": [-2.0], "act_max": [2.3],
                                                        "sens_min": [0, 0, 0, 0, -3.0, 2.0],
                                                        "sens_max": [0, 0, 0, 0, -1.9, 3.1]}}),
            ("crawler", "search", 1, {"delay_on": 0.12, "delay_off": 0.09}),
        ):
            spec = load(creature)
            check_params(spec, params)
            san = San.for_creature(spec)
            run = lib.create_run(kind, creature, read_source(creature)[0], {"metric": "distance", "seconds": SECONDS},
                                 0, 1)
            lib.add_batch(run.run_id, [{"idx": 0, "encoding": san.encode(san.random_weights(0, idx)),
                                        "score": 1.0, "params": params}])
            ids[f"{creature}-{kind}"] = f"{run.run_id}#0"
    return db, ids


def _gait(gaits, case: str) -> Gait:
    db, ids = gaits
    with Library(db) as lib:
        return Gait.from_library(lib, ids[case])


CASES = ["cart-search", "cart-tune", "crawler-search"]


def random_trace(T: int, S: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(on [T, S], bytes [T, S]): sensors that switch far more often than contacts do, each held
    for a random while and flickering now and then, "on" as any non-zero byte."""
    rng = np.random.default_rng(seed)
    hold = rng.integers(1, 60, (T, S))
    on = (np.cumsum(hold, axis=0) // 97) % 2 == 1
    on ^= rng.random((T, S)) < 0.02
    return on, np.where(on, rng.choice([1, 2, 128, 255], (T, S)), 0)


@needs_cc
@pytest.mark.parametrize("case", CASES)
def test_fed_a_recorded_rollout_the_c_san_is_the_kernel_bit_for_bit(gaits, case, tmp_path):
    gait = _gait(gaits, case)
    dt = float(kernel_numbers(gait)["dt"])
    r = gait.replay(SECONDS, fps=1.0 / dt)  # a frame every step: the whole sensor trace
    frames = r.frames
    assert frames is not None
    bits = np.asarray(frames.bits)[0]
    assert bits.shape == (round(SECONDS / dt), gait.san.n_sensors)
    # what the rollout did: frames hold the controller state before each step (the first one
    # san_init's), and each step's activations
    cs, u = frames.cstate, np.asarray(frames.u)[0]
    assert not np.any(np.asarray(cs.istate)[0, 0]) and not np.any(np.asarray(cs.out)[0, 0])
    did = {"out": np.concatenate([np.asarray(cs.out)[0, 1:], np.asarray(r.cstate.out)]).astype(int),
           "istate": np.concatenate([np.asarray(cs.istate)[0, 1:], np.asarray(r.cstate.istate)]),
           "u": u, "targets": targets_of(kernel_numbers(gait), u)}
    assert_identical(figure7(gait, bits, dt), did)
    for flags in (CFLAGS, GNU_FLAGS):
        exe = compile_c(tmp_path, san_c.header(gait), {"main.c": DRIVER}, flags)
        got = run_c(exe, bits.astype(int), dt, gait.san.n_nodes, gait.san.n_actuators)
        assert_identical(got, did)
    # a trace that exercises the network: contacts that come and go, nodes switching both ways,
    # more than one activation level
    assert np.abs(np.diff(bits, axis=0)).sum() >= 100
    assert np.abs(np.diff(got["out"], axis=0)).sum() >= 10
    assert len(np.unique(got["u"])) >= 3


@needs_cc
@pytest.mark.parametrize("dt", [None, 0.0037])
def test_any_sensor_trace_and_any_step(gaits, dt, tmp_path):
    """Random sensor bytes (any non-zero byte is "on") and a step other than the gait's: Figure 7
    in plain Python, bit for bit."""
    gait = _gait(gaits, "cart-tune")
    dt = dt if dt is not None else float(kernel_numbers(gait)["dt"])
    on, values = random_trace(1500, gait.san.n_sensors, 3)
    exe = compile_c(tmp_path, san_c.header(gait), {"main.c": DRIVER})
    got = run_c(exe, values, dt, gait.san.n_nodes, gait.san.n_actuators)
    assert_identical(got, figure7(gait, on, dt))
    assert len(np.unique(got["u"])) == 5


def run_program(folder, source: str, flags: list[str], args: list[str]) -> str:
    """The C program ``source`` compiled with ``flags`` and run with ``args``: its output."""
    exe = compile_c(folder, None, {"prog.c": source}, flags)
    return subprocess.run([exe, *args], capture_output=True, text=True, timeout=60, check=True).stdout


def gnu_mode_fuses(folder) -> bool:
    """Whether cc in GNU_FLAGS fuses a * b + c written as two statements into one FMA here:
    (1 + 2^-52)(1 - 2^-53) - 1 is then 2^-53 - 2^-105, rounded twice 0."""
    return run_program(folder, '#include <stdio.h>\n#include <stdlib.h>\nint main(int argc, char **argv)\n{\n'
                       '    double a = strtod(argv[1], NULL), b = strtod(argv[2], NULL), p = a * b;\n'
                       '    (void)argc;\n    printf("%a\\n", p + strtod(argv[3], NULL));\n    return 0;\n}\n',
                       GNU_FLAGS, ["0x1.0000000000001p0", "0x1.fffffffffffffp-1", "-1"]).strip() != "0x0p+0"


@needs_cc
def test_no_compiler_fuses_the_multiply_adds(gaits, tmp_path):
    """In a GNU mode for this CPU, where GCC fuses a multiply and an add into an FMA even across
    statements, the header still rounds each twice (san_mul_add's volatile product): Figure 7 bit
    for bit; without the volatile it would not be, on a CPU with FMA."""
    if not gnu_mode_fuses(tmp_path):
        pytest.skip("cc does not fuse multiply-adds here (a CPU without FMA?)")
    gait = _gait(gaits, "cart-tune")
    dt = float(kernel_numbers(gait)["dt"])
    on, values = random_trace(1500, gait.san.n_sensors, 4)
    want = figure7(gait, on, dt)
    text = san_c.header(gait)
    exe = compile_c(tmp_path, text, {"main.c": DRIVER}, GNU_FLAGS)
    assert_identical(run_c(exe, values, dt, gait.san.n_nodes, gait.san.n_actuators), want)
    assert text.count("volatile double p = a * b;") == 1
    exe = compile_c(tmp_path, text.replace("volatile double p", "double p"), {"main.c": DRIVER}, GNU_FLAGS)
    fused = run_c(exe, values, dt, gait.san.n_nodes, gait.san.n_actuators)
    assert not np.array_equal(fused["istate"].view(np.uint64), want["istate"].view(np.uint64))
    assert not np.array_equal(fused["targets"].view(np.uint64), want["targets"].view(np.uint64))


@needs_cc
@pytest.mark.parametrize("flags, error", [
    (["-ffast-math"], "without -ffast-math"),
    (["-m32", "-ffreestanding"], "excess precision"),  # x87: FLT_EVAL_METHOD 2
    (["-m32", "-ffreestanding", "-msse2", "-mfpmath=sse"], None),  # FLT_EVAL_METHOD 0
    (["-std=gnu99", "-mavx512fp16"], None),  # FLT_EVAL_METHOD 16: _Float16 in itself, double in double
])
def test_arithmetic_it_cannot_keep_is_refused(flags, error, tmp_path):
    """The header's #error where the compiler would not compute in plain binary64: -ffast-math and
    excess precision (x87); not where double is evaluated in double. GCC on x86 flags: skipped
    where cc does not take them."""
    (tmp_path / "empty.c").write_text("int main(void);\nint main(void) { return 0; }\n")
    probe = subprocess.run([str(CC), *CFLAGS, *flags, "-fsyntax-only", str(tmp_path / "empty.c")],
                           capture_output=True, text=True, timeout=60)
    if probe.returncode != 0:
        pytest.skip(f"cc does not take {' '.join(flags)}")
    text = san_c.header_from_arrays(weights=np.zeros((1, 2)), n_hidden=0, k1=[1.0], k2=[-1.0], act_min=[0.0],
                                    act_max=[1.0], sensors=[("s", "touch")], actuators=[("a", "angular")], dt=0.001)
    (tmp_path / "san.h").write_text(text)
    (tmp_path / "main.c").write_text('#include "san.h"\nint main(void);\nint main(void) { return SAN_N_NODES; }\n')
    r = subprocess.run([str(CC), *CFLAGS, *flags, "-fsyntax-only", str(tmp_path / "main.c")],
                       capture_output=True, text=True, timeout=60)
    if error is None:
        assert r.returncode == 0 and not r.stderr, r.stderr
    else:
        assert r.returncode != 0 and "#error" in r.stderr and error in r.stderr, r.stderr


@needs_cc
def test_the_constants_read_back_exactly(tmp_path):
    """Hexadecimal floating constants, which C99 reads exactly: every double, its sign and the
    smallest and largest kept."""
    rng = np.random.default_rng(7)
    x = np.concatenate([rng.standard_normal(200) * 2.0 ** rng.integers(-60, 60, 200), rng.random(50),
                        [0.0, -0.0, 1.0, -2.0, 0.1, 1 / 0.07, 5e-324, -2.2250738585072014e-308, 1.7976931348623157e308]])
    assert san_c._hex(-0.0) == "-0x0p+0" and san_c._hex(2.0) == "0x1p+1" and san_c._hex(0.75) == "0x1.8p-1"
    source = ("#include <stdio.h>\n#include <string.h>\n#include <stdint.h>\n"
              f"static const double x[{len(x)}] = {{{san_c._hex_list(x)}}};\n"
              "int main(void)\n{\n    unsigned i;\n    for (i = 0; i < sizeof x / sizeof x[0]; i++) {\n"
              "        uint64_t b;\n        memcpy(&b, &x[i], sizeof b);\n"
              '        printf("%016llx\\n", (unsigned long long)b);\n    }\n    return 0;\n}\n')
    out = run_program(tmp_path, source, CFLAGS, [])
    assert np.array_equal(np.array([int(v, 16) for v in out.split()], np.uint64), x.view(np.uint64))


@needs_cc
def test_the_header_is_plain_c99_with_the_gaits_numbers(gaits, tmp_path):
    gait = _gait(gaits, "cart-tune")
    text = san_c.header(gait)
    assert re.findall(r"^#include\s*<([^>]+)>", text, re.M) == ["float.h", "stdint.h"]
    assert "\n#include \"" not in text
    assert text.isascii()
    # two translation units, one including it twice and using nothing of it, link into one
    # program without a warning: static definitions, an include guard, no unused-code warnings
    other = '#include "san.h"\n#include "san.h"\nint other(void);\nint other(void) { return SAN_N_NODES; }\n'
    main = ('#include "san.h"\nint other(void);\nint main(void)\n{\n    san_state s;\n'
            '    uint8_t sensors[SAN_N_SENSORS] = {0};\n    double targets[SAN_N_ACTUATORS];\n'
            '    san_init(&s);\n    san_step(&s, sensors, SAN_DT, targets);\n    return other() != SAN_N_NODES;\n}\n')
    for flags in (CFLAGS, [f for f in CFLAGS if f != "-O2"] + ["-O0"]):
        exe = compile_c(tmp_path, text, {"a.c": other, "main.c": main}, flags)
        assert subprocess.run([exe], timeout=60).returncode == 0
    # the constants are the gait's doubles, the very ones the kernel steps it with: per-node
    # rates, tuned ranges, the step; and every weight
    k, g = kernel_numbers(gait), gait_numbers(gait)
    for name in ("k1", "k2", "act_min", "act_max"):
        (values,) = re.findall(rf"^static const double san_{name}\[\w+\] = \{{([^}}]*)\}};", text, re.M)
        got = np.array([float.fromhex(v) for v in values.split(", ")])
        assert np.array_equal(got.view(np.uint64), k[name].view(np.uint64)), name
        assert np.array_equal(got.view(np.uint64), g[name].view(np.uint64)), name
    (dt,) = re.findall(r"^#define SAN_DT (\S+)", text, re.M)
    assert float.fromhex(dt) == k["dt"] == g["dt"] == 0.001
    assert gait.params.k1 is not None and np.array_equal(g["k1"], gait.params.k1)  # the tuned per-node rates
    assert "static const double san_act_min[SAN_N_ACTUATORS] = {-0x1p+1};  /* -2.0 */" in text
    assert "static const double san_act_max[SAN_N_ACTUATORS] = {0x1.2666666666666p+1};  /* 2.3 */" in text
    assert "[-3.0, -1.9] rad" in text  # a tuned sensor range, in the comment that explains S5
    rows = re.findall(r"^    \{([-0-9, ]+)\},  /\* (\S+) \*/$", text, re.M)
    assert [name for _, name in rows] == ["H1", "H2", "H3", "H4", "H5", "A1"]
    assert np.array_equal([[int(v) for v in row.split(",")] for row, _ in rows], gait.weights)


@needs_cc
def test_names_are_safe_in_identifiers_and_comments(tmp_path):
    """Creature names may hold anything printable: comments stay closed, identifiers valid and
    distinct, and no trigraph or line splice sneaks in."""
    sensors = [("toe */ int x; /*", "touch"), ("knee-1", "angle"), ("knee 1", "angle"), ("??/", "touch"), ("ü", "touch")]
    actuators = [("hip\\", "angular"), ("9", "linear")]
    S, A, H = len(sensors), len(actuators), 2
    w = np.random.default_rng(0).integers(-2, 3, (H + A, S + H + A))
    text = san_c.header_from_arrays(weights=w, n_hidden=H, k1=np.full(H + A, 10.0), k2=np.full(H + A, -10.0),
                                    act_min=[-1.0, 0.1], act_max=[1.0, 0.3], sensors=sensors, actuators=actuators,
                                    dt=0.001, sens_min=np.zeros(S), sens_max=np.ones(S), title="t */ ??/")
    assert text.isascii() and "??" not in text
    for ident in ("SAN_SENSOR_TOE_INT_X", "SAN_SENSOR_KNEE_1", "SAN_SENSOR_KNEE_1_2", "SAN_SENSOR_3",
                  "SAN_SENSOR_4", "SAN_ACTUATOR_HIP", "SAN_ACTUATOR_9"):
        assert ident + " = " in text
    use = ('#include "san.h"\nint main(void)\n{\n    san_state s;\n    uint8_t b[SAN_N_SENSORS] = {0};\n'
           '    double t[SAN_N_ACTUATORS];\n    san_init(&s);\n    b[SAN_SENSOR_KNEE_1_2] = 1;\n'
           '    san_step(&s, b, SAN_DT, t);\n    return SAN_ACTUATOR_9 != 1;\n}\n')
    exe = compile_c(tmp_path, text, {"main.c": use})
    assert subprocess.run([exe], timeout=60).returncode == 0


@pytest.mark.parametrize("change, message", [
    ({"weights": np.full((3, 5), 3)}, "weights: expected integers in [-2, 2]"),
    ({"weights": np.zeros((3, 4))}, "weights: expected shape 3x5"),
    ({"k2": [-1.0, 1.0, -1.0]}, "rates: expected k1 > 0 and k2 < 0"),
    ({"act_min": [0.0, 1.0]}, "act_min: expected 1 values, got 2"),
    ({"actuators": []}, "expected at least one actuator"),
    ({"dt": 0.0}, "dt: expected a positive step"),
])
def test_bad_arrays_are_refused(change, message):
    args = {"weights": np.zeros((3, 5)), "n_hidden": 2, "k1": [10.0] * 3, "k2": [-10.0] * 3, "act_min": [0.0],
            "act_max": [1.0], "sensors": [("s", "touch"), ("t", "touch")], "actuators": [("a", "angular")],
            "dt": 0.001, **change}
    with pytest.raises(ValueError, match=re.escape(message)):
        san_c.header_from_arrays(**args)


def test_export_c_writes_the_header(gaits, tmp_path):
    db, ids = gaits
    gid = ids["cart-tune"]
    out = tmp_path / "san.h"
    r = runner.invoke(app, ["export", gid, "--c", "-o", str(out), "--db", db])
    assert r.exit_code == 0, r.output
    assert out.read_text() == san_c.header(_gait(gaits, "cart-tune"))
    r = runner.invoke(app, ["export", gid, "--c", "--db", db])  # stdout
    assert r.exit_code == 0 and r.stdout == out.read_text()
    assert f"gait {gid} of creature \"cart\"" in r.stdout


@pytest.mark.parametrize("args, needle", [
    (["--c", "--toml"], "--toml and --c: expected one of them"),
    (["--c"], "no gait"),
])
def test_export_c_errors_are_one_line(gaits, tmp_path, args, needle):
    db, ids = gaits
    gait = ids["cart-search"] if "--toml" in args else ids["cart-search"].split("#")[0] + "#7"
    out = tmp_path / "san.h"
    r = runner.invoke(app, ["export", gait, *args, "-o", str(out), "--db", db])
    assert r.exit_code == 2, r.output
    assert r.stderr.count("\n") == 1 and needle in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not out.exists()


@needs_cc
def test_the_documented_loop_compiles(gaits, tmp_path):
    """The documented microcontroller loop (docs/san-in-c.md), with stubs for its sensors and
    servos, is valid C99."""
    readme = (ROOT / "docs" / "san-in-c.md").read_text(encoding="utf-8")
    section = readme.split("# A SAN on a microcontroller", 1)[1]
    loop = section.split("```c\n", 1)[1].split("```", 1)[0]
    program = ('#include "san.h"\nstatic void read_sensors(uint8_t *s) { s[0] = 1; }\n'
               "static void servo_hold(int a, double target) { (void)a; (void)target; }\n"
               "int main(void);\nint main(void)\n{\n" + loop + "}\n")
    compile_c(tmp_path, san_c.header(_gait(gaits, "cart-search")), {"main.c": program}, [*CFLAGS, "-c"])
