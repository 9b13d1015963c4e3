"""The library file's schema: tables, header fields, and how an existing file is checked, created
or upgraded when it is opened.

A library is an SQLite file whose header says ``application_id`` = :data:`APPLICATION_ID` and
``user_version`` = the schema version it was written with. Opening a file with an older schema
version applies :data:`MIGRATIONS` in order, in one transaction; a newer one is refused. Opened
read-only, an older file is read as it is (nothing is written).

Version 2 adds ``runs.owner``: which process (host, pid, start time) writes a running run, so
that a run whose process was killed outright reads as "interrupted", not "running" for ever; and
``fell`` to the rank index, which ranks a gait that stayed up before one that fell at equal scores.
Version 3 adds ``audits`` and version 4 ``selections`` (``sanlab audit``). Version 5 adds
``designs`` and ``design_scores`` (``sanlab design``: each design's outer record, its bodies'
scores written as they are made; its inner searches and tunings are runs as before).
"""

from __future__ import annotations

import codecs
import os
import sqlite3
from collections.abc import Callable

from sanlab.creature.files import NotRegularFile, read_regular_file
from sanlab.library.errors import LibraryError

APPLICATION_ID = 0x53414E4C  # "SANL": marks the file as a sanlab library (PRAGMA application_id)
SCHEMA_VERSION = 5  # PRAGMA user_version

RUN_KINDS = ("search", "tune", "import")
RUN_STATUSES = ("running", "done", "interrupted")
DESIGN_STATUSES = RUN_STATUSES  # a design is running, done, or interrupted like a run

RANK_INDEX = "CREATE INDEX evaluations_by_rank ON evaluations (run_id, nonfinite, score DESC, fell, idx)"

DDL = (
    """
    CREATE TABLE runs (
        run_id         TEXT PRIMARY KEY,
        kind           TEXT NOT NULL CHECK (kind IN ('search', 'tune', 'import')),
        created        TEXT NOT NULL,           -- ISO 8601, UTC
        creature       TEXT NOT NULL,           -- creature name
        creature_text  TEXT NOT NULL,           -- the creature file, verbatim
        creature_hash  TEXT NOT NULL,           -- sha256 hex of creature_text (UTF-8)
        params         TEXT NOT NULL,           -- JSON object: everything about the run
        seed           INTEGER,
        sanlab_version TEXT NOT NULL,
        device         TEXT,
        dtype          TEXT,
        status         TEXT NOT NULL CHECK (status IN ('running', 'done', 'interrupted')),
        parent_gait    TEXT,                    -- 'RUN#IDX' a tuning run starts from
        total          INTEGER NOT NULL CHECK (total >= 0), -- evaluations planned
        owner          TEXT                     -- JSON {host, pid, start} of the process writing it
    )
    """,
    "CREATE INDEX runs_by_created ON runs (created)",
    "CREATE INDEX runs_by_creature ON runs (creature_hash)",
    """
    CREATE TABLE evaluations (
        run_id     TEXT NOT NULL REFERENCES runs (run_id) ON DELETE CASCADE,
        idx        INTEGER NOT NULL CHECK (idx >= 0),
        encoding   TEXT NOT NULL,               -- printable controller encoding
        params     TEXT NOT NULL,               -- JSON object: node delays etc.
        score      REAL,                        -- NULL when the score was NaN
        speed_cm_s REAL,
        fell       INTEGER NOT NULL CHECK (fell IN (0, 1)),
        nonfinite  INTEGER NOT NULL CHECK (nonfinite IN (0, 1)),
        extra      TEXT,                        -- JSON object or NULL
        parent     TEXT,                        -- 'RUN#IDX' of the gait this one was tuned from
        PRIMARY KEY (run_id, idx)
    )
    """,
    # Serves top() and gait('RUN/RANK') without sorting the run's evaluations: its columns are
    # store._RANK_ORDER's, in its order.
    RANK_INDEX,
    """
    CREATE TABLE trace (
        run_id   TEXT NOT NULL REFERENCES runs (run_id) ON DELETE CASCADE,
        trial    INTEGER NOT NULL CHECK (trial >= 0),
        score    REAL,
        accepted INTEGER NOT NULL CHECK (accepted IN (0, 1)),
        PRIMARY KEY (run_id, trial)
    ) WITHOUT ROWID
    """,
)
# Version 3: artefact audits (``sanlab audit``), one per audited gait, the latest kept.
AUDITS_DDL = """
    CREATE TABLE audits (
        run_id      TEXT NOT NULL,
        idx         INTEGER NOT NULL,
        created     TEXT NOT NULL,              -- ISO 8601, UTC
        flagged     INTEGER NOT NULL CHECK (flagged IN (0, 1)),  -- resolution-dependent
        worst       REAL,                       -- largest relative change of the speed
        result      TEXT NOT NULL,              -- JSON object: every nudge's scores
        PRIMARY KEY (run_id, idx),
        FOREIGN KEY (run_id, idx) REFERENCES evaluations (run_id, idx) ON DELETE CASCADE
    ) WITHOUT ROWID
    """
