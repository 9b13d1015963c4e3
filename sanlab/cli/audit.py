"""``sanlab audit``: re-score stored gaits with the step halved and quartered and in float64, and
flag those whose speed does not survive (``sanlab.audit``)."""

from __future__ import annotations

import json
import math
from typing import Annotated

import typer
from rich import box
from rich.table import Table

from sanlab import configure
from sanlab.cli._common import DbOpt, JsonOpt, console, fail, library_call, open_library


def audit(
    target: Annotated[str, typer.Argument(help="A gait (RUN/RANK or RUN#IDX), or a run id to audit its top gaits.")],
    top: Annotated[int | None, typer.Option(min=1, help=(
        "With a run id: audit its K best gaits (default 1); with --select: audit up to K rungs (default 16)."))] = None,
    threshold: Annotated[float, typer.Option(min=0.0, help="Flag a relative speed change above this (0.10 = 10 %).")] = 0.10,
    select: Annotated[bool, typer.Option("--select", help=(
        "With a tuning run: audit the rungs of its climb and store the best-scoring one that no nudge "
        "moves by more than the threshold as its gait RUN#1."))] = False,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Audit gaits for integrator artefacts (dt/2, dt/4, float64).

    Each gait is re-scored exactly as it was scored (same ensemble and draws), once per nudge; a
    gait whose robust speed changes by more than the threshold is flagged resolution-dependent,
    and one whose stored speed is that far from the re-scored one is flagged not reproduced
    (here, in `sanlab show` and in exports). The audit is stored in the library.

    With --select and a tuning run: up to 16 rungs of its chain's climb (its start, its best and
    the vectors that first reached the scores between) are audited, and the best-scoring one that
    keeps its speed (the start itself, when no tuned rung does) is stored as the run's gait RUN#1,
    the tuned result to quote."""
    configure()
    from sanlab.audit import SELECT_TOP, audit_and_store

    if not math.isfinite(threshold):
        raise fail(f"audit: --threshold: expected a finite number >= 0, got {threshold}")
    lib = open_library(db)
    if select:
        if "/" in target or "#" in target:
            raise fail("audit --select: give a tuning run id, not a gait")
        run = library_call(lib.get_run, target)
        if run.kind == "tune" and 0 not in library_call(lib.done_indices, run.run_id):  # the command to run names --db
            raise fail(f"audit --select: run {run.run_id} has not finished: resume it first "
                       f"(sanlab tune --resume {run.run_id} --db {db})")
        log = None if as_json else (lambda m: console.print(f"[dim]{m}[/dim]"))
        try:
            sel = library_call(lambda r: select_and_report(lib, r, threshold, log, as_json, top or SELECT_TOP), run.run_id)
        except KeyboardInterrupt:
            typer.echo("interrupted; nothing of this selection was stored: run the same command again", err=True)
            raise typer.Exit(130) from None
        if as_json:
            typer.echo(json.dumps(sel, indent=2))
        return
    top = top or 1
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
    # borderless and wrapping: seven columns fit 80 characters, a narrower terminal wraps cells
    # rather than cutting off the verdict
    table = Table(title="audit: robust speed (cm/s) under nudges, change against the re-scored speed",
                  box=box.SIMPLE_HEAD, collapse_padding=True, pad_edge=False)
    table.add_column("gait", no_wrap=True)
    for name in ("stored", "re-scored", *names, "verdict"):
        table.add_column(name)
    for a in results:
        cells = [f"{a.speeds[n]:.1f} {100 * a.changes[n]:.0f}%" for n in names]
        verdict = ("[red]not reproduced[/red]" if not a.reproduced else "[red]flagged[/red]" if a.flagged
                   else "[green]robust[/green]")
        table.add_row(a.gait_id, f"{a.stored_cm_s:.1f}", f"{a.nominal_cm_s:.1f}", *cells, verdict)
    console.print(table)
    if any(not a.reproduced for a in results):
        console.print(f"not reproduced: the stored speed is more than {100 * threshold:.0f} % from what this sanlab "
                      "re-scores (a score from another engine, or edited): quote the re-scored speed, or search again")
    if any(a.resolution_dependent for a in results):
        console.print(f"flagged: resolution-dependent (a nudge moved the speed more than {100 * threshold:.0f} %); "
                      "`sanlab show` and exports say so")


def select_and_report(lib, run_id: str, threshold: float = 0.10, log=None, quiet: bool = False, top: int = 16) -> dict:
    """``sanlab.audit.select_robust`` on one tuning run, printed as a table of its rungs unless
    ``quiet``; returns its JSON summary ({"run", "robust_gait", "trial", "speed_cm_s", "worst",
    "candidates": [...]})."""
    from sanlab.audit import rung_name, select_robust

    sel = select_robust(lib, run_id, threshold=threshold, log=log, top=top)
    c = sel.chosen
    out = {"run": sel.run_id, "robust_gait": sel.gait_id, "trial": None if c is None else c.trial,
           "speed_cm_s": None if c is None else c.nominal_cm_s, "worst": None if c is None else c.worst,
           "threshold": threshold, "candidates": [x.to_json() for x in sel.candidates]}
    if quiet:
        return out
    names = list(sel.candidates[0].speeds) if sel.candidates else []
    table = Table(title=f"run {sel.run_id}: the rungs of its climb, audited (cm/s, change against held-out)")
    for name in ("trial", "chain score", "held out", *names, ""):
        table.add_column(name, no_wrap=True)
    for x in sel.candidates:
        mark = "[green]chosen[/green]" if x is c else ("[red]flagged[/red]" if x.worst > threshold else "robust")
        table.add_row(rung_name(x.trial).removeprefix("trial "), f"{x.chain_score:.2f}", f"{x.nominal_cm_s:.1f}",
                      *[f"{x.speeds[n]:.1f} {100 * x.changes[n]:.0f}%" for n in names], mark)
    console.print(table)
    if c is None:
        console.print(f"no rung keeps its speed within {100 * threshold:.0f} % under every nudge: "
                      "this run has no robust tuned gait")
    else:
        console.print(f"robust tuned gait: {sel.gait_id}, {c.nominal_cm_s:.1f} cm/s "
                      f"({rung_name(c.trial)}, worst change {100 * c.worst:.0f} %)")
    return out
