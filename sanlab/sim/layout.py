"""The kernel's tables, declared once: every table's columns with their names, widths and units.

Everything else is made from this declaration or checked against it:

- ``_kernel/layout.h``, the C++ view (a struct per table row, so the kernel reads ``a.ks``, not
  ``f[2]``; enums of the counts, kinds and accumulators), is written by ``python -m
  sanlab.sim.layout`` and compared with :func:`header` by ``tests/sim/test_layout.py``;
- ``kernel.pack`` and ``kernel.numbers`` fill the tables by column name (:meth:`Table.build`);
- the Python constants (``kernel.L_PARENT``, ``kernel.W_DT``, ...) are offsets of this
  declaration, and the ctypes signatures are :data:`ROLLOUT_ARGS` and friends, which the test
  compares with ``_kernel/kernel.cpp``'s entry points.

A table is [rows, width] (one row per link, contact, ...; ``wi`` and ``wf`` one row for the
world); a column of several parts (a point's x and y) takes one value per part. Units SI.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Column:
    """One named column: ``parts`` its sub-columns (e.g. ("x", "y")), none for a single value."""

    name: str
    unit: str = ""
    doc: str = ""
    parts: tuple[str, ...] = ()

    @property
    def width(self) -> int:
        return max(1, len(self.parts))

    @property
    def fields(self) -> list[str]:
        """The C++ struct's fields: the name, or name_part for each part."""
        return [f"{self.name}_{p}" for p in self.parts] if self.parts else [self.name]


@dataclass(frozen=True)
class Table:
    """A table of the kernel: ``name`` (``kernel.Packed``'s field), ``dtype`` ("int32" or
    "float64"), ``rows`` (the count it has a row for, a name of :data:`DIMS`; "world": one row),
    ``struct`` (the C++ row struct's name) and its columns."""

    name: str
    dtype: str
    rows: str
    struct: str
    doc: str
    columns: tuple[Column, ...]

    @property
    def width(self) -> int:
        return sum(c.width for c in self.columns)

    def at(self, column: str) -> int:
        """The offset of ``column`` (a column's name, or name_part of one of its parts)."""
        k = 0
        for c in self.columns:
            if c.name == column:
                return k
            for j, f in enumerate(c.fields):
                if f == column:
                    return k + j
            k += c.width
        raise KeyError(f"{self.name} has no column {column!r}")

    def build(self, batch: tuple[int, ...], n: int, **columns: Any) -> np.ndarray:
        """The table [*batch, n, width] (or [*batch, width] for the world) from an array per
        column ([*batch, n] for one value, [*batch, n, parts] for several), each written at its
        declared offset. Raises KeyError for a column missing or not declared."""
        missing = [c.name for c in self.columns if c.name not in columns]
        extra = sorted(set(columns) - {c.name for c in self.columns})
        if missing or extra:
            raise KeyError(f"{self.name}: columns missing {missing}, not declared {extra}")
        lead = (*batch,) if self.rows == "world" else (*batch, n)
        out = np.empty((*lead, self.width), np.dtype(self.dtype))
        k = 0
        for c in self.columns:
            x = np.asarray(columns[c.name])
            out[..., k:k + c.width] = x.reshape(*lead, c.width) if c.parts else x[..., None]
            k += c.width
        return out


XY = ("x", "y")

# the counts of a creature (the kernel's dims, in this order)
DIMS = (
    ("links", "L", "links (rigid bodies and point masses)"),
    ("contacts", "C", "contact points"),
    ("trees", "T", "trees of links (each free, or welded to the world)"),
    ("dofs", "D", "degrees of freedom"),
    ("sensors", "S", "sensors"),
    ("actuators", "A", "actuators"),
    ("chain", "R", "the longest chain of dofs a link's points depend on"),
    ("rough", "K", "rough terrain's sinusoids"),
    ("nodes", "N", "a SAN's nodes (0 for the other controllers)"),
    ("inputs", "I", "a SAN's inputs: sensors, then nodes"),
    ("springs", "P", "linear springs"),
    ("edges", "E", "water-drag edges"),
    ("follow", "F", "samples of the follow point's path"),
)

