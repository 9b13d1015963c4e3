"""The ``sanlab`` command line. Each command is a small function; heavy imports (jax) stay inside
the commands that need them so that ``sanlab check`` starts fast."""

from __future__ import annotations

import json
import os
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


# ------------------------------------------------------------------ search and the gait library

DbOpt = Annotated[str, typer.Option("--db", help="Gait library file (SQLite).", show_default=True)]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead.")]


def open_library(path: str):
    from sanlab.library import Library, LibraryError

    try:
        return Library(path)
    except LibraryError as e:
        raise fail(str(e)) from None


def _library_call(fn, *args):
    from sanlab.library import LibraryError

    try:
        return fn(*args)
    except LibraryError as e:
        raise fail(str(e)) from None


def _top_rows(lib, run_id: str, n: int) -> list[dict]:
    return [
        {
            "gait": f"{run_id}/{rank}",
            "score": e.score,
            "speed_cm_s": e.speed_cm_s,
            "fell": e.fell,
            "nonfinite": e.nonfinite,
            "encoding": e.encoding,
        }
        for rank, e in enumerate(lib.top(run_id, n), 1)
    ]


def _print_top(rows: list[dict], title: str) -> None:
    table = Table("rank", "gait", "score", "speed (cm/s)", "flags", title=title)
    for rank, r in enumerate(rows, 1):
        flags = ", ".join(f for f, on in (("fell", r["fell"]), ("non-finite", r["nonfinite"])) if on)
        table.add_row(str(rank), r["gait"], f"{r['score']:.3f}", f"{r['speed_cm_s']:.1f}", flags or "-")
    console.print(table)


def _print_distribution(scores: list[float]) -> None:
    import numpy as np

    if not scores:
        return
    s = np.sort(np.asarray(scores))[::-1]
    qs = ", ".join(f"{p}%: {np.percentile(s, 100 - p):.3f}" for p in (1, 5, 10, 50))
    console.print(f"score distribution over {len(s)} controllers (best first) — top {qs}; best {s[0]:.3f}")


def _render_into(lib, run_ids: list[str], out_dir: str, top: int, quiet: bool) -> None:
    from sanlab.render.command import render_top

    os.makedirs(out_dir, exist_ok=True)
    paths = [p for rid in run_ids for p in render_top(lib, rid, out_dir, top=top)]
    if not quiet:
        console.print(f"rendered {len(paths)} files into {escape(out_dir)}")


