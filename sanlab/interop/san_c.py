"""A gait's sensor-actuator network as a dependency-free C99 header (``sanlab export GAIT --c``).

The header is the controller alone, for a microcontroller or any C program: the integer weights,
each node's rates k1, k2, the actuators' ranges, and ``san_step``, Figure 7's node (paper §4) for
every node followed by the actuator mapping. It includes ``<stdint.h>`` and ``<float.h>`` (both
compiler headers that a freestanding C99 implementation has too: no libm, no allocation, no
I/O). Everything is ``static`` (the functions ``static inline``), so the header may be included
in several files of one program.

Numbers are ``double`` (IEEE binary64), because the simulator runs the SAN in float64 (the
kernel's ``san``, ``sanlab/sim/_kernel/step.h``): the same operations on the same float64
constants give the same integrator states, binary outputs, activations and targets, bit for bit.
Until the kernel (commit 811b10c) the simulation ran the SAN in float32 under XLA, which fused
``istate + k dt`` into one fused multiply-add (FMA), and this header was float32 with an exact
FMA emulation. The kernel is built with ``-ffp-contract=off``: the product and the sum of each
multiply-add (``istate + k dt``, ``min + u (max - min)``) are rounded each on its own. So are
they in the header, whatever the compiler's flags: ``san_mul_add`` passes the product through a
``volatile``, which no compiler may fuse with the sum (GCC's GNU modes fuse a multiply and an add
even across statements, where the CPU has an FMA). The constants are C99 hexadecimal floating
constants, which a compiler reads exactly (a decimal one only to within a unit in the last place,
C99 6.4.4.2), with their shortest decimals in comments. The header refuses to compile
(``#error``) where ``double`` is not binary64, where double arithmetic runs in excess precision
(``FLT_EVAL_METHOD`` 2: x87 without SSE2) and under ``-ffast-math``.

Units: sensors are bytes (any non-zero byte is "on"); ``dt`` in seconds; targets in the
actuator's units: radians for an angular actuator (the joint angle of its child link relative to
its parent), metres for a linear one (the distance between its two points). The activations
``u`` in [0, 1], the nodes' binary outputs, integrator states and sums are in the state struct.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

import numpy as np

PREFIX = "san"  # of every name the header defines (upper case for macros and enum values)

_UNITS = {"angular": "rad", "linear": "m"}
_SENSOR_UNITS = {"angle": "rad", "tilt": "rad", "eye": "rad", "length": "m"}
_WHAT = {
    "touch": "on while its contact point touches the ground",
    "angle": "on while its joint angle lies in",
    "tilt": "on while its link's world angle lies in",
    "eye": "on while the follow point's direction lies in",
    "length": "on while the distance of its two points lies in",
}


def header(gait: Any) -> str:
    """The C99 header of ``gait`` (a :class:`sanlab.gait.Gait`): its weights, its per-node rates
    (tuned, or from its delays, or the creature file's), and the actuator and sensor ranges of
    the model it is replayed with (tuned values where the gait has them), each the float64 the
    kernel computes with."""
    gait.require_san("written as a C header")
    spec = gait.spec
    san = gait.san
    k1, k2 = gait.params.rates(san.n_nodes, spec.san.delay_on, spec.san.delay_off)
    p = gait.model().params
    sensors = [(s.name, s.kind) for s in spec.sensors]
    actuators = [(a.name, a.kind) for a in spec.actuators]
    return header_from_arrays(
        weights=gait.weights, n_hidden=san.n_hidden, k1=k1, k2=k2, act_min=p.act_min, act_max=p.act_max,
        sensors=sensors, actuators=actuators, dt=p.dt, sens_min=p.sens_min, sens_max=p.sens_max,
        title=f'gait {gait.gait_id} of creature "{spec.name}" ({gait.metric} {gait.score:.6g})')


def header_from_arrays(
    *,
    weights: Any,
    n_hidden: int,
    k1: Any,
    k2: Any,
    act_min: Any,
    act_max: Any,
    sensors: Sequence[tuple[str, str]],
    actuators: Sequence[tuple[str, str]],
    dt: float,
    sens_min: Any = None,
    sens_max: Any = None,
    title: str = "a sensor-actuator network",
) -> str:
    """The header from explicit arrays: integer ``weights`` [N, I] in [-2, 2] (N = H + A nodes,
    I = S + N inputs: sensors, then the nodes' outputs), rates ``k1`` [N] > 0 and ``k2`` [N] < 0
    (1/s), the actuators' ``act_min``/``act_max`` [A] (rad or m), (name, kind) of each sensor
    and actuator, the step ``dt`` (s) the gait was found with, the sensors' ranges [S] for the
    comments (optional) and a ``title`` for the first comment. The numbers are written as the
    float64 values they are (exactly). Raises ValueError on bad shapes or values."""
    w = np.asarray(weights)
    S, A, H = len(sensors), len(actuators), int(n_hidden)
    N, I = H + A, S + H + A
    if H < 0 or A < 1:
        raise ValueError(f"expected at least one actuator and no negative hidden count, got H={H}, A={A}")
    if w.shape != (N, I):
        raise ValueError(f"weights: expected shape {N}x{I} (nodes x inputs), got {'x'.join(map(str, w.shape))}")
    if not np.all(np.isfinite(w)) or np.any(w != np.round(w)) or np.any(np.abs(w) > 2):
        raise ValueError("weights: expected integers in [-2, 2]")
    k1f, k2f = _floats(k1, N, "k1"), _floats(k2, N, "k2")
    if np.any(k1f <= 0) or np.any(k2f >= 0):
        raise ValueError("rates: expected k1 > 0 and k2 < 0 for every node")
    amin, amax = _floats(act_min, A, "act_min"), _floats(act_max, A, "act_max")
    dtf = float(np.float64(dt))
    if not (np.isfinite(dtf) and dtf > 0):
        raise ValueError(f"dt: expected a positive step (s), got {dt}")
    smin = None if sens_min is None else _floats(sens_min, S, "sens_min")
    smax = None if sens_max is None else _floats(sens_max, S, "sens_max")

    P, M = PREFIX, PREFIX.upper()
    sensor_ids = _identifiers([n for n, _ in sensors])
    actuator_ids = _identifiers([n for n, _ in actuators])
    node_names = [f"H{h + 1}" for h in range(H)] + [n for n, _ in actuators]
    input_names = [n for n, _ in sensors] + node_names

    out: list[str] = []
    add = out.append
    add(f"""/* {_comment(title)}: its sensor-actuator network (SAN) in C99.
 * Generated by sanlab (`sanlab export GAIT --c`); after van de Panne & Fiume, "Sensor-Actuator
 * Networks", SIGGRAPH 1993, section 4 and Figure 7.
 *
 * Use: {P}_state s; {P}_init(&s); then every control period dt (s):
 *     {P}_step(&s, sensors, dt, targets);
 * sensors[{M}_N_SENSORS]: non-zero while a sensor is on, else 0, in the order of enum {P}_sensor
 * below; targets[{M}_N_ACTUATORS]: each actuator's desired angle (rad) or length (m), for its
 * servo to hold. s.u[a] is actuator a's activation in [0, 1], s.out[n] node n's binary output,
 * s.istate[n] its integrator state in [0, 1], s.sum[n] its weighted sum.
 *
 * The gait was found stepping the network every {_float(dtf)} s ({M}_DT). The delays are in
 * seconds, so another period runs the same network, but only {M}_DT replays the simulation.
 *
 * Arithmetic: IEEE double precision (binary64), as sanlab's simulator, whose kernel runs the
 * SAN in float64 (since sanlab's commit 811b10c; before, the simulator ran it in float32 and this
 * header did too): fed the same sensor bytes with the same dt, it gives the simulator's outputs,
 * states, activations and targets bit for bit. The simulator rounds the product and the sum of
 * each multiply-add (istate + k dt, min + u (max - min)) each on its own, never as one fused
 * multiply-add (FMA); so does {P}_mul_add below, whatever the compiler's flags. The constants are
 * hexadecimal, which C99 reads exactly, their decimals in comments. This file refuses to compile
 * where double is not binary64, where double arithmetic runs in excess precision (FLT_EVAL_METHOD
 * 2: x87; use SSE2, e.g. gcc -msse2 -mfpmath=sse) and under -ffast-math. On an FPU of single
 * precision only (Cortex-M4F) double runs in the compiler's software routines: slower, and the
 * same bits where those round as IEEE 754 says (libgcc's do).
 */
#ifndef {M}_H
#define {M}_H

#include <float.h>
#include <stdint.h>

#if FLT_RADIX != 2 || DBL_MANT_DIG != 53 || DBL_MAX_EXP != 1024
#error "{P}.h: needs double to be IEEE binary64 (avr-gcc: -mdouble=64)"
#endif
/* double operations evaluated in double: ISO C's 0 and 1, and TS 18661-3's 16, 32 and 64 (GCC's
 * GNU modes where the FPU does half-precision arithmetic); not 2, x87's long double */
#if !(FLT_EVAL_METHOD == 0 || FLT_EVAL_METHOD == 1 || FLT_EVAL_METHOD == 16 || FLT_EVAL_METHOD == 32 \\
      || FLT_EVAL_METHOD == 64)
#error "{P}.h: double is evaluated in excess precision (FLT_EVAL_METHOD): on x87 use SSE2 (gcc -msse2 -mfpmath=sse)"
#endif
#ifdef __FAST_MATH__
#error "{P}.h: compile the file that includes it without -ffast-math (which lets the compiler change the arithmetic)"
#endif

#define {M}_N_SENSORS {S}
#define {M}_N_HIDDEN {H}
#define {M}_N_ACTUATORS {A}
#define {M}_N_NODES {N}    /* hidden nodes, then actuator nodes */
#define {M}_N_INPUTS {I}   /* sensors, then every node's output */
#define {M}_DT {_hex(dtf)}  /* {_float(dtf)} s: the step the gait was found and scored with */

/* a * b + c, the product rounded to double and then the sum, as the simulator does: the product
 * passes through a volatile, which no compiler may fuse with the sum (GCC's GNU modes contract a
 * multiply and an add into an FMA even across statements, on a CPU that has one). */
static inline double {P}_mul_add(double a, double b, double c)
{{
    volatile double p = a * b;
    return p + c;
}}
""")
    add(f"/* Sensors: input i of every node is sensor i (index into sensors[]). */\nenum {P}_sensor {{")
    for i, ((name, kind), ident) in enumerate(zip(sensors, sensor_ids)):
        rng = ""
        if kind != "touch" and smin is not None and smax is not None:
            rng = f" [{_float(smin[i])}, {_float(smax[i])}] {_SENSOR_UNITS.get(kind, '')}".rstrip()
        add(f"    {M}_SENSOR_{ident} = {i},  /* \"{_comment(name)}\": {kind}, {_WHAT.get(kind, 'on or off')}{rng} */")
    add("};\n")
    add(f"/* Actuators: node {M}_N_HIDDEN + a drives actuator a (index into targets[]). */\nenum {P}_actuator {{")
    for a, ((name, kind), ident) in enumerate(zip(actuators, actuator_ids)):
        unit = _UNITS.get(kind, "")
        add(f"    {M}_ACTUATOR_{ident} = {a},  /* \"{_comment(name)}\": {kind}, target in "
            f"[{_float(amin[a])}, {_float(amax[a])}] {unit} */")
    add("};\n")

    add(f"/* Weights [node][input], integers in [-2, 2] (section 4). Columns: "
        f"{_comment(', '.join(input_names), 200)}. */")
    add(f"static const int8_t {P}_weights[{M}_N_NODES][{M}_N_INPUTS] = {{")
    for n in range(N):
        row = ", ".join(f"{int(v):2d}" for v in w[n])
        add(f"    {{{row}}},  /* {_comment(node_names[n])} */")
    add("};\n")
    add("/* Rates per node (1/s): the integrator climbs by k1 dt while the weighted sum is positive,\n"
        " * else falls by |k2| dt; T_on = 1/k1 and T_off = -1/k2 are the node's delays (section 4). */")
    add(f"static const double {P}_k1[{M}_N_NODES] = {{{_hex_list(k1f)}}};  /* {_float_list(k1f)} */")
    add(f"static const double {P}_k2[{M}_N_NODES] = {{{_hex_list(k2f)}}};  /* {_float_list(k2f)} */\n")
    add("/* Actuator ranges: target = min + u (max - min), rad (angular) or m (linear). */")
    add(f"static const double {P}_act_min[{M}_N_ACTUATORS] = {{{_hex_list(amin)}}};  /* {_float_list(amin)} */")
    add(f"static const double {P}_act_max[{M}_N_ACTUATORS] = {{{_hex_list(amax)}}};  /* {_float_list(amax)} */\n")
    add(f"""typedef struct {P}_state {{
    double istate[{M}_N_NODES];  /* integrator state in [0, 1] (Figure 7's istate) */
    uint8_t out[{M}_N_NODES];    /* binary output, 0 or 1 (an input of every node) */
    int sum[{M}_N_NODES];        /* last weighted sum of the inputs (an integer) */
    double u[{M}_N_ACTUATORS];   /* last activation in [0, 1] of each actuator */
}} {P}_state;

/* All nodes off with istate 0, as at the start of a simulation (section 4). */
static inline void {P}_init({P}_state *s)
{{
    int n;
    for (n = 0; n < {M}_N_NODES; n++) {{
        s->istate[n] = 0.0;
        s->out[n] = 0;
        s->sum[n] = 0;
    }}
    for (n = 0; n < {M}_N_ACTUATORS; n++)
        s->u[n] = 0.0;
}}

/* One step of dt seconds: every node sums its weighted inputs (the sensors and every node's
 * output of the previous step, so the order of the nodes does not matter), integrates with
 * hysteresis (Figure 7), and each actuator node's sum, bounded to [-2, 2], picks its target
 * linearly in [min, max]. Writes targets[{M}_N_ACTUATORS] (rad or m) and updates s. */
static inline void {P}_step({P}_state *s, const uint8_t sensors[{M}_N_SENSORS], double dt,
                            double targets[{M}_N_ACTUATORS])
{{
    int n, i;
    for (n = 0; n < {M}_N_NODES; n++) {{  /* all sums first: from the outputs before this step */
        int sum = 0;
        for (i = 0; i < {M}_N_SENSORS; i++)
            if (sensors[i])
                sum += {P}_weights[n][i];
        for (i = 0; i < {M}_N_NODES; i++)
            if (s->out[i])
                sum += {P}_weights[n][{M}_N_SENSORS + i];
        s->sum[n] = sum;
    }}
    for (n = 0; n < {M}_N_NODES; n++) {{  /* Figure 7 */
        double rate = s->sum[n] > 0 ? {P}_k1[n] : {P}_k2[n];
        double istate = {P}_mul_add(rate, dt, s->istate[n]);  /* istate + k dt */
        if (istate > 1.0) istate = 1.0;
        if (istate < 0.0) istate = 0.0;
        if (s->out[n] == 1 && istate == 0.0) s->out[n] = 0;
        if (s->out[n] == 0 && istate == 1.0) s->out[n] = 1;
        s->istate[n] = istate;
    }}
    for (n = 0; n < {M}_N_ACTUATORS; n++) {{  /* the actuator mapping (section 4) */
        int sum = s->sum[{M}_N_HIDDEN + n];
        double span = {P}_act_max[n] - {P}_act_min[n];
        if (sum > 2) sum = 2;
        if (sum < -2) sum = -2;
        s->u[n] = (double)(sum + 2) * 0.25;  /* exact: 0, 1/4, 1/2, 3/4 or 1 */
        targets[n] = {P}_mul_add(s->u[n], span, {P}_act_min[n]);  /* min + u (max - min) */
    }}
}}

#endif /* {M}_H */
""")
    return "\n".join(out)


def _floats(x: Any, n: int, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64).reshape(-1)
    if a.shape != (n,):
        raise ValueError(f"{what}: expected {n} values, got {a.size}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: expected finite values")
    return a


def _float(x: Any) -> str:
    """The shortest decimal that reads back as float64 ``x``, for the comments."""
    return np.format_float_positional(np.float64(x), unique=True, trim="0")


def _hex(x: Any) -> str:
    """Float64 ``x`` as a C99 hexadecimal floating constant, which the compiler reads exactly
    (C99 6.4.4.2: a decimal one may be read as a neighbour of the nearest double): trailing
    zeros of the fraction dropped, the sign kept (-0.0 is ``-0x0p+0``)."""
    sign, rest = ("-", float(x).hex()[1:]) if np.signbit(x) else ("", float(x).hex())
    mant, exp = rest.split("p")
    mant = mant.rstrip("0").rstrip(".")
    return f"{sign}{mant}p{exp}"


def _float_list(a: np.ndarray) -> str:
    return ", ".join(_float(v) for v in a)


def _hex_list(a: np.ndarray) -> str:
    return ", ".join(_hex(v) for v in a)


def _identifiers(names: Sequence[str]) -> list[str]:
    """Upper-case C identifier tails for ``names`` (A-Z, 0-9, _), unique: a name with nothing
    usable is its index; a repeated one gets its index appended."""
    out: list[str] = []
    for i, name in enumerate(names):
        ident = re.sub(r"[^A-Z0-9]+", "_", name.upper()).strip("_") or str(i)
        while ident in out:
            ident = f"{ident}_{i}"
        out.append(ident)
    return out


def _comment(text: str, limit: int = 80) -> str:
    """``text`` safe inside a C comment: printable ASCII (others escaped), no comment start or
    end, no trigraph, no line splice; at most ``limit`` characters."""
    t = text.encode("ascii", "backslashreplace").decode("ascii")
    t = "".join(c if c.isprintable() else "?" for c in t).replace("\\", "/")
    while "/*" in t or "*/" in t or "??" in t:
        t = t.replace("/*", "/ *").replace("*/", "* /").replace("??", "? ?")
    return t if len(t) <= limit else t[: limit - 3] + "..."
