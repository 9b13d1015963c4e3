"""The ``sanlab`` command line. Each command is a small function; heavy imports (jax) stay inside
the commands that need them so that ``sanlab check`` starts fast."""

from __future__ import annotations

import json
from collections import Counter
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from sanlab.creature import Creature, CreatureError, builtin_names, load, read_source

app = typer.Typer(
    help="Discover how planar creatures can move with sensor-actuator networks.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
console = Console()

CreatureArg = Annotated[
    str, typer.Argument(help="A built-in creature name (see `sanlab creatures`) or a .toml file.")
]


@app.callback()
def main() -> None:
    """Discover how planar creatures can move with sensor-actuator networks."""


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print one plain line to stderr; ``raise fail(...)`` ends the command with ``code``."""
    typer.echo(message, err=True)
    return typer.Exit(code)


def load_or_exit(name_or_path: str) -> tuple[Creature, str]:
    """The creature and where it came from, or exit 2 with the loader's one-line message."""
    try:
        _, where = read_source(name_or_path)
        return load(name_or_path), where
    except CreatureError as e:
        raise fail(str(e)) from None


def _counts(items) -> str:
    kinds = ", ".join(f"{k} {n}" for k, n in Counter(x.kind for x in items).items())
    return f"{len(items)} ({kinds})" if items else "0"


def _hidden(c: Creature) -> int:
    return c.san.hidden if c.san.hidden is not None else len(c.sensors)


def _sizes(c: Creature) -> dict[str, int]:
    n = dict(links=len(c.links), sensors=len(c.sensors), actuators=len(c.actuators))
    return n | {"hidden": _hidden(c)}


@app.command()
def check(creature: CreatureArg) -> None:
    """Validate a creature file and summarise it."""
    c, where = load_or_exit(creature)
    grid = Table.grid(padding=(0, 2))
    grid.add_column(style="bold")
    grid.add_column()
    rows = [
        ("source", escape(where)),
        ("plane", c.world.plane),
        ("links", f"{len(c.links)} ({c.dofs} degrees of freedom)"),
        ("sensors", _counts(c.sensors)),
        ("actuators", _counts(c.actuators)),
        ("hidden nodes", f"{_hidden(c)}" + ("" if c.san.hidden is not None else " (= sensors)")),
        ("dt", f"{c.dt:g} s"),
    ]
    if c.springs:
        rows.insert(5, ("springs", str(len(c.springs))))
    for key, value in rows:
        grid.add_row(key, value)
    about = f": {escape(c.description)}" if c.description else ""
    console.print(f"[green]ok[/green] [bold]{escape(c.name)}[/bold]{about}")
    console.print(grid)


@app.command()
def creatures(
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
) -> None:
    """List the built-in creatures."""
    loaded = {name: load_or_exit(name)[0] for name in builtin_names()}
    rows = [{"name": n, **_sizes(c)} for n, c in loaded.items()]
    if as_json:
        typer.echo(json.dumps(rows, indent=2))
        return
    table = Table("name", "links", "sensors", "actuators", "hidden", "description")
    for r in rows:
        sizes = (str(v) for k, v in r.items() if k != "name")
        table.add_row(r["name"], *sizes, escape(loaded[r["name"]].description))
    console.print(table)


@app.command()
def simulate(
    creature: CreatureArg,
    controllers: Annotated[int, typer.Option("--controllers", "-n", min=1, help="Random SANs to run.")] = 200,
    seconds: Annotated[float, typer.Option(min=0.001, help="Simulated time per controller (s).")] = 6.0,
    seed: Annotated[int, typer.Option(help="Seed of the random weights.")] = 0,
    dtype: Annotated[str, typer.Option(help="float32 or float64.")] = "float32",
    top: Annotated[int, typer.Option(min=0, help="Rows in the table.")] = 10,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead.")] = False,
) -> None:
    """Simulate random sensor-actuator networks on a creature and report how far each got."""
    if dtype not in ("float32", "float64"):
        raise fail(f"--dtype: expected float32 or float64, got {dtype!r}")
    c, _ = load_or_exit(creature)
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
