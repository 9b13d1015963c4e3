"""Free numbers in a creature file, and the couplings that keep a design plausible (paper §6.3).

§6.3 ("Evolution") proposes that the search change a creature's physical parameters too ("link
lengths, masses, and points of attachment"), with the parameters interrelated: "a stronger spring
constant in the actuator ... should increase the mass of the appropriate link. Similarly, a
larger link should also have an increased mass". A creature file says which of its numbers are
free by writing a range in place of the number (docs/creature-format.md, "Free numbers"):

    mass = { min = 0.1, max = 0.3 }               # free, loads at 0.2 (the middle)
    mass = { min = 0.1, max = 0.3, default = 0.25 }
    points = [[0, 0], [0, { min = -0.3, max = -0.1, name = "shin" }]]
    contacts = [[0, { free = "shin" }]]           # the same number again (times, plus: a fixed map)

and its couplings in a ``[design]`` table (``density``, ``strength_mass``, ``total_mass``,
``[[design.total]]``). :func:`read_design` reads both from the parsed TOML; a
:class:`Design` builds the creature of any vector of free values; the loader (``loads``) builds
it at the defaults, so every command that only loads a file sees the creature the file states.
"""

from __future__ import annotations

import difflib
import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ._checks import CreatureError, _Bad, _show, nonempty, printable
from .spec import Creature

__all__ = ["Coupling", "Design", "FreeNumber", "Move", "Total", "read_design"]

FREE = {"min", "max", "default", "name"}  # the keys of a free number
SAME = {"free", "times", "plus"}  # the keys of a use of a named free number
DESIGN = {"density", "strength_mass", "total_mass", "total"}  # the keys of [design]
TOTAL = {"of", "value"}  # the keys of a [[design.total]]
PER_DEG = 180.0 / math.pi  # (N m/deg) * PER_DEG = N m/rad
# Free numbers in one file. A design affords tens of bodies, and CMA-ES over more numbers than
# bodies learns little; the built-in designs free at most 13. `sanlab check` builds the creature
# at both ends of each range (each build reads the whole file), so the cap also bounds its cost.
MAX_FREE = 64


@dataclass(frozen=True)
class FreeNumber:
    """One free number: ``name`` (its ``name`` key, else ``path``), ``path`` where it is written
    (``links[1].mass``; inside a ``[[repeat]]``: ``repeat[0].links[0].mass``, one number shared
    by every copy), its range ``min``..``max`` and ``default`` (in the file's units: m, kg, deg,
    N·m/deg, s), and ``uses``, every path that takes its value."""

    name: str
    path: str
    min: float
    max: float
    default: float
    uses: tuple[str, ...] = ()


@dataclass(frozen=True)
class Move:
    """One free number of a body against the file's default (:meth:`Design.moves`): ``value``
    and ``default`` in ``unit`` (the file's), ``relative`` the change of magnitude over the
    default's (a length written negative that shortens, or a knee fold of -139 deg that becomes
    -103, is a negative change: the file's signs say a direction, not a size); where the sign
    flips, the signed change over the default's magnitude; None for a default of 0. ``size``
    ranks the changes: ``|relative|``, or the change over the range's width for a default of 0."""

    name: str
    default: float
    value: float
    unit: str
    relative: float | None
    size: float

    @property
    def percent(self) -> str:
        """" (+31 %)", the relative change as a note shows it; "" where there is none."""
        return f" ({100 * self.relative:+.0f} %)" if self.relative is not None else ""

    @property
    def moved(self) -> bool:
        """Whether the value differs from the default (beyond rounding)."""
        return abs(self.value - self.default) > 1e-12 * max(1.0, abs(self.default))


@dataclass(frozen=True)
class Total:
    """A total that must hold (§6.3's interrelated parameters): the named free numbers ``of``
    sum to ``value`` (e.g. the total leg length of a thigh and a shin)."""

    of: tuple[str, ...]
    value: float


