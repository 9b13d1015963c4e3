"""Value checks for the creature format: each takes a raw TOML value and returns it converted, or
raises :class:`_Bad` saying what was expected (the table reader turns that into a
:class:`CreatureError` naming the file and the field)."""

from __future__ import annotations

import datetime
import difflib
import math
import re
from collections.abc import Callable, Iterable
from typing import Any

from .spec import MAX_COORDINATE, MAX_MAGNITUDE, MAX_NAME, MAX_POINTS, MIN_POSITIVE, Vec2


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


def printable(s: str) -> str:
    """``s`` safe to print on one line of a terminal: every character Python does not call
    printable (controls such as newlines and escape sequences, format characters such as the
    bidirectional overrides, separators other than the space) written as its Python escape."""
    if s.isprintable():
        return s
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in s)


def _digits(v: int) -> str:
    """How many decimal digits ``v`` has, without writing it out (Python refuses to write an
    integer of more than 4300 digits, and takes quadratic time to write a long one)."""
    n = abs(v)
    if n.bit_length() <= 14_000:  # about 4200 digits: exact
        return str(len(str(n)))
    return f"about {int(n.bit_length() * math.log10(2)) + 1}"


def _show(v: Any) -> str:
    if v is _MISSING:
        return "nothing"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int) and v.bit_length() > 190:  # more digits (about 58) than a message shows
        return f"an integer of {_digits(v)} digits"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list) and len(v) > 20:
        return f"a list of {len(v)} items"
    if isinstance(v, str) and len(v) > 60:
        v = v[:57]  # repr of a 1 MB string is slow to build only to be cut
    try:
        s = repr(v)
    except RecursionError:
        return "a deeply nested value"
    except ValueError:  # it holds an integer of more than 4300 digits, which Python will not write
        return "a value holding an integer too long to print"
    return s if len(s) <= 60 else s[:57] + "..."


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _bound(unit: str) -> float:
    """The largest magnitude a number of ``unit`` may have (spec.MAX_COORDINATE for metres)."""
    return MAX_COORDINATE if unit == "m" else MAX_MAGNITUDE


def _num(what: str, ok: Callable[[float], bool] = lambda x: True, unit: str = "") -> Check:
    """A finite number for which ``ok`` holds, of magnitude at most :func:`_bound` of ``unit``."""
    bound = _bound(unit)
    full = what + _unit(unit)

    def check(v: Any) -> float:
        # an int is exact and may be far beyond a float's range (1 followed by 309 zeros): it is
        # compared as an int, and converted only once it is known to be within the bound
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (isinstance(v, float) and not math.isfinite(v)) \
                or not ok(v):
            raise _Bad(full)
        if abs(v) > bound:
            raise _Bad(f"{what} of magnitude at most {bound:g}{_unit(unit)}")
        return float(v)

    return check


def number(unit: str = "") -> Check:
    return _num("a number", unit=unit)


def positive(unit: str = "") -> Check:
    plain = _num("a positive number", lambda x: x > 0, unit)
    tiny = _num(f"a positive number of at least {MIN_POSITIVE:g}", lambda x: x >= MIN_POSITIVE, unit)

    def check(v: Any) -> float:
        return tiny(plain(v))

    return check


def nonneg(unit: str = "") -> Check:
    return _num("a non-negative number", lambda x: x >= 0, unit)


def within(lo: float, hi: float, unit: str = "", open_lo: bool = False) -> Check:
    what = f"a number in {'(' if open_lo else '['}{lo:g}, {hi:g}]"
    return _num(what, lambda x: (lo < x if open_lo else lo <= x) and x <= hi, unit)


def integer(lo: int = 0, hi: int = (1 << 63) - 1) -> Check:
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise _Bad(f"an integer >= {lo}" if hi == (1 << 63) - 1 else f"an integer in [{lo}, {hi}]")
        return v

    return check


def string(v: Any) -> str:
    if not isinstance(v, str):
        raise _Bad("a string")
    return v


def text(limit: int) -> Check:
    """One line of printable text of at most ``limit`` characters (descriptions)."""

    def check(v: Any) -> str:
        if not isinstance(v, str) or len(v) > limit or not v.isprintable():
            raise _Bad(f"one line of printable text, at most {limit} characters")
        return v

    return check


_DATED = re.compile(r"([0-9]{4}-[0-9]{2}-[0-9]{2}): (.*\S.*)")


def dated(limit: int) -> Check:
    """One line of printable text of at most ``limit`` characters that opens with a real date,
    a colon and a space, and says something after them: "2026-12-04: shin 2 cm longer; faster"
    (a history entry; the date is compared with a ledger's, so it must be a date)."""
    what = f'one line "YYYY-MM-DD: what changed; why" (a date, then printable text; at most {limit} characters)'

    def check(v: Any) -> str:
        if not isinstance(v, str) or len(v) > limit or not v.isprintable():
            raise _Bad(what)
        m = _DATED.fullmatch(v)
        try:
            if m is None:
                raise ValueError
            datetime.date.fromisoformat(m.group(1))
        except ValueError:  # no date, or none that exists (2026-02-30)
            raise _Bad(what) from None
        return v

    return check


def nonempty(v: Any) -> str:
    """A name: printable, not blank, without spaces around it, at most spec.MAX_NAME characters.
    Surrounding spaces are refused rather than stripped: "L2" and " L2" would otherwise be two
    names that print alike, or, stripped, a reference that matches a name the file never wrote."""
    if not isinstance(v, str) or not v.strip() or len(v) > MAX_NAME or not v.isprintable() or v != v.strip():
        raise _Bad(f"a name (printable, not blank, no spaces around it, at most {MAX_NAME} characters)")
    return v


def boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise _Bad("true or false")
    return v


def one_of(options: Iterable[str], what: str = "one of") -> Check:
    options = list(options)

    def check(v: Any) -> str:
        if not isinstance(v, str) or v not in options:
            raise _Bad(f"{what} {options}" + did_you_mean(v, options))
        return v

    return check


def did_you_mean(v: Any, options: Iterable[str]) -> str:
    """" (did you mean 'mass'?)" when ``v`` is a string close to one of ``options``, else ""."""
    if not isinstance(v, str) or len(v) > 100:
        return ""
    close = difflib.get_close_matches(v, list(options), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


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
    what = "a pair of numbers [x, y]"
    coord = _num(what, unit=unit)

    def check(v: Any) -> Vec2:
        if not isinstance(v, list) or len(v) != 2:
            raise _Bad(what + _unit(unit))
        return (coord(v[0]), coord(v[1]))

    return check


def points(what: str, lo: int = 0, hi: int = MAX_POINTS) -> Check:
    """A list of ``lo`` to ``hi`` points [x, y] (m); ``what`` says so in messages."""
    return list_of(vec2(), what, lo, hi)


def link_pair(names: list[str]) -> Check:
    inner = list_of(one_of(names, "one of the link names"), "a pair of link names [from, to]", 2, 2)

    def check(v: Any) -> tuple[str, str]:
        a, b = inner(v)
        if a == b:
            raise _Bad("two different link names [from, to]")
        return (a, b)

    return check
