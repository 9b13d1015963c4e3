"""The library's one exception, and how SQLite's errors map onto it.

SQLite errors are told apart by their result code (``sqlite3.Error.sqlite_errorname``, e.g.
``SQLITE_BUSY`` or ``SQLITE_CONSTRAINT_PRIMARYKEY``), never by their message text, which SQLite
does not promise to keep.
"""

from __future__ import annotations

import sqlite3

from sanlab.creature import printable

MAX_MESSAGE = 600  # characters of a LibraryError's message


class LibraryError(Exception):
    """A one-line, user-facing problem with a gait library or a request to it.

    ``sqlite_errorname``: the SQLite result code behind it (e.g. ``"SQLITE_BUSY"``), or None when
    the problem was found by sanlab itself.
    """

    def __init__(self, message: str, *, sqlite_errorname: str | None = None):
        # One printable line of reasonable length whatever it quotes (a key with an escape
        # sequence, a value nested a thousand deep): it is printed as it is.
        message = printable(str(message))
        if len(message) > MAX_MESSAGE:
            message = message[: MAX_MESSAGE - 3] + "..."
        super().__init__(message)
        self.sqlite_errorname = sqlite_errorname


def errorname(e: BaseException) -> str:
    """The SQLite result code name of ``e`` (extended, e.g. ``SQLITE_BUSY_SNAPSHOT``), or ""."""
    return getattr(e, "sqlite_errorname", None) or ""


def _primary(name: str) -> str:
    # Extended result codes extend the primary name: SQLITE_BUSY_SNAPSHOT is a SQLITE_BUSY.
    return "_".join(name.split("_")[:2])


def is_busy(name: str | None) -> bool:
    """Another connection held a lock for longer than the busy timeout."""
    return _primary(name or "") in ("SQLITE_BUSY", "SQLITE_LOCKED")


def is_duplicate(name: str | None) -> bool:
    """A row's key (primary key or unique index) is already taken."""
    return name in ("SQLITE_CONSTRAINT_PRIMARYKEY", "SQLITE_CONSTRAINT_UNIQUE")


def from_sqlite(e: sqlite3.Error, path: str, timeout: float) -> LibraryError:
    """A :class:`LibraryError` for a SQLite error met while using the library at ``path``."""
    name = errorname(e)
    if is_busy(name):
        return LibraryError(f"{path}: database is locked (another process kept it busy for more "
                            f"than {timeout:g} s)", sqlite_errorname=name)
    return LibraryError(f"{path}: {e}", sqlite_errorname=name or None)