@dataclass(frozen=True)
class Coupling:
    """The ``[design]`` table: ``density`` (links whose mass follows their size at constant
    density: a segment's length, a polygon's area), ``strength_mass`` (kg added to the link an
    angular actuator drives per N·m/deg of its ks above the file's default ks; removed below it),
    ``total_mass`` (kg that all link masses are scaled to sum to, after the rest; "stated": the
    stated creature's total; None: no total),
    ``totals`` (sums of free numbers that hold)."""

    density: tuple[str, ...] = ()
    strength_mass: float = 0.0
    total_mass: float | str | None = None
    totals: tuple[Total, ...] = ()

    @property
    def any(self) -> bool:
        return bool(self.density or self.strength_mass or self.total_mass is not None or self.totals)


@dataclass(frozen=True)
class _Slot:
    """Where a free number goes in the template: value ``times * x + plus`` of number ``index``."""

    index: int
    times: float = 1.0
    plus: float = 0.0


@dataclass(frozen=True)
class Design:
    """A creature file with free numbers: ``free`` (in vector order: the order written),
    ``coupling``, and the parsed file with each free number left as a slot. ``creature(values)``
    is the creature at a vector of free values (shape [len(free)], the file's units), couplings
    applied; ``creature()`` is the file's stated creature (every default)."""

    source: str
    free: tuple[FreeNumber, ...]
    coupling: Coupling
    template: Any = field(repr=False)
    expand: Callable[[dict], dict] = field(repr=False)  # writes out [[repeat]] (loader.expand_repeats)
    build: Callable[[dict], Creature] = field(repr=False)  # written-out data -> creature (loader.build)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.free)

    @property
    def lo(self) -> np.ndarray:
        return np.array([f.min for f in self.free], float)

    @property
    def hi(self) -> np.ndarray:
        return np.array([f.max for f in self.free], float)

    @property
    def defaults(self) -> np.ndarray:
        return np.array([f.default for f in self.free], float)

    def off_totals(self) -> list[tuple[int, float]]:
        """Each ``[[design.total]]`` its numbers' defaults do not sum to: (its index, the sum of
        their defaults). The file loads at its defaults; :meth:`project` (every body of a design,
        its reference too) moves them onto the total."""
        index = {n: i for i, n in enumerate(self.names)}
        out = []
        for k, t in enumerate(self.coupling.totals):
            total = float(sum(self.defaults[index[n]] for n in t.of))
            if abs(total - t.value) > 1e-9 * max(1.0, abs(t.value)):
                out.append((k, total))
        return out

    def slots(self) -> dict[str, _Slot]:
        """Path (``links[1].points[1][1]``) -> the slot there: which free number, times, plus."""
        out: dict[str, _Slot] = {}

        def walk(v: Any, path: str) -> None:
            if isinstance(v, _Slot):
                out[path] = v
            elif isinstance(v, dict):
                for k, x in v.items():
                    walk(x, _join(path, k))
            elif isinstance(v, list):
                for i, x in enumerate(v):
                    walk(x, _join(path, i))

        walk(self.template, "")
        return out

    def project(self, values: Sequence[float] | np.ndarray) -> np.ndarray:
        """``values`` clipped to their ranges, every ``[[design.total]]`` made to hold: the numbers
        of a total are scaled together about their lower ends until they sum to its value (the
        ranges allow it: :func:`read_design` checks that each total lies within its numbers' reach)."""
        v = np.clip(np.asarray(values, float), self.lo, self.hi)
        index = {n: i for i, n in enumerate(self.names)}
        for t in self.coupling.totals:
            ix = np.array([index[n] for n in t.of])
            lo, hi = self.lo[ix], self.hi[ix]
            x = v[ix]
            # x = lo + s (x - lo) for s >= 0 until it meets a range end, then the rest take up the remainder
            for _ in range(len(ix) + 1):
                gap = t.value - x.sum()
                if abs(gap) <= 1e-12 * max(1.0, abs(t.value)):
                    break
                room = (hi - x) if gap > 0 else (x - lo)
                movable = room > 0
                if not movable.any():
                    break
                share = np.where(movable, room, 0.0)
                x = x + np.sign(gap) * share * min(1.0, abs(gap) / share.sum())
            v[ix] = np.clip(x, lo, hi)
        return v

    def data(self, values: Sequence[float] | np.ndarray | None = None) -> Any:
        """The parsed file with the free values (projected) written in, couplings not yet applied."""
        v = self.defaults if values is None else self.project(values)
        return _fill(self.template, v)

    def creature(self, values: Sequence[float] | np.ndarray | None = None) -> Creature:
        """The creature at ``values`` (the defaults when None), couplings applied. Raises
        CreatureError (one line naming the file) when the values make an invalid creature (a
        segment of zero length, a parent's anchor ...)."""
        if values is None:
            return self._default
        return self._build(values)

    @cached_property
    def _default(self) -> Creature:
        # the file's stated creature: every command that loads the file, and `check`, ask for it
        return self._build(None)

    def _build(self, values: Sequence[float] | np.ndarray | None) -> Creature:
        data = self.expand(self.data(values))
        c = self.build(data)
        if not (self.coupling.density or self.coupling.strength_mass or self.coupling.total_mass is not None):
            return c
        ref = self._stated() if values is not None else c
        masses = coupled_masses(c, ref, self.coupling)
        links = data["links"]
        for i, m in enumerate(masses):
            old = links[i]["mass"]
            links[i] = dict(links[i], mass=float(m))
            if isinstance(links[i].get("inertia"), int | float) and not isinstance(links[i]["inertia"], bool):
                links[i]["inertia"] = links[i]["inertia"] * float(m) / old  # written inertia follows the mass
        return self.build(data)

    def text(self, text: str, values: Sequence[float] | np.ndarray, note: str = "", history: str = "") -> str:
        """The creature file of one body: ``text`` (the file with free numbers) with each free
        number and each use of one replaced by its value (projected), the masses the couplings
        give written into the links, and no ``[design]`` table; ``note`` (lines) as a comment
        block on top, and ``history`` (one "YYYY-MM-DD: ..." line; docs/creature-format.md,
        "History"), when given, appended to the file's ``history`` array after its own entries.
        Comments and layout are kept; a file with ``[[repeat]]`` tables is written out (one table
        per part), as ``sanlab export --toml`` does. The result loads as ``self.creature(values)``
        (equal: a history is no part of a creature's identity); raises CreatureError where that is
        no valid creature."""
        import tomlkit
        from tomlkit.items import Array

        v = self.project(values)
        creature = self.creature(v)
        if "repeat" in tomlkit.parse(text):
            doc = tomlkit.document()
            doc.update(self.expand(self.data(v)))
        else:
            doc = tomlkit.parse(text)
            _write(doc, v, self.slots())
            if "design" in doc:
                del doc["design"]
        if self.coupling.density or self.coupling.strength_mass or self.coupling.total_mass is not None:
            for link, table in zip(creature.links, doc["links"], strict=True):
                table["mass"] = float(link.mass)  # exact (repr), so the file loads as the body
                if "inertia" in table:
                    table["inertia"] = float(link.inertia)
        if history:
            if "history" not in doc:
                doc["history"] = tomlkit.array()  # placed after the file's last top-level value
            entries = doc["history"]
            assert isinstance(entries, Array)  # the loader took it for an array of strings
            entries.append(history)
            entries.multiline(True)  # one entry a line: each is a sentence
        head = "".join(f"# {line}".rstrip() + "\n" for line in note.splitlines())
        return (head + "\n" if head else "") + tomlkit.dumps(doc)

    def moves(self, values: Sequence[float] | np.ndarray) -> list[Move]:
        """Each free number of the body at ``values`` (shape [len(free)], projected into the
        ranges first) against its default, in vector order."""
        out = []
        for f, x, unit in zip(self.free, self.project(values), self.units, strict=True):
            x = float(x)
            if not f.default:
                rel = None
            elif x * f.default > 0:
                rel = (abs(x) - abs(f.default)) / abs(f.default)
            else:
                rel = (x - f.default) / abs(f.default)
            size = abs(rel) if rel is not None else abs(x - f.default) / (f.max - f.min)
            out.append(Move(f.name, f.default, x, unit, rel, size))
        return out

    def changes(self, values: Sequence[float] | np.ndarray) -> list[str]:
        """One line per free number (and per link mass the couplings change): its default, the
        body's value and the change of magnitude relative to the default's (:class:`Move`)."""
        out = [f"{m.name}: {m.default:.6g} -> {m.value:.6g}{m.percent}" for m in self.moves(values)]
        if self.coupling.any:
            for a, b in zip(self.creature().links, self.creature(self.project(values)).links, strict=True):
                if abs(a.mass - b.mass) > 1e-12:
                    out.append(f"mass of {a.name}: {a.mass:.4g} -> {b.mass:.4g} kg "
                               f"({100 * (b.mass - a.mass) / a.mass:+.0f} %)")
        return out


    @property
    def units(self) -> tuple[str, ...]:
        """Each free number's unit (in vector order), the one the format gives the field it is
        written in (docs/creature-format.md): "m", "kg", "deg", "s", "N·m/deg" (an angular
        actuator's ks), "N/m" (a linear one's) ...; "" for a field without a unit."""
        return tuple(unit_of(self.template, f.path) for f in self.free)

    def _stated(self) -> Creature:
        """The creature at the defaults, before couplings (the reference sizes and strengths)."""
        return self._stated_once

    @cached_property
    def _stated_once(self) -> Creature:
        # built once: every body's couplings are measured against it (a build reads the whole file)
        return self.build(self.expand(self.data()))

    def total_mass(self, values: Sequence[float] | np.ndarray | None = None) -> float:
        """The creature's total mass (kg) at ``values``."""
        return float(sum(link.mass for link in self.creature(values).links))

    def ends(self, budget_s: float | None = None) -> list[tuple[float, float] | None]:
        """For each free number, the total mass (kg) with it at its min and at its max (the rest
        at their defaults; totals projected), or NaN where that end makes no valid creature. Each
        end is a creature built from the whole file (two builds with couplings), so the cost is
        about 2 x len(free) builds; ``budget_s``: stop after that many seconds of wall time, the
        numbers not reached None (their ends not checked); None: every end."""
        out: list[tuple[float, float] | None] = []
        start = time.perf_counter()
        for i, f in enumerate(self.free):
            if budget_s is not None and time.perf_counter() - start >= budget_s:
                out += [None] * (len(self.free) - i)
                break
            row = []
            for x in (f.min, f.max):
                v = self.defaults.copy()
                v[i] = x
                try:
                    row.append(self.total_mass(v))
                except CreatureError:
                    row.append(float("nan"))
            out.append((row[0], row[1]))
        return out


