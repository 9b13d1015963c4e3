"""Walking the TOML tables of a creature file: :class:`_Table` reads one table with checks from
``_checks`` and locates every problem (``links[2].mass``); the field schema below lists the keys
each table accepts (anything else is a typo and an error)."""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Iterable
from typing import Any

from ._checks import _MISSING, _REQUIRED, _SAME, Check, CreatureError, _Bad, _show, printable
from .spec import MAX_KEY_PARTS, MAX_KEY_PARTS_TOTAL

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")

# One key part (bare or quoted), and a run of them, for the scan before parsing: possessive
# quantifiers never backtrack, and a run is tried from each of its parts at most once per part it
# holds (MAX_KEY_PARTS + 1), so the scan is linear in the text.
_PART = r"""(?:[A-Za-z0-9_-]++|"(?:[^"\\\n]|\\.)*+"|'[^'\n]*+')"""
_RUN = rf"{_PART}(?:[ \t]*+\.[ \t]*+{_PART}){{0,{MAX_KEY_PARTS}}}+"  # at most one more than the bound
_TOKENS = re.compile(
    r'(?:"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\')|#[^\n]*+'  # multi-line strings and comments, skipped whole
    rf"|\[[ \t]*+(?P<head>{_RUN})(?=[ \t]*+\])"  # a table header's key (or an array of one value)
    rf"|(?P<run>{_RUN})(?P<key>[ \t]*+=)?"  # a key if "=" follows; else a value (or a part of one)
)
_WHOLE_RUN = re.compile(rf"{_PART}(?:[ \t]*+\.[ \t]*+{_PART})*+")


def key_fault(text: str) -> tuple[int, str, str] | None:
    """(offset, what was expected, what was found) for the first key of TOML ``text`` past the
    format's bounds on keys, or None: a dotted key or table header (``a.b.c = 1``, ``[a.b.c]``,
    ``{ a.b.c = 1 }``) of more than spec.MAX_KEY_PARTS parts, or more than spec.MAX_KEY_PARTS_TOTAL
    key parts in all. Linear in ``len(text)`` (0.2 s for 1 MiB).

    Python's TOML reader (tomllib) spends time and memory quadratic in the parts of one dotted
    key (25,000 parts in 50 KB: 7.9 s and 2.5 GB), and about 1 KB per key part however short
    (1 MiB of ``[bN.a.a...]`` headers: 440 MB), so the loader looks first. Strings and comments
    are skipped whole, so a dot in them never counts; a value never has more than two dot-joined
    parts (``1.5``, ``07:32:00.999``), so none is taken for a long key. The total is an upper
    bound: an array of one value (``[1.5]``) counts as a header would."""
    total = 0
    for m in _TOKENS.finditer(text):
        run = m.group("head") or m.group("run")
        if run is None:
            continue
        parts = run.count(".") + 1 if '"' not in run and "'" not in run else len(re.findall(_PART, run))
        if parts > MAX_KEY_PARTS:
            at = m.start("head") if m.group("head") else m.start()
            whole = _WHOLE_RUN.match(text, at)
            n = len(re.findall(_PART, whole.group())) if whole else parts
            return at, f"a dotted key or table header of at most {MAX_KEY_PARTS} parts", f"one of {n:,} parts"
        if m.group("head") or m.group("key") is not None:
            total += parts
            if total > MAX_KEY_PARTS_TOTAL:
                return (m.start(), f"at most {MAX_KEY_PARTS_TOTAL:,} key parts in all (keys and table headers; "
                        "a.b.c counts 3)", "more")
    return None


def show_key(key: str) -> str:
    """A TOML key as the file would write it: bare if it can be, else a quoted string with every
    unprintable character escaped (a key may hold a newline or an escape sequence)."""
    if _BARE_KEY.fullmatch(key):
        return key
    return '"' + printable(key).replace('"', '\\"') + '"'


