"""A gait's sensor-actuator network as a dependency-free C99 header (``sanlab export GAIT --c``).

The header is the controller alone, for a microcontroller or any C program: the integer weights,
each node's rates k1, k2, the actuators' ranges, and ``san_step``, Figure 7's node (paper §4) for
every node followed by the actuator mapping. It includes ``<stdint.h>`` and ``<float.h>`` (both
compiler headers that a freestanding C99 implementation has too: no libm, no allocation, no
I/O). Everything is ``static`` (the functions ``static inline``), so the header may be included
in several files of one program.

Numbers are ``float`` (IEEE single precision), because the search and replays run the SAN in
float32 (``sanlab.san.San.apply``): the same operations on the same float32 constants (each
written as the shortest decimal that reads back as the float32 sanlab uses) give the same
integrator states, binary outputs and targets, bit for bit. One detail decides that: XLA
compiles ``istate + k dt`` (and the simulator's ``min + u (max - min)``) into a fused
multiply-add, rounded once, on CPUs that have one (x86-64 since 2013, ARMv8; GPUs as a rule
too, which these tests do not check). The header does the same (``SAN_FMA``: an exact emulation in double precision by default, no libm;
``fmaf`` or an FPU instruction may replace it); ``-DSAN_UNFUSED`` rounds the product and the
sum each on its own instead, as XLA does on a CPU without FMA. Either way the program must be
compiled without ``-ffast-math``.

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
    the model it is replayed with (tuned values where the gait has them), in float32."""
    spec = gait.spec
    san = gait.san
    k1, k2 = gait.params.rates(san.n_nodes, spec.san.delay_on, spec.san.delay_off)
    p = gait.model("float64").params
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
    comments (optional) and a ``title`` for the first comment. Raises ValueError on bad shapes
    or values."""
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
    dtf = np.float32(dt)
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
 * Arithmetic: single-precision float, as sanlab's float32 simulation: fed the same sensor bytes
 * with the same dt, it gives sanlab's outputs, states and targets bit for bit. sanlab's compiled
 * step rounds each multiply-add (istate + k dt, min + u (max - min)) once, as a fused
 * multiply-add (XLA does so on a CPU with FMA); so does {M}_FMA below, exactly, in double
 * precision (no libm). Define {M}_FMA before including this file to use a faster exact one, e.g.
 *     #include <math.h>
 *     #define {M}_FMA(a, b, c) fmaf(a, b, c)   (an FPU's vfma.f32 on a Cortex-M4F or M7)
 * or define {M}_UNFUSED to round the product and the sum each on its own (sanlab on a CPU without
 * FMA). Never compile with -ffast-math.
 */
#ifndef {M}_H
#define {M}_H

#include <float.h>
#include <stdint.h>

#define {M}_N_SENSORS {S}
#define {M}_N_HIDDEN {H}
#define {M}_N_ACTUATORS {A}
#define {M}_N_NODES {N}    /* hidden nodes, then actuator nodes */
#define {M}_N_INPUTS {I}   /* sensors, then every node's output */
#define {M}_DT {_float(dtf)}f  /* s: the step the gait was found and scored with */

#if defined({M}_UNFUSED)
/* a * b + c rounded twice; each its own statement, so that no compiler fuses them (an ISO C
 * compiler fuses only within one expression; GCC's GNU modes also across statements unless
 * -ffp-contract=off, which -std=c99 implies) */
static inline float {P}_mul_add(float a, float b, float c)
{{
    float p = a * b;
    return p + c;
}}
#undef {M}_FMA
#define {M}_FMA(a, b, c) {P}_mul_add(a, b, c)
#elif !defined({M}_FMA)
#if DBL_MANT_DIG < 53 || FLT_EVAL_METHOD < 0 || FLT_EVAL_METHOD > 1
#error "no IEEE double, or excess precision: define {M}_FMA (e.g. fmaf of math.h) or {M}_UNFUSED"
#endif
/* a * b + c rounded once to float, as an FMA instruction does: the product of two floats is exact
 * in double; the sum is rounded to odd in double (Knuth's TwoSum gives its exact error, and an
 * inexact sum takes the odd one of its two neighbours), and a double rounded to odd rounds to
 * nearest float correctly, having at least 24 + 2 bits (Boldo & Melquiond 2008). */
static inline float {P}_fma(float a, float b, float c)
{{
    double p = (double)a * (double)b;
    double s = p + (double)c;
    double back = s - p;
    double e = (p - (s - back)) + ((double)c - back);  /* s + e == p + c exactly */
    if (e != 0.0) {{
        union {{ double d; uint64_t u; }} v;
        v.d = s;
        if ((v.u & 1u) == 0)  /* even: its neighbour on e's side is odd */
            v.u = ((e > 0.0) == (s > 0.0)) ? v.u + 1u : v.u - 1u;
        s = v.d;
    }}
    return (float)s;
}}
#define {M}_FMA(a, b, c) {P}_fma(a, b, c)
#endif
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
    add(f"static const float {P}_k1[{M}_N_NODES] = {{{_float_list(k1f)}}};")
    add(f"static const float {P}_k2[{M}_N_NODES] = {{{_float_list(k2f)}}};\n")
    add("/* Actuator ranges: target = min + u (max - min), rad (angular) or m (linear). */")
    add(f"static const float {P}_act_min[{M}_N_ACTUATORS] = {{{_float_list(amin)}}};")
    add(f"static const float {P}_act_max[{M}_N_ACTUATORS] = {{{_float_list(amax)}}};\n")
    add(f"""typedef struct {P}_state {{
    float istate[{M}_N_NODES];  /* integrator state in [0, 1] (Figure 7's istate) */
    uint8_t out[{M}_N_NODES];   /* binary output, 0 or 1 (an input of every node) */
    int sum[{M}_N_NODES];       /* last weighted sum of the inputs (an integer) */
    float u[{M}_N_ACTUATORS];   /* last activation in [0, 1] of each actuator */
}} {P}_state;

