"""``sanlab tune``: phase 2, fine-tune stored gaits (one chain each) into new tune runs."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from rich.table import Table

from sanlab import configure
from sanlab.cli._common import DbOpt, JsonOpt, ProgressBar, console, fail, library_call, open_library


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
    configure()
    from sanlab.library import LibraryError
    from sanlab.search.tune import tune as run_tune

    lib = open_library(db)  # the gaits to tune are in it: a missing file is a mistyped --db
    if top is not None:
        run = library_call(lib.get_run, gait)
        gaits = [f"{run.run_id}/{k}" for k in range(1, min(top, run.count) + 1)]
    else:
        library_call(lib.gait, gait)
        gaits = [gait]
    bar = ProgressBar(console.is_terminal and not as_json, f"tune ({method})")
    try:
        with bar:
            results = run_tune(lib, gaits, method=method, trials=trials, seed=seed, morphology=morphology,
                               terrain=terrain, batch=batch,
                               reporter=lambda p: bar.update("tune", p.trials, p.total, p.rate, p.best))
    except ValueError as e:
        raise fail(f"tune: {e}") from None
    except LibraryError as e:
        raise fail(str(e)) from None
    rows = [{"gait": r.gait, "tuned_gait": r.tuned_gait, "before": r.before, "after": r.after, "trials": r.trials}
            for r in results]
    if render_dir:
        from sanlab.cli.render import render_into

        render_into(lib, [r.run_id for r in results], render_dir, 1, quiet=as_json)
    if as_json:
        typer.echo(json.dumps(rows[0] if top is None else rows, indent=2))
        return
    table = Table("gait", "tuned gait", "score before", "after", "speed before (cm/s)", "after", "accepted")
    for r in results:
        table.add_row(r.gait, r.tuned_gait, f"{r.before['score']:.3f}", f"{r.after['score']:.3f}",
                      f"{r.before['speed_cm_s']:.1f}", f"{r.after['speed_cm_s']:.1f}", f"{r.accepted}/{r.trials}")
    console.print(table)
    console.print(f"{len(results)} chain(s) x {trials} trials ({method}) in {results[0].seconds:.0f} s")