@app.command()
def search(
    creature: Annotated[str | None, typer.Argument(help="Built-in name or .toml file (omit with --resume).")] = None,
    controllers: Annotated[int, typer.Option("--controllers", "-n", min=1, help="Random SANs to evaluate.")] = 200,
    seconds: Annotated[float | None, typer.Option(min=0.001, help="Evaluation time (s); default: the creature file's.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the random weights.")] = 0,
    metric: Annotated[str | None, typer.Option(help="distance | distance_upright | hopping | pursuit; default: the creature file's.")] = None,
    batch: Annotated[int, typer.Option(min=1, help="Controllers simulated (and committed) together.")] = 256,
    dtype: Annotated[str, typer.Option(help="float32 or float64.")] = "float32",
    db: DbOpt = "sanlab.db",
    resume: Annotated[str | None, typer.Option(help="Continue an interrupted run.")] = None,
    top: Annotated[int, typer.Option(min=1, help="Gaits to show.")] = 10,
    render_dir: Annotated[str | None, typer.Option("--render", help="Write the top gaits' GIFs and strobes here.")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Phase 1 (paper §5.2): evaluate random SANs, keep every score, show the best gaits."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from sanlab.search import run_search

    if dtype not in ("float32", "float64"):
        raise fail(f"--dtype: expected float32 or float64, got {dtype!r}")
    if (creature is None) == (resume is None):
        raise fail("search: give a CREATURE, or --resume RUN_ID (not both)")
    text = where = ""
    if creature is not None:
        load_or_exit(creature)
        text, where = read_source(creature)
    lib = open_library(db)
    show = console.is_terminal and not as_json
    progress = Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.0f} eval/s"), TextColumn("best {task.fields[best]:.3f}"),
        TimeElapsedColumn(), console=console, disable=not show, transient=False,
    )
    task = None

    def report(p) -> None:
        nonlocal task
        if task is None:
            task = progress.add_task(f"search {p.run_id}", total=p.total, rate=0.0, best=p.best)
        progress.update(task, completed=p.evaluated, rate=p.rate, best=p.best)

    run_id = resume
    try:
        with progress:
            run_id = _library_call(
                lambda: run_search(
                    lib, text, where, controllers=controllers, seconds=seconds, seed=seed,
                    metric=metric, batch=batch, dtype=dtype, reporter=report, resume=resume,
                )
            )
    except KeyboardInterrupt:
        rid = lib.runs()[0].run_id if run_id is None else run_id
        typer.echo(f"interrupted; resume with: sanlab search --resume {rid} --db {db}", err=True)
        raise typer.Exit(130) from None
    except ValueError as e:
        raise fail(f"search: {e}") from None
    rows = _top_rows(lib, run_id, top)
    if render_dir:
        _render_into(lib, [run_id], render_dir, top, quiet=as_json)
    if as_json:
        typer.echo(json.dumps({"run_id": run_id, "evaluated": lib.count(run_id), "top": rows}, indent=2))
        return
    run = lib.get_run(run_id)
    _print_top(rows, f"run {run_id}: {run.creature}, {lib.count(run_id)} controllers, metric {run.params['metric']}")
    _print_distribution(lib.scores(run_id))


@app.command()
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


