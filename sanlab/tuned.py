"""A stored gait in the creature file's terms: its parameters in the file's units (degrees,
N·m/deg, seconds, metres, kilograms), its weight matrix by the file's sensor, hidden and actuator
names, and the creature file with a tuned gait's parameters applied (``sanlab show GAIT``,
``sanlab show GAIT --network``, ``sanlab export GAIT --toml``).

What a tuned gait changes (``sanlab.search.space``): per-node delays, actuator ranges and gains,
range-sensor ranges, and with ``--morphology`` a length scale per link (its outline, contacts,
centre of mass and attachment points scale with it, its mass as tuned), or, for a file with free
numbers, the values of those (``sanlab.creature.free``). Everything but per-node
delays has a place in the file; delays that differ between nodes do not ([san] holds one pair),
so :func:`apply_to_file` writes them as a comment and leaves [san] as it was.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sanlab import __version__
from sanlab.creature import loads
from sanlab.creature.spec import Creature
from sanlab.gait import Gait

PER_DEG = 180.0 / math.pi  # N m/rad -> N m/deg: divide by it; rad -> deg: multiply


def node_names(spec: Creature) -> tuple[list[str], list[str]]:
    """(inputs, nodes) of the creature's SANs, by name: inputs are the sensors, then the hidden
    nodes (H1, H2, ...), then the actuator nodes (named after their actuators); nodes are the
    hidden and the actuator nodes. Shapes: I = S + H + A and N = H + A."""
    hidden = [f"H{i + 1}" for i in range(spec.n_hidden)]
    nodes = hidden + [a.name for a in spec.actuators]
    return [s.name for s in spec.sensors] + nodes, nodes


def network_table(gait: Gait) -> dict:
    """The gait's weights by name: {"inputs": [I], "nodes": [N], "weights": [N][I] ints in
    [-2, 2]} (row: a node; column: an input it takes)."""
    inputs, nodes = node_names(gait.spec)
    return {"inputs": inputs, "nodes": nodes, "weights": np.asarray(gait.weights, int).tolist()}


def _tuned(gait: Gait) -> dict[str, np.ndarray]:
    """The gait's creature numbers (SI), the file's wherever the gait does not override them."""
    s = gait.spec
    model = gait.params.to_json().get("model") or {}
    nominal = {
        "act_min": [a.min for a in s.actuators], "act_max": [a.max for a in s.actuators],
        "act_ks": [a.ks for a in s.actuators], "act_kd": [a.kd for a in s.actuators],
        "sens_min": [getattr(x, "min", 0.0) for x in s.sensors], "sens_max": [getattr(x, "max", 0.0) for x in s.sensors],
        "mass": [k.mass for k in s.links], "inertia": [k.inertia for k in s.links],
    }
    return {k: np.asarray(model.get(k, v), float) for k, v in nominal.items()}


def _delays(gait: Gait) -> tuple[np.ndarray, np.ndarray]:
    """Each node's T_on, T_off (s) [N]."""
    p, n = gait.params.to_json(), gait.san.n_nodes
    if "k1" in p:
        return 1.0 / np.asarray(p["k1"], float), -1.0 / np.asarray(p["k2"], float)
    on = p.get("delay_on", gait.spec.san.delay_on)
    off = p.get("delay_off", gait.spec.san.delay_off)
    return np.full(n, float(on)), np.full(n, float(off))


