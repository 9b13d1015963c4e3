"""``sanlab modes``: a run's useful controllers grouped into gait modes (``sanlab.modes``)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from sanlab.cli._common import (
    DbOpt,
    JsonOpt,
    console,
    dump_json,
    fail,
    id_column,
    library_call,
    open_library,
    record,
    safe,
)

if TYPE_CHECKING:
    from sanlab.modes import Mode


def modes(
    run_id: Annotated[str, typer.Argument(metavar="RUN_ID", help="A run id (or an unambiguous prefix).")],
    min_score: Annotated[float | None, typer.Option(help=(
        "Controllers scoring at least this are grouped (default: a fifth of the run's best score)."))] = None,
    top: Annotated[int, typer.Option(min=1, max=10_000, help="Modes to show, best first (--json: all).")] = 10,
    singletons: Annotated[bool, typer.Option("--singletons", help=(
        "Also show modes of a single gait (hidden by default: a kind only one gait has; --json lists "
        "them all)."))] = False,
    min_cluster: Annotated[int, typer.Option(min=2, max=1000, help=(
        "Smallest group the density clustering forms within a kind (at least: a kind of many gaits uses half the "
        "square root of their count)."))] = 3,
    rescore: Annotated[bool, typer.Option("--rescore", help=(
        "A search stored before sanlab computed descriptors: evaluate its useful gaits again, as the run did, "
        "for theirs (nothing is stored)."))] = False,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Group a run's useful controllers into gait modes and name them.

    Useful: not fallen, finite, scoring at least --min-score. Controllers are split by kind (the
    rule that names each one's own gait, and its direction along x), then grouped within a kind by
    HDBSCAN on their standardised behaviour descriptors (a straggler joins its nearest group) and,
    exactly, by their periodic sensor signature (the same cycle of sensor words is the same mode);
    each mode is named where a rule fits (rolling, flipping, swimming, hopping, walking, shuffling,
    sliding; seen from above: circling, turning, swimming, undulating, sliding; else "mode 1", "mode 2"...) and
    shown with its best gait, its size and its descriptors' medians. Modes of a single gait (a kind
    only one gait has) are hidden unless --singletons (the count is said); the names shown are
    numbered first, without gaps."""
    from sanlab.modes import of_run

    lib = open_library(db, readonly=True)
    run = library_call(lib.get_run, run_id)
    try:
        found, threshold, missing = library_call(of_run, lib, run.run_id, min_score, min_cluster, rescore)
    except ValueError as e:
        raise fail(f"modes: {e}") from None
    if missing and not found:
        raise fail(f"run {run.run_id} has no behaviour descriptors (stored before sanlab computed them); "
                   f"`sanlab modes {run.run_id} --rescore` evaluates its useful gaits again for them")
    if as_json:
        typer.echo(dump_json(record("modes", {"run_id": run.run_id, "creature": run.creature, "min_score": threshold,
                                              "without_descriptors": missing, "modes": [m.to_json() for m in found]})))
        return
    if missing:
        console.print(f"{missing} useful controllers were stored without descriptors and are left out")
    shown = found if singletons else [m for m in found if m.size > 1]
    if not shown and found:  # nothing but single gaits: a table of them says more than an empty one
        shown = found
        console.print("every mode is a single gait: too few useful controllers to group (search more with -n, "
                      "or lower --min-score)")
    hidden = len(found) - len(shown)
    print_modes(shown[:top], f"run {run.run_id}: {run.creature}, {len(shown)} modes of "
                             f"{sum(m.size for m in shown)} controllers scoring at least {threshold:.3g}")
    if len(shown) > top:
        console.print(f"and {len(shown) - top} more modes (--top {len(shown)} shows them all)")
    if hidden:
        console.print(f"{hidden} mode{'s' * (hidden > 1)} of a single gait hidden (--singletons shows "
                      f"{'them' if hidden > 1 else 'it'})")


def print_modes(found: list[Mode], title: str) -> None:
    """The modes table: name, size, best gait, its speed (cm/s; arrow: direction along x), the mode's
    median turns over the run, airborne fraction and period (its signature: ``--json``)."""
    from sanlab.cli._common import ARROWS, direction

    table = Table("mode", "size", id_column("best gait", [m.best.gait_id for m in found]), "cm/s", "turns", "airborne",
                  "period s", title=safe(title))
    for m in found:
        s = m.summary
        f = lambda v, fmt: "-" if not math.isfinite(v) else format(v, fmt)
        arrow = ARROWS[direction(m.best.descriptors.get("vx_cm_s"))]
        table.add_row(safe(m.name), str(m.size), m.best.gait_id, f"{arrow} {m.best.speed_cm_s:.1f}",
                      f(m.turns, "+.2f"), f(s["airborne"], ".2f"), f(s["period_s"], ".2f"))
    console.print(table)
