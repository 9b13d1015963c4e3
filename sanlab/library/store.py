"""The gait library's store: runs, their evaluated controllers and tuning traces in one SQLite
file (see :class:`Library` for what it guarantees)."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import pathlib
import secrets
import socket
import sqlite3
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from datetime import datetime, timezone
from typing import Any

from sanlab import __version__
from sanlab.library import _schema, errors
from sanlab.library._values import (
    BadText,
    Damaged,
    as_float,
    decode_text,
    from_json,
    from_text,
    index,
    integer,
    real,
    sha256,
    text,
    to_json,
)
from sanlab.library.errors import LibraryError
from sanlab.library.exchange import export_record, validate_gait
from sanlab.library.ids import is_permanent, parse_gait_id, resolve_id, resolve_run
from sanlab.library.records import (
    AuditRecord,
    DesignRecord,
    DesignScore,
    Evaluation,
    EvaluationRow,
    Run,
    TracePoint,
    TraceRow,
)

DEFAULT_PATH = "sanlab.db"

# Best first; at equal scores a gait that stayed up before one that fell (so fallen gaits scored
# 0 never fill a top 10 ahead of standing ones); non-finite ones (and NaN scores, stored as NULL,
# which sort last under DESC) last.
_RANK_ORDER = "nonfinite ASC, score DESC, fell ASC, idx ASC"
_RUNS_QUERY = ("SELECT r.*, (SELECT count(*) FROM evaluations e WHERE e.run_id = r.run_id) AS n, "
               "(SELECT count(*) FROM trace t WHERE t.run_id = r.run_id) AS n_trials FROM runs r")

_DESIGNS_QUERY = ("SELECT d.*, (SELECT count(*) FROM design_scores s WHERE s.design_id = d.design_id) AS n "
                  "FROM designs d")

_SQL_INT_MAX = 2**63 - 1  # SQLite's largest INTEGER

_ROW_KEYS = {"idx", "encoding", "params", "score", "speed_cm_s", "fell", "nonfinite", "extra",
             "parent"}
_ROW_REQUIRED = {"idx", "encoding", "score"}


class Library:
    """A gait library file; ``with Library(path) as lib: ...``.

    A search (paper §5.2) or a tuning run (§5.3) is a *run*; each controller it simulates is an
    *evaluation* of that run, addressed by its index ``idx`` (0..N-1) or its rank (see
    ``sanlab.library.ids`` for gait ids). What it guarantees:

    - **Opening.** A missing or empty file is created as a new library (its directory must
      exist); an older schema is upgraded in one transaction; a foreign, damaged or newer file is
      refused and left untouched, and so is anything that is not a regular file (a FIFO is never
      waited on). Every problem is a :class:`LibraryError` with a one-line message naming the
      file (``timeout`` s: how long to wait for another writer's lock).
    - **Reading only.** ``readonly=True`` writes nothing, ever: it reads a library in a folder
      the user cannot write (where SQLite cannot make its ``-shm`` file, the file is read as
      immutable, which is exact as long as no ``-wal`` file holds uncheckpointed commits) and
      refuses a missing or empty file.
    - **Damaged files.** :meth:`check_intact` runs SQLite's quick check; the commands that write
      (search, tune, import, audit, reproduce, the studio's jobs) call it first and refuse a file
      that fails it (pages overwritten), in one line, before doing any work.
    - **Damaged cells.** A stored value that cannot be read back (text that is not UTF-8, JSON
      that does not parse, a value of the wrong type) never ends in a traceback: :meth:`runs`
      lists such a run with status "damaged", and reading it (:meth:`get_run`, :meth:`gait`,
      :meth:`top`, ...) raises a LibraryError naming the run, the column and what to do. Nothing
      else in the file is affected.
    - **Owners.** A running run records the process writing it (host, pid, start time); once
      that process is gone (killed outright, so it could not say so), the run reads as
      "interrupted" (:meth:`mark_stale_runs` also stores it so), and only its owner may write it
      while it lives.
    - **Atomicity.** Every method that writes is one transaction: a batch of evaluations, a
      trace, a new run or a status change is stored whole or not at all.
    - **Durability.** WAL journaling with ``synchronous = NORMAL``: a committed transaction
      survives the writing process being killed at any moment (an interrupted search loses at
      most the batch in flight); after a power cut the last commits may be lost, never the
      file's consistency.
    - **Concurrency.** Any number of processes may open the same file. Readers never block a
      writer and are never blocked by one (each read sees the last commit before it); writers
      take turns, each waiting up to ``timeout`` seconds for the write lock before a
      LibraryError ("database is locked"). Ranks of a run that is still being written may move
      between two calls.
    - **Threads.** One Library belongs to the thread that opened it (sqlite3's own rule); open one
      per thread or process instead of sharing it.
    """

    def __init__(self, path: str | os.PathLike = DEFAULT_PATH, *, timeout: float = 30.0,
                 readonly: bool = False):
        self.path = os.fspath(path)
        self.timeout = timeout
        self.readonly = readonly
        self._conn: sqlite3.Connection | None = None
        _schema.check_file(self.path)
        if readonly and not self.path.startswith("file:") and self.path != ":memory:" \
                and not os.path.exists(self.path):
            raise LibraryError(f"{self.path}: no such gait library (give --db PATH)")
        conn = self._connect()
        try:
            _schema.open_schema(conn, self.path, readonly)
        except sqlite3.Error as e:
            conn.close()
            if readonly and self._cannot_share(e):
                conn = self._connect(immutable=True)  # a read-only folder: no -shm can be made
            else:
                raise self._open_error(e) from None
        except LibraryError:
            conn.close()
            raise
        self._conn = conn

    def _connect(self, immutable: bool = False) -> sqlite3.Connection:
        target, uri = self.path, False
        if self.readonly and not self.path.startswith("file:") and self.path != ":memory:":
            flag = "immutable=1" if immutable else "mode=ro"
            target, uri = f"{pathlib.Path(os.path.abspath(self.path)).as_uri()}?{flag}", True
        try:
            # Autocommit mode: transactions are opened explicitly (BEGIN IMMEDIATE) by _write.
            conn = sqlite3.connect(target, timeout=self.timeout, isolation_level=None, uri=uri)
        except sqlite3.Error as e:
            raise LibraryError(f"{self.path}: cannot open: {e}",
                               sqlite_errorname=errors.errorname(e) or None) from None
        conn.row_factory = sqlite3.Row
        conn.text_factory = decode_text  # bad UTF-8 in a cell is read, marked, never raised
        if immutable:
            try:
                _schema.open_schema(conn, self.path, True)
            except sqlite3.Error as e:
                conn.close()
                raise self._open_error(e) from None
            except LibraryError:
                conn.close()
                raise
        return conn

    def _cannot_share(self, e: sqlite3.Error) -> bool:
        """Whether ``e`` is SQLite failing to make the WAL index (-shm) of a library it may only
        read (a read-only folder, or a full disk: an I/O error), and the file can be read as
        immutable without missing a commit (no -wal)."""
        name = errors.errorname(e)
        if not name.startswith(("SQLITE_CANTOPEN", "SQLITE_READONLY", "SQLITE_IOERR")):
            return False
        wal = self.path + "-wal"
        if os.path.exists(wal) and os.path.getsize(wal) > 0:
            raise LibraryError(f"{self.path}: cannot read: its folder is read-only and {wal} holds "
                               "commits not yet in the file; open it once where the folder is "
                               "writable (or copy the folder with both files)") from None
        return True

    def _open_error(self, e: sqlite3.Error) -> LibraryError:
        name = errors.errorname(e)
        if errors.is_busy(name):
            return errors.from_sqlite(e, self.path, self.timeout)
        if name.startswith("SQLITE_READONLY") or name.startswith("SQLITE_CANTOPEN"):
            return LibraryError(f"{self.path}: cannot write: the file or its folder is read-only ({e}); "
                                "commands that only read it work, to write give --db a writable copy",
                                sqlite_errorname=name)
        if name.startswith("SQLITE_CORRUPT"):  # a page of its schema (sqlite_schema) overwritten
            return LibraryError(f"{self.path}: damaged: SQLite cannot read its schema ({e}); rebuild it with "
                                f"sqlite3 {self.path} .recover", sqlite_errorname=name)
        return LibraryError(f"{self.path}: not a usable database file ({e})",
                            sqlite_errorname=name or None)

    def check_intact(self) -> None:
        """Raise :class:`LibraryError` (one line naming the file) unless SQLite's quick check
        (``PRAGMA quick_check``: every page, cell and record readable, without the slower index
        cross-check of ``integrity_check``) passes. Commands that write call it before doing any
        work, so that a damaged file takes no new run. It reads the whole file: 0.02 s for
        100,000 evaluations (14 MiB)."""
        with self._sql() as conn:
            try:
                rows = conn.execute("PRAGMA quick_check(1)").fetchall()
                first = str(rows[0][0]) if rows else "no answer"
            except sqlite3.Error as e:  # so damaged that the check itself cannot read it
                first = str(e)
        if first != "ok":
            why = " ".join(first.replace("*** in database main ***", "").split())[:200]
            raise LibraryError(f"{self.path}: damaged: SQLite's quick check fails ({why}); commands that write "
                               "refuse it (read what is left with sanlab runs / export, or rebuild it with "
                               f"sqlite3 {self.path} .recover)")

    # -- plumbing --------------------------------------------------------------------------------

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None
            if self.readonly:
                self._tidy()

    def _tidy(self) -> None:
        """Remove the empty ``-wal`` and the ``-shm`` that reading a WAL library leaves beside it.

        A read-only connection may make them but never removes them (only the last connection
        that can write does, as it closes), so every read-only command used to leave two files
        behind. A connection that can write is opened and closed for it, only while the ``-wal``
        holds nothing: its checkpoint then writes nothing to the library. Where another process
        has the library open, its files are its own, and closing this one leaves them."""
        wal, shm = self.path + "-wal", self.path + "-shm"
        if self.path.startswith("file:") or self.path == ":memory:" or not os.path.exists(shm):
            return
        try:
            if os.path.exists(wal) and os.path.getsize(wal) > 0:
                return
            conn = sqlite3.connect(self.path, timeout=0.05, isolation_level=None)
            try:
                conn.execute("PRAGMA query_only = 1")
                conn.execute("SELECT count(*) FROM sqlite_master").fetchone()
            finally:
                conn.close()
        except (sqlite3.Error, OSError):
            pass  # a read-only folder or file, or a writer holding a lock: the files stay, as before

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
        except sqlite3.Error as e:
            raise errors.from_sqlite(e, self.path, self.timeout) from None

    @contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One short write transaction: all of it commits, or none of it."""
        with self._sql() as conn:
            # IMMEDIATE takes the write lock up front, so the busy timeout applies here rather
            # than failing later when a read transaction tries to upgrade.
            conn.execute("BEGIN IMMEDIATE")
            try:
                yield conn
                # A COMMIT that fails (a full disk: SQLITE_FULL) may leave the transaction open;
                # rolled back here, or every later write of this connection would fail on BEGIN
                # ("cannot start a transaction within a transaction"), the run's "interrupted" too.
                conn.execute("COMMIT")
            except BaseException:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                raise

    def _resolve(self, ref: str) -> str:
        """The full run id for an exact id or an unambiguous prefix."""
        with self._sql() as conn:
            return resolve_run(conn, ref, self.path)

    def _require_run(self, conn: sqlite3.Connection, run_id: str) -> None:
        if conn.execute("SELECT 1 FROM runs WHERE run_id = ?", (run_id,)).fetchone() is None:
            raise LibraryError(f"no run {run_id!r} in {self.path}")

    def _damaged(self, what: str, e: Damaged) -> LibraryError:
        return LibraryError(f"{self.path}: {what} is damaged ({e}); the rest of the library is intact: "
                            "restore this file from a backup to read it, or leave it be")

    # -- runs ------------------------------------------------------------------------------------

    def create_run(self, kind: str, creature: str, creature_text: str, params: dict,
                   seed: int | None, total: int, dtype: str | None = None,
                   device: str | None = None, sanlab_version: str | None = None,
                   parent_gait: str | None = None) -> Run:
        """Record a new run (status "running"; "done" for an import) and return it.

        ``kind``: one of "search", "tune", "import". ``params``: a JSON-serialisable dict of the
        run's settings. ``total``: evaluations planned. ``parent_gait`` (a tuning run's starting
        gait) may be given in either gait id form; it is stored as the permanent ``RUN#IDX``.
        Raises LibraryError on a bad argument.
        """
        return self.get_run(self._insert_run(self._run_values(
            kind, creature, creature_text, params, seed, total, dtype, device, sanlab_version, parent_gait)))

    def _run_values(self, kind: str, creature: str, creature_text: str, params: dict, seed: int | None,
                    total: int, dtype: str | None, device: str | None, sanlab_version: str | None,
                    parent_gait: str | None) -> dict:
        """The ``runs`` columns of a new run, every value checked (LibraryError)."""
        if kind not in _schema.RUN_KINDS:
            raise LibraryError(f"unknown run kind {kind!r} "
                               f"(expected one of {', '.join(_schema.RUN_KINDS)})")
        if not isinstance(creature_text, str):
            raise LibraryError("creature_text must be the creature file's text (a str)")
        if not isinstance(params, dict):
            raise LibraryError("run params must be a dict")
        total = index(total, "total")
        if parent_gait is not None:
            parent_gait = self.gait(parent_gait).gait_id
        status = "done" if kind == "import" else "running"
        optional = lambda v, what: None if v is None else text(v, what)
        values = dict(
            kind=kind, created=datetime.now(timezone.utc).isoformat(timespec="microseconds"),
            creature=text(str(creature), "creature"), creature_text=text(creature_text, "creature_text"),
            creature_hash=sha256(creature_text), params=to_json(params, "run params", finite=True),
            seed=None if seed is None else integer(seed, "seed"),
            sanlab_version=text(sanlab_version or __version__, "sanlab_version"),
            device=optional(device, "device"), dtype=optional(dtype, "dtype"),
            status=status, parent_gait=parent_gait, total=total,
            owner=_owner() if status == "running" else None)
        return values

    def _insert_run(self, values: dict, rows: list | None = None) -> str:
        """Insert a run (column values) under a fresh id, and with it ``rows`` (evaluation
        values, run id first) in the same transaction; returns the id."""
        for _ in range(20):
            run_id = secrets.token_hex(4)
            try:
                with self._write() as conn:
                    conn.execute(
                        f"INSERT INTO runs (run_id, {', '.join(values)}) "
                        f"VALUES (?{', ?' * len(values)})", (run_id, *values.values()))
                    if rows:
                        conn.executemany(
                            "INSERT INTO evaluations (run_id, idx, encoding, params, score, speed_cm_s, "
                            "fell, nonfinite, extra, parent) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                            [(run_id, *r[1:]) for r in rows])
            except LibraryError as e:
                if errors.is_duplicate(e.sqlite_errorname):
                    continue  # 1 in 4 billion per existing run: draw another id
                raise
            return run_id
        raise LibraryError(f"{self.path}: could not find a free run id")

    def set_status(self, run_id: str, status: str) -> None:
        """Mark a run "running" (this process becomes its owner: refused while another live
        process owns it), "done" or "interrupted"."""
        if status not in _schema.RUN_STATUSES:
            raise LibraryError(f"unknown run status {status!r} "
                               f"(expected one of {', '.join(_schema.RUN_STATUSES)})")
        with self._write() as conn:
            row = conn.execute("SELECT status, owner FROM runs WHERE run_id = ?", (run_id,)).fetchone()
            if row is None:
                raise LibraryError(f"no run {run_id!r} in {self.path}")
            owner = row["owner"]
            if status == "running":
                other = _parse_owner(owner)
                if row["status"] == "running" and other is not None and other != _me() and _alive(other):
                    raise LibraryError(f"{self.path}: run {run_id} is being written by process "
                                       f"{other.get('pid')} on {other.get('host')}; wait for it to "
                                       "finish, or stop it first")
                owner = _owner()
            conn.execute("UPDATE runs SET status = ?, owner = ? WHERE run_id = ?", (status, owner, run_id))

    def get_run(self, run_id: str) -> Run:
        """The run with this id or unambiguous id prefix (a LibraryError if it is damaged)."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            row = conn.execute(_RUNS_QUERY + " WHERE r.run_id = ?", (run_id,)).fetchone()
        try:
            return _run(row)
        except Damaged as e:
            raise self._damaged(f"run {run_id}", e) from None

    def runs(self, *, check_evaluations: bool = False) -> list[Run]:
        """All runs, newest first; a damaged one with status "damaged" (and whatever of it
        could be read: text with U+FFFD for bad bytes, params {} when they do not parse).
        ``check_evaluations``: also "damaged" when one of the run's evaluation cells is
        (:meth:`damaged_gaits`; a pass over every evaluation, for listings people read, not for
        polling)."""
        with self._sql() as conn:
            rows = conn.execute(_RUNS_QUERY + " ORDER BY r.created DESC, r.rowid DESC").fetchall()
        bad = self.damaged_gaits() if check_evaluations else {}
        out = []
        for r in rows:
            try:
                run = _run(r)
            except Damaged:
                run = _run(r, strict=False)
            out.append(dataclasses.replace(run, status="damaged") if run.run_id in bad else run)
        return out

    def damage(self, run_id: str) -> str | None:
        """Why run ``run_id`` cannot be read (e.g. "its params are not valid JSON"), or None."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            row = conn.execute(_RUNS_QUERY + " WHERE r.run_id = ?", (run_id,)).fetchone()
        try:
            _run(row)
        except Damaged as e:
            return str(e)
        return None

    def damaged_gaits(self) -> dict[str, str]:
        """Per run with damaged evaluation cells, the first such gait ("RUN#IDX"): a score or
        speed that is not a number, an encoding that is not text, params or extra that are not
        JSON. One pass of SQL over the evaluations (what a listing can afford; a cell of bad UTF-8
        is found when its gait is read)."""
        with self._sql() as conn:
            rows = conn.execute(
                "SELECT run_id, min(idx) FROM evaluations WHERE "
                "typeof(score) NOT IN ('real', 'integer', 'null') OR typeof(speed_cm_s) NOT IN ('real', 'integer', 'null') "
                "OR typeof(encoding) != 'text' OR typeof(params) != 'text' OR NOT json_valid(params) "
                "OR (extra IS NOT NULL AND (typeof(extra) != 'text' OR NOT json_valid(extra))) "
                "GROUP BY run_id").fetchall()
        return {r[0]: f"{r[0]}#{r[1]}" for r in rows}

    def mark_stale_runs(self) -> list[str]:
        """Store "interrupted" for every run whose status says "running" but whose owner process
        on this host is gone (killed outright); returns their ids. Runs owned on other hosts
        are left alone (there is no telling whether their process lives)."""
        with self._sql() as conn:
            rows = conn.execute("SELECT run_id, owner FROM runs WHERE status = 'running'").fetchall()
        stale = [r["run_id"] for r in rows if _stale(r["owner"])]
        if stale:
            with self._write() as conn:
                for run_id in stale:  # checked again under the write lock: the owner may have moved on
                    row = conn.execute("SELECT status, owner FROM runs WHERE run_id = ?", (run_id,)).fetchone()
                    if row is not None and row["status"] == "running" and _stale(row["owner"]):
                        conn.execute("UPDATE runs SET status = 'interrupted' WHERE run_id = ?", (run_id,))
        return stale

    def discard_run(self, run_id: str) -> None:
        """Delete a run that has no evaluations yet (one that failed before its first batch), so
        it leaves nothing behind; a run with stored evaluations is refused (nothing is lost)."""
        with self._write() as conn:
            self._require_run(conn, run_id)
            n = conn.execute("SELECT count(*) FROM evaluations WHERE run_id = ?", (run_id,)).fetchone()[0]
            if n:
                raise LibraryError(f"run {run_id} has {n} stored evaluation{'s' * (n != 1)}; it is kept")
            conn.execute("DELETE FROM trace WHERE run_id = ?", (run_id,))
            conn.execute("DELETE FROM runs WHERE run_id = ?", (run_id,))

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
        except LibraryError as e:
            if not errors.is_duplicate(e.sqlite_errorname):
                raise
            with self._sql() as conn:
                stored = {r[0] for r in conn.execute(
                    "SELECT idx FROM evaluations WHERE run_id = ?", (run_id,))}
            clash = sorted(seen & stored)
            shown = ", ".join(f"#{i}" for i in clash[:5]) + (", ..." if len(clash) > 5 else "")
            raise LibraryError(f"run {run_id} already has evaluation {shown} "
                               "(pass replace=True to overwrite); nothing of the batch "
                               "was stored", sqlite_errorname=e.sqlite_errorname) from None

    def commit(self, evaluations: Sequence[EvaluationRow] = (), trace: Sequence[TraceRow] = (),
               done: Sequence[str] = ()) -> None:
        """Store evaluated controllers and tuning trials of any runs, and mark the runs ``done``
        finished, all in one transaction (a driver's batch: stored whole or not at all). Raises
        LibraryError as :meth:`add_batch` and :meth:`add_trace` do, storing nothing."""
        by_run: dict[str, list[tuple]] = {}
        for i, row in enumerate(evaluations):
            by_run.setdefault(row.run_id, []).append(_evaluation_values(row.run_id, i, row.to_json()))
        for run_id, values in by_run.items():
            idx = [v[1] for v in values]
            if len(set(idx)) != len(idx):
                raise LibraryError(f"run {run_id}: the batch holds an idx twice")
        points = [_trace_values(t.run_id, i, {"trial": t.trial, "score": t.score, "accepted": t.accepted})
                  for i, t in enumerate(trace)]
        with self._write() as conn:
            for run_id in {*by_run, *(p[0] for p in points), *done}:
                self._require_run(conn, run_id)
            for values in by_run.values():
                conn.executemany(
                    "INSERT INTO evaluations (run_id, idx, encoding, params, score, speed_cm_s, "
                    "fell, nonfinite, extra, parent) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", values)
            conn.executemany("INSERT INTO trace (run_id, trial, score, accepted) VALUES (?, ?, ?, ?)", points)
            conn.executemany("UPDATE runs SET status = 'done' WHERE run_id = ?", [(r,) for r in done])

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

        Ranked by score descending, then standing before fallen, then idx ascending; non-finite
        evaluations come last.
        """
        run_id = self._resolve(run_id)
        limit = -1 if n is None else max(0, integer(n, "n"))
        with self._sql() as conn:
            rows = conn.execute(f"SELECT * FROM evaluations WHERE run_id = ? "
                                f"ORDER BY {_RANK_ORDER} LIMIT ?", (run_id, limit)).fetchall()
        return [self._evaluation(r, rank) for rank, r in enumerate(rows, 1)]

    def tally(self, run_id: str) -> dict[str, int]:
        """How many of the run's stored evaluations there are, fell, and went non-finite:
        {"evaluated", "fell", "nonfinite"} (what a search reports under its table)."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            n, fell, nonfinite = conn.execute(
                "SELECT count(*), coalesce(sum(fell), 0), coalesce(sum(nonfinite), 0) FROM evaluations "
                "WHERE run_id = ?", (run_id,)).fetchone()
        return {"evaluated": n, "fell": fell, "nonfinite": nonfinite}

    def same_runs(self, kind: str, creature_text: str, params: dict, seed: int | None) -> list[Run]:
        """Earlier runs of ``kind`` with this exact creature text, settings and seed, newest first:
        a new run like them would repeat them (their results are already in the library)."""
        key = to_json(params, "run params", finite=True)
        with self._sql() as conn:
            rows = conn.execute(_RUNS_QUERY + " WHERE r.kind = ? AND r.creature_hash = ? AND r.seed IS ? "
                                "ORDER BY r.created DESC", (kind, sha256(creature_text), seed)).fetchall()
        out = []
        for r in rows:
            try:
                run = _run(r)
            except Damaged:
                continue
            if run.creature_text == creature_text and to_json(run.params, "run params") == key:
                out.append(run)
        return out

    def scores(self, run_id: str) -> list[float]:
        """Every stored score of the run in idx order (NaN where the score was not a number)."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            rows = conn.execute("SELECT idx, score FROM evaluations WHERE run_id = ? ORDER BY idx", (run_id,)).fetchall()
        out = []
        for r in rows:
            try:
                out.append(as_float(r[1]))
            except Damaged as e:
                raise self._damaged(f"gait {run_id}#{r[0]}'s score", e) from None
        return out

    def gait(self, gait_id: str) -> Evaluation:
        """The evaluation named ``RUN/RANK`` (1-based, best first) or ``RUN#IDX``."""
        run_ref, rank, idx = parse_gait_id(gait_id)
        run_id = self._resolve(run_ref)
        with self._sql() as conn:
            if rank is not None:
                # past SQLite's integers (2^63 - 1) no gait can be: not found, not an OverflowError
                row = conn.execute(f"SELECT * FROM evaluations WHERE run_id = ? "
                                   f"ORDER BY {_RANK_ORDER} LIMIT 1 OFFSET ?",
                                   (run_id, rank - 1)).fetchone() if rank <= _SQL_INT_MAX else None
                if row is None:
                    n = self.count(run_id)
                    raise LibraryError(f"no gait {gait_id!r}: run {run_id} has {n} "
                                       f"evaluation{'s' * (n != 1)}")
                return self._evaluation(row, rank)
            row = conn.execute(
                f"SELECT * FROM (SELECT *, row_number() OVER (ORDER BY {_RANK_ORDER}) AS rank "
                "FROM evaluations WHERE run_id = ?) WHERE idx = ?", (run_id, idx)).fetchone() \
                if idx is not None and idx <= _SQL_INT_MAX else None
        if row is None:
            raise LibraryError(f"no gait {gait_id!r}: run {run_id} has no evaluation #{idx}")
        return self._evaluation(row, row["rank"])

    def _evaluation(self, row: sqlite3.Row, rank: int | None) -> Evaluation:
        try:
            return _evaluation(row, rank)
        except Damaged as e:
            raise self._damaged(f"gait {row['run_id']}#{row['idx']}", e) from None

    # -- artefact audits -------------------------------------------------------------------------

    def put_selection(self, run_id: str, idx: int, result: dict, gait: dict | None = None,
                      audit: dict | None = None, *, flagged: bool = False, worst: float = 0.0) -> None:
        """Store a tuning run's audited selection (``sanlab.audit.select_robust``) in one
        transaction: its record ``result`` (JSON) and, as the run's evaluation ``idx``, the chosen
        gait ``gait`` (an :meth:`add_batch` row, replacing an earlier one) with its ``audit``; with
        ``gait`` None (no rung survived), an earlier chosen gait at ``idx`` and its audit are
        removed. Raises LibraryError for an unknown run."""
        run_id = self._resolve(run_id)
        created = datetime.now(timezone.utc).isoformat(timespec="microseconds")
        text = to_json(result, "selection")
        audit_text = None if audit is None else to_json(audit, "audit results")
        worst_v = real(worst, "audit: worst") if math.isfinite(worst) else None
        values = None if gait is None else _evaluation_values(run_id, 0, {**gait, "idx": idx})
        with self._write() as conn:
            self._require_run(conn, run_id)
            conn.execute("DELETE FROM audits WHERE run_id = ? AND idx = ?", (run_id, idx))
            conn.execute("DELETE FROM evaluations WHERE run_id = ? AND idx = ?", (run_id, idx))
            if values is not None:
                conn.execute("INSERT INTO evaluations (run_id, idx, encoding, params, score, speed_cm_s, "
                             "fell, nonfinite, extra, parent) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", values)
                if audit_text is not None:
                    conn.execute("INSERT INTO audits (run_id, idx, created, flagged, worst, result) "
                                 "VALUES (?, ?, ?, ?, ?, ?)", (run_id, idx, created, int(bool(flagged)), worst_v, audit_text))
            conn.execute("INSERT OR REPLACE INTO selections (run_id, created, idx, result) VALUES (?, ?, ?, ?)",
                         (run_id, created, None if gait is None else idx, text))

    def selection(self, run_id: str) -> dict | None:
        """A tuning run's stored audited selection ({"idx": the chosen evaluation or None,
        "created", **its record}), or None if none was made (or the record is not a JSON
        object: a damaged record is made again, never trusted)."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            if not _schema._has_table(conn, "selections"):
                return None  # an older library opened read-only, as it is
            row = conn.execute("SELECT idx, created, result FROM selections WHERE run_id = ?", (run_id,)).fetchone()
        if row is None:
            return None
        try:
            result = json.loads(row[2])
        except (TypeError, ValueError):
            return None
        return {**result, "idx": row[0], "created": row[1]} if isinstance(result, dict) else None

    def add_audit(self, gait_id: str, result: dict, *, flagged: bool, worst: float) -> AuditRecord:
        """Store the audit of gait ``gait_id`` (replacing an earlier one of the same gait)."""
        ev = self.gait(gait_id)
        created = datetime.now(timezone.utc).isoformat(timespec="microseconds")
        worst_v = real(worst, "audit: worst") if math.isfinite(worst) else None
        text = to_json(result, "audit results")
        with self._write() as conn:
            conn.execute("INSERT OR REPLACE INTO audits (run_id, idx, created, flagged, worst, result) "
                         "VALUES (?, ?, ?, ?, ?, ?)", (ev.run_id, ev.idx, created, int(bool(flagged)), worst_v, text))
        return AuditRecord(ev.gait_id, created, bool(flagged), as_float(worst_v), json.loads(text))

    def audit(self, gait_id: str) -> AuditRecord | None:
        """The stored audit of a gait, or None if it was never audited."""
        ev = self.gait(gait_id)
        return self.audits(ev.run_id).get(ev.idx)

    def audits(self, run_id: str) -> dict[int, AuditRecord]:
        """Every stored audit of a run's gaits, by evaluation index."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            if conn.execute("SELECT 1 FROM sqlite_schema WHERE type = 'table' AND name = 'audits'").fetchone() is None:
                return {}  # an older library opened read-only, as it is
            rows = conn.execute("SELECT idx, created, flagged, worst, result FROM audits WHERE run_id = ?",
                                (run_id,)).fetchall()
        return {r[0]: AuditRecord(f"{run_id}#{r[0]}", r[1], bool(r[2]), as_float(r[3]), json.loads(r[4])) for r in rows}

    # -- tuning history --------------------------------------------------------------------------

    def add_trace(self, run_id: str, rows: list[dict]) -> None:
        """Store tuning trials (dicts: ``trial``, ``score``, ``accepted``) in one transaction."""
        values = [_trace_values(run_id, i, row) for i, row in enumerate(rows)]
        try:
            with self._write() as conn:
                self._require_run(conn, run_id)
                conn.executemany("INSERT INTO trace (run_id, trial, score, accepted) "
                                 "VALUES (?, ?, ?, ?)", values)
        except LibraryError as e:
            if errors.is_duplicate(e.sqlite_errorname):
                raise LibraryError(f"run {run_id}: the trace already has one of these trials; "
                                   "nothing of the batch was stored",
                                   sqlite_errorname=e.sqlite_errorname) from None
            raise

    def trace(self, run_id: str) -> list[TracePoint]:
        """The run's tuning trials in trial order."""
        run_id = self._resolve(run_id)
        with self._sql() as conn:
            rows = conn.execute("SELECT trial, score, accepted FROM trace WHERE run_id = ? "
                                "ORDER BY trial", (run_id,)).fetchall()
        try:
            return [TracePoint(r[0], as_float(r[1]), bool(r[2])) for r in rows]
        except Damaged as e:
            raise self._damaged(f"the tuning trace of run {run_id}", e) from None

    # -- designs ---------------------------------------------------------------------------------

    def begin_design(self, creature: str, source: str, creature_text: str, settings: dict,
                     free: Sequence[dict]) -> DesignRecord:
        """Mark the design of ``creature_text`` (the file with free numbers, read from ``source``)
        with ``settings`` (a JSON object; keys and values as ``sanlab.design.DesignSettings``)
        "running", this process its owner, and return it: the design stored before with the same
        file and settings (made again, it continues: its scores and result stay until replaced),
        else a new one. ``free``: each free number {name, path, min, max, default, unit}. Raises
        LibraryError for a bad argument, or while another live process writes that design."""
        text(creature_text, "creature_text")
        if not isinstance(settings, dict):
            raise LibraryError("design settings must be a dict")
        if not all(isinstance(f, dict) for f in free):
            raise LibraryError("free numbers must be dicts")
        key = to_json(settings, "design settings", finite=True)
        free_text = to_json(list(free), "free numbers", finite=True)
        now = datetime.now(timezone.utc).isoformat(timespec="microseconds")
        with self._write() as conn:
            rows = conn.execute("SELECT design_id, creature_text, settings, status, owner FROM designs "
                                "WHERE creature_hash = ? ORDER BY created", (sha256(creature_text),)).fetchall()
            same = [r for r in rows if r["creature_text"] == creature_text and r["settings"] == key]
            if same:
                row = same[0]
                other = _parse_owner(row["owner"])
                if row["status"] == "running" and other is not None and other != _me() and _alive(other):
                    raise LibraryError(f"{self.path}: design {row['design_id']} is being written by process "
                                       f"{other.get('pid')} on {other.get('host')}; wait for it to finish, or stop it first")
                design_id = row["design_id"]
                conn.execute("UPDATE designs SET status = 'running', owner = ?, updated = ? WHERE design_id = ?",
                             (_owner(), now, design_id))
            else:
                design_id = secrets.token_hex(4)
                while conn.execute("SELECT 1 FROM designs WHERE design_id = ?", (design_id,)).fetchone():
                    design_id = secrets.token_hex(4)  # 1 in 4 billion per design: draw another
                conn.execute(
                    "INSERT INTO designs (design_id, created, updated, creature, source, creature_text, creature_hash, "
                    "settings, free, status, owner, result, sanlab_version) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, 'running', ?, "
                    "NULL, ?)", (design_id, now, now, text(str(creature), "creature"), text(str(source), "source"),
                                 creature_text, sha256(creature_text), key, free_text, _owner(), __version__))
        return self.get_design(design_id)

    def add_design_score(self, design_id: str, round: int, place: int, seed: int, values: Sequence[float],
                         record: dict) -> None:
        """Store one body of a design scored on one seed (replacing an earlier score of the same
        body and seed): ``round`` (-1: the reference) and ``place`` (its index in the round),
        ``values`` [D] (its free values), ``record`` (``sanlab.reproduce.robust_tuned``'s: its
        "speed" in cm/s, its "gait" RUN#IDX or None, "pruned" when so). Raises LibraryError for an
        unknown design or a bad value."""
        r = integer(round, "design score: round")
        if r < -1:
            raise LibraryError(f"design score: round must be >= -1, not {r}")
        i = index(place, "design score: place")
        sd = integer(seed, "design score: seed")
        if not isinstance(record, dict):
            raise LibraryError("design score: record must be a dict")
        body = [real(v, "design score: values") for v in values]
        if any(v is None or not math.isfinite(v) for v in body):
            raise LibraryError(f"design score: values must be finite numbers, not {list(values)[:8]}")
        gait = record.get("gait")
        gait = gait.strip().lower() if isinstance(gait, str) else gait  # ids are case-insensitive, stored in lower case
        if gait is not None and not is_permanent(gait):
            raise LibraryError(f"design score: gait must be a gait id 'RUN#IDX' or None, not {gait!r}")
        row = (design_id, r, i, sd, to_json(body, "design score: values"), real(record.get("speed"), "design score: speed"),
               gait, int(bool(record.get("pruned"))), to_json(record, "design score: record"))
        now = datetime.now(timezone.utc).isoformat(timespec="microseconds")
        with self._write() as conn:
            if conn.execute("UPDATE designs SET updated = ? WHERE design_id = ?", (now, design_id)).rowcount == 0:
                raise LibraryError(f"no design {design_id!r} in {self.path}")
            conn.execute("INSERT OR REPLACE INTO design_scores (design_id, round, idx, seed, body, speed_cm_s, gait, "
                         "pruned, record) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)", row)

    def end_design(self, design_id: str, status: str, result: dict | None = None) -> None:
        """Mark a design "done" (with its ``result``: {"chosen": {"round", "index"}, "seconds",
        "text"}) or "interrupted" (its result, if any, kept). Raises LibraryError for an unknown
        design or status."""
        if status not in ("done", "interrupted"):
            raise LibraryError(f"a design ends 'done' or 'interrupted', not {status!r}")
        if status == "done" and not isinstance(result, dict):
            raise LibraryError("a design done needs its result (a dict)")
        result_text = None if result is None else to_json(result, "design result")
        now = datetime.now(timezone.utc).isoformat(timespec="microseconds")
        with self._write() as conn:
            n = conn.execute("UPDATE designs SET status = ?, updated = ?, result = coalesce(?, result) WHERE design_id = ?",
                             (status, now, result_text, design_id)).rowcount
            if n == 0:
                raise LibraryError(f"no design {design_id!r} in {self.path}")

    def designs(self) -> list[DesignRecord]:
        """Every design, newest first; a damaged one with status "damaged" (what of it could
        be read). An older library opened read-only has none."""
        with self._sql() as conn:
            if not _schema._has_table(conn, "designs"):
                return []
            rows = conn.execute(_DESIGNS_QUERY + " ORDER BY d.created DESC, d.design_id").fetchall()
        out = []
        for r in rows:
            try:
                out.append(_design(r))
            except Damaged:
                out.append(_design(r, strict=False))
        return out

    def get_design(self, ref: str) -> DesignRecord:
        """The design with this id or unambiguous id prefix (LibraryError: none, several, or
        damaged)."""
        design_id = self._resolve_design(ref)
        with self._sql() as conn:
            row = conn.execute(_DESIGNS_QUERY + " WHERE d.design_id = ?", (design_id,)).fetchone()
        try:
            return _design(row)
        except Damaged as e:
            raise self._damaged(f"design {design_id}", e) from None

    def design_scores(self, ref: str) -> list[DesignScore]:
        """A design's scores: every body on every seed scored so far, by round (the reference,
        -1, first), place in the round and seed."""
        design_id = self._resolve_design(ref)
        with self._sql() as conn:
            rows = conn.execute("SELECT * FROM design_scores WHERE design_id = ? ORDER BY round, idx, seed",
                                (design_id,)).fetchall()
        out = []
        for r in rows:
            try:
                values = _cell(r, "body", lambda v: from_json(v, list))
                if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in values):
                    raise Damaged("its body: numbers were expected")
                out.append(DesignScore(round=_cell(r, "round", _int), index=_cell(r, "idx", _int), seed=_cell(r, "seed", _int),
                                       values=tuple(float(x) for x in values),
                                       speed_cm_s=_cell(r, "speed_cm_s", as_float),
                                       gait=_cell(r, "gait", _optional(from_text)), pruned=bool(r["pruned"]),
                                       record=_cell(r, "record", from_json)))
            except Damaged as e:
                raise self._damaged(f"design {design_id}'s score of body {r['round']}.{r['idx']} on seed {r['seed']}",
                                    e) from None
        return out

    def _resolve_design(self, ref: str) -> str:
        with self._sql() as conn:
            if not _schema._has_table(conn, "designs"):
                raise LibraryError(f"no design {ref!r} in {self.path}")
            return resolve_id(conn, "design", ref, self.path)

    # -- exchange --------------------------------------------------------------------------------

    def export_gait(self, gait_id: str) -> dict:
        """A self-contained description of one gait (``sanlab.library.exchange``): strict JSON.
        Raises LibraryError for a gait that does not read as one (a damaged row, or a creature or
        encoding this sanlab cannot read): what :meth:`import_gait` would refuse is not written."""
        ev = self.gait(gait_id)
        record = export_record(self.get_run(ev.run_id), ev)
        try:
            validate_gait(record)  # never write a file that an import would refuse
        except LibraryError as e:
            raise LibraryError(f"{self.path}: gait {ev.gait_id} cannot be exported: its stored row does not read "
                               f"as a gait ({str(e).removeprefix('bad sanlab gait: ')})") from None
        audit = self.audits(ev.run_id).get(ev.idx)
        if audit is not None:  # informative: an import stores the gait, not its audit
            worst = audit.worst if math.isfinite(audit.worst) else None
            record["audit"] = {"flagged": audit.flagged, "worst": worst, "created": audit.created, "result": audit.result}
        return record

    def import_gait(self, data: dict) -> str:
        """Store an exported gait as a new run of kind "import"; return its gait id ``RUN/1``.

        The run's params are the source run's params plus ``imported_from`` (the source id).
        Raises LibraryError if ``data`` is not a well-formed exported gait.
        """
        d = validate_gait(data)
        run_params = dict(d["run_params"], imported_from=d.get("source"))
        seed = run_params.get("seed")
        run = self._run_values(
            "import", d["creature"], d["creature_text"], run_params,
            seed if isinstance(seed, int) and not isinstance(seed, bool) else None, 1,
            d.get("dtype"), None, d.get("sanlab_version"), None)
        score = d["score"]
        row = _evaluation_values("", 0, {
            "idx": 0, "encoding": d["encoding"], "params": d["params"],
            "score": math.nan if score is None else score,
            "speed_cm_s": d["speed_cm_s"], "fell": d["fell"],
            "nonfinite": d.get("nonfinite", False), "extra": d.get("extra")})
        return f"{self._insert_run(run, [row])}/1"  # the run and its gait in one transaction


# -- rows ----------------------------------------------------------------------------------------


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
    where = f"batch row {i} (idx {str(row['idx'])[:40]})"
    idx = index(row["idx"], f"{where}: idx")
    text(row["encoding"], f"{where}: encoding")
    params = row.get("params") or {}
    extra = row.get("extra")
    if not isinstance(params, dict) or not (extra is None or isinstance(extra, dict)):
        raise LibraryError(f"{where}: params and extra must be dicts")
    score = real(row["score"], f"{where}: score")
    parent = row.get("parent")
    if parent is not None and not is_permanent(parent):
        raise LibraryError(f"{where}: parent must be a gait id 'RUN#IDX', not {parent!r}")
    nonfinite = bool(row.get("nonfinite", False)) or score is None or not math.isfinite(score)
    return (run_id, idx, row["encoding"], to_json(params, f"{where}: params"), score,
            real(row.get("speed_cm_s"), f"{where}: speed_cm_s"),
            int(bool(row.get("fell", False))), int(nonfinite),
            None if extra is None else to_json(extra, f"{where}: extra"), parent)


def _trace_values(run_id: str, i: int, row: Any) -> tuple:
    if not isinstance(row, dict) or not {"trial", "score", "accepted"} <= row.keys():
        raise LibraryError(f"trace row {i}: expected a dict with trial, score, accepted")
    return (run_id, index(row["trial"], f"trace row {i}: trial"), real(row["score"], f"trace row {i}: score"),
            int(bool(row["accepted"])))


def _cell(row: sqlite3.Row, column: str, read: Any) -> Any:
    """``read(row[column])``, a Damaged error naming the column if the cell cannot be read."""
    try:
        return read(row[column])
    except Damaged as e:
        raise Damaged(f"its {column}: {e}") from None


def _optional(read: Any) -> Any:
    return lambda v: None if v is None else read(v)


def _run(row: sqlite3.Row, strict: bool = True) -> Run:
    """The Run of a ``runs`` row; ``strict=False``: whatever can be read, status "damaged"."""
    if not strict:
        lenient = lambda v: v if isinstance(v, str) else "" if v is None else repr(v)
        try:
            params = json.loads(str(row["params"]))
        except (json.JSONDecodeError, RecursionError):
            params = {}
        return Run(run_id=lenient(row["run_id"]), kind=lenient(row["kind"]), created=lenient(row["created"]),
                   creature=lenient(row["creature"]) or "?", creature_text="", creature_hash="",
                   params=params if isinstance(params, dict) else {}, seed=None,
                   sanlab_version=lenient(row["sanlab_version"]), device=None, dtype=None, status="damaged",
                   parent_gait=None, total=row["total"] if isinstance(row["total"], int) else 0, count=row["n"],
                   trials=row["n_trials"])
    status = _cell(row, "status", from_text)
    if status == "running" and "owner" in row.keys() and _stale(row["owner"]):
        status = "interrupted"  # its process is gone: it was killed before it could say so
    return Run(run_id=_cell(row, "run_id", from_text), kind=_cell(row, "kind", from_text),
               created=_cell(row, "created", from_text), creature=_cell(row, "creature", from_text),
               creature_text=_cell(row, "creature_text", from_text),
               creature_hash=_cell(row, "creature_hash", from_text), params=_cell(row, "params", from_json),
               seed=_cell(row, "seed", _optional(_int)), sanlab_version=_cell(row, "sanlab_version", from_text),
               device=_cell(row, "device", _optional(from_text)), dtype=_cell(row, "dtype", _optional(from_text)),
               status=status, parent_gait=_cell(row, "parent_gait", _optional(from_text)),
               total=_cell(row, "total", _int), count=row["n"], trials=row["n_trials"])


def _design(row: sqlite3.Row, strict: bool = True) -> DesignRecord:
    """The DesignRecord of a ``designs`` row; ``strict=False``: what can be read, status "damaged"."""
    if not strict:
        lenient = lambda v: v if isinstance(v, str) else "" if v is None else repr(v)
        return DesignRecord(design_id=lenient(row["design_id"]), created=lenient(row["created"]),
                            updated=lenient(row["updated"]), creature=lenient(row["creature"]) or "?",
                            source=lenient(row["source"]), creature_text="", creature_hash="", settings={}, free=(),
                            status="damaged", result=None, sanlab_version=lenient(row["sanlab_version"]), scores=row["n"])
    status = _cell(row, "status", from_text)
    if status == "running" and _stale(row["owner"]):
        status = "interrupted"  # its process is gone: it was killed before it could say so
    free = _cell(row, "free", lambda v: from_json(v, list))
    if not all(isinstance(f, dict) for f in free):
        raise Damaged("its free: objects were expected")
    return DesignRecord(design_id=_cell(row, "design_id", from_text), created=_cell(row, "created", from_text),
                        updated=_cell(row, "updated", from_text), creature=_cell(row, "creature", from_text),
                        source=_cell(row, "source", from_text), creature_text=_cell(row, "creature_text", from_text),
                        creature_hash=_cell(row, "creature_hash", from_text), settings=_cell(row, "settings", from_json),
                        free=tuple(free), status=status, result=_cell(row, "result", _optional(from_json)),
                        sanlab_version=_cell(row, "sanlab_version", from_text), scores=row["n"])


def _int(v: Any) -> int:
    if isinstance(v, int) and not isinstance(v, bool):
        return v
    raise Damaged(f"an integer was expected, the cell holds {str(v)[:40]!r}")


def _evaluation(row: sqlite3.Row, rank: int | None) -> Evaluation:
    return Evaluation(run_id=row["run_id"], idx=row["idx"], encoding=_cell(row, "encoding", from_text),
                      params=_cell(row, "params", from_json), score=_cell(row, "score", as_float),
                      speed_cm_s=_cell(row, "speed_cm_s", as_float), fell=bool(row["fell"]),
                      nonfinite=bool(row["nonfinite"]),
                      extra=_cell(row, "extra", _optional(from_json)),
                      parent=_cell(row, "parent", _optional(from_text)), rank=rank)


# -- owners of running runs ----------------------------------------------------------------------


def _proc_stat(pid: int) -> list[bytes]:
    """Process ``pid``'s /proc stat fields after its name (state first); [] where there are none
    (not Linux, or no such process)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return []


def _process_start(pid: int) -> str | None:
    """When process ``pid`` started (Linux: clock ticks since boot, /proc), so that a reused pid
    is not taken for the owner; None where that cannot be known."""
    fields = _proc_stat(pid)
    return fields[19].decode() if len(fields) > 19 else None


def _me() -> dict:
    return {"host": socket.gethostname(), "pid": os.getpid(), "start": _process_start(os.getpid())}


def _owner() -> str:
    return json.dumps(_me(), sort_keys=True)


def _parse_owner(owner: Any) -> dict | None:
    try:
        o = json.loads(owner) if isinstance(owner, str) and not isinstance(owner, BadText) else None
    except (json.JSONDecodeError, RecursionError):
        return None
    return o if isinstance(o, dict) and isinstance(o.get("pid"), int) else None


def _alive(owner: dict) -> bool:
    """Whether the owner process still runs (True where it cannot be told: another host)."""
    if owner.get("host") != socket.gethostname():
        return True
    pid = owner["pid"]
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True  # someone else's process, or a pid we cannot ask about: assume it lives
    fields = _proc_stat(pid)
    if fields[:1] in ([b"Z"], [b"X"]):
        return False  # it has exited; only its parent has not reaped it yet
    start = owner.get("start")
    return start is None or (fields[19].decode() if len(fields) > 19 else None) in (None, start)


def _stale(owner: Any) -> bool:
    """A running run's owner column says its process is gone."""
    o = _parse_owner(owner)
    return o is not None and not _alive(o)
