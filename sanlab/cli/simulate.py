"""``sanlab simulate``: a quick look at random SANs on a creature; nothing is stored."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from sanlab import configure
from sanlab.cli._common import CreatureArg, DtypeOpt, check_dtype, console, load_or_exit


def simulate(
    creature: CreatureArg,
    controllers: Annotated[int, typer.Option("--controllers", "-n", min=1, help="Random SANs to run.")] = 200,
    seconds: Annotated[float, typer.Option(min=0.001, help="Simulated time per controller (s).")] = 6.0,
    seed: Annotated[int, typer.Option(help="Seed of the random weights.")] = 0,
    dtype: DtypeOpt = "float32",
    top: Annotated[int, typer.Option(min=0, help="Rows in the table.")] = 10,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead.")] = False,
) -> None:
    """Simulate random sensor-actuator networks on a creature and report how far each got."""
    check_dtype(dtype)
    c, _ = load_or_exit(creature)
    configure()
    from sanlab.engine_report import simulate_random

    with console.status(f"compiling and simulating {controllers} controllers...", spinner="dots") as _:
        rep = simulate_random(c, controllers, seconds, seed, dtype)
    if as_json:
        typer.echo(json.dumps(rep, indent=2))
        return
    table = Table("rank", "controller", "distance (m)", "speed (cm/s)", "body angle (deg)", "ok")
    for r, row in enumerate(rep["top"][:top], 1):
        table.add_row(
            str(r), str(row["controller"]), f"{row['distance_m']:+.3f}", f"{row['speed_cm_s']:.1f}",
            f"{row['final_angle_deg']:.0f}", "yes" if row["finite"] else "[red]non-finite[/red]",
        )
    console.print(table)
    console.print(
        f"{rep['controllers']} random SANs x {rep['seconds']:g} s on [bold]{escape(c.name)}[/bold]: "
        f"{rep['steps_per_s'] / 1e6:.2f} M creature-steps/s on {rep['devices']} "
        f"(first call {rep['first_call_s']:.1f} s incl. compile), "
        f"largest ground penetration {rep['max_penetration_m'] * 100:.2f} cm, "
        f"{rep['non_finite']} non-finite"
    )
