"""The gait library: every run and every evaluated controller, in one SQLite file.

A search (paper §5.2) or a tuning run (§5.3) is a *run*; each controller it simulates is an
*evaluation* of that run, addressed by its index ``idx`` (0..N-1). Gaits are named in two ways:

- ``RUN/RANK`` — the RANK-th best evaluation of the run (1 = best), e.g. ``3fa1c2d0/1``. Ranks
  move while a run is still adding evaluations.
- ``RUN#IDX`` — the evaluation with index IDX, e.g. ``3fa1c2d0#17``. Permanent; this is the form
  stored in references (``Run.parent_gait``, ``Evaluation.parent``, exports).

RUN may be any unambiguous prefix of a run id, as with git commits.

The file uses WAL journaling, so readers (``sanlab runs``, a second terminal) never block a
search that is writing and are never blocked by it; each batch of evaluations is one short
transaction, so a crash loses at most the batch in flight.
"""

from __future__ import annotations

import codecs
import hashlib
import json
import math
import operator
import os
import re
import secrets
import sqlite3
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any, Iterator

from sanlab import __version__

DEFAULT_PATH = "sanlab.db"

APPLICATION_ID = 0x53414E4C  # "SANL": marks the file as a sanlab library (PRAGMA application_id)
SCHEMA_VERSION = 1  # PRAGMA user_version
GAIT_FORMAT = "sanlab-gait"
GAIT_FORMAT_VERSION = 1

RUN_KINDS = ("search", "tune", "import")
RUN_STATUSES = ("running", "done", "interrupted")

_SQLITE_MAGIC = b"SQLite format 3\x00"