def size(link) -> float:
    """A link's size for constant density: a segment's length (m), a polygon's area (m^2); 0 for a
    point mass (its mass never follows a size)."""
    from .geometry import polygon_moments

    if link.shape.kind == "segment":
        (x0, y0), (x1, y1) = link.shape.points
        return math.hypot(x1 - x0, y1 - y0)
    if link.shape.kind == "polygon":
        return abs(polygon_moments(link.shape.points)[0])
    return 0.0


def coupled_masses(c: Creature, ref: Creature, coupling: Coupling) -> np.ndarray:
    """Link masses (kg, [L]) of ``c`` after ``coupling``, against the stated creature ``ref``:
    density (mass x size / stated size), then muscle mass (strength_mass x the change in the ks
    of each angular actuator, N·m/deg, on the link its joint moves), then the total."""
    m = np.array([link.mass for link in c.links], float)
    for i, (link, was) in enumerate(zip(c.links, ref.links, strict=True)):
        if (link.name in coupling.density or "*" in coupling.density) and size(was) > 0:
            m[i] *= size(link) / size(was)
    if coupling.strength_mass:
        names = [link.name for link in c.links]
        for a, was in zip(c.actuators, ref.actuators, strict=True):
            if a.kind == "angular" and was.kind == "angular":
                m[names.index(a.joint)] += coupling.strength_mass * (a.ks - was.ks) / PER_DEG
    floor = 1e-3 * np.array([link.mass for link in ref.links])  # a muscle never takes a link's mass below 0.1 %
    m = np.maximum(m, floor)
    if coupling.total_mass is not None:
        stated = sum(link.mass for link in ref.links)
        m *= (stated if coupling.total_mass == "stated" else float(coupling.total_mass)) / m.sum()
    return m