TABLES = (
    Table("li", "int32", "links", "LinkInts", "per link: its place in the creature", (
        Column("parent", doc="the parent link, -1 for a tree's root"),
        Column("point", doc="1: a point mass (no rotation)"),
        Column("dof", doc="its dofs: a root's translation, its rotation (-1: none)", parts=("x", "y", "rot")),
        Column("tree", doc="the tree it belongs to"),
        Column("welded", doc="1: a root fixed to the world"),
        Column("aniso", doc="1: anisotropic friction along an axis"),
        Column("axis", doc="the friction axis runs from link to link (-1: the link's own x axis)",
               parts=("from", "to")),
        Column("spring", doc="1: a passive spring at its joint"),
        Column("limit", doc="1: joint stops at its joint"),
    )),
    Table("ti", "int32", "trees", "TreeInts", "per tree", (
        Column("root", doc="its root link"),
        Column("free", doc="1: free in the plane, 0: welded to the world"),
        Column("point", doc="1: a lone point mass"),
    )),
    Table("ci", "int32", "contacts", "ContactInts", "per contact", (Column("link"),)),
    Table("si", "int32", "sensors", "SensorInts", "per sensor", (
        Column("kind", doc="SENSORS: touch, angle, tilt, eye, length"),
        Column("on", doc="touch: the contact; the others: the link it reads"),
        Column("second", doc="length: the other link; eye: the link its axis starts at (-1: its own x axis)"),
        Column("third", doc="eye: the link its axis ends at"),
    )),
    Table("ai", "int32", "actuators", "ActuatorInts", "per actuator", (
        Column("kind", doc="ACTUATORS: angular (a servo at a joint), linear (between two points)"),
        Column("link", doc="angular: the joint's (child) link; linear: the first link"),
        Column("link_b", doc="linear: the second link"),
    )),
    Table("pi", "int32", "springs", "SpringInts", "per linear spring", (Column("link", parts=("a", "b")),)),
    Table("ei", "int32", "edges", "EdgeInts", "per water-drag edge", (Column("link"),)),
    Table("wi", "int32", "world", "WorldInts", "the world", (
        Column("terrain", doc="TERRAINS: flat, slope, hill, rough"),
        Column("hidden", doc="a SAN's hidden nodes"),
        Column("plane", doc="PLANES: vertical, horizontal (seen from above)"),
        Column("follow", doc="1: a follow point"),
        Column("follow_loop", doc="1: its path is a loop"),
        Column("articulated", doc="1: the articulated O(n) route, 0: the dense L D L^T"),
    )),
    Table("lf", "float64", "links", "LinkNumbers", "per link", (
        Column("mass", "kg"),
        Column("inertia", "kg m^2", "about its centre of mass"),
        Column("com", "m", "centre of mass in its frame", XY),
        Column("anchor", "m", "its joint in its parent's frame", XY),
        Column("pose", "m, rad", "a welded root's place in the world", ("x", "y", "angle")),
        Column("mu", "", "friction coefficients", ("forward", "backward", "lateral")),
        Column("jspring", "N m/rad, N m s/rad, rad", "passive joint spring", ("k", "c", "rest")),
        Column("limit", "rad, rad, N m/rad, N m s/rad", "joint stops", ("min", "max", "k", "c")),
    )),
    Table("cf", "float64", "contacts", "ContactNumbers", "per contact", (
        Column("point", "m", "in its link's frame", XY),
        Column("load", "N", "normal load (horizontal plane)"),
    )),
    Table("sf", "float64", "sensors", "SensorNumbers", "per sensor", (
        Column("min", "rad or m", "it is on while its value lies in [min, max]"),
        Column("max", "rad or m"),
        Column("point", "m", "eye: the eye in its link's frame; length: the first end", XY),
        Column("point_b", "m", "length: the second end", XY),
    )),
    Table("af", "float64", "actuators", "ActuatorNumbers", "per actuator", (
        Column("min", "rad or m", "target at activation 0"),
        Column("max", "rad or m", "target at activation 1"),
        Column("ks", "N m/rad or N/m", "servo stiffness"),
        Column("kd", "N m s/rad or N s/m", "servo damping"),
        Column("point_a", "m", "linear: the end on the first link", XY),
        Column("point_b", "m", "linear: the end on the second link", XY),
    )),
    Table("pf", "float64", "springs", "SpringNumbers", "per linear spring", (
        Column("point_a", "m", "", XY),
        Column("point_b", "m", "", XY),
        Column("ks", "N/m"),
        Column("kd", "N s/m"),
        Column("rest", "m"),
    )),
    Table("ef", "float64", "edges", "EdgeNumbers", "per water-drag edge", (
        Column("a", "m", "one end in its link's frame", XY),
        Column("b", "m", "the other end", XY),
    )),
    Table("wf", "float64", "world", "WorldNumbers", "the world", (
        Column("gravity", "m/s^2"),
        Column("ground_k", "N/m", "ground stiffness per contact"),
        Column("ground_c", "N s/m", "ground damping per contact"),
        Column("slip", "m/s", "friction's stick-slip speed"),
        Column("dt", "s"),
        Column("slope", "m/m", "slope's tan(angle)"),
        Column("hill", "m", "hill's height, half width and centre", ("height", "half_width", "centre")),
        Column("water_k", "N s/m^2", "normal drag"),
        Column("water_t", "N s/m^2", "tangential (skin) drag"),
        Column("follow_ds", "m", "arc length between the follow path's samples"),
        Column("follow_speed", "m/s"),
    )),
    Table("rough", "float64", "rough", "RoughTerm", "per rough sinusoid: h += amplitude sin(wavenumber x + phase)", (
        Column("amplitude", "m"), Column("wavenumber", "rad/m"), Column("phase", "rad"),
    )),
    Table("follow", "float64", "follow", "FollowSample", "the follow path, equally spaced in arc length",
          (Column("point", "m", "", XY),)),
)
TABLE = {t.name: t for t in TABLES}
# each link's chain, [links, chain] int32 each (not column tables): ri the dofs, rl what each is
# (-1 / -2 the tree's x / y, -3 none, else the link whose joint it is), rn [links] how many
CHAINS = ("ri", "rl", "rn")
# the order of the tables in the kernel's call
ORDER = ("li", "ri", "rl", "rn", "ti", "ci", "si", "ai", "pi", "ei", "wi", "lf", "cf", "sf", "af", "pf", "ef", "wf",
         "rough", "follow")
