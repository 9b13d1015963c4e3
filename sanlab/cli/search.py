"""``sanlab search``: phase 1, random SANs into the gait library (resumable)."""

from __future__ import annotations

from typing import Annotated

import typer
from rich.markup import escape

from sanlab.cli._common import (
    METRIC_HELP,
    AddressOpt,
    BackendOpt,
    DbOpt,
    DtFactorsOpt,
    DtJitterOpt,
    DtypeOpt,
    EnsembleOpt,
    JsonOpt,
    ProgressBar,
    ProgressLines,
    WorkersOpt,
    backend_or_exit,
    check_dtype,
    check_render_dir,
    check_run_args,
    console,
    dump_json,
    ensemble_or_exit,
    fail,
    library_call,
    load_or_exit,
    next_steps,
    open_library,
    print_ceiling_share,
    print_distribution,
    print_static_warnings,
    print_top,
    record,
    refuse_still,
    refuse_with_resume,
    top_rows,
)
from sanlab.creature import read_source
from sanlab.creature.spec import SCORE_UNITS


def _ribs_or_exit() -> None:
    """Exit 2 with one line naming the extra to install when pyribs (MAP-Elites' archive) is absent."""
    from sanlab.search.map_elites import MissingExtra, ribs

    try:
        ribs("archives", "--strategy map-elites")
    except MissingExtra as e:
        raise fail(f"search: {e}") from None


