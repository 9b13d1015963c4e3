"""What the command modules share: the console, ``fail``, printing user text safely, strict
JSON, loading a creature, opening the gait library, validating arguments before a run is
created, writing output files whole or not at all, the common options, the table of a run's
best gaits and the progress bar."""

from __future__ import annotations

import contextlib
import json
import math
import os
import stat
import tempfile
import threading
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Column, Table

from sanlab.creature import Creature, CreatureError, load, printable, read_source
from sanlab.creature.spec import MAX_STEPS, METRICS

if TYPE_CHECKING:  # the library is imported when a command opens one, not at start-up
    from sanlab.library import Library

console = Console()

T = TypeVar("T")

CreatureArg = Annotated[
    str, typer.Argument(metavar="CREATURE", help="A built-in creature name (see `sanlab creatures`) or a .toml file.")
]
DbOpt = Annotated[str, typer.Option("--db", help="Gait library file (SQLite).", show_default=True)]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print JSON instead (machine-readable).")]
DtypeOpt = Annotated[str, typer.Option(help="The simulation's arithmetic: float64 (default) or float32 (the "
                                                  "creature's numbers rounded, every step in float32: 2 to 3 times as "
                                                  "fast; scores agree with float64's by distribution, not bit for bit).")]
METRIC_HELP = " | ".join(METRICS)
EnsembleOpt = Annotated[int, typer.Option(
    "--ensemble", help="Score each controller as the median over K perturbed copies (start pose jittered by "
                       "1 mm and 0.5 deg), K from 1 to 256; 1: a single unperturbed rollout.")]
DtFactorsOpt = Annotated[str | None, typer.Option(
    "--dt-factors", help="The ensemble's members run at these factors on the time step in turn, and the lowest "
                         "group median is the score, so a gait of one step size cannot win; default 1,0.5 "
                         "(1 with --ensemble 1); 1: every member at the creature's step.")]
DtJitterOpt = Annotated[float, typer.Option(
    "--dt-jitter", min=0.0, help="Scale each member's step by 1 + U(-D, D) as well (D < 0.5; default 0: off).")]
BackendOpt = Annotated[str, typer.Option(
    "--backend", help="Where evaluations run: local (this machine's cores) or ray (Ray workers; needs "
                      "pip install 'sanlab\\[cluster]').")]
AddressOpt = Annotated[str | None, typer.Option(
    "--address", help="With --backend ray: the cluster (auto, or ray://HOST:PORT); default: start one here.")]
WorkersOpt = Annotated[int | None, typer.Option(
    "--workers", min=1, help="With --backend ray: workers (default: one per CPU of the cluster).")]


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print one plain line to stderr; ``raise fail(...)`` ends the command with ``code``.

    The line is made printable (newlines, escape sequences written as escapes): it may quote a
    file name or a value the user gave."""
    typer.echo(printable(message), err=True)
    return typer.Exit(code)


def warn(message: str) -> None:
    """One printable line on stderr that does not end the command."""
    typer.echo(printable(message), err=True)


def safe(text: Any) -> str:
    """User-controlled text (a name, a path, a stored value) for ``console.print``: printable,
    and Rich markup escaped, so it can neither move the cursor nor restyle the terminal."""
    return escape(printable(str(text)))


def dump_json(obj: Any) -> str:
    """Strict JSON text (``--json``): NaN and infinities become null, as JSON has neither."""
    return json.dumps(_finite(obj), indent=2, allow_nan=False)


def record(name: str, fields: dict) -> dict:
    """``fields`` as the ``--json`` record ``name``: its first field ``"schema":
    "sanlab/<name>/1"`` names the JSON Schema it follows (``sanlab/schemas/<name>.json``, ``sanlab.cli._schemas``,
    documented in docs/json.md); the number goes up when a field changes meaning or goes away."""
    from sanlab.cli._schemas import schema_id

    return {"schema": schema_id(name), **fields}


def _finite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if hasattr(obj, "tolist"):  # NumPy scalars and arrays
        return _finite(obj.tolist())
    return obj


def check_dtype(dtype: str) -> None:
    """Exit 2 unless ``dtype`` is one the simulator compiles to."""
    if dtype not in ("float32", "float64"):
        raise fail(f"--dtype: expected float32 or float64, got {dtype!r}")


def ensemble_or_exit(members: int, dt_factors: str | None = None, dt_jitter: float = 0.0) -> Any:
    """The :class:`sanlab.evaluate.Ensemble` of ``--ensemble K``, ``--dt-factors F,F`` and
    ``--dt-jitter D`` (``sanlab.evaluate.ensemble.default_ensemble``), or exit 2 with one line."""
    from sanlab.evaluate.ensemble import default_ensemble

    check_count("--ensemble", members, 1, MAX_MEMBERS)
    if not (math.isfinite(dt_jitter) and 0 <= dt_jitter < 0.5):
        raise fail(f"--dt-jitter: expected a number in [0, 0.5), got {dt_jitter:g}")
    factors = None
    if dt_factors is not None:
        try:
            factors = tuple(float(x) for x in dt_factors.split(","))
        except ValueError:
            raise fail(f"--dt-factors: expected comma-separated numbers such as 1,0.5, got {dt_factors!r}") from None
    try:
        return default_ensemble(members, factors, dt_jitter)
    except ValueError as e:
        which = "--dt-factors" if "dt_factors" in str(e) or "step factors" in str(e) else "--ensemble"
        raise fail(option_error(which, e)) from None


def backend_or_exit(name: str, address: str | None, workers: int | None) -> Any:
    """The evaluation backend of ``--backend``, ``--address``, ``--workers``, or exit 2 with one
    line (Ray missing: how to install it)."""
    from sanlab.evaluate import make_backend

    try:
        return make_backend(name, address=address, workers=workers)
    except ImportError as e:
        raise fail(str(e)) from None
    except ValueError as e:
        raise fail(option_error("--backend", e)) from None


def load_or_exit(name_or_path: str) -> tuple[Creature, str]:
    """The creature and where it came from, or exit 2 with the loader's one-line message."""
    try:
        _, where = read_source(name_or_path)
        return load(name_or_path), where
    except CreatureError as e:
        raise fail(str(e)) from None


