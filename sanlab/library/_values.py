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
    # NumPy / JAX scalars and arrays, so callers need not convert them by hand.
    if hasattr(obj, "tolist"):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON-serialisable")


def to_json(obj: Any, what: str) -> str:
    """Canonical JSON text of ``obj`` (sorted keys, no spaces) for a TEXT column."""
    try:
        return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_json_default)
    except (TypeError, ValueError) as e:
        raise LibraryError(f"{what} are not JSON-serialisable: {e}") from None


def integer(value: Any, what: str) -> int:
    if isinstance(value, bool):
        raise LibraryError(f"{what} must be an integer, not {value!r}")
    try:
        return operator.index(value)
    except TypeError:
        raise LibraryError(f"{what} must be an integer, not {value!r}") from None


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
        raise LibraryError(f"{what} must be a number, not {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise LibraryError(f"{what} must be a number, not {value!r}") from None
    return None if math.isnan(x) else x


def as_float(value: float | None) -> float:
    """A REAL column's value as a float: NULL reads back as NaN."""
    return math.nan if value is None else float(value)


def strict_json(obj: Any) -> Any:
    """``obj`` with every NaN or infinity replaced by None: strict JSON has neither."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [strict_json(v) for v in obj]
    return obj