def file_values(gait: Gait) -> dict:
    """The gait's parameters in the creature file's units, beside the file's own values:
    {"rows": [{"part", "name", "value", "file", "unit"}]}: each node's delays (s), each
    actuator's range (deg or m) and gains (N·m/deg, N·m·s/deg or N/m, N·s/m), each range
    sensor's range (deg or m), and with a morphology each link's length scale and mass (kg), or
    each free number's value (the file's units). A pattern gait has no SAN: its rows are the
    pattern's period (s), and each actuator's phase and duty (fractions of the period), its two
    targets (the levels in the actuator's units) and gains; ``file`` is None where the file has
    no such number."""
    s, t = gait.spec, _tuned(gait)
    free = gait.params.free
    rows: list[dict[str, Any]] = []

    def add(part: str, name: str, value: float, file: float | None, unit: str) -> None:
        rows.append({"part": part, "name": name, "value": float(value), "file": None if file is None else float(file),
                     "unit": unit})

    if gait.params.pattern is not None:
        p = gait.params.pattern
        add("pattern", "period", p[-1], None, "s")
        for a, act in enumerate(s.actuators):
            ang = act.kind == "angular"
            k, unit = (PER_DEG, "deg") if ang else (1.0, "m")
            lo, hi = t["act_min"][a], t["act_max"][a]
            add(f"actuator {act.name}", "phase", p[4 * a], None, "period")
            add(f"actuator {act.name}", "duty", p[4 * a + 1], None, "period")
            add(f"actuator {act.name}", "low_deg" if ang else "low", (lo + p[4 * a + 2] * (hi - lo)) * k, None, unit)
            add(f"actuator {act.name}", "high_deg" if ang else "high", (lo + p[4 * a + 3] * (hi - lo)) * k, None, unit)
            add(f"actuator {act.name}", "ks", t["act_ks"][a] / k, act.ks / k, "N m/deg" if ang else "N/m")
            add(f"actuator {act.name}", "kd", t["act_kd"][a] / k, act.kd / k, "N m s/deg" if ang else "N s/m")
        return {"rows": rows}

    on, off = _delays(gait)
    if "k1" in gait.params.to_json():  # tuned: each node its own delays
        _, nodes = node_names(s)
        for i, node in enumerate(nodes):
            add(f"node {node}", "T_on", on[i], s.san.delay_on, "s")
            add(f"node {node}", "T_off", off[i], s.san.delay_off, "s")
    else:
        add("san (every node)", "delay_on", on[0], s.san.delay_on, "s")
        add("san (every node)", "delay_off", off[0], s.san.delay_off, "s")
    for a, act in enumerate(s.actuators):
        ang = act.kind == "angular"
        k = PER_DEG if ang else 1.0
        add(f"actuator {act.name}", "min_deg" if ang else "min", t["act_min"][a] * k, act.min * k, "deg" if ang else "m")
        add(f"actuator {act.name}", "max_deg" if ang else "max", t["act_max"][a] * k, act.max * k, "deg" if ang else "m")
        add(f"actuator {act.name}", "ks", t["act_ks"][a] / k, act.ks / k, "N m/deg" if ang else "N/m")
        add(f"actuator {act.name}", "kd", t["act_kd"][a] / k, act.kd / k, "N m s/deg" if ang else "N s/m")
    for i, sen in enumerate(s.sensors):
        if sen.kind == "touch":
            continue
        length = sen.kind == "length"
        k = 1.0 if length else PER_DEG
        add(f"sensor {sen.name}", "min" if length else "min_deg", t["sens_min"][i] * k, sen.min * k, "m" if length else "deg")
        add(f"sensor {sen.name}", "max" if length else "max_deg", t["sens_max"][i] * k, sen.max * k, "m" if length else "deg")
    if free is not None and s.design is not None:
        for f, x in zip(s.design.free, free, strict=True):
            add(f"free number {f.name}", "value", x, f.default, "")
    if gait.params.to_json().get("scale"):
        for i, link in enumerate(s.links):
            add(f"link {link.name}", "length scale", gait.params.to_json()["scale"][i], 1.0, "")
            add(f"link {link.name}", "mass", t["mass"][i], link.mass, "kg")
    return {"rows": rows}


def _num(x: float) -> float:
    """``x`` to 10 significant digits: what a person would write, exact enough to round-trip."""
    return float(f"{float(x):.10g}")


def _scaled(pts: Any, k: float) -> list:
    return [[_num(p[0] * k), _num(p[1] * k)] for p in pts]


