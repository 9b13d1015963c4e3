"""``sanlab audit``: re-score stored gaits with the step halved and quartered and in float64, and
flag those whose speed does not survive (``sanlab.audit``)."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from rich.table import Table

from sanlab import configure
from sanlab.cli._common import DbOpt, JsonOpt, console, library_call, open_library


def audit(
    target: Annotated[str, typer.Argument(help="A gait (RUN/RANK or RUN#IDX), or a run id to audit its top gaits.")],
    top: Annotated[int, typer.Option(min=1, help="With a run id: audit its K best gaits.")] = 1,
    threshold: Annotated[float, typer.Option(min=0.0, help="Flag a relative speed change above this (0.10 = 10 %).")] = 0.10,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Audit gaits for integrator artefacts (dt/2, dt/4, float64).

    Each gait is re-scored exactly as it was scored (same ensemble and draws), once per nudge; a
    gait whose robust speed changes by more than the threshold is flagged resolution-dependent,
    here, in `sanlab show` and in exports. The audit is stored in the library."""
    configure()
    from sanlab.audit import audit_and_store

    lib = open_library(db)
    if "/" in target or "#" in target:
        gaits = [library_call(lib.gait, target).gait_id]
    else:
        run = library_call(lib.get_run, target)
        gaits = [e.gait_id for e in library_call(lib.top, run.run_id, top)]
    log = None if as_json else (lambda m: console.print(f"[dim]{m}[/dim]"))
    results = [library_call(lambda g: audit_and_store(lib, g, threshold=threshold, log=log), g) for g in gaits]
    if as_json:
        typer.echo(json.dumps([{"gait": a.gait_id, "flagged": a.flagged, "worst": a.worst if a.worst != float("inf") else None,
                                **a.to_json()} for a in results], indent=2))
        return
    names = list(results[0].speeds) if results else []
    table = Table(title="audit: robust speed (cm/s) under nudges, change against the re-scored speed")
    table.add_column("gait", no_wrap=True)
    for name in ("stored", "re-scored", *names, "verdict"):
        table.add_column(name, no_wrap=True)
    for a in results:
        cells = [f"{a.speeds[n]:.1f} {100 * a.changes[n]:.0f}%" for n in names]
        verdict = "[red]flagged[/red]" if a.flagged else "[green]robust[/green]"
        table.add_row(a.gait_id, f"{a.stored_cm_s:.1f}", f"{a.nominal_cm_s:.1f}", *cells, verdict)
    console.print(table)
    if any(a.flagged for a in results):
        console.print(f"flagged: resolution-dependent (a nudge moved the speed more than {100 * threshold:.0f} %); "
                      "`sanlab show` and exports say so")