_SCHEMA = (
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
        total          INTEGER NOT NULL CHECK (total >= 0)  -- evaluations planned
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
    # Serves top() and gait('RUN/RANK') without sorting the run's evaluations.
    "CREATE INDEX evaluations_by_rank ON evaluations (run_id, nonfinite, score DESC, idx)",
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
_TABLES = ("runs", "evaluations", "trace")

# Best first; non-finite ones (and NaN scores, stored as NULL, which sort last under DESC) last.
_RANK_ORDER = "nonfinite ASC, score DESC, idx ASC"

_RUN_REF = re.compile(r"[0-9a-f]+")
_GAIT_ID = re.compile(r"([0-9a-f]+)(?:/(\d+)|#(\d+))")
_PARENT_REF = re.compile(r"[0-9a-f]+#\d+")

_ROW_KEYS = {"idx", "encoding", "params", "score", "speed_cm_s", "fell", "nonfinite", "extra",
             "parent"}
_ROW_REQUIRED = {"idx", "encoding", "score"}


class LibraryError(Exception):
    """A one-line, user-facing problem with a gait library or a request to it."""


@dataclass(frozen=True)
class Run:
    """One search or tuning run (or one imported gait)."""

    run_id: str  # 8 lowercase hex characters
    kind: str  # "search", "tune" or "import"
    created: str  # ISO 8601 UTC
    creature: str  # creature name
    creature_text: str = field(repr=False)  # the creature file, verbatim
    creature_hash: str = field(repr=False)  # sha256 hex of creature_text
    params: dict = field(repr=False)  # everything about the run (seconds, metric, batch, ...)
    seed: int | None
    sanlab_version: str
    device: str | None
    dtype: str | None
    status: str  # "running", "done" or "interrupted"
    parent_gait: str | None  # "RUN#IDX" a tuning run starts from
    total: int  # evaluations planned
    count: int  # evaluations stored


@dataclass(frozen=True)
class Evaluation:
    """One evaluated controller of a run."""

    run_id: str
    idx: int  # index within the run, 0..N-1
    encoding: str  # printable controller encoding
    params: dict  # node delays etc.
    score: float  # NaN when the score was not a number
    speed_cm_s: float  # NaN when unknown
    fell: bool
    nonfinite: bool  # the simulation or the score went non-finite; ranked last
    extra: dict | None  # metric details etc.
    parent: str | None  # "RUN#IDX" of the gait this one was tuned from
    rank: int | None = None  # 1-based place in the run's ranking, when looked up by rank

    @property
    def gait_id(self) -> str:
        """The permanent address of this evaluation, ``RUN#IDX``."""
        return f"{self.run_id}#{self.idx}"


@dataclass(frozen=True)
class TracePoint:
    """One trial of a tuning run."""

    trial: int
    score: float
    accepted: bool


class Library:
    """A gait library file; ``with Library(path) as lib: ...``."""

    def __init__(self, path: str | os.PathLike = DEFAULT_PATH, *, timeout: float = 30.0):
        self.path = os.fspath(path)
        self.timeout = timeout
        self._conn: sqlite3.Connection | None = None
        _check_file(self.path)
        try:
            # Autocommit mode: transactions are opened explicitly (BEGIN IMMEDIATE) by _write.
            conn = sqlite3.connect(self.path, timeout=timeout, isolation_level=None)
        except sqlite3.Error as e:
            raise LibraryError(f"{self.path}: cannot open: {e}") from None
        conn.row_factory = sqlite3.Row
        try:
            self._open(conn)
        except LibraryError:
            conn.close()
            raise
        except sqlite3.Error as e:
            conn.close()
            if "locked" in str(e) or "busy" in str(e):
                raise LibraryError(f"{self.path}: database is locked (another process kept it "
                                   f"busy for more than {timeout:g} s)") from None
            raise LibraryError(f"{self.path}: not a usable database file ({e})") from None
        self._conn = conn

    def _open(self, conn: sqlite3.Connection) -> None:
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        if app_id == 0 and version == 0 and _is_empty(conn):
            self._create(conn)
        elif app_id != APPLICATION_ID:
            raise LibraryError(f"{self.path}: not a sanlab gait library "
                               "(it is an SQLite database of another application)")
        elif version > SCHEMA_VERSION:
            raise LibraryError(f"{self.path}: written by a newer sanlab (library schema version "
                               f"{version}; this sanlab reads up to {SCHEMA_VERSION})")
        elif version < 1:
            raise LibraryError(f"{self.path}: damaged sanlab gait library (schema version "
                               f"{version})")
        missing = [t for t in _TABLES if not _has_table(conn, t)]
        if missing:
            raise LibraryError(f"{self.path}: damaged sanlab gait library "
                               f"(missing table {missing[0]!r})")
        # WAL is persistent in the file; setting it again would need a lock a writer may hold.
        if conn.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
            conn.execute("PRAGMA journal_mode = WAL")
        conn.execute("PRAGMA synchronous = NORMAL")  # with WAL: durable against process crashes
        conn.execute("PRAGMA foreign_keys = ON")

    def _create(self, conn: sqlite3.Connection) -> None:
        conn.execute("PRAGMA journal_mode = WAL")
        conn.execute("BEGIN IMMEDIATE")
        try:
            # Another process may have created the library since we looked.
            if _is_empty(conn):
                for statement in _SCHEMA:
                    conn.execute(statement)
                # Header fields are transactional: a library is either complete or absent.
                conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            conn.execute("COMMIT")
        except BaseException:
            if conn.in_transaction:
                conn.execute("ROLLBACK")
            raise

    # -- plumbing --------------------------------------------------------------------------------

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def __enter__(self) -> Library:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Library({self.path!r})"

    @contextmanager
    def _sql(self) -> Iterator[sqlite3.Connection]:
        """The connection, with sqlite3 errors turned into one-line LibraryErrors."""
        if self._conn is None:
            raise LibraryError(f"{self.path}: the library is closed")
        try:
            yield self._conn
        except sqlite3.OperationalError as e:
            if "locked" in str(e) or "busy" in str(e):
                raise LibraryError(f"{self.path}: database is locked (another process kept it "
                                   f"busy for more than {self.timeout:g} s)") from None
            raise LibraryError(f"{self.path}: {e}") from None
        except sqlite3.Error as e:
            raise LibraryError(f"{self.path}: {e}") from None

    @contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One short write transaction: all of it commits, or none of it."""
        with self._sql() as conn:
            # IMMEDIATE takes the write lock up front, so the busy timeout applies here rather
            # than failing later when a read transaction tries to upgrade.
            conn.execute("BEGIN IMMEDIATE")
            try:
                yield conn
            except BaseException:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                raise
            conn.execute("COMMIT")

    def _resolve(self, ref: str) -> str:
        """The full run id for an exact id or an unambiguous prefix."""
        key = str(ref).strip().lower()
        if not _RUN_REF.fullmatch(key):
            raise LibraryError(f"no run {ref!r} in {self.path}")
        with self._sql() as conn:
            ids = [r[0] for r in conn.execute(
                "SELECT run_id FROM runs WHERE run_id GLOB ? ORDER BY run_id LIMIT 6",
                (key + "*",))]
        if key in ids:
            return key
        if not ids:
            raise LibraryError(f"no run {ref!r} in {self.path}")
        if len(ids) > 1:
            shown = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
            raise LibraryError(f"run id {ref!r} is ambiguous in {self.path}: it matches {shown}")
        return ids[0]

    def _require_run(self, conn: sqlite3.Connection, run_id: str) -> None:
        if conn.execute("SELECT 1 FROM runs WHERE run_id = ?", (run_id,)).fetchone() is None:
            raise LibraryError(f"no run {run_id!r} in {self.path}")

    # -- runs ------------------------------------------------------------------------------------

    def create_run(self, kind: str, creature: str, creature_text: str, params: dict,
                   seed: int | None, total: int, dtype: str | None = None,
                   device: str | None = None, sanlab_version: str | None = None,
                   parent_gait: str | None = None) -> Run:
        """Record a new run (status "running") and return it.

        ``parent_gait`` (a tuning run's starting gait) may be given in either gait id form; it is
        stored as the permanent ``RUN#IDX``.
        """
        if kind not in RUN_KINDS:
            raise LibraryError(f"unknown run kind {kind!r} "
                               f"(expected one of {', '.join(RUN_KINDS)})")
        if not isinstance(creature_text, str):
            raise LibraryError("creature_text must be the creature file's text (a str)")
        if not isinstance(params, dict):
            raise LibraryError("run params must be a dict")
        total = _index(total, "total")
        if parent_gait is not None:
            parent_gait = self.gait(parent_gait).gait_id
        values = dict(
            kind=kind, created=datetime.now(timezone.utc).isoformat(timespec="microseconds"),
            creature=str(creature), creature_text=creature_text,
            creature_hash=_sha256(creature_text), params=_to_json(params, "run params"),
            seed=None if seed is None else _integer(seed, "seed"),
            sanlab_version=sanlab_version or __version__, device=device, dtype=dtype,
            status="done" if kind == "import" else "running", parent_gait=parent_gait,
            total=total)
        for _ in range(20):
            run_id = secrets.token_hex(4)
            try:
                with self._write() as conn:
                    conn.execute(
                        f"INSERT INTO runs (run_id, {', '.join(values)}) "
                        f"VALUES (?{', ?' * len(values)})", (run_id, *values.values()))
            except LibraryError:
                with self._sql() as conn:
                    taken = conn.execute("SELECT 1 FROM runs WHERE run_id = ?",
                                         (run_id,)).fetchone()
                if taken:  # 1 in 4 billion per existing run: draw another id
                    continue
                raise
            return self.get_run(run_id)
        raise LibraryError(f"{self.path}: could not find a free run id")

    def set_status(self, run_id: str, status: str) -> None:
        """Mark a run "running", "done" or "interrupted"."""
        if status not in RUN_STATUSES:
            raise LibraryError(f"unknown run status {status!r} "
                               f"(expected one of {', '.join(RUN_STATUSES)})")
        with self._write() as conn:
            if conn.execute("UPDATE runs SET status = ? WHERE run_id = ?",
                            (status, run_id)).rowcount == 0:
                raise LibraryError(f"no run {run_id!r} in {self.path}")

    def get_run(self, run_id: str) -> Run:
        """The run with this id or unambiguous id prefix."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            row = conn.execute(_RUNS_QUERY + " WHERE r.run_id = ?", (run_id,)).fetchone()
        return _run(row)

    def runs(self) -> list[Run]:
        """All runs, newest first."""
        with self._sql() as conn:
            rows = conn.execute(_RUNS_QUERY + " ORDER BY r.created DESC, r.rowid DESC").fetchall()
        return [_run(r) for r in rows]

    # -- evaluations -----------------------------------------------------------------------------

    def add_batch(self, run_id: str, rows: list[dict], *, replace: bool = False) -> None:
        """Store evaluated controllers of a run, all in one transaction.

        Each row is a dict with ``idx``, ``encoding`` and ``score`` and optionally ``params``
        (dict), ``speed_cm_s``, ``fell``, ``nonfinite``, ``extra`` (dict) and ``parent``
        ("RUN#IDX"). A score that is not finite marks the row non-finite. Storing an idx the run
        already has is an error unless ``replace=True``.
        """
        values = [_evaluation_values(run_id, i, row) for i, row in enumerate(rows)]
        seen: set[int] = set()
        for v in values:
            if v[1] in seen:
                raise LibraryError(f"the batch holds idx {v[1]} twice")
            seen.add(v[1])
        verb = "INSERT OR REPLACE" if replace else "INSERT"
        try:
            with self._write() as conn:
                self._require_run(conn, run_id)
                conn.executemany(
                    f"{verb} INTO evaluations (run_id, idx, encoding, params, score, speed_cm_s, "
                    "fell, nonfinite, extra, parent) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    values)
        except LibraryError:
            if replace:
                raise
            with self._sql() as conn:
                stored = {r[0] for r in conn.execute(
                    "SELECT idx FROM evaluations WHERE run_id = ?", (run_id,))}
            clash = sorted(seen & stored)
            if clash:
                shown = ", ".join(f"#{i}" for i in clash[:5]) + (", ..." if len(clash) > 5 else "")
                raise LibraryError(f"run {run_id} already has evaluation {shown} "
                                   "(pass replace=True to overwrite); nothing of the batch "
                                   "was stored") from None
            raise

    def done_indices(self, run_id: str) -> set[int]:
        """The indices of the run's stored evaluations (to resume an interrupted run)."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            return {r[0] for r in conn.execute("SELECT idx FROM evaluations WHERE run_id = ?",
                                               (run_id,))}

    def count(self, run_id: str) -> int:
        """How many evaluations the run has stored."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            return conn.execute("SELECT count(*) FROM evaluations WHERE run_id = ?",
                                (run_id,)).fetchone()[0]

    def top(self, run_id: str, n: int | None = 10) -> list[Evaluation]:
        """The run's best ``n`` evaluations (all with ``n=None``), best first, with ranks.

        Ranked by score descending, ties by idx ascending; non-finite evaluations come last.
        """
        run_id = self._resolve(run_id)
        limit = -1 if n is None else max(0, _integer(n, "n"))
        with self._sql() as conn:
            rows = conn.execute(f"SELECT * FROM evaluations WHERE run_id = ? "
                                f"ORDER BY {_RANK_ORDER} LIMIT ?", (run_id, limit)).fetchall()
        return [_evaluation(r, rank) for rank, r in enumerate(rows, 1)]

    def scores(self, run_id: str) -> list[float]:
        """Every stored score of the run in idx order (NaN where the score was not a number)."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            return [_float(r[0]) for r in conn.execute(
                "SELECT score FROM evaluations WHERE run_id = ? ORDER BY idx", (run_id,))]

    def gait(self, gait_id: str) -> Evaluation:
        """The evaluation named ``RUN/RANK`` (1-based, best first) or ``RUN#IDX``."""
        run_ref, rank, idx = _parse_gait_id(gait_id)
        run_id = self._resolve(run_ref)
        with self._sql() as conn:
            if rank is not None:
                row = conn.execute(f"SELECT * FROM evaluations WHERE run_id = ? "
                                   f"ORDER BY {_RANK_ORDER} LIMIT 1 OFFSET ?",
                                   (run_id, rank - 1)).fetchone()
                if row is None:
                    n = self.count(run_id)
                    raise LibraryError(f"no gait {gait_id!r}: run {run_id} has {n} "
                                       f"evaluation{'s' * (n != 1)}")
                return _evaluation(row, rank)
            row = conn.execute(
                f"SELECT * FROM (SELECT *, row_number() OVER (ORDER BY {_RANK_ORDER}) AS rank "
                "FROM evaluations WHERE run_id = ?) WHERE idx = ?", (run_id, idx)).fetchone()
        if row is None:
            raise LibraryError(f"no gait {gait_id!r}: run {run_id} has no evaluation #{idx}")
        return _evaluation(row, row["rank"])

    # -- tuning history --------------------------------------------------------------------------

    def add_trace(self, run_id: str, rows: list[dict]) -> None:
        """Store tuning trials (dicts: ``trial``, ``score``, ``accepted``) in one transaction."""
        values = []
        for i, row in enumerate(rows):
            if not isinstance(row, dict) or not {"trial", "score", "accepted"} <= row.keys():
                raise LibraryError(f"trace row {i}: expected a dict with trial, score, accepted")
            values.append((run_id, _index(row["trial"], f"trace row {i}: trial"),
                           _real(row["score"], f"trace row {i}: score"),
                           int(bool(row["accepted"]))))
        try:
            with self._write() as conn:
                self._require_run(conn, run_id)
                conn.executemany("INSERT INTO trace (run_id, trial, score, accepted) "
                                 "VALUES (?, ?, ?, ?)", values)
        except LibraryError as e:
            if "UNIQUE" in str(e):
                raise LibraryError(f"run {run_id}: the trace already has one of these trials; "
                                   "nothing of the batch was stored") from None
            raise

    def trace(self, run_id: str) -> list[TracePoint]:
        """The run's tuning trials in trial order."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            rows = conn.execute("SELECT trial, score, accepted FROM trace WHERE run_id = ? "
                                "ORDER BY trial", (run_id,)).fetchall()
        return [TracePoint(r[0], _float(r[1]), bool(r[2])) for r in rows]

    # -- exchange --------------------------------------------------------------------------------

    def export_gait(self, gait_id: str) -> dict:
        """A self-contained description of one gait; strict JSON (NaN and infinities: None)."""
        ev = self.gait(gait_id)
        run = self.get_run(ev.run_id)
        return _strict_json({
            "format": GAIT_FORMAT,
            "version": GAIT_FORMAT_VERSION,
            "source": ev.gait_id,
            "creature": run.creature,
            "creature_text": run.creature_text,
            "creature_hash": run.creature_hash,
            "encoding": ev.encoding,
            "params": ev.params,
            "score": ev.score,
            "speed_cm_s": ev.speed_cm_s,
            "fell": ev.fell,
            "nonfinite": ev.nonfinite,
            "extra": ev.extra,
            "run_params": run.params,
            "dtype": run.dtype,
            "sanlab_version": run.sanlab_version,
        })

    def import_gait(self, data: dict) -> str:
        """Store an exported gait as a new run of kind "import"; return its gait id ``RUN/1``.

        The run's params are the source run's params plus ``imported_from`` (the source id).
        """
        d = _validate_gait(data)
        run_params = dict(d["run_params"], imported_from=d.get("source"))
        seed = run_params.get("seed")
        run = self.create_run(
            "import", d["creature"], d["creature_text"], run_params,
            seed=seed if isinstance(seed, int) and not isinstance(seed, bool) else None, total=1,
            dtype=d.get("dtype"), device=None, sanlab_version=d.get("sanlab_version"))
        score = d["score"]
        self.add_batch(run.run_id, [{
            "idx": 0, "encoding": d["encoding"], "params": d["params"],
            "score": math.nan if score is None else score,
            "speed_cm_s": d["speed_cm_s"], "fell": d["fell"],
            "nonfinite": d.get("nonfinite", False), "extra": d.get("extra")}])
        return f"{run.run_id}/1"


# -- helpers -------------------------------------------------------------------------------------

_RUNS_QUERY = ("SELECT r.*, (SELECT count(*) FROM evaluations e WHERE e.run_id = r.run_id) "
               "AS n FROM runs r")


def _check_file(path: str) -> None:
    """Refuse, before SQLite sees it, anything that cannot be a library at ``path``."""
    if path == ":memory:" or path.startswith("file:"):
        return
    if os.path.isdir(path):
        raise LibraryError(f"{path}: is a directory, not a gait library")
    if not os.path.exists(path):
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            raise LibraryError(f"{path}: cannot create a gait library there: "
                               f"directory {folder} does not exist")
        return
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError as e:
        raise LibraryError(f"{path}: cannot read: {e.strerror or e}") from None
    if head and not head.startswith(_SQLITE_MAGIC):  # an empty file becomes a new library
        what = "it is a text file" if _looks_like_text(head) else "unrecognised binary content"
        raise LibraryError(f"{path}: not a database file ({what})")


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


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _json_default(obj: Any) -> Any:
    # NumPy / JAX scalars and arrays, so callers need not convert them by hand.
    if hasattr(obj, "tolist"):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON-serialisable")


def _to_json(obj: Any, what: str) -> str:
    try:
        return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_json_default)
    except (TypeError, ValueError) as e:
        raise LibraryError(f"{what} are not JSON-serialisable: {e}") from None


def _integer(value: Any, what: str) -> int:
    if isinstance(value, bool):
        raise LibraryError(f"{what} must be an integer, not {value!r}")
    try:
        return operator.index(value)
    except TypeError:
        raise LibraryError(f"{what} must be an integer, not {value!r}") from None


def _index(value: Any, what: str) -> int:
    i = _integer(value, what)
    if i < 0:
        raise LibraryError(f"{what} must be >= 0, not {i}")
    return i


def _real(value: Any, what: str) -> float | None:
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


def _float(value: float | None) -> float:
    return math.nan if value is None else float(value)


def _strict_json(obj: Any) -> Any:
    """``obj`` with every NaN or infinity replaced by None: strict JSON has neither."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _strict_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_strict_json(v) for v in obj]
    return obj


def _evaluation_values(run_id: str, i: int, row: Any) -> tuple:
    if not isinstance(row, dict):
        raise LibraryError(f"batch row {i}: expected a dict, got {type(row).__name__}")
    missing = _ROW_REQUIRED - row.keys()
    if missing:
        raise LibraryError(f"batch row {i}: missing {', '.join(sorted(missing))}")
    unknown = row.keys() - _ROW_KEYS
    if unknown:
        raise LibraryError(f"batch row {i}: unknown field {', '.join(sorted(map(str, unknown)))} "
                           f"(put anything else in 'extra')")
    where = f"batch row {i} (idx {row['idx']!r})"
    idx = _index(row["idx"], f"{where}: idx")
    if not isinstance(row["encoding"], str):
        raise LibraryError(f"{where}: encoding must be a str")
    params = row.get("params") or {}
    extra = row.get("extra")
    if not isinstance(params, dict) or not (extra is None or isinstance(extra, dict)):
        raise LibraryError(f"{where}: params and extra must be dicts")
    score = _real(row["score"], f"{where}: score")
    parent = row.get("parent")
    if parent is not None and not (isinstance(parent, str) and _PARENT_REF.fullmatch(parent)):
        raise LibraryError(f"{where}: parent must be a gait id 'RUN#IDX', not {parent!r}")
    nonfinite = bool(row.get("nonfinite", False)) or score is None or not math.isfinite(score)
    return (run_id, idx, row["encoding"], _to_json(params, f"{where}: params"), score,
            _real(row.get("speed_cm_s"), f"{where}: speed_cm_s"),
            int(bool(row.get("fell", False))), int(nonfinite),
            None if extra is None else _to_json(extra, f"{where}: extra"), parent)


def _run(row: sqlite3.Row) -> Run:
    return Run(run_id=row["run_id"], kind=row["kind"], created=row["created"],
               creature=row["creature"], creature_text=row["creature_text"],
               creature_hash=row["creature_hash"], params=json.loads(row["params"]),
               seed=row["seed"], sanlab_version=row["sanlab_version"], device=row["device"],
               dtype=row["dtype"], status=row["status"], parent_gait=row["parent_gait"],
               total=row["total"], count=row["n"])


def _evaluation(row: sqlite3.Row, rank: int | None) -> Evaluation:
    return Evaluation(run_id=row["run_id"], idx=row["idx"], encoding=row["encoding"],
                      params=json.loads(row["params"]), score=_float(row["score"]),
                      speed_cm_s=_float(row["speed_cm_s"]), fell=bool(row["fell"]),
                      nonfinite=bool(row["nonfinite"]),
                      extra=None if row["extra"] is None else json.loads(row["extra"]),
                      parent=row["parent"], rank=rank)


def _parse_gait_id(gait_id: Any) -> tuple[str, int | None, int | None]:
    """(run reference, rank, idx) of ``RUN/RANK`` or ``RUN#IDX``; exactly one of rank, idx."""
    m = _GAIT_ID.fullmatch(gait_id.strip().lower()) if isinstance(gait_id, str) else None
    if m is None:
        raise LibraryError(f"malformed gait id {gait_id!r}: expected RUN/RANK (e.g. 3fa1c2d0/1, "
                           "1 = best) or RUN#IDX (e.g. 3fa1c2d0#17)")
    run_ref, rank, idx = m.group(1), m.group(2), m.group(3)
    if rank is not None:
        if int(rank) < 1:
            raise LibraryError(f"malformed gait id {gait_id!r}: ranks start at 1 (the best)")
        return run_ref, int(rank), None
    return run_ref, None, int(idx)


def _validate_gait(data: Any) -> dict:
    """``data`` if it is a well-formed exported gait; a LibraryError naming the first fault."""
    if not isinstance(data, dict):
        raise LibraryError(f"not a sanlab gait: expected a JSON object, got {type(data).__name__}")
    if data.get("format") != GAIT_FORMAT:
        raise LibraryError(f"not a sanlab gait: 'format' is {data.get('format')!r}, "
                           f"expected {GAIT_FORMAT!r}")
    version = data.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise LibraryError(f"bad sanlab gait: 'version' must be a positive integer, "
                           f"not {version!r}")
    if version > GAIT_FORMAT_VERSION:
        raise LibraryError(f"sanlab gait format version {version} is newer than this sanlab "
                           f"reads ({GAIT_FORMAT_VERSION})")
    number = (int, float)
    fields = {  # name: (accepted types, required)
        "creature": (str, True), "creature_text": (str, True), "encoding": (str, True),
        "params": (dict, True), "score": (number + (type(None),), True),
        "speed_cm_s": (number + (type(None),), True), "fell": (bool, True),
        "run_params": (dict, True), "nonfinite": (bool, False),
        "extra": ((dict, type(None)), False), "source": ((str, type(None)), False),
        "creature_hash": (str, False), "dtype": ((str, type(None)), False),
        "sanlab_version": ((str, type(None)), False),
    }
    for name, (types, required) in fields.items():
        if name not in data:
            if required:
                raise LibraryError(f"bad sanlab gait: missing field {name!r}")
            continue
        value = data[name]
        bad_bool = isinstance(value, bool) and types is not bool
        if bad_bool or not isinstance(value, types):
            raise LibraryError(f"bad sanlab gait: field {name!r} has the wrong type "
                               f"({type(value).__name__})")
    if not data["encoding"].strip():
        raise LibraryError("bad sanlab gait: field 'encoding' is empty")
    if "creature_hash" in data and data["creature_hash"] != _sha256(data["creature_text"]):
        raise LibraryError("bad sanlab gait: 'creature_hash' does not match 'creature_text' "
                           "(was the creature text edited?)")
    return data
