"""``sanlab ceiling``: a creature's pattern ceiling, the reference a SAN gait's speed is judged by."""

from __future__ import annotations

import time
from typing import Annotated

import typer
from rich.markup import escape

from sanlab.cli._common import (
    AddressOpt,
    BackendOpt,
    CreatureArg,
    DbOpt,
    JsonOpt,
    ProgressBar,
    WorkersOpt,
    backend_or_exit,
    check_seed,
    console,
    dump_json,
    fail,
    library_call,
    load_or_exit,
    open_library,
    print_next,
    record,
)
from sanlab.creature import read_source


def ceiling(
    creature: CreatureArg,
    evaluations: Annotated[int, typer.Option("--evaluations", "-n", min=32, max=10_000_000, help=(
        "Patterns to evaluate (CMA-ES restarts every 40 generations of 32)."))] = 2560,
    seed: Annotated[int, typer.Option(help="Seed of the search.")] = 0,
    backend: BackendOpt = "local",
    address: AddressOpt = None,
    workers: WorkersOpt = None,
    db: DbOpt = "sanlab.db",
    resume: Annotated[str | None, typer.Option(help="Continue an interrupted pattern search (its RUN id).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """The pattern ceiling: how fast the body goes when its actuators are switched on a clock.

    Searches open-loop square waves (per actuator a phase, a duty and two targets, one period for
    all) by CMA-ES under the same robust objective as every SAN score, stores them as pattern
    gaits (run `search --strategy pattern`), and audits the best until one is robust. `show`, the
    studio and `reproduce` then say what fraction of it a SAN gait of this creature reaches. A
    reference, not a bound: where the closed loop holds a gait an open loop cannot, SANs pass it.
    With --backend ray the search and the audits run on a Ray cluster (docs/ray.md), with the same result."""
    from sanlab.search.ceiling import measure

    check_seed(seed)
    load_or_exit(creature)
    text, where = read_source(creature)
    engine = backend_or_exit(backend, address, workers)
    lib = open_library(db, create=resume is None)
    bar = ProgressBar(console.is_terminal and not as_json)
    t0 = time.perf_counter()
    run_id = resume

    def report(p) -> None:
        nonlocal run_id
        run_id = p.run_id
        alive = "" if p.workers is None else f" ({p.workers} workers)"
        bar.update(f"ceiling {p.run_id}: patterns{alive}", p.evaluated, p.total, p.rate, p.best)

    try:
        with bar:
            bar.waiting(f"ceiling {escape(creature)}: starting")
            run_id, c = library_call(lambda: measure(lib, text, where, evaluations=evaluations, seed=seed, reporter=report,
                                                     backend=engine, resume=resume))
    except KeyboardInterrupt:
        if run_id:
            typer.echo(f"interrupted; resume with: sanlab ceiling {creature} --resume {run_id} --db {db}", err=True)
        raise typer.Exit(130) from None
    except (ValueError, ConnectionError) as e:
        raise fail(f"ceiling: {e}") from None
    seconds = time.perf_counter() - t0
    if as_json:
        typer.echo(dump_json(record("ceiling", {"run_id": run_id, "creature": lib.get_run(run_id).creature,
                                                "ceiling": None if c is None else c.to_json(), "seconds": seconds})))
        return
    name = lib.get_run(run_id).creature
    if c is None:
        console.print(f"pattern ceiling of {escape(name)}: none (every pattern fell or blew up in run {run_id})")
        return
    vouched = ("audited: robust" if c.robust else "its audit's ensemble fell: not vouched for" if c.fell
               else f"audit: {c.verdict or 'not audited'}: not vouched for")
    console.print(f"pattern ceiling of [bold]{escape(name)}[/bold]: [bold]{c.speed_cm_s:.1f} cm/s[/bold] "
                  f"(gait {c.gait}, {vouched}; run {run_id}, {c.evaluations} patterns, {seconds:.0f} s)")
    print_next(db, [f"sanlab show {c.gait}", f"sanlab render {c.gait} -o ceiling.png"])