# -- reading ------------------------------------------------------------------------------------


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _err(shown: str, where: str, what: str, got: Any) -> CreatureError:
    return CreatureError(f"{shown}: {where or '(top level)'}: expected {what}, got {_show(got)}")


# The unit of a field by its key (docs/creature-format.md); keys ending in _deg are degrees, and
# ks, kd, stiffness, damping, min and max depend on the table they are in (see unit_of).
UNITS = {"mass": "kg", "inertia": "kg·m²", "points": "m", "com": "m", "contacts": "m", "position": "m",
         "anchor": "m", "at": "m", "rest": "m", "height": "m", "width": "m", "center": "m", "wavelength": "m",
         "fell_com_height": "m", "fell_link_height": "m", "gravity": "m/s²", "speed": "m/s", "slip_speed": "m/s",
         "water_drag": "N·s/m²", "delay_on": "s", "delay_off": "s", "seconds": "s", "dt": "s"}
_PART = re.compile(r"\[(\d+)\]|([^.\[\]]+)")


def unit_of(data: Any, path: str) -> str:
    """The unit of the number at ``path`` (``actuators[0].ks``, as :class:`FreeNumber` writes
    it) of the parsed file ``data``: a key's unit (:data:`UNITS`, ``*_deg``: deg); an actuator's
    ``ks``/``kd`` by its type (angular: N·m/deg, N·m·s/deg; linear: N/m, N·s/m); ``stiffness``
    and ``damping`` of a joint's ``spring`` or ``limit`` per degree, of a spring or the ground
    per metre; ``min``/``max`` (a length sensor's, a linear actuator's) m. "" where the format
    gives none or the path is not in ``data``."""
    parts: list[str | int] = [int(i) if i else k for i, k in _PART.findall(path)]
    keys = [k for k, p in enumerate(parts) if isinstance(p, str)]
    if not keys:
        return ""
    key = str(parts[keys[-1]])
    table: Any = data
    try:
        for p in parts[:keys[-1]]:
            table = table[p]
    except (KeyError, IndexError, TypeError):
        return ""  # not a path of this file
    angular = isinstance(table, dict) and table.get("type") == "angular"
    per_deg = "spring" in parts or "limit" in parts
    if key.endswith("_deg"):
        return "deg"
    if key in ("ks", "kd"):
        return {("ks", True): "N·m/deg", ("kd", True): "N·m·s/deg", ("ks", False): "N/m",
                ("kd", False): "N·s/m"}[key, angular]
    if key in ("stiffness", "damping"):
        return {("stiffness", True): "N·m/deg", ("damping", True): "N·m·s/deg", ("stiffness", False): "N/m",
                ("damping", False): "N·s/m"}[key, per_deg]
    if key in ("min", "max"):
        return "m"
    return UNITS.get(key, "")