# Version 4: audited selections (``sanlab audit RUN --select``), one per tuning run, the latest
# kept; the chosen gait itself is an evaluation of the run (with its audit).
SELECTIONS_DDL = """
    CREATE TABLE selections (
        run_id      TEXT PRIMARY KEY REFERENCES runs (run_id) ON DELETE CASCADE,
        created     TEXT NOT NULL,              -- ISO 8601, UTC
        idx         INTEGER,                    -- the chosen gait's evaluation; NULL: no rung survived
        result      TEXT NOT NULL               -- JSON object: settings and every audited rung
    ) WITHOUT ROWID
    """
# Version 5: designs (``sanlab design``). A design is found again by its creature file and
# settings (``sanlab design`` made again continues it); each body's score on each seed is a row,
# written as it is made, so that an interrupted design shows what it has.
DESIGNS_DDL = """
    CREATE TABLE designs (
        design_id      TEXT PRIMARY KEY,        -- 8 hex digits (its own namespace, not a run id)
        created        TEXT NOT NULL,           -- ISO 8601, UTC
        updated        TEXT NOT NULL,           -- ISO 8601, UTC: its last score or status
        creature       TEXT NOT NULL,           -- creature name
        source         TEXT NOT NULL,           -- where the file was read (a path)
        creature_text  TEXT NOT NULL,           -- the file with free numbers, verbatim
        creature_hash  TEXT NOT NULL,           -- sha256 hex of creature_text (UTF-8)
        settings       TEXT NOT NULL,           -- JSON object: sanlab.design.DesignSettings
        free           TEXT NOT NULL,           -- JSON array: [{name, path, min, max, default, unit}]
        status         TEXT NOT NULL CHECK (status IN ('running', 'done', 'interrupted')),
        owner          TEXT,                    -- JSON {host, pid, start} of the process writing it
        result         TEXT,                    -- JSON object once done: {chosen: {round, index}, seconds, text}
        sanlab_version TEXT NOT NULL
    )
    """
DESIGNS_INDEX = "CREATE INDEX designs_by_creature ON designs (creature_hash)"
DESIGN_SCORES_DDL = """
    CREATE TABLE design_scores (
        design_id  TEXT NOT NULL REFERENCES designs (design_id) ON DELETE CASCADE,
        round      INTEGER NOT NULL CHECK (round >= -1),   -- the strategy's round; -1: the reference
        idx        INTEGER NOT NULL CHECK (idx >= 0),      -- the body's place in its round
        seed       INTEGER NOT NULL,                       -- the search's seed or a validation seed
        body       TEXT NOT NULL,                          -- JSON array [D]: the free values
        speed_cm_s REAL,                                   -- robust tuned speed (0: none kept, or pruned)
        gait       TEXT,                                   -- RUN#IDX of the robust gait, NULL: none
        pruned     INTEGER NOT NULL CHECK (pruned IN (0, 1)),
        record     TEXT NOT NULL,                          -- JSON object: sanlab.reproduce.robust_tuned's
        PRIMARY KEY (design_id, round, idx, seed)
    ) WITHOUT ROWID
    """
DDL = (*DDL, AUDITS_DDL, SELECTIONS_DDL, DESIGNS_DDL, DESIGNS_INDEX, DESIGN_SCORES_DDL)
TABLES = ("runs", "evaluations", "trace", "audits", "selections", "designs", "design_scores")
# tables an older file, read as it is (read-only), does not have yet
ADDED_IN = {"audits": 3, "selections": 4, "designs": 5, "design_scores": 5}

# MIGRATIONS[v] upgrades a version-v file to version v + 1 inside the open transaction; DDL
# always creates the newest schema directly.
Migration = Callable[[sqlite3.Connection], None]


def _owner_and_fell(conn: sqlite3.Connection) -> None:
    conn.execute("ALTER TABLE runs ADD COLUMN owner TEXT")
    conn.execute("DROP INDEX IF EXISTS evaluations_by_rank")
    conn.execute(RANK_INDEX)


def _add_audits(conn: sqlite3.Connection) -> None:
    conn.execute(AUDITS_DDL)


def _add_selections(conn: sqlite3.Connection) -> None:
    conn.execute(SELECTIONS_DDL)


def _add_designs(conn: sqlite3.Connection) -> None:
    for statement in (DESIGNS_DDL, DESIGNS_INDEX, DESIGN_SCORES_DDL):
        conn.execute(statement)


MIGRATIONS: dict[int, Migration] = {1: _owner_and_fell, 2: _add_audits, 3: _add_selections, 4: _add_designs}

_SQLITE_MAGIC = b"SQLite format 3\x00"


