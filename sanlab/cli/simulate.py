"""``sanlab simulate``: a quick look at random SANs on a creature; nothing is stored."""

from __future__ import annotations

from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from sanlab.cli._common import (
    ARROWS,
    CreatureArg,
    DtFactorsOpt,
    DtJitterOpt,
    DtypeOpt,
    EnsembleOpt,
    check_dtype,
    check_run_args,
    console,
    direction,
    dump_json,
    ensemble_or_exit,
    load_or_exit,
    print_static_warnings,
    record,
)
from sanlab.creature.spec import SCORE_UNITS


def report_record(rep: dict, top: int) -> dict:
    """``sanlab.random_sans.simulate_random``'s report as the ``simulate`` record: the rows in
    the gait rows' words (``dx_m`` and ``direction``, ``nonfinite``), the counts as search's
    ``tally``, the best ``top`` rows."""
    rows = [{"controller": r["controller"], "score": r["score"], "speed_cm_s": r["speed_cm_s"], "dx_m": r.get("dx_m"),
             "direction": direction(r.get("dx_m")), "fell": r["fell"], "nonfinite": not r["finite"]} for r in rep["top"]]
    tally = {"evaluated": len(rows), "fell": sum(r["fell"] for r in rows), "nonfinite": sum(r["nonfinite"] for r in rows)}
    keep = ("creature", "controllers", "seconds", "seed", "dtype", "metric")
    return record("simulate", {**{k: rep[k] for k in keep}, "score_unit": SCORE_UNITS.get(rep["metric"]),
                               **{k: rep[k] for k in ("ensemble", "devices", "wall_s", "steps_per_s")},
                               "tally": tally, "top": rows[:top]})


def simulate(
    creature: CreatureArg,
    controllers: Annotated[int, typer.Option("--controllers", "-n", min=1, help="Random SANs to run.")] = 200,
    seconds: Annotated[float | None, typer.Option(help="Simulated time per controller (s); default: the creature file's.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the random weights.")] = 0,
    ensemble: EnsembleOpt = 8,
    dt_factors: DtFactorsOpt = None,
    dt_jitter: DtJitterOpt = 0.0,
    dtype: DtypeOpt = "float64",
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
    from sanlab.random_sans import simulate_random

    with console.status(f"compiling and simulating {controllers} controllers...", spinner="dots") as _:
        rep = simulate_random(c, controllers, seconds, seed, dtype, ens)
    rep = report_record(rep, top)
    if as_json:
        typer.echo(dump_json(rep))
        return
    unit = rep["score_unit"]
    table = Table("rank", "controller", f"score ({unit})" if unit else "score", "dx (m)", "speed (cm/s)", "flags")
    for r, row in enumerate(rep["top"], 1):
        flags = ", ".join(f for f, on in (("fell", row["fell"]), ("non-finite", row["nonfinite"])) if on)
        dx = "-" if row["dx_m"] is None else f"{row['dx_m']:+.3f}"
        table.add_row(str(r), str(row["controller"]), f"{row['score']:.3f}", dx,
                      f"{ARROWS[row['direction']]} {row['speed_cm_s']:.1f}", flags or "-")
    console.print(table)
    console.print(
        f"{rep['controllers']} random SANs x {rep['seconds']:g} s on [bold]{escape(c.name)}[/bold], "
        f"metric {rep['metric']}, ensemble of {rep['ensemble']}: "
        f"{rep['steps_per_s'] / 1e6:.3g} M creature-steps/s on {rep['devices']} "
        f"({rep['wall_s']:.1f} s), {rep['tally']['fell']} fell, {rep['tally']['nonfinite']} non-finite"
    )