def _join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def read_design(data: dict, shown: str, expand: Callable[[dict], dict], build: Callable[[dict], Creature]) -> Design:
    """The free numbers and couplings of a parsed creature file ``data`` (before its ``[[repeat]]``
    tables are written out), ``shown`` naming the file in messages; ``expand`` and ``build``: the
    loader's (its ``[[repeat]]`` written out; the creature of written-out data). Raises CreatureError (one
    line: file, field, what was expected) for a malformed range, a use of an unknown name, or a
    malformed ``[design]`` table."""
    free: list[dict] = []
    named: dict[str, int] = {}
    uses: list[tuple[str, dict]] = []

    def walk(v: Any, path: str) -> Any:
        if isinstance(v, dict):
            keys = set(v)
            if "min" in keys and "max" in keys and keys <= FREE:
                return _free(v, path)
            if "free" in keys and keys <= SAME:
                uses.append((path, v))
                return ("use", path, v)
            _not_quite(v, path, shown)
            return {k: walk(x, _join(path, k)) for k, x in v.items()}
        if isinstance(v, list):
            return [walk(x, _join(path, i)) for i, x in enumerate(v)]
        return v

    def _free(v: dict, path: str) -> _Slot:
        for key in ("min", "max", "default"):
            if key in v and not _is_number(v[key]):
                raise _err(shown, _join(path, key), "a finite number (an end of a free number's range)", v[key])
        lo, hi = float(v["min"]), float(v["max"])
        if not lo < hi:
            raise _err(shown, _join(path, "max"), f"a number above min = {lo:g} (a free number's range)", v["max"])
        default = float(v.get("default", float(f"{(lo + hi) / 2:.12g}")))  # the middle, without 0.30000000000000004
        if not lo <= default <= hi:
            raise _err(shown, _join(path, "default"), f"a number within [{lo:g}, {hi:g}] (the range)", v["default"])
        if len(free) >= MAX_FREE:
            raise CreatureError(f"{shown}: {printable(path)}: expected at most {MAX_FREE} free numbers in a file (a "
                                f"design affords tens of bodies; `sanlab check` builds both ends of each), got more")
        name = path
        if "name" in v:
            name = v["name"]
            try:
                nonempty(name)  # as every other name: printed in tables, written into files
            except _Bad as e:
                raise _err(shown, _join(path, "name"), e.what, name) from None
            if name in named:
                raise _err(shown, _join(path, "name"), f"a name not used by another free number "
                           f"({free[named[name]]['path']})", name)
            named[name] = len(free)
        free.append({"name": name, "path": path, "min": lo, "max": hi, "default": default, "uses": [path]})
        return _Slot(len(free) - 1)

    body = {k: v for k, v in data.items() if k != "design"}
    template = walk(body, "")
    slots: dict[str, _Slot] = {}
    for path, v in uses:
        name = v["free"]
        if name not in named:
            hint = f"one of {sorted(named)}" if named else "none is named: give one a name key"
            raise _err(shown, _join(path, "free"), f"the name of a free number ({hint})", name)
        for key in ("times", "plus"):
            if key in v and not _is_number(v[key]):
                raise _err(shown, _join(path, key), "a finite number", v[key])
        slots[path] = _Slot(named[name], float(v.get("times", 1.0)), float(v.get("plus", 0.0)))
        free[named[name]]["uses"].append(path)
    template = _resolve(template, slots)
    numbers = tuple(FreeNumber(f["name"], f["path"], f["min"], f["max"], f["default"], tuple(f["uses"])) for f in free)
    coupling = _coupling(data.get("design"), shown, numbers, data)
    return Design(shown, numbers, coupling, template, expand, build)


