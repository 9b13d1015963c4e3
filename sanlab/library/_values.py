"""Python values into and out of the library's columns: checked integers and reals (NaN is
stored as NULL), canonical JSON, strict JSON for export, and the creature text's hash. Every
check raises LibraryError naming ``what`` was wrong."""

from __future__ import annotations

import hashlib
import json
import math
import operator
from typing import Any

from sanlab.library.errors import LibraryError


def sha256(text: str) -> str:
    """Hex SHA-256 of ``text`` encoded as UTF-8 (``runs.creature_hash``)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _json_default(obj: Any) -> Any:
    # NumPy scalars and arrays, so callers need not convert them by hand.
    if hasattr(obj, "tolist"):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON-serialisable")


def to_json(obj: Any, what: str, finite: bool = False) -> str:
    """Canonical JSON text of ``obj`` (sorted keys, no spaces) for a TEXT column: strict JSON,
    never NaN or Infinity (which strict readers refuse). ``finite``: refuse a non-finite number
    (run settings, where null would change their meaning); else store it as null."""
    try:
        if finite:
            return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_json_default, allow_nan=False)
        return json.dumps(strict_json(json.loads(json.dumps(obj, default=_json_default))), sort_keys=True,
                          separators=(",", ":"), allow_nan=False)
    except ValueError as e:
        if finite and "Out of range float" in str(e):
            raise LibraryError(f"{what} hold a number that is not finite (NaN or infinity)") from None
        raise LibraryError(f"{what} are not JSON-serialisable: {e}") from None
    except TypeError as e:
        raise LibraryError(f"{what} are not JSON-serialisable: {e}") from None
    except RecursionError:
        raise LibraryError(f"{what} are nested too deep to store") from None


INT64 = (-(1 << 63), (1 << 63) - 1)  # what an SQLite INTEGER holds


def integer(value: Any, what: str) -> int:
    """``value`` as an int an SQLite INTEGER column holds (64 bits, signed)."""
    if isinstance(value, bool):
        raise LibraryError(f"{what} must be an integer, not {value!r}")
    try:
        i = operator.index(value)
    except TypeError:
        raise LibraryError(f"{what} must be an integer, not {_short(value)}") from None
    if not INT64[0] <= i <= INT64[1]:
        raise LibraryError(f"{what} must be an integer in [-2**63, 2**63 - 1], not {_short(i)}")
    return i


def text(value: Any, what: str) -> str:
    """``value`` as a str a TEXT column can hold (UTF-8: no lone surrogates)."""
    if not isinstance(value, str):
        raise LibraryError(f"{what} must be a str, not {type(value).__name__}")
    try:
        value.encode("utf-8")
    except UnicodeEncodeError as e:
        raise LibraryError(f"{what} is not valid Unicode text (a lone surrogate at {e.start})") from None
    return value


def _short(value: Any) -> str:
    s = repr(value)
    return s if len(s) <= 40 else s[:37] + "..."


def index(value: Any, what: str) -> int:
    i = integer(value, what)
    if i < 0:
        raise LibraryError(f"{what} must be >= 0, not {i}")
    return i


def real(value: Any, what: str) -> float | None:
    """A float for a REAL column; NaN becomes NULL (SQLite would do so anyway)."""
    if value is None:
        return None
    if isinstance(value, (bool, str, bytes)):
        raise LibraryError(f"{what} must be a number, not {_short(value)}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise LibraryError(f"{what} must be a number, not {_short(value)}") from None
    return None if math.isnan(x) else x


class Damaged(ValueError):
    """A stored cell that cannot be read back (bad UTF-8, bad JSON, a value of the wrong type):
    ``what`` says which and why. The store turns it into a LibraryError naming the run."""


def as_float(value: Any) -> float:
    """A REAL column's value as a float: NULL reads back as NaN; anything else is damage."""
    if value is None:
        return math.nan
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    raise Damaged(f"a number was expected, the cell holds {_short(value)}")


class BadText(str):
    """What the connection's text factory returns for TEXT that is not UTF-8: the text decoded
    with U+FFFD in place of the bad bytes (fit to list), marked so that reading it strictly
    (:func:`from_text`, :func:`from_json`) refuses it."""


def decode_text(data: bytes) -> str:
    """The library connection's ``text_factory``: UTF-8, or a :class:`BadText`."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return BadText(data.decode("utf-8", "replace"))


def from_text(value: Any) -> str:
    """A TEXT cell read strictly: a str of valid UTF-8, or :class:`Damaged`."""
    if isinstance(value, BadText):
        raise Damaged("its text is not valid UTF-8")
    if not isinstance(value, str):
        raise Damaged(f"text was expected, the cell holds {type(value).__name__}")
    return value


def from_json(value: Any, kind: type = dict) -> Any:
    """A JSON cell read strictly: an object (``kind``), or :class:`Damaged`."""
    try:
        obj = json.loads(from_text(value))
    except (json.JSONDecodeError, RecursionError):
        raise Damaged("it is not valid JSON") from None
    if not isinstance(obj, kind):
        raise Damaged(f"a JSON {kind.__name__} was expected, it holds a {type(obj).__name__}")
    return obj


def strict_json(obj: Any) -> Any:
    """``obj`` with every NaN or infinity replaced by None: strict JSON has neither."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [strict_json(v) for v in obj]
    return obj
