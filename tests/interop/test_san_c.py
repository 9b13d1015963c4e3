"""The C99 header of ``sanlab export GAIT --c`` against the Python SAN.

Compiled with the system's C compiler and fed the sensor trace of a recorded rollout (a frame
every step), the header's ``san_step`` switches every node on the same step as ``San.apply``
(float32) and as the rollout itself did, with the same integrator states, activations and
actuator targets, bit for bit: both do the same float32 operations on the same float32 constants,
each multiply-add rounded once where XLA fuses it (a CPU with FMA) and twice where it does not
(``-DSAN_UNFUSED``). The C is compiled as ISO C99 with every warning an error."""

from __future__ import annotations

import functools
import re
import shutil
import subprocess
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.creature import load, read_source
from sanlab.gait import Gait, check_params
from sanlab.interop import san_c
from sanlab.library import Library
from sanlab.san import San, SanParams
from tests.helpers import ROOT

CC = shutil.which("cc")
CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic"]  # ISO C99: no contraction
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

static unsigned long bits_of(float x)
{
    uint32_t b;
    memcpy(&b, &x, sizeof b);
    return (unsigned long)b;
}

int main(int argc, char **argv)
{
    char line[4096];
    san_state s;
    float dt;
    if (argc != 2)
        return 2;
    dt = strtof(argv[1], NULL);
    san_init(&s);
    while (fgets(line, sizeof line, stdin)) {
        uint8_t sensors[SAN_N_SENSORS];
        float targets[SAN_N_ACTUATORS];
        char *p = line;
        int i;
        for (i = 0; i < SAN_N_SENSORS; i++)
            sensors[i] = (uint8_t)strtol(p, &p, 10);
        san_step(&s, sensors, dt, targets);
        for (i = 0; i < SAN_N_NODES; i++)
            printf("%d ", s.out[i]);
        for (i = 0; i < SAN_N_NODES; i++)
            printf("%08lx ", bits_of(s.istate[i]));
        for (i = 0; i < SAN_N_ACTUATORS; i++)
            printf("%08lx ", bits_of(s.u[i]));
        for (i = 0; i < SAN_N_ACTUATORS; i++)
            printf("%08lx ", bits_of(targets[i]));
        printf("\n");
    }
    return 0;
}
"""


def compile_c(folder, text: str, sources: dict[str, str], flags=CFLAGS) -> str:
    """``text`` as folder/san.h and ``sources`` beside it, compiled and linked (not even a warning
    allowed); the program's path."""
    (folder / "san.h").write_text(text)
    for name, src in sources.items():
        (folder / name).write_text(src)
    exe = str(folder / "prog")
    r = subprocess.run([str(CC), *flags, "-I", str(folder), *(str(folder / n) for n in sources), "-o", exe],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and not r.stderr, r.stderr
    return exe


def run_c(exe: str, sensors, dt, n_nodes: int, n_actuators: int) -> dict[str, np.ndarray]:
    """The compiled SAN fed ``sensors`` [T, S] (bytes) with step ``dt`` (s): its outputs [T, N],
    istate [T, N], u [T, A] and targets [T, A] (float32) after each step."""
    stdin = "".join(" ".join(map(str, row)) + "\n" for row in np.asarray(sensors, int).tolist())
    r = subprocess.run([exe, float(np.float32(dt)).hex()], input=stdin, capture_output=True, text=True,
                       timeout=120, check=True)
    rows = [line.split() for line in r.stdout.splitlines()]
    assert len(rows) == len(sensors)
    N, A = n_nodes, n_actuators
    f32 = lambda a, b: np.array([[int(x, 16) for x in row[a:b]] for row in rows], np.uint32).view(np.float32)
    return {"out": np.array([[int(x) for x in row[:N]] for row in rows]), "istate": f32(N, 2 * N),
            "u": f32(2 * N, 2 * N + A), "targets": f32(2 * N + A, 2 * N + 2 * A)}


def run_python(gait: Gait, bits, dt) -> dict[str, np.ndarray]:
    """``San.apply`` (float32) fed ``bits`` [T, S] with step ``dt``: outputs, istate and u after
    each step, and the targets the simulator makes of u."""
    san = gait.san

    @jax.jit
    def run(params, bits, dt):  # the parameters as arguments, as in a rollout: XLA folds constants
        def body(state, b):
            state, u = san.apply(params, state, b, dt)
            return state, (state.out, state.istate, u)

        return jax.lax.scan(body, san.init(params, None), bits)[1]

    params = SanParams(*(x[0] for x in gait.san_params("float32")))
    out, istate, u = (np.asarray(x) for x in run(params, jnp.asarray(bits, jnp.float32), jnp.float32(dt)))
    return {"out": out.astype(int), "istate": istate, "u": u, "targets": targets_of(gait, u, xla_fuses())}


@functools.cache
def xla_fuses() -> bool:
    """Whether XLA rounds ``istate + k dt`` once here (a fused multiply-add, as on any CPU with
    FMA): then 0.01 - 10 x 0.001 is float32(0.001)'s rounding error, not 0."""
    dt, k = np.float32(0.001), np.float32(-10.0)
    return float(jax.jit(lambda i, k, dt: i + k * dt)(-k * dt, k, dt)) != 0.0


def mode(fused: bool) -> list[str]:
    """The compiler flags of the header's arithmetic: fused multiply-adds (its default) or not."""
    return [] if fused else ["-DSAN_UNFUSED"]


def fma32(a, b, c) -> np.float32:
    """a b + c rounded once to the nearest float32 (ties to even): exact rational arithmetic."""
    x = Fraction(float(a)) * Fraction(float(b)) + Fraction(float(c))
    f = np.float32(float(x))  # within one float32 step of the answer
    near = [np.nextafter(f, np.float32(-np.inf)), f, np.nextafter(f, np.float32(np.inf))]
    return min(near, key=lambda v: (abs(Fraction(float(v)) - x), int(np.float32(v).view(np.uint32)) & 1))


def mul_add(a, b, c, fused: bool) -> np.float32:
    a, b, c = np.float32(a), np.float32(b), np.float32(c)
    return fma32(a, b, c) if fused else np.float32(a * b) + c


def targets_of(gait: Gait, u, fused: bool) -> np.ndarray:
    """The actuator targets [T, A] of activations u as the simulator computes them,
    ``act_min + u (act_max - act_min)`` in float32 with the gait's model's ranges."""
    p = gait.model("float32").params
    lo, hi = np.asarray(p.act_min, np.float32), np.asarray(p.act_max, np.float32)
    u = np.asarray(u, np.float32)
    table = {(a, v): mul_add(v, hi[a] - lo[a], lo[a], fused) for a in range(len(lo)) for v in np.unique(u[:, a])}
    return np.array([[table[a, v] for a, v in enumerate(row)] for row in u], np.float32).reshape(u.shape)


def figure7(gait: Gait, on, dt, fused: bool) -> dict[str, np.ndarray]:
    """Figure 7 step by step in plain Python (no JAX): the reference for either arithmetic."""
    w = np.asarray(gait.weights, int)
    k1, k2 = (np.asarray(x, np.float32) for x in gait.params.rates(gait.san.n_nodes, gait.spec.san.delay_on,
                                                                      gait.spec.san.delay_off))
    H = gait.san.n_hidden
    istate, out = np.zeros(len(w), np.float32), np.zeros(len(w), int)
    rows = {"out": [], "istate": [], "u": []}
    for bits in np.asarray(on, bool):
        total = w @ np.concatenate([bits.astype(int), out])
        for n in range(len(w)):
            x = mul_add(k1[n] if total[n] > 0 else k2[n], dt, istate[n], fused)
            istate[n] = min(max(x, np.float32(0)), np.float32(1))
            out[n] = 0 if out[n] == 1 and istate[n] == 0 else 1 if out[n] == 0 and istate[n] == 1 else out[n]
        rows["out"].append(out.copy())
        rows["istate"].append(istate.copy())
        rows["u"].append(((np.clip(total[H:], -2, 2) + 2) * 0.25).astype(np.float32))
    res = {k: np.array(v) for k, v in rows.items()}
    res["targets"] = targets_of(gait, res["u"], fused)
    return res


def assert_identical(got: dict, want: dict) -> None:
    for key in ("out", "istate", "u", "targets"):
        a, b = np.asarray(got[key]), np.asarray(want[key])
        assert a.shape == b.shape, key
        if a.dtype == np.float32:  # bit for bit: compare the bit patterns
            a, b = a.view(np.uint32), np.asarray(b, np.float32).view(np.uint32)
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


@needs_cc
@pytest.mark.parametrize("case", CASES)
def test_fed_a_recorded_rollout_the_c_san_is_the_python_san_bit_for_bit(gaits, case, tmp_path):
    gait = _gait(gaits, case)
    dt = gait.model("float32").params.dt
    r = gait.replay(SECONDS, fps=1.0 / float(dt))  # a frame every step: the whole sensor trace
    frames = r.frames
    assert frames is not None
    bits = np.asarray(frames.bits)[0]
    assert bits.shape == (round(SECONDS / float(dt)), gait.san.n_sensors)
    exe = compile_c(tmp_path, san_c.header(gait), {"main.c": DRIVER}, CFLAGS + mode(xla_fuses()))
    got = run_c(exe, bits.astype(int), dt, gait.san.n_nodes, gait.san.n_actuators)

    assert_identical(got, run_python(gait, bits, dt))
    # ... and what the rollout itself did: frames hold the controller state before each step
    cs, u = frames.cstate, np.asarray(frames.u)[0]
    after = {"out": np.concatenate([np.asarray(cs.out)[0, 1:], np.asarray(r.cstate.out)]).astype(int),
             "istate": np.concatenate([np.asarray(cs.istate)[0, 1:], np.asarray(r.cstate.istate)]),
             "u": u, "targets": targets_of(gait, u, xla_fuses())}
    assert_identical(got, after)
    # a trace that exercises the network: contacts that come and go, nodes switching both ways,
    # more than one activation level
    assert np.abs(np.diff(bits, axis=0)).sum() >= 100
    assert np.abs(np.diff(got["out"], axis=0)).sum() >= 10
    assert len(np.unique(got["u"])) >= 3


@needs_cc
@pytest.mark.parametrize("dt", [None, 0.0037])
def test_any_sensor_trace_and_any_step(gaits, dt, tmp_path):
    """Random sensor bytes (any non-zero byte is "on") that switch far more often than contacts
    do, and a step other than the gait's: Figure 7 in plain Python, bit for bit, in either
    arithmetic, and the Python SAN in XLA's."""
    gait = _gait(gaits, "cart-tune")
    dt = np.float32(dt if dt is not None else gait.model("float32").params.dt)
    rng = np.random.default_rng(3)
    T, S = 1500, gait.san.n_sensors
    hold = rng.integers(1, 60, (T, S))  # each sensor keeps its value for a random while
    on = (np.cumsum(hold, axis=0) // 97) % 2 == 1
    on ^= rng.random((T, S)) < 0.02  # and flickers now and then
    values = np.where(on, rng.choice([1, 2, 128, 255], (T, S)), 0)
    for fused in (True, False):
        exe = compile_c(tmp_path, san_c.header(gait), {"main.c": DRIVER}, CFLAGS + mode(fused))
        got = run_c(exe, values, dt, gait.san.n_nodes, gait.san.n_actuators)
        assert_identical(got, figure7(gait, on, dt, fused))
        if fused == xla_fuses():
            assert_identical(got, run_python(gait, on, dt))
        assert len(np.unique(got["u"])) == 5


@needs_cc
def test_the_fused_multiply_add_is_rounded_once(tmp_path):
    """SAN_FMA, the header's FMA in double precision, against exact rational arithmetic: on
    random operands of every scale and on the cases where rounding the double sum to nearest
    first would be wrong (an exact result just off a float32 midpoint); fmaf from math.h in its
    place gives the same."""
    rng = np.random.default_rng(5)
    n = 3000
    a = (rng.standard_normal(n) * 2.0 ** rng.integers(-30, 30, n)).astype(np.float32)
    b = (rng.standard_normal(n) * 2.0 ** rng.integers(-30, 30, n)).astype(np.float32)
    c = (rng.standard_normal(n) * 2.0 ** rng.integers(-60, 60, n)).astype(np.float32)
    near = rng.random(n) < 0.5  # half of them: c near a b, so that they nearly cancel
    c[near] = (-a[near].astype(np.float64) * b[near] * (1 + rng.standard_normal(near.sum()) * 1e-6)).astype(np.float32)
    # (1 + 2^-23)(1 - 2^-23) = 1 - 2^-46: 2^24 + 2 + that is 2^24 + 3 - 2^-46, just below the
    # midpoint 2^24 + 3, which the double sum rounds to (and that midpoint to even, 2^24 + 4);
    # the other way round from 2^24 + 2 - that; at many scales and both signs
    traps = []
    for e in range(-40, 40, 3):
        for sign in (1.0, -1.0):
            for m in (1, 3, 5):  # 2^23 + m: odd
                x = sign * np.ldexp(1.0 + 2.0 ** -23, e)
                y = 1.0 - 2.0 ** -23
                z = sign * np.ldexp(2.0 ** 24 + 2 * m, e)
                traps += [(x, y, z), (-x, y, z)]
    t = np.array(traps, np.float64).astype(np.float32)
    a, b, c = np.concatenate([a, t[:, 0]]), np.concatenate([b, t[:, 1]]), np.concatenate([c, t[:, 2]])
    want = np.array([fma32(*abc) for abc in zip(a, b, c)], np.float32)
    assert np.any(want != ((a.astype(np.float64) * b + c).astype(np.float32)))  # the traps trap
    program = ('#include <stdio.h>\n#include <stdlib.h>\n#include <string.h>\n{pre}#include "san.h"\n'
               'int main(void)\n{{\n    char line[256];\n    while (fgets(line, sizeof line, stdin)) {{\n'
               '        char *p = line;\n        float a = strtof(p, &p), b = strtof(p, &p), c = strtof(p, &p);\n'
               '        float r = SAN_FMA(a, b, c);\n        uint32_t bits;\n        memcpy(&bits, &r, sizeof bits);\n'
               '        printf("%08lx\\n", (unsigned long)bits);\n    }}\n    return 0;\n}}\n')
    stdin = "".join(f"{float(x).hex()} {float(y).hex()} {float(z).hex()}\n" for x, y, z in zip(a, b, c))
    text = san_c.header_from_arrays(weights=np.zeros((1, 2)), n_hidden=0, k1=[1.0], k2=[-1.0], act_min=[0.0],
                                    act_max=[1.0], sensors=[("s", "touch")], actuators=[("a", "angular")], dt=0.001)
    for pre, libs in (("", []), ("#include <math.h>\n#define SAN_FMA(a, b, c) fmaf(a, b, c)\n", ["-lm"])):
        (tmp_path / "main.c").write_text(program.format(pre=pre))
        exe = str(tmp_path / "fma")
        (tmp_path / "san.h").write_text(text)
        r = subprocess.run([str(CC), *CFLAGS, "-I", str(tmp_path), str(tmp_path / "main.c"), "-o", exe, *libs],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0 and not r.stderr, r.stderr
        out = subprocess.run([exe], input=stdin, capture_output=True, text=True, timeout=60, check=True).stdout
        got = np.array([int(x, 16) for x in out.split()], np.uint32)
        bad = np.flatnonzero(got != want.view(np.uint32))
        assert bad.size == 0, f"{pre or 'SAN_FMA'}: {a[bad[0]]!r} * {b[bad[0]]!r} + {c[bad[0]]!r}"


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
            '    uint8_t sensors[SAN_N_SENSORS] = {0};\n    float targets[SAN_N_ACTUATORS];\n'
            '    san_init(&s);\n    san_step(&s, sensors, SAN_DT, targets);\n    return other() != SAN_N_NODES;\n}\n')
    for flags in (CFLAGS, [f for f in CFLAGS if f != "-O2"] + ["-O0"]):
        exe = compile_c(tmp_path, text, {"a.c": other, "main.c": main}, flags)
        assert subprocess.run([exe], timeout=60).returncode == 0
    # the constants are the gait's: per-node rates, tuned ranges, every weight
    k1 = np.asarray(gait.params.k1, np.float32)
    assert f"static const float san_k1[SAN_N_NODES] = {{{', '.join(san_c._float(v) + 'f' for v in k1)}}};" in text
    assert "static const float san_act_min[SAN_N_ACTUATORS] = {-2.0f};" in text
    assert "static const float san_act_max[SAN_N_ACTUATORS] = {2.3f};" in text
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
           '    float t[SAN_N_ACTUATORS];\n    san_init(&s);\n    b[SAN_SENSOR_KNEE_1_2] = 1;\n'
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
               "static void servo_hold(int a, float target) { (void)a; (void)target; }\n"
               "int main(void);\nint main(void)\n{\n" + loop + "}\n")
    compile_c(tmp_path, san_c.header(_gait(gaits, "cart-search")), {"main.c": program}, [*CFLAGS, "-c"])