def _not_quite(v: dict, path: str, shown: str) -> None:
    """Raise CreatureError for a table at ``path`` meant as a free number or a use of one but
    neither (a key misspelt, ``max`` missing, keys of both): the loader would only say that it
    expected a number there and got a table. A table is taken as meant so when its values are
    plain (numbers, strings), it has a key ``min``, ``max``, ``default`` or ``free``, and each of
    its keys is one of a free number's or a use's or close to one; other tables (a length
    sensor's min and max beside its type and link) are the loader's to judge."""
    keys = [k for k in v if isinstance(k, str)]
    known = sorted(FREE | SAME)
    if not keys or any(isinstance(x, dict | list) for x in v.values()) or not set(keys) & {"min", "max", "default", "free"}:
        return
    unknown = [k for k in keys if k not in FREE | SAME]
    close = {k: difflib.get_close_matches(k, known, n=1, cutoff=0.75) for k in unknown if len(k) <= 100}
    if len(close) < len(unknown) or not all(close.values()):
        return  # a key unlike any of a free number's: some other table
    if unknown:
        k = unknown[0]
        kind = "a use of a free number" if "free" in keys else "a free number"
        fields = sorted(SAME) if "free" in keys else sorted(FREE)
        raise CreatureError(f"{shown}: {_join(path, printable(k))}: unknown field of {kind}; did you mean "
                            f"{close[k][0]!r}? expected one of {fields}")
    if "free" in keys:
        both = sorted(set(keys) & (FREE - {"name"}))
        raise CreatureError(f"{shown}: {path}: expected a free number (min, max, default, name) or a use of one "
                            f"(free, times, plus), got a table with keys of both ({', '.join(both)} and free)")
    missing = " and ".join(k for k in ("min", "max") if k not in keys)
    raise CreatureError(f"{shown}: {path}: expected a free number with min and max "
                        f"(e.g. {{ min = 0.1, max = 0.3 }}), got a table without {missing}")


def _write(node: Any, values: np.ndarray, slots: dict[str, _Slot]) -> None:
    """Replace, in a tomlkit document, each free number and each use of one by its value."""

    def walk(x: Any, path: str) -> None:
        keys = list(x.keys()) if isinstance(x, dict) else range(len(x)) if isinstance(x, list) else []
        for k in keys:
            at = _join(path, k)
            if at in slots:
                x[k] = float(slots[at].times * values[slots[at].index] + slots[at].plus)  # repr: exact
            else:
                walk(x[k], at)

    walk(node, "")


