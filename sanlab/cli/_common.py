"""What the command modules share: the console, ``fail``, loading a creature, opening the gait
library, the common options, the table of a run's best gaits and the progress bar."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from sanlab.creature import Creature, CreatureError, load, read_source
from sanlab.creature.spec import METRICS

if TYPE_CHECKING:  # the library is imported when a command opens one, not at start-up
    from sanlab.library import Library

console = Console()

T = TypeVar("T")

CreatureArg = Annotated[
    str, typer.Argument(help="A built-in creature name (see `sanlab creatures`) or a .toml file.")
]
DbOpt = Annotated[str, typer.Option("--db", help="Gait library file (SQLite).", show_default=True)]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead.")]
DtypeOpt = Annotated[str, typer.Option(help="float32 or float64.")]
METRIC_HELP = " | ".join(METRICS)
EnsembleOpt = Annotated[int, typer.Option(
    "--ensemble", help="Score each controller as the median over K perturbed copies (start pose jittered by "
                       "1 mm and 0.5 deg); 1: a single unperturbed rollout.")]
BackendOpt = Annotated[str, typer.Option(
    "--backend", help="Where evaluations run: local (this machine's cores or GPU) or ray (Ray workers; needs "
                      "pip install 'sanlab[cluster]').")]
AddressOpt = Annotated[str | None, typer.Option(
    "--address", help="With --backend ray: the cluster (auto, or ray://HOST:PORT); default: start one here.")]
WorkersOpt = Annotated[int | None, typer.Option(
    "--workers", min=1, help="With --backend ray: workers (default: one per CPU of the cluster).")]


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print one plain line to stderr; ``raise fail(...)`` ends the command with ``code``."""
    typer.echo(message, err=True)
    return typer.Exit(code)


def check_dtype(dtype: str) -> None:
    """Exit 2 unless ``dtype`` is one the simulator compiles to."""
    if dtype not in ("float32", "float64"):
        raise fail(f"--dtype: expected float32 or float64, got {dtype!r}")


def ensemble_or_exit(members: int) -> Any:
    """The :class:`sanlab.evaluate.Ensemble` of ``--ensemble K``, or exit 2 with one line."""
    from sanlab.evaluate import Ensemble

    try:
        return Ensemble(members=members)
    except ValueError as e:
        raise fail(f"--ensemble: {e}") from None


def backend_or_exit(name: str, address: str | None, workers: int | None) -> Any:
    """The evaluation backend of ``--backend``, ``--address``, ``--workers``, or exit 2 with one
    line (Ray missing: how to install it)."""
    from sanlab.evaluate import make_backend

    try:
        return make_backend(name, address=address, workers=workers)
    except ImportError as e:
        raise fail(str(e)) from None
    except ValueError as e:
        raise fail(f"--backend: {e}") from None


def load_or_exit(name_or_path: str) -> tuple[Creature, str]:
    """The creature and where it came from, or exit 2 with the loader's one-line message."""
    try:
        _, where = read_source(name_or_path)
        return load(name_or_path), where
    except CreatureError as e:
        raise fail(str(e)) from None


def open_library(path: str, *, create: bool = False) -> Library:
    """The gait library at ``path``, or exit 2 with one line.

    Only commands that start new runs pass ``create=True``: everywhere else a missing file is a
    mistyped ``--db``, refused rather than silently created empty.
    """
    from sanlab.library import Library, LibraryError

    if not create and not path.startswith("file:") and path != ":memory:" and not os.path.exists(path):
        raise fail(f"{path}: no such gait library (give --db PATH)")
    try:
        return Library(path)
    except LibraryError as e:
        raise fail(str(e)) from None


def library_call(fn: Callable[..., T], *args: Any) -> T:
    """``fn(*args)``, or exit 2 with the LibraryError's one line."""
    from sanlab.library import LibraryError

    try:
        return fn(*args)
    except LibraryError as e:
        raise fail(str(e)) from None


def top_rows(lib: Library, run_id: str, n: int) -> list[dict]:
    """The run's ``n`` best gaits as the rows ``--json`` prints; ``resolution_dependent`` is the
    verdict of the gait's stored audit (None: never audited, see ``sanlab audit``)."""
    audits = lib.audits(run_id)
    return [
        {
            "gait": f"{run_id}/{rank}",
            "score": e.score,
            "speed_cm_s": e.speed_cm_s,
            "fell": e.fell,
            "nonfinite": e.nonfinite,
            "resolution_dependent": audits[e.idx].flagged if e.idx in audits else None,
            "encoding": e.encoding,
        }
        for rank, e in enumerate(lib.top(run_id, n), 1)
    ]


def print_top(rows: list[dict], title: str) -> None:
    table = Table("rank", "gait", "score", "speed (cm/s)", "flags", title=title)
    for rank, r in enumerate(rows, 1):
        flags = ", ".join(f for f, on in (("fell", r["fell"]), ("non-finite", r["nonfinite"]),
                                          ("resolution-dependent", r.get("resolution_dependent"))) if on)
        table.add_row(str(rank), r["gait"], f"{r['score']:.3f}", f"{r['speed_cm_s']:.1f}", flags or "-")
    console.print(table)


def print_distribution(scores: list[float]) -> None:
    import numpy as np

    if not scores:
        return
    s = np.sort(np.asarray(scores))[::-1]
    qs = ", ".join(f"{p}%: {np.percentile(s, 100 - p):.3f}" for p in (1, 5, 10, 50))
    console.print(f"score distribution over {len(s)} controllers (best first) — top {qs}; best {s[0]:.3f}")


class ProgressBar:
    """A Rich progress bar fed by a driver's reports: done/total, evaluations per second, best
    score; drawn only when ``show`` (a terminal, and no ``--json``)."""

    def __init__(self, show: bool, title: str | None = None):
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        first = TextColumn(f"[bold]{escape(title)}" if title else "[bold]{task.description}")
        self.progress = Progress(
            first, BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[rate]:.0f} eval/s"), TextColumn("best {task.fields[best]:.3f}"),
            TimeElapsedColumn(), console=console, disable=not show, transient=False,
        )
        self._task: Any = None

    def update(self, description: str, completed: int, total: int, rate: float, best: float) -> None:
        if self._task is None:
            self._task = self.progress.add_task(description, total=total, rate=0.0, best=best)
        self.progress.update(self._task, completed=completed, rate=rate, best=best)

    def __enter__(self) -> ProgressBar:
        self.progress.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.progress.__exit__(*exc)