def apply_to_file(gait: Gait) -> str:
    """The creature file the gait was found with (its text as stored, comments and layout kept),
    with the gait's parameters written into it in the file's units (see the module docstring);
    raises ValueError if the result is not a valid creature file."""
    import tomlkit

    gait.require_san("written into its creature file")
    s, t = gait.spec, _tuned(gait)
    text = gait.creature_text
    free = gait.params.free
    if s.design is not None:  # the body first, its free numbers written in: the file is this gait's, not a range
        text = s.design.text(text, free if free is not None else s.design.defaults)
    doc = tomlkit.parse(text)
    written_out = "repeat" in doc
    if written_out:  # each repeated part gets values of its own: write the copies out (comments are lost)
        import tomllib

        from sanlab.creature.loader import expand_repeats

        doc = tomlkit.document()
        doc.update(expand_repeats(tomllib.loads(gait.creature_text)))
    acts, sens = doc.get("actuators", []), doc.get("sensors", [])
    for a, act in enumerate(s.actuators):
        ang = act.kind == "angular"
        k = PER_DEG if ang else 1.0
        acts[a]["min_deg" if ang else "min"] = _num(t["act_min"][a] * k)
        acts[a]["max_deg" if ang else "max"] = _num(t["act_max"][a] * k)
        acts[a]["ks"] = _num(t["act_ks"][a] / k)
        acts[a]["kd"] = _num(t["act_kd"][a] / k)
    for i, sen in enumerate(s.sensors):
        if sen.kind == "touch":
            continue
        k = 1.0 if sen.kind == "length" else PER_DEG
        suffix = "" if sen.kind == "length" else "_deg"
        sens[i]["min" + suffix] = _num(t["sens_min"][i] * k)
        sens[i]["max" + suffix] = _num(t["sens_max"][i] * k)
    on, off = _delays(gait)
    note = ""
    if not per_node_delays(gait):
        if "san" not in doc:
            doc["san"] = tomlkit.table()
        doc["san"]["delay_on"] = _num(on[0])
        doc["san"]["delay_off"] = _num(off[0])
    else:
        _, nodes = node_names(s)
        note = ("\n# The gait's node delays differ between nodes, which [san] cannot say (one delay_on and one\n"
                "# delay_off for all): [san] keeps the file's, so this file is not exactly the gait. They were,\n"
                "# as T_on/T_off in s:\n# " +
                ", ".join(f"{n} {a:.4g}/{b:.4g}" for n, a, b in zip(nodes, on, off)) + "\n")
    if gait.params.to_json().get("scale"):
        _apply_morphology(doc, s, np.asarray(gait.params.to_json()["scale"], float), t)
    head = (f"# Written by `sanlab export {gait.gait_id} --toml` (sanlab {__version__}): {s.name} with the\n"
            "# parameters of that gait applied (actuator and sensor ranges and gains, link sizes, and its\n"
            "# node delays where every node has the same).\n" +
            ("# Its [[repeat]] tables are written out, one table per part (its comments are not kept).\n"
             if written_out else ""))
    text = head + note + tomlkit.dumps(doc)
    loads(text, f"the creature file of gait {gait.gait_id}")  # a CreatureError is a ValueError
    return text


def per_node_delays(gait: Gait) -> bool:
    """Whether the gait's node delays differ between nodes, which a creature file cannot say
    ([san] holds one delay_on and one delay_off): its file from :func:`apply_to_file` then keeps
    the file's delays and is not exactly the gait."""
    on, off = _delays(gait)
    return not (np.allclose(on, on[0]) and np.allclose(off, off[0]))


def _apply_morphology(doc: Any, s: Creature, scale: np.ndarray, t: dict[str, np.ndarray]) -> None:
    """Link sizes: what ``sanlab.search.space`` scales, written back into the file's tables."""
    index = {k.name: i for i, k in enumerate(s.links)}
    links = doc["links"]
    for i, link in enumerate(s.links):
        lt, k = links[i], float(scale[i])
        if link.shape.points:
            lt["points"] = _scaled(link.shape.points, k)
        for key in ("contacts", "com"):
            if key in lt:  # defaults follow the scaled outline by themselves
                lt[key] = _scaled(link.contacts, k) if key == "contacts" else _scaled([link.com], k)[0]
        if link.parent is not None and "anchor" in lt:
            lt["anchor"] = _scaled([link.anchor], float(scale[index[link.parent]]))[0]
        lt["mass"] = _num(t["mass"][i])
        if "inertia" in lt:
            lt["inertia"] = _num(t["inertia"][i])

    def point(table: Any, ref: Any) -> None:
        if "at" in table:
            table["at"] = _scaled([ref.at], float(scale[index[ref.link]]))[0]

    for i, sen in enumerate(s.sensors):
        if sen.kind == "eye":
            point(doc["sensors"][i], sen.at)
        elif sen.kind == "length":
            point(doc["sensors"][i]["a"], sen.a)
            point(doc["sensors"][i]["b"], sen.b)
    for i, act in enumerate(s.actuators):
        if act.kind == "linear":
            point(doc["actuators"][i]["a"], act.a)
            point(doc["actuators"][i]["b"], act.b)
    for i, spr in enumerate(s.springs):
        table = doc["springs"][i]
        point(table["a"], spr.a)
        point(table["b"], spr.b)
        table["rest"] = _num(spr.rest)  # tuning keeps each spring's rest length