@app.command()
def show(
    run_id: Annotated[str, typer.Argument(help="A run id (or an unambiguous prefix).")],
    top: Annotated[int, typer.Option(min=1, help="Gaits to show.")] = 10,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Show a run's best gaits: rank, score, speed and flags."""
    lib = open_library(db)
    run = _library_call(lib.get_run, run_id)
    rows = _top_rows(lib, run.run_id, top)
    if as_json:
        out = {"run_id": run.run_id, "kind": run.kind, "creature": run.creature, "status": run.status,
               "evaluated": lib.count(run.run_id), "params": run.params, "top": rows}
        typer.echo(json.dumps(out, indent=2))
        return
    _print_top(rows, f"run {run.run_id}: {run.creature} ({run.status}), metric {run.params.get('metric', '?')}")
    _print_distribution(lib.scores(run.run_id))


@app.command("export")
def export_(
    gait: Annotated[str, typer.Argument(help="RUN_ID/RANK, e.g. 3fa1c2d0/1.")],
    out: Annotated[str | None, typer.Option("--out", "-o", help="Write to this file instead of stdout.")] = None,
    db: DbOpt = "sanlab.db",
) -> None:
    """Export a gait (creature, encoding, parameters, score) as JSON."""
    lib = open_library(db)
    data = json.dumps(_library_call(lib.export_gait, gait), indent=2)
    if out:
        with open(out, "w") as f:
            f.write(data + "\n")
    else:
        typer.echo(data)


@app.command("import")
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
    lib = open_library(db)
    typer.echo(_library_call(lib.import_gait, data))


@app.command()
def tune(
    gait: Annotated[str, typer.Argument(help="RUN/RANK or RUN#IDX; or a run id with --top K.")],
    method: Annotated[str, typer.Option(help="sa (simulated annealing) or sga (stochastic gradient ascent).")] = "sa",
    trials: Annotated[int, typer.Option(min=1, help="Trials per gait (the paper: 1000).")] = 1000,
    seed: Annotated[int, typer.Option(help="Seed of the perturbations.")] = 0,
    top: Annotated[int | None, typer.Option(min=1, help="Tune a run's top K gaits as parallel chains.")] = None,
    morphology: Annotated[bool, typer.Option("--morphology", help="Also tune link lengths (and so masses).")] = False,
    terrain: Annotated[str, typer.Option(help="flat, or rough / hill: score each proposal over several terrains.")] = "flat",
    batch: Annotated[int, typer.Option(min=1, help="Evaluations simulated together per round.")] = 128,
    render_dir: Annotated[str | None, typer.Option("--render", help="Write the tuned gaits' GIFs and strobes here.")] = None,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Phase 2 (paper §5.3): fine-tune a gait's sensor, actuator and delay parameters."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from sanlab.search.tune import tune as run_tune

    lib = open_library(db)
    if top is not None:
        run = _library_call(lib.get_run, gait)
        gaits = [f"{run.run_id}/{k}" for k in range(1, min(top, run.count) + 1)]
    else:
        _library_call(lib.gait, gait)
        gaits = [gait]
    show = console.is_terminal and not as_json
    progress = Progress(
        TextColumn(f"[bold]tune ({method})"), BarColumn(), MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.0f} eval/s"), TextColumn("best {task.fields[best]:.3f}"),
        TimeElapsedColumn(), console=console, disable=not show,
    )
    task = None

    def report(p) -> None:
        nonlocal task
        if task is None:
            task = progress.add_task("tune", total=p.total, rate=0.0, best=p.best)
        progress.update(task, completed=p.trials, rate=p.rate, best=p.best)

    try:
        with progress:
            results = run_tune(lib, gaits, method=method, trials=trials, seed=seed, morphology=morphology,
                               terrain=terrain, batch=batch, reporter=report)
    except ValueError as e:
        raise fail(f"tune: {e}") from None
    rows = [{"gait": r.gait, "tuned_gait": r.tuned_gait, "before": r.before, "after": r.after, "trials": r.trials}
            for r in results]
    if render_dir:
        _render_into(lib, [r.run_id for r in results], render_dir, 1, quiet=as_json)
    if as_json:
        typer.echo(json.dumps(rows[0] if top is None else rows, indent=2))
        return
    table = Table("gait", "tuned gait", "score before", "after", "speed before (cm/s)", "after", "accepted")
    for r in results:
        table.add_row(r.gait, r.tuned_gait, f"{r.before['score']:.3f}", f"{r.after['score']:.3f}",
                      f"{r.before['speed_cm_s']:.1f}", f"{r.after['speed_cm_s']:.1f}", f"{r.accepted}/{r.trials}")
    console.print(table)
    console.print(f"{len(results)} chain(s) x {trials} trials ({method}) in {results[0].seconds:.0f} s")


@app.command()
def reproduce(
    creatures: Annotated[str | None, typer.Option(help="Comma-separated names (default: all of Table 1 that are built in).")] = None,
    seed: Annotated[int, typer.Option(help="Seed of phase 1 and phase 2.")] = 0,
    controllers: Annotated[int, typer.Option(min=1, help="Random SANs per creature (the paper: 200).")] = 200,
    trials: Annotated[int, typer.Option(min=1, help="Annealing trials on each best gait (the paper: 1000).")] = 1000,
    out: Annotated[str, typer.Option(help="Markdown report to write.")] = "report.md",
    db: DbOpt = "sanlab.db",
) -> None:
    """Reproduce the paper's Table 1 (phase 1 + simulated annealing per creature) as a Markdown report."""
    from sanlab.reproduce import TABLE1
    from sanlab.reproduce import reproduce as run

    names = [c.strip() for c in creatures.split(",")] if creatures else [n for n in TABLE1 if n in builtin_names()]
    for n in names:
        load_or_exit(n)
    lib = open_library(db)
    report = run(lib, names, seed=seed, controllers=controllers, trials=trials, log=lambda s: console.print(s))
    with open(out, "w") as f:
        f.write(report)
    console.print(f"wrote {out}")


from sanlab.render.command import render  # noqa: E402  (imports its drawing libraries lazily)

app.command()(render)

from sanlab.studio.command import studio  # noqa: E402  (imports its web stack lazily)

app.command()(studio)