ROW_TABLES = ("lf", "cf", "sf", "af", "pf", "ef", "wf", "rough")  # the float tables a batch row may carry its own of

TERRAINS = ("flat", "slope", "hill", "rough")
SENSORS = ("touch", "angle", "tilt", "eye", "length")
ACTUATORS = ("angular", "linear")
KINDS = ("san", "hold", "sine", "reflex", "pattern")  # the kernel's controllers
INSPECT = ("poses", "energy", "momenta", "velocity", "sense", "follow_point", "centre_of_mass")
METRIC_KINDS = ("distance", "distance_upright", "hopping", "pursuit", "tracking")
# the observers' config oi: these, then the fell links, the joints' dofs and the touch sensors
OBSERVE = ("kind", "fell_com", "fell_link", "depth", "root", "sensors", "n_fell", "n_joints", "n_touch")
OBSERVE_F = ("fell_angle", "fell_com_height", "fell_link_height")  # of: rad, m, m
PLANES = ("vertical", "horizontal")
# what the observers accumulate per row: the metric's ingredients (start and end centre of mass
# (m), start height, hopping's integral (m^2 s), pursuit's (m), fell (0/1), deepest contact (m)),
# the descriptors' sums, tracking's (the sum over steps of the distance to the follow point, and
# that distance at the first step, m); then duty [touch sensors], the ring of sensor words and
# their start times [EVENTS] each
ACC = ("p0x", "p0y", "y0", "hop", "pursuit", "fell", "deepest", "px", "py", "steps", "height", "height2", "turn",
       "angle", "airborne", "joint_speed", "word", "candidate", "since", "changes", "gap", "gap0")