def search(
    ctx: typer.Context,
    creature: Annotated[str | None, typer.Argument(metavar="CREATURE", help="Built-in name or .toml file (omit with --resume).")] = None,
    controllers: Annotated[int, typer.Option("--controllers", "-n", min=1, help="Controllers to evaluate (random SANs, or --strategy's).")] = 200,
    seconds: Annotated[float | None, typer.Option(help="Evaluation time (s); default: the creature file's.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the random weights.")] = 0,
    metric: Annotated[str | None, typer.Option(help=f"{METRIC_HELP}; default: the creature file's.")] = None,
    batch: Annotated[int | None, typer.Option(min=1, help=(
        "Controllers simulated (and committed) together, at most --controllers; map-elites' generation "
        "(default 256; map-elites 64)."))] = None,
    strategy: Annotated[str, typer.Option(help=(
        "random (§5.2: random SANs; many modes), catcma (the fastest SAN: a sixth random, then CatCMAwM over the "
        "weights from the best; give -n in the thousands), rhythm (the fastest SAN where the body wants a rhythm: a "
        "sixth random, then SANs built as clocks, CMA-ES over their rhythm; -n in the thousands), reflex (rhythm, "
        "its last quarter on reflexes: the sensors' weights to the actuators of the best SAN), map-elites (a repertoire: the best gait in each cell of "
        "--grid; needs pip install 'sanlab[qd]') or pattern (open-loop square waves, no SAN: the ceiling's search; "
        "see sanlab ceiling)."))] = "random",
    grid: Annotated[str | None, typer.Option(help=(
        "map-elites: two behaviour descriptors NAME,NAME or NAME:LO:HI,NAME:LO:HI (default vx_cm_s,airborne; "
        "names: vx_cm_s, height_m, height_sd_m, turns_per_s, airborne, joint_speed_rad_s, period_s; a range left "
        "out: [0, 1] for airborne, else three times the first generation's extent)."))] = None,
    bins: Annotated[int, typer.Option(min=2, max=1000, help="map-elites: cells along each descriptor.")] = 16,
    ensemble: EnsembleOpt = 8,
    dt_factors: DtFactorsOpt = None,
    dt_jitter: DtJitterOpt = 0.0,
    backend: BackendOpt = "local",
    address: AddressOpt = None,
    workers: WorkersOpt = None,
    dtype: DtypeOpt = "float64",
    db: DbOpt = "sanlab.db",
    resume: Annotated[str | None, typer.Option(help="Continue an interrupted run.")] = None,
    top: Annotated[int, typer.Option(min=1, help="Gaits to show.")] = 10,
    render_dir: Annotated[str | None, typer.Option("--render", help="Write the top gaits' GIFs and strobes here.")] = None,
    force: Annotated[bool, typer.Option("--force", help=(
        "Search a creature that `sanlab check` finds can never move (no actuator that drives anything, or no sensor "
        "on at rest) all the same."))] = False,
    as_json: JsonOpt = False,
) -> None:
    """Phase 1 (paper §5.2): evaluate random SANs, keep every score, show the best gaits.

    With --strategy catcma, -n controllers find the fastest SAN instead: the first sixth random,
    then a mixed-integer CMA-ES (CatCMAwM) over the weights from the best of them. With --strategy
    rhythm, the first sixth random, then SANs whose hidden nodes make a clock (each actuator
    switched on a rhythm of period, phases and duties), CMA-ES over that rhythm; its gaits carry
    their own node delays and ranges, and tune as any; --strategy reflex spends the last quarter
    on reflexes, CatCMAwM over the weights from the sensors to the actuator nodes of the best SAN,
    its clock untouched. With --strategy map-elites, they are spent on a repertoire: the first tenth random, then mutants of the
    archive's elites, keeping the best gait of each cell of --grid. With --strategy pattern, on
    open-loop square waves (pattern gaits, no SAN; `sanlab ceiling` makes the creature's ceiling of them)."""
    check_dtype(dtype)
    # The creature is read, and refused, before the simulator is imported: a mistyped name is answered at once
    spec = load_or_exit(creature)[0] if creature is not None and resume is None else None
    if spec is not None and not force:
        refuse_still(spec, str(creature))
    from sanlab.search import run_search
    from sanlab.search.map_elites import DEFAULT_GENERATION, MissingExtra, archive_stats, parse_grid
    from sanlab.search.pattern import POPSIZE
    from sanlab.search.registry import names

    ens = ensemble_or_exit(ensemble, dt_factors, dt_jitter)
    if (creature is None) == (resume is None):
        raise fail("search: give a CREATURE, or --resume RUN_ID (not both)")
    if resume is not None:
        refuse_with_resume(ctx, "search", ("controllers", "seconds", "seed", "metric", "batch", "ensemble", "dt_factors", "dt_jitter",
                                               "dtype", "strategy", "grid", "bins"))
    if strategy not in names(1):
        raise fail(f"--strategy: expected one of {', '.join(names(1))}, got {strategy!r}")
    if strategy == "map-elites" and resume is None:
        _ribs_or_exit()
    if batch is None:
        batch = DEFAULT_GENERATION if strategy == "map-elites" else POPSIZE if strategy in ("pattern", "rhythm", "reflex") else 256
    text = where = ""
    archive = None
    if creature is not None:
        spec = spec or load_or_exit(creature)[0]
        check_run_args(spec, controllers=controllers, seconds=seconds, metric=metric, seed=seed, batch=batch, top=top)
        if strategy == "map-elites":
            try:
                archive = parse_grid(grid, bins)
            except ValueError as e:
                raise fail(f"--grid: {e}") from None
        elif grid is not None:
            raise fail("--grid: only with --strategy map-elites")
        text, where = read_source(creature)
        print_static_warnings(spec, creature)
    check_render_dir(render_dir)
    engine = backend_or_exit(backend, address, workers)
    lib = open_library(db, create=resume is None)  # resuming needs the library the run is in
    bar = ProgressBar(console.is_terminal and not as_json)
    lines = ProgressLines(not console.is_terminal, "search", "controllers")  # a log gets lines, as tune's does
    run_id = resume

    def report(p) -> None:
        nonlocal run_id
        run_id = p.run_id  # known from the first report on, so Ctrl-C names this run
        label = f"search {p.run_id}"
        if p.stats:
            label += f" (coverage {p.stats['coverage']:.0%}, QD {p.stats['qd_score']:.3g})"
        if p.evaluated == 0:  # a creature's first run compiles here, for up to a minute: say so
            label += ": first batch (compiled first, on a creature's first run)"
        bar.update(label + ("" if p.workers is None else f" ({p.workers} workers)"), p.evaluated, p.total, p.rate,
                   p.best)
        lines.update(p.evaluated, p.total, p.rate, p.best, workers=p.workers)

    try:
        with bar:
            bar.waiting(f"search {escape(creature)}: starting" if creature else "resuming")
            run_id = library_call(
                lambda: run_search(
                    lib, text, where, controllers=controllers, seconds=seconds, seed=seed,
                    metric=metric, batch=batch, dtype=dtype, ensemble=ens, reporter=report, resume=resume,
                    backend=engine, strategy=strategy, grid=archive,
                )
            )
    except KeyboardInterrupt:
        rid = lib.runs()[0].run_id if run_id is None else run_id
        typer.echo(f"interrupted; resume with: sanlab search --resume {rid} --db {db}", err=True)
        raise typer.Exit(130) from None
    except (ValueError, ConnectionError, MissingExtra) as e:  # MissingExtra: resuming a map-elites run without pyribs
        raise fail(f"search: {e}") from None
    rows = top_rows(lib, run_id, top)
    if render_dir:
        from sanlab.cli.render import render_into

        render_into(lib, [run_id], render_dir, top, quiet=as_json)
    run = lib.get_run(run_id)
    stats = archive_stats(lib, run_id)
    metric = run.settings.metric or ""
    if as_json:
        out = record("search", {"run_id": run_id, "creature": run.creature, "metric": metric,
                                "score_unit": SCORE_UNITS.get(metric), "evaluated": lib.count(run_id),
                                "tally": lib.tally(run_id), "top": rows})
        if stats is not None:
            out["archive"] = stats
        typer.echo(dump_json(out))
        return
    print_top(rows, f"run {run_id}: {run.creature}, {lib.count(run_id)} controllers, metric {metric}",
              SCORE_UNITS.get(metric, ""))
    print_distribution(lib.scores(run_id))
    if rows:
        print_ceiling_share(lib, rows[0]["gait"], rows[0]["speed_cm_s"])
    if stats is not None:
        console.print(f"archive over {' x '.join(stats['grid']['names'])}: {stats['elites']} elites, coverage "
                      f"{stats['coverage']:.1%}, QD-score {stats['qd_score']:.4g}")
    earlier = [r.run_id for r in lib.same_runs("search", run.creature_text, run.params, run.seed) if r.run_id != run_id]
    next_steps(db, run_id, rows, lib.tally(run_id), earlier)