def check_file(path: str) -> None:
    """Refuse, before SQLite sees it, anything that cannot be a library at ``path``.

    A missing file is fine (it will be created) if its directory exists; so is an empty file.
    Raises LibraryError otherwise, naming ``path``.
    """
    if path == ":memory:" or path.startswith("file:"):
        return
    if not path.strip():
        raise LibraryError("the gait library's path is empty (give --db PATH)")
    if os.path.isdir(path):
        raise LibraryError(f"{path}: is a directory, not a gait library")
    if not os.path.exists(path):
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            raise LibraryError(f"{path}: cannot create a gait library there: "
                               f"directory {folder} does not exist")
        return
    try:  # opened without blocking: a FIFO or a device is refused, never waited on
        head = read_regular_file(path, 0, head=4096)
    except NotRegularFile as e:
        raise LibraryError(f"{path}: is {e.kind}, not a gait library (give --db the path of a file)") from None
    except OSError as e:
        raise LibraryError(f"{path}: cannot read: {e.strerror or e}") from None
    if head and not head.startswith(_SQLITE_MAGIC):  # an empty file becomes a new library
        what = "it is a text file" if _looks_like_text(head) else "unrecognised binary content"
        raise LibraryError(f"{path}: not a database file ({what})")


def open_schema(conn: sqlite3.Connection, path: str, readonly: bool = False) -> None:
    """Make ``conn`` (autocommit mode) ready to use: create the schema in an empty file, upgrade
    an older one, refuse a foreign, newer or damaged one (LibraryError naming ``path``); then set
    WAL journaling, ``synchronous = NORMAL`` and foreign keys. ``readonly``: write nothing (an
    empty file is refused, an older schema read as it is)."""
    app_id = conn.execute("PRAGMA application_id").fetchone()[0]
    version = conn.execute("PRAGMA user_version").fetchone()[0]
    if app_id == 0 and version == 0 and _is_empty(conn):
        if readonly:
            raise LibraryError(f"{path}: an empty file, not yet a gait library (a search creates one)")
        _create(conn)
    elif app_id != APPLICATION_ID:
        raise LibraryError(f"{path}: not a sanlab gait library "
                           "(it is an SQLite database of another application)")
    elif version > SCHEMA_VERSION:
        raise LibraryError(f"{path}: written by a newer sanlab (library schema version "
                           f"{version}; this sanlab reads up to {SCHEMA_VERSION})")
    elif version < 1:
        raise LibraryError(f"{path}: damaged sanlab gait library (schema version {version})")
    elif version < SCHEMA_VERSION and not readonly:
        _upgrade(conn, path)
    if not readonly:
        version = SCHEMA_VERSION  # created or upgraded
    missing = [t for t in TABLES if ADDED_IN.get(t, 1) <= version and not _has_table(conn, t)]
    if missing:
        raise LibraryError(f"{path}: damaged sanlab gait library (missing table {missing[0]!r})")
    if readonly:
        return
    # WAL is persistent in the file; setting it again would need a lock a writer may hold.
    if conn.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
        conn.execute("PRAGMA journal_mode = WAL")
    conn.execute("PRAGMA synchronous = NORMAL")  # with WAL: durable against process crashes
    conn.execute("PRAGMA foreign_keys = ON")


def _create(conn: sqlite3.Connection) -> None:
    conn.execute("PRAGMA journal_mode = WAL")
    with _transaction(conn):
        # Another process may have created the library since we looked.
        if _is_empty(conn):
            for statement in DDL:
                conn.execute(statement)
            # Header fields are transactional: a library is either complete or absent.
            conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")


def _upgrade(conn: sqlite3.Connection, path: str) -> None:
    with _transaction(conn):
        # Read again under the write lock: another process may have upgraded it meanwhile.
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        for v in range(version, SCHEMA_VERSION):
            if v not in MIGRATIONS:
                raise LibraryError(f"{path}: no upgrade from library schema version {v}")
            MIGRATIONS[v](conn)
        conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")


class _transaction:
    """BEGIN IMMEDIATE ... COMMIT, or ROLLBACK on any exception (``conn`` in autocommit mode)."""

    def __init__(self, conn: sqlite3.Connection):
        self.conn = conn

    def __enter__(self) -> sqlite3.Connection:
        self.conn.execute("BEGIN IMMEDIATE")
        return self.conn

    def __exit__(self, kind, value, tb) -> None:
        if kind is None:
            self.conn.execute("COMMIT")
        elif self.conn.in_transaction:
            self.conn.execute("ROLLBACK")


def _looks_like_text(head: bytes) -> bool:
    if b"\x00" in head:
        return False
    try:
        codecs.getincrementaldecoder("utf-8")().decode(head, final=False)
    except UnicodeDecodeError:
        return False
    return True


def _is_empty(conn: sqlite3.Connection) -> bool:
    return conn.execute("SELECT count(*) FROM sqlite_schema").fetchone()[0] == 0


def _has_table(conn: sqlite3.Connection, name: str) -> bool:
    return conn.execute("SELECT 1 FROM sqlite_schema WHERE type = 'table' AND name = ?",
                        (name,)).fetchone() is not None