EVENTS = 64

# the C entry points, argument by argument: (name, C type); kernel.py's ctypes signatures are
# made from these and tests/sim/test_layout.py compares them with kernel.cpp's. f32: the
# arithmetic, float64 (0) or float32 (1), the arrays float64 either way
ROLLOUT_ARGS = (
    ("kind", "int32_t"), ("scalar", "int32_t"), ("dims", "const int32_t *"), ("tables", "const void *const *"),
    ("per_row", "const int32_t *"), ("state", "double *const *"), ("par", "const double *"), ("cst", "double *"),
    ("weights", "const int16_t *"), ("NP", "int32_t"), ("oi", "const int32_t *"), ("of", "const double *"),
    ("init", "int32_t"), ("acc", "double *"), ("qd", "double *"), ("frames", "double *"), ("every", "int64_t"),
    ("n_frames", "int64_t"), ("T", "int64_t"), ("steps", "int64_t"), ("f32", "int32_t"),
)
INSPECT_ARGS = (
    ("kind", "int32_t"), ("scalar", "int32_t"), ("dims", "const int32_t *"), ("tables", "const void *const *"),
    ("per_row", "const int32_t *"), ("in", "const double *"), ("out", "double *"), ("T", "int64_t"), ("f32", "int32_t"),
)
START_ARGS = (
    ("dims", "const int32_t *"), ("tables", "const void *const *"), ("per_row", "const int32_t *"), ("q", "double *"),
    ("seat_rows", "const double *"), ("anchor", "double *"), ("T", "int64_t"), ("f32", "int32_t"),
)


def _enum(prefix: str, names, last: str | None = None) -> str:
    items = [f"{prefix}{n.upper()}" for n in names] + ([last] if last else [])
    return "enum { " + ", ".join(items) + " };"


def header() -> str:
    """The text of ``_kernel/layout.h``: the C++ view of this declaration."""
    out = ["// The kernel's tables, as sanlab/sim/layout.py declares them. GENERATED by `python -m",
           "// sanlab.sim.layout`: edit the declaration, not this file (tests/sim/test_layout.py compares them).",
           "#pragma once", "#include <cstdint>", "", "namespace sanlab {", ""]
    out += ["// the counts (kernel.cpp: Tables reads dims[DIM_...])", _enum("DIM_", [d[0] for d in DIMS], "DIM_COUNT"), ""]
    for name, values in (("TERRAIN_", TERRAINS), ("S_", SENSORS), ("ACT_", ACTUATORS), ("K_", KINDS), ("I_", INSPECT),
                         ("M_", METRIC_KINDS), ("O_", OBSERVE), ("OF_", OBSERVE_F), ("PLANE_", PLANES)):
        out.append(_enum(name, values, "O_LISTS" if name == "O_" else None))
    out += ["// the accumulators per row (ACC), then duty [n_touch], words and times [EVENTS]",
            _enum("A_", ACC, "A_FIXED"), f"constexpr int EVENTS = {EVENTS};", ""]
    for t in TABLES:
        field = "int32_t" if t.dtype == "int32" else "V"
        templ = "" if t.dtype == "int32" else "template <class V> "
        out.append(f"// {t.name}: {t.doc} ({t.dtype}, [{t.rows}, {t.width}])")
        out.append(f"{templ}struct {t.struct} {{")
        for c in t.columns:
            note = "; ".join(x for x in (c.unit, c.doc) if x)
            out.append(f"  {field} {', '.join(c.fields)};" + (f"  // {note}" if note else ""))
        out.append("};")
        out.append(f"constexpr int {t.name.upper()}_WIDTH = {t.width};")
        out.append("")
    out += ["}  // namespace sanlab", ""]
    return "\n".join(out)


def _write() -> None:
    from pathlib import Path

    path = Path(__file__).parent / "_kernel" / "layout.h"
    path.write_text(header())
    print(f"wrote {path}")


if __name__ == "__main__":
    _write()