def _resolve(v: Any, slots: dict[str, _Slot]) -> Any:
    if isinstance(v, tuple) and len(v) == 3 and v[0] == "use":
        return slots[v[1]]
    if isinstance(v, dict):
        return {k: _resolve(x, slots) for k, x in v.items()}
    if isinstance(v, list):
        return [_resolve(x, slots) for x in v]
    return v


def _fill(v: Any, values: np.ndarray) -> Any:
    if isinstance(v, _Slot):
        return v.times * float(values[v.index]) + v.plus
    if isinstance(v, dict):
        return {k: _fill(x, values) for k, x in v.items()}
    if isinstance(v, list):
        return [_fill(x, values) for x in v]
    return v


def _coupling(raw: Any, shown: str, free: tuple[FreeNumber, ...], data: dict) -> Coupling:
    if raw is None:
        return Coupling()
    if not isinstance(raw, dict):
        raise _err(shown, "design", "a table of couplings", raw)
    for key in raw:
        if key not in DESIGN:
            raise CreatureError(f"{shown}: design.{printable(str(key))}: unknown field; expected one of {sorted(DESIGN)}")
    links = data.get("links")
    link_names = [x.get("name") for x in links if isinstance(x, dict)] if isinstance(links, list) else []
    rep = data.get("repeat")
    rep = rep if isinstance(rep, list) else []
    repeated = any(isinstance(r, dict) and "links" in r for r in rep)
    density: tuple[str, ...] = ()
    d = raw.get("density", False)
    if d is True:
        density = ("*",)
    elif isinstance(d, list) and all(isinstance(x, str) for x in d):
        for i, x in enumerate(d):
            if x not in link_names and not repeated:
                raise _err(shown, f"design.density[{i}]", f"one of the link names {link_names}", x)
        density = tuple(d)
    elif d is not False:
        raise _err(shown, "design.density", "true (every link) or a list of link names", d)
    sm = raw.get("strength_mass", 0.0)
    if not _is_number(sm) or sm < 0:
        raise _err(shown, "design.strength_mass", "a number >= 0 (kg per N·m/deg of actuator strength)", sm)
    tm = raw.get("total_mass")
    if tm is not None and not (tm is True or (_is_number(tm) and tm > 0)):
        raise _err(shown, "design.total_mass", "true (the stated total) or a mass > 0 (kg)", tm)
    totals = []
    raw_totals = raw.get("total", [])
    if not isinstance(raw_totals, list):
        raise _err(shown, "design.total", "an array of [[design.total]] tables", raw_totals)
    by_name = {f.name: f for f in free}
    held: dict[str, int] = {}  # free number -> the total that holds it
    for k, t in enumerate(raw_totals):
        where = f"design.total[{k}]"
        if not isinstance(t, dict):
            raise _err(shown, where, "a table with of (names of free numbers) and an optional value", t)
        for key in t:
            if key not in TOTAL:
                raise CreatureError(f"{shown}: {where}.{printable(str(key))}: unknown field; expected one of {sorted(TOTAL)}")
        of = t.get("of")
        if not isinstance(of, list) or len(of) < 2 or not all(isinstance(x, str) for x in of) or len(set(of)) < len(of):
            raise _err(shown, f"{where}.of", "a list of at least 2 different names of free numbers", of)
        for i, x in enumerate(of):
            if x not in by_name:
                raise _err(shown, f"{where}.of[{i}]", f"the name of a free number (one of {sorted(by_name)})", x)
            if x in held:  # each total is kept by moving its own numbers: a shared one would undo the other
                raise _err(shown, f"{where}.of[{i}]", f"a free number in no other total (design.total[{held[x]}] "
                           "holds it, and two totals on one number cannot both be kept)", x)
            held[x] = k
        fs = [by_name[x] for x in of]
        value = t.get("value", sum(f.default for f in fs))
        lo, hi = sum(f.min for f in fs), sum(f.max for f in fs)
        if not _is_number(value) or not lo <= value <= hi:
            raise _err(shown, f"{where}.value", f"a number within [{lo:g}, {hi:g}] (the sum of the ranges)", value)
        totals.append(Total(tuple(of), float(value)))
    return Coupling(density, float(sm), None if tm is None else "stated" if tm is True else float(tm), tuple(totals))