class _Table:
    """One TOML table being read. ``path`` (e.g. "links[2]") locates it in messages; ``label``
    (e.g. 'sensor "left_toe"') names the item it describes once its name is known."""

    def __init__(self, src: str, path: str, data: Any, fields: Iterable[str] | None, label: str = ""):
        self.src, self.path, self.label = src, path, label
        if not isinstance(data, dict):
            raise self.error("", "a table", data)
        self.data = data
        if fields is not None:  # None: the caller restricts once it knows the table's type
            self.restrict(fields)

    def at(self, key: str) -> str:
        """``path.key``; ``key`` is a field name or a path below it (``points[1]``), from the code."""
        return f"{self.path}.{key}" if self.path and key else (key or self.path)

    def where(self, key: str) -> str:
        """The field's location in messages: path, and the item's name when it has one."""
        loc = self.at(key) or "(top level)"
        return f"{loc} ({self.label})" if self.label else loc

    def error(self, key: str, what: str, got: Any) -> CreatureError:
        return CreatureError(f"{self.src}: {self.where(key)}: expected {what}, got {_show(got)}")

    def restrict(self, fields: Iterable[str], context: str = "") -> None:
        """Reject keys outside ``fields`` (catches typos before they become confusing errors)."""
        fields = sorted(fields)
        for key in self.data:
            if key not in fields:
                close = difflib.get_close_matches(key, fields, n=1, cutoff=0.6) if len(key) <= 100 else []
                hint = f"did you mean {close[0]!r}? " if close else ""
                raise CreatureError(f"{self.src}: {self.where(show_key(key))}: unknown field{context}; "
                                    f"{hint}expected one of {fields}")

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, check: Check, default: Any = _REQUIRED) -> Any:
        v = self.data.get(key, _MISSING)
        if v is _MISSING and default is not _REQUIRED:
            return default
        try:
            return check(v)
        except _Bad as e:
            raise self.error(key + e.sub, e.what, v if e.got is _SAME else e.got) from None

    def forbid(self, key: str, why: str) -> None:
        if key in self.data:
            raise self.error(key, f"no {key} {why}", self.data[key])

    def table(self, key: str, fields: Iterable[str]) -> _Table | None:
        if key not in self.data:
            return None
        return _Table(self.src, self.at(key), self.data[key], fields, self.label)

    def tables(self, key: str, fields: Iterable[str] | None, lo: int = 0, hi: int | None = None) -> list[_Table]:
        """An array of tables ``[[key]]``, at least ``lo`` and at most ``hi`` of them."""
        v = self.data.get(key, [])
        if not isinstance(v, list) or len(v) < lo:
            what = f"at least one [[{key}]] table" if lo else f"an array of [[{key}]] tables"
            raise self.error(key, what, v if key in self.data else _MISSING)
        if hi is not None and len(v) > hi:
            raise CreatureError(f"{self.src}: {self.where(key)}: expected at most {hi} [[{key}]] tables, got {len(v)}")
        return [_Table(self.src, f"{self.at(key)}[{i}]", x, fields) for i, x in enumerate(v)]


def spec_default(cls: type, name: str) -> Any:
    """The default of field ``name`` of spec dataclass ``cls``: the one source of every default."""
    f = {f.name: f for f in dataclasses.fields(cls)}[name]
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    raise KeyError(f"{cls.__name__}.{name} has no default")


def radians_field(t: _Table, key: str, check: Check, default: float) -> float:
    """A field the file gives in degrees, in radians; ``default`` (rad) when it is absent."""
    deg = t.get(key, check, None)
    return default if deg is None else math.radians(deg)


# -- the field schema: the keys each table accepts ----------------------------------------------

TOP = {
    "name", "description", "history", "dt", "world", "san", "evaluation", "links", "sensors", "actuators",
    "springs",
}  # fmt: skip
WORLD = {"plane", "gravity", "water_drag", "water_tangential", "ground", "terrain", "follow"}
GROUND = {"stiffness", "damping", "friction", "slip_speed"}
TERRAIN = {
    "flat": {"kind"},
    "slope": {"kind", "angle_deg"},
    "hill": {"kind", "height", "width", "center"},
    "rough": {"kind", "height", "wavelength", "seed"},
}
FOLLOW = {"points", "speed", "loop"}
SAN = {"hidden", "delay_on", "delay_off"}
EVALUATION = {
    "metric", "seconds", "fell_link", "fell_angle_deg", "fell_com_height", "fell_link_height",
    "hop_k", "direction",
}  # fmt: skip
LINK = {
    "name", "mass", "shape", "points", "inertia", "com", "contacts", "position", "angle_deg",
    "parent", "anchor", "spring", "limit", "friction", "drag", "fixed",
}  # fmt: skip
SPRING = {"stiffness", "damping", "rest_deg"}
LIMIT = {"min_deg", "max_deg", "stiffness", "damping"}
FRICTION = {"forward", "backward", "lateral", "axis"}
POINT = {"link", "at"}
SENSOR = {
    "touch": {"link", "contact"},
    "angle": {"link", "min_deg", "max_deg"},
    "tilt": {"link", "min_deg", "max_deg"},
    "eye": {"link", "at", "min_deg", "max_deg", "axis"},
    "length": {"a", "b", "min", "max"},
}
ACTUATOR = {
    "angular": {"joint", "min_deg", "max_deg", "ks", "kd"},
    "linear": {"a", "b", "min", "max", "ks", "kd"},
}
SPRINGS = {"name", "a", "b", "stiffness", "damping", "rest"}
