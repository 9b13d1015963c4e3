"""Value checks for the creature format: each takes a raw TOML value and returns it converted, or
raises :class:`_Bad` saying what was expected (the table reader turns that into a
:class:`CreatureError` naming the file and the field)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

from .spec import Vec2


class CreatureError(ValueError):
    """A bad creature file; ``str()`` is one line: ``file: field: expected X, got Y``."""


_REQUIRED = object()  # no default: the field must be present
_MISSING = object()  # the value of an absent field; every check rejects it
_SAME = object()


class _Bad(Exception):
    """``what`` was expected; ``sub`` (e.g. "[1]") locates the culprit inside the checked value."""

    def __init__(self, what: str, sub: str = "", got: Any = _SAME):
        self.what, self.sub, self.got = what, sub, got


Check = Callable[[Any], Any]


def _show(v: Any) -> str:
    if v is _MISSING:
        return "nothing"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, dict):
        return "a table"
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _num(what: str, ok: Callable[[float], bool] = lambda x: True) -> Check:
    def check(v: Any) -> float:
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float))
            or not math.isfinite(v)
            or not ok(v)
        ):
            raise _Bad(what)
        return float(v)

    return check


def number(unit: str = "") -> Check:
    return _num("a number" + _unit(unit))


def positive(unit: str = "") -> Check:
    return _num("a positive number" + _unit(unit), lambda x: x > 0)


def nonneg(unit: str = "") -> Check:
    return _num("a non-negative number" + _unit(unit), lambda x: x >= 0)


def within(lo: float, hi: float, unit: str = "", open_lo: bool = False) -> Check:
    what = f"a number in {'(' if open_lo else '['}{lo:g}, {hi:g}]" + _unit(unit)
    return _num(what, lambda x: (lo < x if open_lo else lo <= x) and x <= hi)


def integer(lo: int = 0) -> Check:
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise _Bad(f"an integer >= {lo}")
        return v

    return check


def string(v: Any) -> str:
    if not isinstance(v, str):
        raise _Bad("a string")
    return v


def nonempty(v: Any) -> str:
    if not isinstance(v, str) or not v.strip():
        raise _Bad("a non-empty string")
    return v


def boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise _Bad("true or false")
    return v


def one_of(options: Iterable[str], what: str = "one of") -> Check:
    options = list(options)

    def check(v: Any) -> str:
        if not isinstance(v, str) or v not in options:
            raise _Bad(f"{what} {options}")
        return v

    return check


def list_of(item: Check, what: str, lo: int = 0, hi: int | None = None) -> Check:
    def check(v: Any) -> tuple:
        if not isinstance(v, list) or len(v) < lo or (hi is not None and len(v) > hi):
            raise _Bad(what)
        out = []
        for i, x in enumerate(v):
            try:
                out.append(item(x))
            except _Bad as e:
                raise _Bad(e.what, f"[{i}]{e.sub}", x if e.got is _SAME else e.got) from None
        return tuple(out)

    return check


def vec2(unit: str = "m") -> Check:
    coord = number()

    def check(v: Any) -> Vec2:
        if not isinstance(v, list) or len(v) != 2:
            raise _Bad("a pair of numbers [x, y]" + _unit(unit))
        try:
            return (coord(v[0]), coord(v[1]))
        except _Bad:
            raise _Bad("a pair of numbers [x, y]" + _unit(unit)) from None

    return check


def points(what: str, lo: int = 0, hi: int | None = None) -> Check:
    return list_of(vec2(), what, lo, hi)


def link_pair(names: list[str]) -> Check:
    inner = list_of(one_of(names, "one of the link names"), "a pair of link names [from, to]", 2, 2)

    def check(v: Any) -> tuple[str, str]:
        a, b = inner(v)
        if a == b:
            raise _Bad("two different link names [from, to]")
        return (a, b)

    return check
