"""``sanlab tune``: phase 2, fine-tune stored gaits (one chain each) into new tune runs, every
trial committed as it is decided; ``--resume`` finishes interrupted ones."""

from __future__ import annotations

import math
from typing import Annotated

import typer
from rich.table import Table

from sanlab.cli._common import (
    ARROWS,
    MAX_BATCH,
    AddressOpt,
    BackendOpt,
    DbOpt,
    DtFactorsOpt,
    DtJitterOpt,
    EnsembleOpt,
    JsonOpt,
    ProgressBar,
    ProgressLines,
    WorkersOpt,
    backend_or_exit,
    check_count,
    check_render_dir,
    check_seed,
    console,
    direction,
    dump_json,
    duration,
    ensemble_or_exit,
    fail,
    id_column,
    library_call,
    open_library,
    print_ceiling_share,
    print_next,
    record,
    refuse_with_resume,
)

LONG_TUNE_S = 60.0  # a tune expected to take longer says how long, once its pace is measured


def tune(
    ctx: typer.Context,
    gait: Annotated[str | None, typer.Argument(metavar="GAIT|RUN_ID", help="RUN/RANK or RUN#IDX; or a run id with --top K (omit with --resume).")] = None,
    method: Annotated[str, typer.Option(help="sa (simulated annealing) or sga (stochastic gradient ascent).")] = "sa",
    trials: Annotated[int, typer.Option(min=1, help="Trials per gait (the paper: 1000).")] = 1000,
    seed: Annotated[int, typer.Option(help="Seed of the perturbations.")] = 0,
    top: Annotated[int | None, typer.Option(min=1, help=(
        "Tune a run's top K gaits as parallel chains (a rhythm or reflex run: its K - 1 best and the best "
        "random SAN of its warm-up)."))] = None,
    morphology: Annotated[bool, typer.Option("--morphology", help=(
        "Also tune the body: a file's free numbers that shape it (the local case of `sanlab design`), "
        "else link lengths (and so masses)."))] = False,
    terrain: Annotated[str, typer.Option(help="flat, or rough / hill: score each proposal over several terrains.")] = "flat",
    batch: Annotated[int | None, typer.Option(min=1, help=(
        "Evaluations simulated together per round (default: 8, or one per chain if more, on the CPU's cores "
        "where the kernel runs: benchmarks/tune_batch.py measured it)."))] = None,
    ensemble: EnsembleOpt = 8,
    dt_factors: DtFactorsOpt = None,
    dt_jitter: DtJitterOpt = 0.0,
    resume: Annotated[list[str] | None, typer.Option(
        "--resume", help="Finish an interrupted tune run (repeat for each chain of one tuning).")] = None,
    backend: BackendOpt = "local",
    address: AddressOpt = None,
    workers: WorkersOpt = None,
    select: Annotated[bool, typer.Option("--select", help=(
        "Then audit each chain's climb and store its best-scoring gait that keeps its speed within 10 % "
        "(--threshold) at dt/2 and dt/4 as RUN#1 (as `sanlab audit RUN --select`)."))] = False,
    threshold: Annotated[float | None, typer.Option(min=0.0, help=(
        "With --select: the largest relative speed change a nudge may cause (default 0.10 = 10 %)."))] = None,
    render_dir: Annotated[str | None, typer.Option("--render", help="Write the tuned gaits' GIFs and strobes here.")] = None,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Phase 2 (paper §5.3): fine-tune a gait's sensor, actuator and delay parameters.

    Each trial is scored as the median over an ensemble of perturbed copies; the tuned gait's
    stored score is its best vector re-scored on fresh perturbations (held out)."""
    from sanlab.library import LibraryError
    from sanlab.search.tune import tune as run_tune

    ens = ensemble_or_exit(ensemble, dt_factors, dt_jitter)
    if threshold is not None and not select:
        raise fail("tune: --threshold applies to --select; add --select, or drop it")
    if threshold is not None and not math.isfinite(threshold):
        raise fail(f"tune: --threshold: expected a finite number >= 0, got {threshold}")
    limit = 0.10 if threshold is None else threshold
    select_opts = " --select" + ("" if threshold is None else f" --threshold {threshold:g}")
    check_count("--trials", trials)
    if batch is not None:
        check_count("--batch", batch, 1, MAX_BATCH)
    check_seed(seed)
    if (gait is None) == (not resume):
        raise fail("tune: give a GAIT, or --resume RUN_ID (not both)")
    if resume:
        refuse_with_resume(ctx, "tune", ("method", "trials", "seed", "top", "morphology", "terrain", "batch", "ensemble",
                                             "dt_factors", "dt_jitter"))
    check_render_dir(render_dir)
    engine = backend_or_exit(backend, address, workers)
    lib = open_library(db)  # the gaits to tune are in it: a missing file is a mistyped --db
    gaits: list[str] = []
    if gait is not None and top is not None:
        from sanlab.search.rhythm import starts

        run = library_call(lib.get_run, gait)
        gaits = [e.gait_id for e in library_call(starts, lib, run.run_id, min(top, run.count))]
    elif gait is not None:
        library_call(lib.gait, gait)
        gaits = [gait]
    if batch is None and gaits:
        from sanlab.search.tune import default_batch

        batch = default_batch(len(gaits))
    shown = console.is_terminal and not as_json
    bar = ProgressBar(shown, f"tune ({method})")
    lines = ProgressLines(not console.is_terminal, "tune", "trials")  # a log gets lines instead of a bar
    run_ids: tuple[str, ...] = tuple(resume or ())
    said = [False]

    def report(p) -> None:
        nonlocal run_ids
        run_ids = p.run_ids  # known from the first report on, so Ctrl-C names these runs
        bar.update("tune" + ("" if p.workers is None else f" ({p.workers} workers)"), p.trials, p.total, p.rate, p.best)
        lines.update(p.trials, p.total, p.rate, p.best, workers=p.workers)
        left = lines.left(p.trials, p.total)
        if not said[0] and left is not None:
            said[0] = True
            if left >= LONG_TUNE_S:  # said once, at the first measured round: before most of the wait
                what = (f"{p.total} trials ({len(run_ids)} chain{'s' * (len(run_ids) > 1)}"
                        + (f", --batch {batch})" if batch is not None else ")"))
                line = (f"tune: about {duration(left)} more for {what}, at the pace of the first round; "
                        "Ctrl-C keeps every decided trial (--resume goes on)")
                if shown:
                    bar.progress.console.print(line, soft_wrap=True, highlight=False)
                else:
                    typer.echo(line, err=True)

    from sanlab.evaluate.ray_backend import WorkerError

    try:
        with bar:
            results = run_tune(lib, gaits, method=method, trials=trials, seed=seed, morphology=morphology,
                               terrain=terrain, batch=batch, ensemble=ens, reporter=report, resume=resume or (),
                               backend=engine)
    except KeyboardInterrupt:
        hint = " ".join(f"--resume {r}" for r in run_ids) + (select_opts if select else "")
        typer.echo(f"interrupted; resume with: sanlab tune {hint} --db {db}" if run_ids else "interrupted", err=True)
        raise typer.Exit(130) from None
    except (ValueError, ConnectionError) as e:
        raise fail(f"tune: {e}") from None
    except LibraryError as e:
        raise fail(str(e)) from None
    except WorkerError as e:  # an evaluation raised on a Ray worker: its one line
        raise fail(f"tune: {e}", 1) from None
    def stored_dx(gait_id: str):
        dx = (library_call(lib.gait, gait_id).extra or {}).get("dx_m")
        return dx if isinstance(dx, (int, float)) and not isinstance(dx, bool) else None

    dxs = [(stored_dx(r.gait), stored_dx(r.tuned_gait)) for r in results]  # (start, tuned): the arrows
    rows = [record("tuning", {"gait": r.gait, "tuned_gait": r.tuned_gait, "run_id": r.run_id, "before": r.before,
                              "after": r.after, "direction": direction(dx[1]), "trials": r.trials, "accepted": r.accepted})
            for r, dx in zip(results, dxs)]
    if select:
        from sanlab.cli.audit import select_and_report

        try:
            for row, r in zip(rows, results):
                row["selection"] = library_call(lambda run_id: select_and_report(lib, run_id, limit, quiet=True), r.run_id)
        except KeyboardInterrupt:
            cmds = "; ".join(f"sanlab audit {r.run_id}{select_opts} --db {db}" for r in results)
            typer.echo(f"interrupted during the selection; every tuned gait is stored ({', '.join(r.tuned_gait for r in results)}). "
                       f"To select: {cmds}", err=True)
            raise typer.Exit(130) from None
    if render_dir:
        from sanlab.cli.render import render_into

        render_into(lib, [r.run_id for r in results], render_dir, 1, quiet=as_json)
    if as_json:
        typer.echo(dump_json(rows))  # always a list, one element per chain (one gait: a list of one)
        return
    table = Table(id_column("gait", [r.gait for r in results]), id_column("tuned gait", [r.tuned_gait for r in results]),
                  "score before", "after", "speed before (cm/s)", "after", "accepted")
    for r, (dx0, dx1) in zip(results, dxs):  # the arrow: which way along x the stored gait moved (→ +x, ← -x)
        table.add_row(r.gait, r.tuned_gait, f"{r.before['score']:.3f}", f"{r.after['score']:.3f}",
                      f"{ARROWS[direction(dx0)]} {r.before['speed_cm_s']:.1f}",
                      f"{ARROWS[direction(dx1)]} {r.after['speed_cm_s']:.1f}", f"{r.accepted}/{r.trials}")
    console.print(table)
    from sanlab.audit import rung_name

    for row, r in zip(rows, results) if select else ():
        sel = row["selection"]
        n = len(sel["candidates"])
        if sel["robust_gait"] is None:
            console.print(f"{r.run_id}: no rung of its climb ({n} audited) keeps its speed within {100 * limit:g} % at "
                          "dt/2 and dt/4: no robust tuned gait")
        else:
            console.print(f"{r.run_id}: robust tuned gait {sel['robust_gait']}, {sel['speed_cm_s']:.1f} cm/s "
                          f"({rung_name(sel['trial'])}, worst change {100 * sel['worst']:.0f} % of {n} rungs audited)")
    console.print(f"{len(results)} chain(s) x {trials if not resume else results[0].trials} trials in "
                  f"{results[0].seconds:.0f} s (this session). 'before' is the start re-scored on the chain's own "
                  "ensemble draws, 'after' the tuned gait re-scored on held-out draws: with an ensemble of a chaotic "
                  "gait these differ from the stored score, and 'after' can be below 'before'; `sanlab audit` "
                  "says how far such a score can be trusted" + (", and `--select` finds the best that survives." if not select
                                                                else "; a robust tuned gait is the one to quote."))
    best = next((row["selection"]["robust_gait"] for row in rows if row.get("selection", {}).get("robust_gait")), None) \
        or rows[0]["tuned_gait"]
    print_ceiling_share(lib, best, lib.gait(best).speed_cm_s, "the tuned gait")
    print_next(db, [f"sanlab show {best}", f"sanlab render {best}",
                    f"sanlab audit {best}" if not select else f"sanlab export {best}"])
