"""Walking the TOML tables of a creature file: :class:`_Table` reads one table with checks from
``_checks`` and locates every problem (``links[2].mass``); the field schema below lists the keys
each table accepts (anything else is a typo and an error)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

from ._checks import _MISSING, _REQUIRED, _SAME, Check, CreatureError, _Bad, _show


class _Table:
    """One TOML table being read. ``path`` (e.g. "links[2]") locates it in messages."""

    def __init__(self, src: str, path: str, data: Any, fields: Iterable[str] | None):
        self.src, self.path = src, path
        if not isinstance(data, dict):
            raise self.error("", "a table", data)
        self.data = data
        if fields is not None:  # None: the caller restricts once it knows the table's type
            self.restrict(fields)

    def at(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path and key else (key or self.path)

    def error(self, key: str, what: str, got: Any) -> CreatureError:
        return CreatureError(
            f"{self.src}: {self.at(key) or '(top level)'}: expected {what}, got {_show(got)}"
        )

    def restrict(self, fields: Iterable[str], context: str = "") -> None:
        """Reject keys outside ``fields`` (catches typos before they become confusing errors)."""
        fields = sorted(fields)
        for key in self.data:
            if key not in fields:
                raise CreatureError(
                    f"{self.src}: {self.at(key)}: unknown field{context}; expected one of {fields}"
                )

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
        return _Table(self.src, self.at(key), self.data[key], fields) if key in self.data else None

    def tables(self, key: str, fields: Iterable[str] | None, lo: int = 0) -> list[_Table]:
        """An array of tables ``[[key]]``."""
        v = self.data.get(key, [])
        if not isinstance(v, list) or len(v) < lo:
            what = f"at least one [[{key}]] table" if lo else f"an array of [[{key}]] tables"
            raise self.error(key, what, v if key in self.data else _MISSING)
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
    "name", "description", "dt", "world", "san", "evaluation", "links", "sensors", "actuators",
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
