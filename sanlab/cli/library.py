"""``sanlab runs``, ``show``, ``export`` and ``import``: reading and exchanging the gait library."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from rich.table import Table

from sanlab.cli._common import (
    DbOpt,
    JsonOpt,
    console,
    fail,
    library_call,
    open_library,
    print_distribution,
    print_top,
    top_rows,
)


def runs(db: DbOpt = "sanlab.db", as_json: JsonOpt = False) -> None:
    """List the runs in the gait library, newest first."""
    lib = open_library(db)
    rows = [
        {"run_id": r.run_id, "kind": r.kind, "creature": r.creature, "status": r.status,
         "evaluated": r.count, "total": r.total, "created": r.created}
        for r in lib.runs()
    ]
    if as_json:
        typer.echo(json.dumps(rows, indent=2))
        return
    table = Table("run", "kind", "creature", "status", "evaluated", "created")
    for r in rows:
        created = r["created"][:19].replace("T", " ")
        table.add_row(r["run_id"], r["kind"], r["creature"], r["status"], f"{r['evaluated']}/{r['total']}", created)
    console.print(table)


def show(
    run_id: Annotated[str, typer.Argument(help="A run id (or an unambiguous prefix).")],
    top: Annotated[int, typer.Option(min=1, help="Gaits to show.")] = 10,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Show a run's best gaits: rank, score, speed and flags."""
    lib = open_library(db)
    run = library_call(lib.get_run, run_id)
    rows = top_rows(lib, run.run_id, top)
    if as_json:
        out = {"run_id": run.run_id, "kind": run.kind, "creature": run.creature, "status": run.status,
               "evaluated": lib.count(run.run_id), "params": run.params, "top": rows}
        typer.echo(json.dumps(out, indent=2))
        return
    print_top(rows, f"run {run.run_id}: {run.creature} ({run.status}), metric {run.metric or '?'}")
    print_distribution(lib.scores(run.run_id))


def export_(
    gait: Annotated[str, typer.Argument(help="RUN_ID/RANK, e.g. 3fa1c2d0/1.")],
    out: Annotated[str | None, typer.Option("--out", "-o", help="Write to this file instead of stdout.")] = None,
    db: DbOpt = "sanlab.db",
) -> None:
    """Export a gait (creature, encoding, parameters, score) as JSON."""
    lib = open_library(db)
    data = json.dumps(library_call(lib.export_gait, gait), indent=2)
    if out:
        with open(out, "w") as f:
            f.write(data + "\n")
    else:
        typer.echo(data)


def import_(
    file: Annotated[str, typer.Argument(help="A JSON file written by `sanlab export`.")],
    db: DbOpt = "sanlab.db",
) -> None:
    """Import a gait exported by `sanlab export`; prints its new gait id."""
    try:
        with open(file) as f:
            data = json.load(f)
    except OSError as e:
        raise fail(f"{file}: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise fail(f"{file}: expected JSON, got a syntax error at line {e.lineno}") from None
    lib = open_library(db, create=True)  # an import starts a run: it may start the library too
    typer.echo(library_call(lib.import_gait, data))
