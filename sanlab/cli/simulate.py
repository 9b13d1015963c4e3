"""``sanlab simulate``: a quick look at random SANs on a creature; nothing is stored."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from sanlab import configure
from sanlab.cli._common import (
    CreatureArg,
    DtFactorsOpt,
    DtJitterOpt,
    DtypeOpt,
    EnsembleOpt,
    check_dtype,
    check_run_args,
    console,
    ensemble_or_exit,
    load_or_exit,
    print_static_warnings,
)


def simulate(
    creature: CreatureArg,
    controllers: Annotated[int, typer.Option("--controllers", "-n", min=1, help="Random SANs to run.")] = 200,
    seconds: Annotated[float | None, typer.Option(min=0.001, help="Simulated time per controller (s); default: the creature file's.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the random weights.")] = 0,
    ensemble: EnsembleOpt = 8,
    dt_factors: DtFactorsOpt = None,
    dt_jitter: DtJitterOpt = 0.0,
    dtype: DtypeOpt = "float32",
    top: Annotated[int, typer.Option(min=0, help="Best controllers shown (rows of the table, entries of --json's top).")] = 10,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead.")] = False,
) -> None:
    """Score random sensor-actuator networks on a creature as `sanlab search` does (same seed, same
    scores), without storing them."""
    check_dtype(dtype)
    c, _ = load_or_exit(creature)
    check_run_args(c, controllers=controllers, seconds=seconds, seed=seed)
    seconds = seconds if seconds is not None else c.evaluation.seconds
    ens = ensemble_or_exit(ensemble, dt_factors, dt_jitter)
    print_static_warnings(c, creature)  # as search does: the same file, the same warnings
    configure()
    from sanlab.engine_report import simulate_random

    with console.status(f"compiling and simulating {controllers} controllers...", spinner="dots") as _:
        rep = simulate_random(c, controllers, seconds, seed, dtype, ens)
    rep["top"] = rep["top"][:top]
    if as_json:
        typer.echo(json.dumps(rep, indent=2))
        return
    table = Table("rank", "controller", "score", "distance (m)", "speed (cm/s)", "flags")
    for r, row in enumerate(rep["top"], 1):
        flags = ", ".join(f for f, on in (("fell", row["fell"]), ("non-finite", not row["finite"])) if on)
        table.add_row(str(r), str(row["controller"]), f"{row['score']:.3f}", f"{row['distance_m']:.3f}",
                      f"{row['speed_cm_s']:.1f}", flags or "-")
    console.print(table)
    console.print(
        f"{rep['controllers']} random SANs x {rep['seconds']:g} s on [bold]{escape(c.name)}[/bold], "
        f"metric {rep['metric']}, ensemble of {rep['ensemble']}: "
        f"{rep['steps_per_s'] / 1e6:.3g} M creature-steps/s on {rep['devices']} "
        f"({rep['wall_s']:.1f} s incl. compile), {rep['non_finite']} non-finite"
    )