/* All nodes off with istate 0, as at the start of a simulation (section 4). */
static inline void {P}_init({P}_state *s)
{{
    int n;
    for (n = 0; n < {M}_N_NODES; n++) {{
        s->istate[n] = 0.0f;
        s->out[n] = 0;
        s->sum[n] = 0;
    }}
    for (n = 0; n < {M}_N_ACTUATORS; n++)
        s->u[n] = 0.0f;
}}

/* One step of dt seconds: every node sums its weighted inputs (the sensors and every node's
 * output of the previous step, so the order of the nodes does not matter), integrates with
 * hysteresis (Figure 7), and each actuator node's sum, bounded to [-2, 2], picks its target
 * linearly in [min, max]. Writes targets[{M}_N_ACTUATORS] (rad or m) and updates s. */
static inline void {P}_step({P}_state *s, const uint8_t sensors[{M}_N_SENSORS], float dt,
                            float targets[{M}_N_ACTUATORS])
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
        float rate = s->sum[n] > 0 ? {P}_k1[n] : {P}_k2[n];
        float istate = {M}_FMA(rate, dt, s->istate[n]);  /* istate + k dt */
        if (istate > 1.0f) istate = 1.0f;
        if (istate < 0.0f) istate = 0.0f;
        if (s->out[n] == 1 && istate == 0.0f) s->out[n] = 0;
        if (s->out[n] == 0 && istate == 1.0f) s->out[n] = 1;
        s->istate[n] = istate;
    }}
    for (n = 0; n < {M}_N_ACTUATORS; n++) {{  /* the actuator mapping (section 4) */
        int sum = s->sum[{M}_N_HIDDEN + n];
        float span = {P}_act_max[n] - {P}_act_min[n];
        if (sum > 2) sum = 2;
        if (sum < -2) sum = -2;
        s->u[n] = (float)(sum + 2) * 0.25f;  /* exact: 0, 1/4, 1/2, 3/4 or 1 */
        targets[n] = {M}_FMA(s->u[n], span, {P}_act_min[n]);  /* min + u (max - min) */
    }}
}}

#endif /* {M}_H */
""")
    return "\n".join(out)


def _floats(x: Any, n: int, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64).reshape(-1)
    if a.shape != (n,):
        raise ValueError(f"{what}: expected {n} values, got {a.size}")
    f = a.astype(np.float32)
    if not np.all(np.isfinite(f)):
        raise ValueError(f"{what}: expected finite values")
    return f


def _float(x: Any) -> str:
    """The shortest decimal that reads back as float32 ``x`` (a C float literal without its
    ``f``): the compiler then rounds it to exactly the float sanlab computes with."""
    return np.format_float_positional(np.float32(x), unique=True, trim="0")


def _float_list(a: np.ndarray) -> str:
    return ", ".join(_float(v) + "f" for v in a)


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
