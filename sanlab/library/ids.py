"""Gait ids: the one grammar for naming runs and gaits.

- ``RUN`` — a run: its 8 hex digits, or any unambiguous prefix (as with git commits).
- ``RUN/RANK`` — the RANK-th best evaluation of the run (1 = best), e.g. ``3fa1c2d0/1``. Ranks
  move while a run is still adding evaluations.
- ``RUN#IDX`` — the evaluation with index IDX, e.g. ``3fa1c2d0#17``. Permanent; this is the form
  stored in references (``Run.parent_gait``, ``Evaluation.parent``, exports).

Ids are case-insensitive and stored in lower case.
"""

from __future__ import annotations

import re
import sqlite3
from typing import Any

from sanlab.library.errors import LibraryError

_RUN_REF = re.compile(r"[0-9a-f]+")
# ASCII digits only: ``\d`` would also match other scripts' digits ("3fa1c2d0/" and an Arabic-Indic one read as rank 1)
_GAIT_ID = re.compile(r"([0-9a-f]+)(?:/([0-9]+)|#([0-9]+))")
_PERMANENT = re.compile(r"[0-9a-f]+#[0-9]+")
MAX_DIGITS = 30  # of a rank or an index: past an int64 a rank is simply not found; int() never meets a huge one
_SHAPE = re.compile(r"([^\s/#]+)(?:/[0-9]+|#[0-9]+)")  # a gait id's form, whatever its run part


def parse_gait_id(gait_id: Any) -> tuple[str, int | None, int | None]:
    """(run reference, rank, idx) of ``RUN/RANK`` or ``RUN#IDX``: exactly one of rank and idx is
    set. Raises LibraryError for anything else."""
    m = _GAIT_ID.fullmatch(gait_id.strip().lower()) if isinstance(gait_id, str) else None
    if m is None:
        shape = _SHAPE.fullmatch(gait_id.strip()) if isinstance(gait_id, str) else None
        if shape is not None:  # RUN/RANK or RUN#IDX in form, with a run part that is no run id
            bad = sorted({ch for ch in shape.group(1).lower() if ch not in "0123456789abcdef"})
            raise LibraryError(f"malformed gait id {gait_id!r}: its run part {shape.group(1)!r} has {', '.join(map(repr, bad))}, "
                               "which no run id has (run ids are hexadecimal: 0-9 and a-f, e.g. 3fa1c2d0)")
        raise LibraryError(f"malformed gait id {gait_id!r}: expected RUN/RANK (e.g. 3fa1c2d0/1, "
                           "1 = best) or RUN#IDX (e.g. 3fa1c2d0#17)")
    run_ref, rank, idx = m.group(1), m.group(2), m.group(3)
    if len(rank or idx) > MAX_DIGITS:
        raise LibraryError(f"malformed gait id {gait_id[:40]!r}{'...' * (len(gait_id) > 40)}: "
                           f"expected {'a rank' if rank is not None else 'an index'} of at most {MAX_DIGITS} digits")
    if rank is not None:
        if int(rank) < 1:
            raise LibraryError(f"malformed gait id {gait_id!r}: ranks start at 1 (the best)")
        return run_ref, int(rank), None
    return run_ref, None, int(idx)


def is_permanent(gait_id: Any) -> bool:
    """Whether ``gait_id`` is a permanent gait id ``RUN#IDX`` (lower case)."""
    return isinstance(gait_id, str) and _PERMANENT.fullmatch(gait_id) is not None


def resolve_run(conn: sqlite3.Connection, ref: str, path: str) -> str:
    """The full run id in the library at ``path`` (for messages) for an exact run id or an
    unambiguous prefix. Raises LibraryError if there is none or several."""
    return resolve_id(conn, "run", ref, path)


_ID_COLUMNS = {"run": ("runs", "run_id"), "design": ("designs", "design_id")}


def resolve_id(conn: sqlite3.Connection, kind: str, ref: str, path: str) -> str:
    """The full id of a ``kind`` ("run" or "design") in the library at ``path`` for an exact id
    or an unambiguous prefix (hex digits). Raises LibraryError if there is none or several."""
    table, column = _ID_COLUMNS[kind]
    key = str(ref).strip().lower()
    if not _RUN_REF.fullmatch(key):
        raise LibraryError(f"no {kind} {ref!r} in {path}")
    ids = [r[0] for r in conn.execute(
        f"SELECT {column} FROM {table} WHERE {column} GLOB ? ORDER BY {column} LIMIT 6", (key + "*",))]
    if key in ids:
        return key
    if not ids:
        raise LibraryError(f"no {kind} {ref!r} in {path}")
    if len(ids) > 1:
        shown = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
        raise LibraryError(f"{kind} id {ref!r} is ambiguous in {path}: it matches {shown}")
    return ids[0]
