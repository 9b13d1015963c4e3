"""``sanlab check`` and ``sanlab creatures``: validate and summarise creature files (no JAX)."""

from __future__ import annotations

import json
from collections import Counter
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from sanlab.cli._common import CreatureArg, console, load_or_exit
from sanlab.creature import Creature, builtin_names


def _counts(items) -> str:
    kinds = ", ".join(f"{k} {n}" for k, n in Counter(x.kind for x in items).items())
    return f"{len(items)} ({kinds})" if items else "0"


def _sizes(c: Creature) -> dict[str, int]:
    n = dict(links=len(c.links), sensors=len(c.sensors), actuators=len(c.actuators))
    return n | {"hidden": c.n_hidden}


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
        ("hidden nodes", f"{c.n_hidden}" + ("" if c.san.hidden is not None else " (= sensors)")),
        ("dt", f"{c.dt:g} s"),
    ]
    if c.springs:
        rows.insert(5, ("springs", str(len(c.springs))))
    for key, value in rows:
        grid.add_row(key, value)
    about = f": {escape(c.description)}" if c.description else ""
    console.print(f"[green]ok[/green] [bold]{escape(c.name)}[/bold]{about}")
    console.print(grid)


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