def open_library(path: str, *, create: bool = False, readonly: bool = False) -> Library:
    """The gait library at ``path``, or exit 2 with one line.

    Only commands that start new runs pass ``create=True``: everywhere else a missing file is a
    mistyped ``--db``, refused rather than silently created empty. Commands that only read pass
    ``readonly=True``: they write nothing, so they work on a library in a read-only folder; the
    others get a library that passes SQLite's quick check (``Library.check_intact``). An
    empty path (``--db ''``) is refused: SQLite would make a temporary database of it, and a run
    stored there could never be found again.
    """
    from sanlab.library import Library, LibraryError

    if not path.strip():
        raise fail("--db: expected the path of a gait library file, got an empty path")
    if not create and not path.startswith("file:") and path != ":memory:" and not os.path.exists(path):
        raise fail(f"{path}: no such gait library (give --db PATH)")
    try:
        lib = Library(path, readonly=readonly)
    except LibraryError as e:
        raise fail(str(e)) from None
    if not readonly:  # a command that writes: a damaged file takes no new run (issue 48)
        try:
            lib.check_intact()
        except LibraryError as e:
            lib.close()
            raise fail(str(e)) from None
    _opened.append(lib)
    return lib


_opened: list[Library] = []  # closed when the command ends (close_libraries), whatever way it ends


def close_libraries() -> None:
    """Close every library a command opened: a read-only one then removes the empty ``-wal`` and
    ``-shm`` files SQLite made for it (``Library.close``)."""
    while _opened:
        with contextlib.suppress(Exception):  # closing must not hide what ended the command
            _opened.pop().close()


# -- arguments, checked before anything is created -----------------------------------------------

MAX_COUNT = 10_000_000  # controllers, trials: more would not finish in a day
MAX_BATCH = 65_536
MAX_TOP = 10_000
MAX_MEMBERS = 256  # ensemble members: each evaluation is this many rollouts
SEED_RANGE = (0, 2**63 - 1)  # what the library stores (an SQLite INTEGER) and NumPy seeds take


def check_render_dir(out_dir: str | None) -> None:
    """``--render DIR`` of search and tune, checked before the run starts (not after hours of it):
    an existing folder, or a new one whose parent exists (no chain of folders is made)."""
    if out_dir is None:
        return
    if not out_dir.strip():
        raise fail("--render: expected a folder, got an empty path")
    if os.path.exists(out_dir):
        if not os.path.isdir(out_dir):
            raise fail(f"--render {out_dir}: expected a folder, got an existing file")
        return
    parent = os.path.dirname(os.path.abspath(out_dir))
    if not os.path.isdir(parent):
        raise fail(f"--render {out_dir}: directory {parent} does not exist")


