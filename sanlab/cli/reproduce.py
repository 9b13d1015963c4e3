"""``sanlab reproduce``: the paper's Table 1 as a Markdown report (see ``sanlab.reproduce``)."""

from __future__ import annotations

import os
from typing import Annotated

import typer

from sanlab.cli._common import (
    AddressOpt,
    BackendOpt,
    DbOpt,
    DtFactorsOpt,
    ProgressBar,
    ProgressLines,
    WorkersOpt,
    backend_or_exit,
    check_run_args,
    console,
    ensemble_or_exit,
    fail,
    library_call,
    load_or_exit,
    open_library,
    output_file,
    safe,
    warn,
)
from sanlab.creature import builtin_names
from sanlab.creature.table1 import TABLE1

STRATEGIES = ("random", "catcma", "rhythm", "reflex")  # phase 1's, as reproduce runs them


def _command_line() -> str | None:
    """This call as typed (``sanlab reproduce ...``), for the report to name; None when the
    process was not started as ``sanlab reproduce`` (a test's runner)."""
    import shlex
    import sys

    if sys.argv[1:2] != ["reproduce"]:
        return None
    return shlex.join(["sanlab", *sys.argv[1:]])


def reproduce(
    creatures: Annotated[str | None, typer.Option(help="Comma-separated names (default: all of Table 1 that are built in).")] = None,
    seed: Annotated[int, typer.Option(help="Seed of phase 1 and phase 2.")] = 0,
    seeds: Annotated[str | None, typer.Option(help="Several seeds (0-4, 0,2,7): the report opens with the median, min and max over them.")] = None,
    controllers: Annotated[int, typer.Option(min=1, help="Phase-1 evaluations per creature: random SANs (the paper: 200), or --strategy's.")] = 200,
    strategy: Annotated[str, typer.Option(help=(
        "Phase 1: random (the paper's §5.2), catcma (CatCMAwM over the weights), rhythm (SANs built as "
        "clocks, CMA-ES over their rhythm) or reflex (rhythm, then reflexes on its best)."))] = "random",
    also: Annotated[str | None, typer.Option(help=(
        "A second phase-1 budget, STRATEGY:N (rhythm:3000: sanlab's search at its budget), made for every "
        "creature scored by a speed; the report opens with both side by side."))] = None,
    ceiling: Annotated[int, typer.Option(min=0, help="Also measure each creature's pattern ceiling with this many patterns (sanlab ceiling; 0: not).")] = 0,
    trials: Annotated[int, typer.Option(min=1, help="Annealing trials per creature (the paper: 1000).")] = 1000,
    top: Annotated[int | None, typer.Option(min=1, help="Spread the trials over the K best phase-1 gaits (trials/K each; §5.3; default 4).")] = None,
    ensemble: Annotated[int, typer.Option(min=1, help="Score each controller over K perturbed copies (1: single sample).")] = 8,
    dt_factors: DtFactorsOpt = None,
    out: Annotated[str, typer.Option(help="Markdown report to write.")] = "report.md",
    audit: Annotated[bool, typer.Option(help="Audit each tuned gait (dt/2, dt/4) and print the audit beside its speed.")] = True,
    ledger: Annotated[str | None, typer.Option(help="JSON-lines file of finished rows: a row it holds is reused, a new one appended.")] = None,
    backend: BackendOpt = "local",
    address: AddressOpt = None,
    workers: WorkersOpt = None,
    pieces: Annotated[int | None, typer.Option(min=1, help=(
        "Rows (creature x seed) made side by side (default: 1 with --backend local, every row with ray).")
    )] = None,
    db: DbOpt = "sanlab.db",
) -> None:
    """Reproduce the paper's Table 1 (phase 1 + simulated annealing per creature) as a Markdown report.

    Resumable: the same command again on the same --db reuses every finished search, tuning run and audit, and continues an interrupted one where it stopped.
    With --ledger, finished rows are kept in a small file that travels without the library (a table made in pieces).
    With --backend ray every evaluation runs on a Ray cluster's workers, the rows side by side (docs/ray.md);
    the library and the ledger stay here, and the rows are the same."""
    from sanlab.reproduce import chains, parse_seeds
    from sanlab.reproduce import reproduce as run

    ens = ensemble_or_exit(ensemble, dt_factors)
    if strategy not in STRATEGIES:
        raise fail(f"--strategy: expected one of {', '.join(STRATEGIES)}, got {safe(strategy)}")
    second = None
    if also is not None:
        how, _, many = also.partition(":")
        if how not in STRATEGIES or not many.isdigit() or int(many) < 1:
            raise fail(f"--also: expected STRATEGY:N with a strategy of {', '.join(STRATEGIES)} and N >= 1 "
                       f"(rhythm:3000), got {safe(also)}")
        second = (how, int(many))
    if seeds is not None and seed != 0:
        raise fail("give --seed or --seeds, not both")
    try:
        seed_list = parse_seeds(seeds) if seeds is not None else [seed]
    except ValueError as e:
        raise fail(f"--seeds {safe(seeds)}: {str(e).removeprefix('seeds: ')}") from None
    try:
        top = chains(top, trials, min(controllers, second[1]) if second else controllers)
    except ValueError as e:
        raise fail(f"--{e}") from None

    names = [c.strip() for c in creatures.split(",")] if creatures else [n for n in TABLE1 if n in builtin_names()]
    for n in names:  # every argument checked before the first run is created
        spec = load_or_exit(n)[0]
        for sd in seed_list:
            for many in (controllers, *((second[1],) if second else ())):
                check_run_args(spec, controllers=many, trials=trials // top, seed=sd, top=top)
    if not os.path.isdir(os.path.dirname(os.path.abspath(out))):
        raise fail(f"--out {out}: directory {os.path.dirname(os.path.abspath(out))} does not exist")
    book = None
    if ledger is not None:
        from sanlab.reproduce import Ledger

        try:
            book = Ledger(ledger)  # a malformed ledger is refused before any work
        except (ValueError, OSError) as e:
            raise fail(f"--ledger: {safe(str(e))}") from None
        if not os.path.isdir(os.path.dirname(os.path.abspath(ledger))):
            raise fail(f"--ledger {safe(ledger)}: directory {safe(os.path.dirname(os.path.abspath(ledger)))} does not exist")
    engine = backend_or_exit(backend, address, workers)
    lib = open_library(db, create=True)
    shown = console.is_terminal
    bar = ProgressBar(shown)
    steps: dict[str, ProgressLines] = {}  # a log gets tune's lines, one series per step of a row

    def progress(stage: str, p) -> None:
        if isinstance(p, str):  # an audit's step (a rung can take a minute), or the rows done
            if shown:
                bar.progress.console.print(f"[dim]{safe(stage)}: {safe(p)}[/dim]", soft_wrap=True, highlight=False)
            else:
                warn(f"reproduce: {stage}: {p}")
            return
        alive = "" if p.workers is None else f" ({p.workers} workers)"
        bar.update(safe(stage) + alive, p.evaluated, p.total, p.rate, p.best, key=stage)
        if stage not in steps:
            steps[stage] = ProgressLines(not shown, f"reproduce: {stage}",
                                         "controllers" if stage.endswith(("search", "ceiling")) else "trials")
        steps[stage].update(p.evaluated, p.total, p.rate, p.best, workers=p.workers)

    try:
        with bar:
            report = library_call(lambda: run(lib, names, seeds=seed_list, controllers=controllers, trials=trials,
                                              log=lambda s: console.print(s), ensemble=ens, audit=audit, top=top,
                                              ledger=book, command=_command_line(), progress=progress,
                                              strategy=strategy, ceiling=ceiling, backend=engine, also=second,
                                              pieces=pieces or (len(names) * len(seed_list) if backend == "ray" else 1)))
    except KeyboardInterrupt:
        typer.echo("interrupted; every stored evaluation is kept: run the same command again to continue", err=True)
        raise typer.Exit(130) from None
    with output_file(out) as path, open(path, "w", encoding="utf-8") as f:
        f.write(report)
    console.print(f"wrote {safe(out)}")