def check_count(option: str, value: int, lo: int = 1, hi: int = MAX_COUNT) -> int:
    """Exit 2 unless ``lo <= value <= hi`` (an option like ``--controllers``)."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise fail(f"{option}: expected an integer in [{lo}, {hi:,}], got {value}")
    return value


def check_seed(value: int, option: str = "--seed") -> int:
    """Exit 2 unless ``value`` is a seed the library can store."""
    return check_count(option, value, *SEED_RANGE)


def check_seconds(value: float | None, spec: Creature | None = None, option: str = "--seconds") -> float | None:
    """Exit 2 unless ``value`` is None or a finite evaluation time > 0 that ``spec`` can run
    (at most spec.MAX_STEPS steps of its dt, the creature file's own limit)."""
    if value is None:
        return None
    dt = spec.dt if spec is not None else 1e-3
    most = MAX_STEPS * dt
    if not isinstance(value, (int, float)) or not math.isfinite(value) or not 0 < value <= most:
        raise fail(f"{option}: expected a number of seconds in (0, {most:g}] ({MAX_STEPS:,} steps of dt = {dt:g} s), "
                   f"got {value}")
    if value < dt:
        raise fail(f"{option}: expected at least one step of dt = {dt:g} s, got {value:g}")
    return float(value)


def option_error(option: str, e: Exception) -> str:
    """``option: message`` for an error about an option's value, without the option's bare name
    twice when the message already starts with it ("--metric: metric: ...")."""
    msg, bare = str(e), option.lstrip("-") + ": "
    return f"{option}: {msg[len(bare):] if msg.startswith(bare) else msg}"


def check_metric(value: str | None, spec: Creature, option: str = "--metric") -> str | None:
    """Exit 2 unless ``value`` is None or a metric ``spec`` can be scored by."""
    if value is None:
        return None
    from sanlab.metrics import Metric

    try:
        Metric.for_creature(spec, value)
    except ValueError as e:
        raise fail(option_error(option, e)) from None
    return value


def check_gait(value: str, option: str = "GAIT") -> str:
    """Exit 2 unless ``value`` is a well-formed gait id (RUN/RANK or RUN#IDX)."""
    from sanlab.library import LibraryError, parse_gait_id

    try:
        parse_gait_id(value)
    except LibraryError as e:
        raise fail(option_error(option, e)) from None
    return value


def check_run_args(spec: Creature, *, controllers: int | None = None, seconds: float | None = None,
                   metric: str | None = None, seed: int | None = None, batch: int | None = None,
                   trials: int | None = None, top: int | None = None) -> None:
    """Every argument of a command that starts a run (search, tune, simulate, reproduce), checked
    against ``spec`` before anything is compiled or stored; exit 2 with one line on the first
    bad one. Arguments left None are not checked."""
    if controllers is not None:
        check_count("--controllers", controllers)
    if trials is not None:
        check_count("--trials", trials)
    if batch is not None:
        check_count("--batch", batch, 1, MAX_BATCH)
    if top is not None:
        check_count("--top", top, 1, MAX_TOP)
    if seed is not None:
        check_seed(seed)
    check_seconds(seconds, spec)
    check_metric(metric, spec)


# -- output files ----------------------------------------------------------------------------------


def check_writable(path: str, option: str, command: str) -> None:
    """Exit 2 with one line naming ``command``, ``option`` and ``path`` unless ``path`` looks
    writable: its folder exists, is a folder and may be written, and ``path`` is no folder. For a
    command that writes only at its end (``sanlab design``): a mistyped folder is told before the
    work, not after it. Writing may still fail (a full disk): the writer reports that itself."""
    folder = os.path.dirname(os.path.abspath(path))
    why = None
    if not os.path.isdir(folder):
        why = f"no such folder {folder}" if not os.path.exists(folder) else f"{folder} is not a folder"
    elif os.path.isdir(path):
        why = "it is a folder"
    elif not os.access(folder, os.W_OK | os.X_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        why = "permission denied"
    if why is not None:
        raise fail(f"{command}: {option} {path}: cannot write ({why})")


@contextlib.contextmanager
def output_file(path: str, option: str = "--out") -> Iterator[str]:
    """Where to write ``path`` so that it appears whole or not at all: a temporary file beside it
    (same extension), moved into place when the block ends; removed, with the target untouched,
    if the block fails. A target that exists and is not a regular file (``/dev/stdout``, a FIFO)
    is written directly. An OSError (a full disk, a read-only folder) exits 2 with one line
    naming the file."""
    try:
        st = os.stat(path)
        direct = not stat.S_ISREG(st.st_mode)
    except FileNotFoundError:
        direct = False
    except OSError as e:
        raise fail(f"{option} {path}: cannot write ({e.strerror or e})") from None
    if direct:
        try:
            yield path
        except OSError as e:
            raise fail(f"{option} {path}: cannot write ({e.strerror or e})") from None
        return
    folder = os.path.dirname(os.path.abspath(path))
    stem, ext = os.path.splitext(os.path.basename(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{stem}.", suffix=f".part{ext}", dir=folder)
        os.close(fd)
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)  # as open() would make it, not mkstemp's 0600
    except OSError as e:
        raise fail(f"{option} {path}: cannot write ({e.strerror or e})") from None
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as e:
        raise fail(f"{option} {path}: cannot write ({e.strerror or e}); nothing was written, "
                   "free some space or choose another folder") from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def refuse_with_resume(ctx: typer.Context, command: str, names: tuple[str, ...]) -> None:
    """Exit 2 when any option of ``names`` (parameter names) was given on the command line
    together with --resume: a resumed run keeps its own stored settings, so such an option would
    be silently ignored."""
    def explicit(name: str) -> bool:
        src = ctx.get_parameter_source(name)  # typer vendors its own click: compare the enum by name
        return src is not None and src.name in ("COMMANDLINE", "ENVIRONMENT")

    given = [p for p in ctx.command.params if p.name in names and explicit(p.name)]
    if given:
        flags = ", ".join(p.opts[0] for p in given)
        raise fail(f"{command}: {flags} cannot change a resumed run (it continues with its stored settings); "
                   "drop them, or start a new run")


def library_call(fn: Callable[..., T], *args: Any) -> T:
    """``fn(*args)``, or exit 2 with the LibraryError's one line (1 with a remote worker's error,
    ``sanlab.evaluate.ray_backend.WorkerError``)."""
    from sanlab.evaluate.ray_backend import WorkerError
    from sanlab.library import LibraryError

    try:
        return fn(*args)
    except LibraryError as e:
        raise fail(str(e)) from None
    except WorkerError as e:
        raise fail(str(e), 1) from None


def direction(dx_m: Any) -> str | None:
    """"+x" or "-x": which way a gait moved along x (its signed displacement ``dx_m``, m), or
    None when that is unknown or it did not move."""
    if isinstance(dx_m, bool) or not isinstance(dx_m, (int, float)) or not math.isfinite(dx_m) or dx_m == 0:
        return None
    return "+x" if dx_m > 0 else "-x"


ARROWS = {"+x": "→", "-x": "←", None: " "}


def top_rows(lib: Library, run_id: str, n: int) -> list[dict]:
    """The run's ``n`` best gaits as the rows ``--json`` prints (the gait row of
    ``sanlab/schemas/gait-row.json``): gait id, score, speed (cm/s), the signed displacement
    along x ``dx_m`` (m) and ``direction`` ("+x", "-x"; null where the run did not store it),
    flags (``verdict``: the stored audit's, "robust", "resolution-dependent", "undecided" or
    "not reproduced", and ``flagged``, ``resolution_dependent`` and ``reproduced`` from it; null
    when it was never audited; see ``sanlab audit``), encoding, and ``kind``: "san", or "pattern"
    for an open-loop pattern (``search --strategy pattern``, the pattern ceiling)."""
    audits = lib.audits(run_id)
    rows = []
    for rank, e in enumerate(lib.top(run_id, n), 1):
        dx = (e.extra or {}).get("dx_m")
        dx = dx if isinstance(dx, (int, float)) and not isinstance(dx, bool) else None
        rows.append({
            "gait": f"{run_id}/{rank}", "score": e.score, "speed_cm_s": e.speed_cm_s, "dx_m": dx,
            "direction": direction(dx), "fell": e.fell, "nonfinite": e.nonfinite,
            "verdict": audits[e.idx].verdict if e.idx in audits else None,
            "flagged": audits[e.idx].flagged if e.idx in audits else None,
            "resolution_dependent": audits[e.idx].resolution_dependent if e.idx in audits else None,
            "reproduced": audits[e.idx].reproduced if e.idx in audits else None, "encoding": e.encoding,
            "kind": "pattern" if "pattern" in (e.params or {}) else "san",
        })
    return rows


def id_column(header: str, ids: list[str]) -> Column:
    """A table column of ids (gaits, runs): never cut nor wrapped, as wide as the longest; a
    narrow terminal folds the other columns instead. The id is what a user copies."""
    return Column(header, no_wrap=True, overflow="fold", min_width=max((len(i) for i in ids), default=0))


def print_top(rows: list[dict], title: str, unit: str = "", selected: int | None = None) -> None:
    """The table of a run's best gaits; the speed column carries an arrow for the direction of
    motion along x (→ +x, ← -x) where the run stored it. ``unit``: the score's unit;
    ``selected``: the rank of a tuning run's audited selection (flagged "quote this")."""
    score = f"score ({unit})" if unit else "score"
    table = Table("rank", id_column("gait", [r["gait"] for r in rows]), score, "speed (cm/s)", "flags",
                  title=safe(title))
    for rank, r in enumerate(rows, 1):
        flags = ", ".join(f for f, on in (("pattern", r.get("kind") == "pattern"), ("fell", r["fell"]),
                                          ("non-finite", r["nonfinite"]),
                                          ("not reproduced", r.get("reproduced") is False),
                                          ("resolution-dependent", r.get("resolution_dependent")),
                                          ("audit undecided", r.get("verdict") == "undecided"),
                                          ("audited: robust", r.get("verdict") == "robust"),
                                          ("quote this", rank == selected)) if on)
        arrow = ARROWS[r.get("direction")]
        table.add_row(str(rank), r["gait"], f"{r['score']:.3f}", f"{arrow} {r['speed_cm_s']:.1f}", flags or "-")
    console.print(table)
    zero = [str(rank) for rank, r in enumerate(rows, 1) if abs(r["score"]) < 0.0005 and not r["fell"] and not r["nonfinite"]]
    if zero:  # an imported walker2d's rows: 0.000, no flag and "← -8.9" left the reader to guess why
        console.print(f"score 0.000 without a flag (rank {', '.join(zero)}): a score is the median over the gait's "
                      "perturbed members (with two step sizes, dt and dt/2, of the group that scored lower), and its median "
                      "member scored about 0: it fell, or did not move the way the file scores (\"fell\" needs more "
                      "than half of all members to fall); the speed is a median of the same members, and may point "
                      "the way that scores nothing")


def print_distribution(scores: list[float]) -> None:
    import numpy as np

    if not scores:
        return
    s = np.sort(np.asarray(scores))[::-1]
    qs = ", ".join(f"{p}%: {np.percentile(s, 100 - p):.3f}" for p in (1, 5, 10, 50))
    console.print(f"score distribution over {len(s)} controllers (best first) — top {qs}; best {s[0]:.3f}")


def next_steps(db: str, run_id: str, rows: list[dict], tally: dict[str, int] | None = None,
               earlier: list[str] | None = None) -> None:
    """What a search prints under its table: where the run is stored, how many controllers fell
    or went non-finite, whether it repeats earlier runs (their ids), and the next commands with
    the real ids (show, render, tune)."""
    if tally:
        console.print(f"stored in {safe(db)} as run {run_id}: {tally['evaluated']} controllers, {tally['fell']} fell, "
                      f"{tally['nonfinite']} non-finite (scored 0)")
    if earlier:
        console.print(f"[yellow]this repeats run{'s' * (len(earlier) > 1)} {', '.join(earlier)}[/yellow] (same creature "
                      "file, settings and seed: the same results); change --seed for new controllers")
    if rows:
        best = rows[0]["gait"]
        tune = [f"sanlab tune {best}"] if rows[0].get("kind") != "pattern" else []  # a pattern has no SAN to tune
        print_next(db, [f"sanlab show {best}", f"sanlab render {best} -o best.png", *tune, f"sanlab audit {best}"])


def print_ceiling_share(lib: Library, gait_id: str, speed_cm_s: float, what: str = "the best") -> None:
    """One line: what fraction of its creature's pattern ceiling (``sanlab ceiling``, stored in
    ``lib`` for the same creature file, metric and time) the gait ``gait_id`` reaches at
    ``speed_cm_s``; nothing when no ceiling is stored or the gait is a pattern itself."""
    from sanlab.search.ceiling import find

    ev = library_call(lib.gait, gait_id)
    if "pattern" in (ev.params or {}):
        return
    run = library_call(lib.get_run, ev.run_id)
    s = run.settings
    c = library_call(find, lib, run.creature_text, s.metric, s.seconds)
    share = None if c is None else c.fraction(speed_cm_s)
    if c is not None and share is not None:
        vouched = "audited: robust" if c.robust else "not vouched for by an audit"
        console.print(f"{what} ({gait_id}, {speed_cm_s:.1f} cm/s) reaches {100 * share:.0f} % of the creature's pattern "
                      f"ceiling ({c.speed_cm_s:.1f} cm/s, gait {c.gait}, {vouched})", soft_wrap=True)


def quoted_gait(lib: Library, run_id: str) -> tuple[str | None, bool]:
    """(the gait of run ``run_id`` to quote, whether an audited selection chose it): a tuning
    run's stored selection (``sanlab audit RUN --select``, stored as ``RUN#1``) when it found a
    robust rung, else None with True when a selection found none, else None with False. Its
    rank (``RUN/RANK``) is not this id: a selection often scores below the chain's best
    (``RUN#0``, rank 1), which no audit vouched for (issue 57)."""
    sel = library_call(lib.selection, run_id) if library_call(lib.get_run, run_id).kind == "tune" else None
    if sel is None:
        return None, False
    return (f"{run_id}#{sel['idx']}" if isinstance(sel.get("idx"), int) else None), True


def print_next(db: str, commands: list[str], without_db: tuple[str, ...] = ()) -> None:
    """The "next:" line under a command's output: ``commands`` (each given ``--db`` when the
    library is not the default one), then ``without_db`` (commands that take no library, as
    they are), four spaces apart, never wrapped inside a command."""
    db_opt = "" if db == "sanlab.db" else f" --db {db}"
    shown = [f"{safe(c)}{safe(db_opt)}" for c in commands] + [safe(c) for c in without_db]
    if shown:
        console.print("next: " + "    ".join(shown), soft_wrap=True)


class ProgressBar:
    """A Rich progress bar fed by a driver's reports: done/total, evaluations per second, best
    score, time elapsed and an estimate of the time left; drawn only when ``show`` (a terminal,
    and no ``--json``)."""

    def __init__(self, show: bool, title: str | None = None, unit: str = "",
                 rate: str | None = "{task.fields[rate]:.0f} eval/s", best: str = "best {task.fields[best]:.3f}"):
        """``unit``: what is counted, after done/total ("scores"); ``rate`` and ``best``: their
        columns' Rich formats (``rate`` None: no rate column, for work of minutes a unit)."""
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        first = TextColumn(f"[bold]{escape(title)}" if title else "[bold]{task.description}")
        columns = [first, BarColumn(), MofNCompleteColumn(), *([TextColumn(escape(unit))] if unit else []),
                   *([TextColumn(rate)] if rate else []), TextColumn(best)]
        self.progress = Progress(
            *columns, TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), console=console,
            disable=not show, transient=False,
        )
        self._task: Any = None
        self._key: str | None = None
        self._keyed: dict[str, Any] = {}
        self._lock = threading.Lock()

    def waiting(self, description: str, total: int | None = None) -> None:
        """Show ``description`` before the first report: a first batch can take a minute (its
        compile, on a creature's first run), and a bar at 0/N with no word looked stuck."""
        if self._task is None:
            self._task = self.progress.add_task(description, total=total, rate=0.0, best=0.0)

    def update(self, description: str, completed: int, total: int, rate: float, best: float,
               key: str | None = None) -> None:
        """Move the bar; a ``key`` not seen before starts a new bar under the others, and a key
        seen before moves its own bar (a job of several steps, some side by side, ``sanlab
        reproduce``: each its own count, pace and time left)."""
        with self._lock:  # rows made side by side report from their own threads
            if key is not None and key != self._key:
                self._key, self._task = key, self._keyed.get(key)
            if self._task is None:
                self._task = self.progress.add_task(description, total=total, rate=0.0, best=best)
                if key is not None:
                    self._keyed[key] = self._task
            self.progress.update(self._task, description=description, total=total, completed=completed, rate=rate,
                                 best=best)

    def __enter__(self) -> ProgressBar:
        self.progress.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.progress.__exit__(*exc)


def duration(seconds: float) -> str:
    """``seconds`` as a person says it: "45 s", "3 min 20 s", "1 h 05 min"."""
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class ProgressLines:
    """Progress as plain lines on stderr, for output that is not a terminal (a log file, a pipe),
    where :class:`ProgressBar` draws nothing: a line each time another tenth of the work is done,
    and at least every ``every_s`` seconds while it goes on, e.g. "tune: 30/100 trials (30 %),
    2.1 eval/s, best 1.234, 1 min 05 s elapsed, about 2 min 30 s left"."""

    def __init__(self, show: bool, what: str, unit: str, every_s: float = 60.0, rate: str | None = "{:.1f} eval/s",
                 best: str = "best {:.3f}"):
        """``rate`` and ``best``: how a line writes them (``str.format`` of the number; ``rate``
        None: left out, for work of minutes a unit)."""
        import time

        self.show, self.what, self.unit, self.every_s = show, what, unit, every_s
        self.rate, self.best = rate, best
        self._clock = time.perf_counter
        self._t0 = self._clock()
        self._last_t = self._t0
        self._last_tenth = 0
        self._last_done = 0
        self._mark: tuple[float, int] | None = None  # (time, done) of the first report with work done

    def update(self, done: int, total: int, rate: float, best: float, workers: int | None = None) -> None:
        """``workers``: the workers alive on a cluster, said in the line (None: not said)."""
        now = self._clock()
        if self._mark is None or done <= self._mark[1]:
            self._mark = (now, done)  # the rate is measured after the first batch, which compiles
        tenth = 10 * done // max(total, 1)
        if not self.show or done == 0 or done == self._last_done or (
                tenth <= self._last_tenth and now - self._last_t < self.every_s and done < total):
            return
        self._last_tenth, self._last_t, self._last_done = tenth, now, done
        left = self.left(done, total, now)
        tail = f", about {duration(left)} left" if left is not None and done < total else ""
        said = f"{self.rate.format(rate)}, " if self.rate else ""
        said += "" if workers is None else f"{workers} workers alive, "
        warn(f"{self.what}: {done}/{total} {self.unit} ({100 * done // max(total, 1)} %), {said}"
             f"{self.best.format(best)}, {duration(now - self._t0)} elapsed{tail}")

    def left(self, done: int, total: int, now: float | None = None) -> float | None:
        """Seconds left at the pace since the first report (None until work was done after it)."""
        now = self._clock() if now is None else now
        if self._mark is None or done <= self._mark[1]:
            return None
        t, d = self._mark
        return (now - t) / (done - d) * (total - done)


def refuse_still(spec: Creature, creature: str, command: str = "search") -> None:
    """Exit 2 with one line (the reason and the fix) when ``spec`` can never move: it has no
    actuator that drives anything (``sanlab.check.actuators``: every controller would score what
    the body does by itself), or no sensor is on at rest, so every SAN holds every servo at mid
    range (``sanlab.check.at_rest``, which needs no simulation and says nothing where it cannot
    tell). ``--force`` skips this."""
    from sanlab.check import actuators, at_rest

    idle = [f for f in actuators(spec) if f.warning]
    if idle:
        why = idle[0].message.replace("actuators: none", "no actuators").replace("actuators: every one", "every actuator")
        raise fail(f"{command}: {creature} can never move: {why} (or give --force to {command} it anyway)")
    still = [f for f in at_rest(spec) if f.warning]
    if still:
        raise fail(f"{command}: {creature} can never move: {still[0].message.replace('sensors at rest: none', 'no sensor').removeprefix('sensors at rest: ')} "
                   f"(or give --force to {command} it anyway)")


def print_static_warnings(spec, creature: str) -> None:
    """The warnings of `sanlab check` that need no simulation (no actuator that drives anything,
    angle ranges that look like radians, actuators too weak or too strong for their load, servos
    the step cannot resolve, sensors all off at rest), once, on stderr; the simulated
    ones (start pose, sinking, ground, standing, sensors) cost a compilation and are left to
    `sanlab check --simulate`."""
    from rich.console import Console

    from sanlab.check import static

    err = Console(stderr=True)  # stdout stays the table, or the JSON
    found = [f.message for f in static(spec) if f.warning]
    for message in found:
        err.print(f"[yellow]warning:[/yellow] {safe(message)}", soft_wrap=True, highlight=False)
    if found:
        err.print(f"(sanlab check {safe(creature)} --simulate says more)", soft_wrap=True, highlight=False)
