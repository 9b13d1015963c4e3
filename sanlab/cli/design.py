"""``sanlab design FILE``: search a creature file's free numbers together with its controllers
(paper §6.3; ``sanlab.design``), every run stored in the library; made again, it continues."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from sanlab.cli._common import (
    AddressOpt,
    BackendOpt,
    CreatureArg,
    DbOpt,
    EnsembleOpt,
    JsonOpt,
    ProgressBar,
    ProgressLines,
    WorkersOpt,
    backend_or_exit,
    check_count,
    check_seed,
    check_writable,
    console,
    dump_json,
    fail,
    open_library,
    output_file,
    print_next,
    record,
    safe,
    warn,
)


def _seeds(text: str) -> tuple[int, ...]:
    try:
        seeds = tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise fail(f"design: --seeds: expected seeds separated by commas (e.g. 1,2), got {text!r}") from None
    if not seeds:
        raise fail(f"design: --seeds: expected at least one seed, got {text!r}")
    for x in seeds:
        check_seed(x, "--seeds")
    twice = sorted({x for x in seeds if seeds.count(x) > 1})
    if twice:  # a seed counted twice in the mean would only weigh its draws more
        raise fail(f"design: --seeds: expected different seeds, got {text!r} "
                   f"({', '.join(map(str, twice))} more than once)")
    return seeds


def design(
    creature: CreatureArg,
    designs: Annotated[int, typer.Option(min=1, help="Bodies to score in the search (the reference not counted).")] = 8,
    generation: Annotated[int, typer.Option(min=1, help="Bodies per round of the strategy.")] = 4,
    strategy: Annotated[str, typer.Option(help="cma-es (pyribs' CMA-ES over the free numbers; needs pip install 'sanlab[qd]') or random.")] = "cma-es",
    controllers: Annotated[int, typer.Option(min=1, help="Each body's phase 1: random SANs, or --search's evaluations.")] = 200,
    search: Annotated[str, typer.Option(help=(
        "Each body's phase 1: random (§5.2), catcma (random SANs, then CatCMAwM from the best) or rhythm "
        "(random SANs, then SANs built as clocks, CMA-ES over their rhythm) or reflex (rhythm, then reflexes on "
        "its best)."))] = "random",
    trials: Annotated[int, typer.Option(min=1, help="Annealing trials of each chain of each body's phase 2.")] = 100,
    top: Annotated[int, typer.Option(min=1, help="Chains per body: its best phase-1 SANs tuned.")] = 2,
    seconds: Annotated[float | None, typer.Option(min=0.01, help="Evaluation time (s); default: the file's.")] = None,
    ensemble: EnsembleOpt = 8,
    seed: Annotated[int, typer.Option(help="Seed of the search (its SANs, draws and bodies).")] = 0,
    validate: Annotated[int, typer.Option(min=1, help="Best bodies scored again on --seeds; the chosen one is "
                                                       "the best of them there, if it beats the file's defaults.")] = 2,
    seeds: Annotated[str | None, typer.Option(help="Validation seeds, other than --seed (default: --seed + 1).")] = None,
    prune: Annotated[float, typer.Option(min=0.0, max=0.99, help=(
        "Skip phase 2 for a body whose best phase-1 speed is below this fraction of the reference's "
        "(it scores 0); 0: prune none. Phase 1 never chooses a body."))] = 0.0,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Write the chosen body's creature file here "
                                                                  "(default: FILE-design.toml in the working folder, "
                                                                  "FILE the source file's stem or the built-in's "
                                                                  "name: b13.toml -> b13-design.toml).")] = None,
    render: Annotated[str | None, typer.Option("--render", help="Also draw the reference's and the chosen body's "
                                                                  "robust gaits side by side (a .png contact sheet).")] = None,
    backend: BackendOpt = "local",
    address: AddressOpt = None,
    workers: WorkersOpt = None,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Search a file's free numbers with its controllers, scored by robust tuned speed (§6.3).

    Each body is scored as a Table 1 row: phase 1, a short phase 2 on its best SANs, the audited
    selection. The best bodies and the reference (the file's defaults) are scored again on other
    seeds; the chosen body is written as a creature file. Run it again to continue. Progress: a
    bar on a terminal, else a line per score (a body on one seed) on stderr."""
    from sanlab.creature import CreatureError, load_design, read_source

    check_count("--controllers", controllers)
    check_count("--ensemble", ensemble, 1, 256)
    check_seed(seed)
    valid_seeds = _seeds(seeds) if seeds is not None else (seed + 1,)
    if seed in valid_seeds:
        raise fail(f"design: --seeds: expected seeds other than --seed {seed} (the search's own), got {seeds}")
    if strategy not in ("cma-es", "random"):
        raise fail(f"design: --strategy: expected cma-es or random, got {strategy!r}")
    if strategy == "cma-es":  # pyribs' CMA-ES: the optional qd extra
        from sanlab.search.map_elites import MissingExtra, ribs

        try:
            ribs("emitters.opt", "--strategy cma-es")
        except MissingExtra as e:
            raise fail(f"design: {e} (or --strategy random)") from None
    try:
        text, where = read_source(creature)
        d, spec = load_design(creature)
    except CreatureError as e:
        raise fail(str(e)) from None
    if not d.free:
        raise fail(f"{creature}: expected free numbers to design (a range in place of a number, e.g. "
                   "mass = { min = 0.1, max = 0.3 }: docs/creature-format.md), got none")
    # named after the file, not its creature's name: two files of one creature (a copy edited)
    # would write over each other's result
    stem = where.removeprefix("builtin:") if where.startswith("builtin:") else Path(where).stem
    target = out if out is not None else Path(f"{stem}-design.toml")
    if render is not None and not render.lower().endswith(".png"):
        raise fail(f"design: --render: expected a .png file, got {render!r}")
    # both are written after the whole design (minutes to hours): a bad folder is told now
    check_writable(str(target), "--out", "design")
    if render is not None:
        check_writable(render, "--render", "design")
    from sanlab.design import DesignSettings, run_design
    from sanlab.library import LibraryError

    engine = backend_or_exit(backend, address, workers)

    if search not in ("random", "catcma", "rhythm", "reflex"):
        raise fail(f"design: --search: expected random, catcma, rhythm or reflex, got {safe(search)}")
    settings = DesignSettings(designs, generation, strategy, controllers, trials, top, seconds, ensemble, seed,
                              validate, valid_seeds, prune, search)
    from sanlab.design import reference_name

    for k, total in d.off_totals():  # said before the hours of the design, not after
        t = d.coupling.totals[k]
        warn(f"warning: {creature}: design.total[{k}]: the defaults of {' + '.join(t.of)} sum to {total:.6g}, not "
             f"{t.value:.6g}: the reference is {reference_name(d)}, not the file as it loads")
    lib = open_library(db, create=True)
    shown = console.is_terminal and not as_json
    bar = ProgressBar(shown, "design", unit="scores", rate=None, best="best {task.fields[best]:.1f} cm/s")
    # a log or a pipe gets lines instead of a bar, as for `sanlab tune` (a score takes minutes)
    lines = ProgressLines(not console.is_terminal, "design", "scores", rate=None, best="best {:.1f} cm/s")
    n_valid = min(validate, designs)
    plan = (f"design: {1 + designs} scores on seed {seed} (the reference and {designs} "
            f"bod{'y' if designs == 1 else 'ies'}), then up to {n_valid + 1} on each validation seed "
            f"({', '.join(map(str, valid_seeds))}: the best {n_valid} and the reference, none if no body scored above 0)")

    planned = [False]

    def report(done: int, total: int, best: float, what: str) -> None:
        if not planned[0]:  # once the settings are accepted, before the first score's minutes
            planned[0] = True
            if shown:
                bar.progress.console.print(plan, soft_wrap=True, highlight=False)
            elif not console.is_terminal:
                warn(plan)
        bar.update(f"design {what}" if what else "design", done, total, 0.0, best)
        lines.update(done, total, 0.0, best)

    from sanlab.evaluate.ray_backend import WorkerError

    try:
        with bar:
            bar.waiting("design: the reference body (a first compile takes a minute)")
            result = run_design(lib, d, text, where, settings, report, engine)
    except KeyboardInterrupt:
        typer.echo("interrupted; every finished run is in the library: run the same command again to continue",
                   err=True)
        raise typer.Exit(130) from None
    except (ValueError, LibraryError) as e:
        raise fail(f"design: {e}") from None
    except WorkerError as e:  # an evaluation raised on a Ray worker: its one line
        raise fail(f"design: {e}", 1) from None
    with output_file(str(target), "--out") as path:  # whole or not at all; a full disk is one line too
        Path(path).write_text(result.text, encoding="utf-8")
    s, ch, ref = settings, result.chosen, result.reference
    ref_name = reference_name(d)
    if render is not None:
        rec = ch.speeds[s.seed] if not ch.speeds[s.seed].get("pruned") else ch.speeds[s.seeds[0]]
        _render(lib, render, [(f"reference ({ref_name})", ref.speeds[s.seed]), ("chosen", rec)],
                f"{spec.name}: the reference and the chosen body")
    if as_json:
        typer.echo(dump_json(record("design", {"creature": spec.name, "source": where, "written": str(target),
                                               **result.to_json(), "seconds": result.seconds})))
        return
    table = Table("body", f"seed {s.seed} (cm/s)", *(f"seed {x}" for x in s.seeds), "robust gait, or why 0")
    for b in result.bodies:
        rec = b.speeds[s.seed]
        table.add_row(b.label + (" (chosen)" if b is ch else ""), f"{b.speed(s.seed):.1f}",
                      *(f"{b.speed(x):.1f}" if x in b.speeds else "" for x in s.seeds),
                      safe(b.why(s.seed) or rec["gait"] or "none"))
    console.print(table)
    _print_values(d, result.bodies, ch)
    seeds_said = f"seed{'s' * (len(s.seeds) > 1)} {', '.join(map(str, s.seeds))}"
    if result.validated:
        console.print(f"robust tuned speed, mean on {seeds_said}: chosen {ch.mean(s.seeds):.1f} cm/s{_why(ch, s.seeds)}, "
                      f"reference ({safe(ref_name)}) {ref.mean(s.seeds):.1f} cm/s{_why(ref, s.seeds)}", soft_wrap=True)
    if ch is ref:
        why = ("no body beat the reference on the validation seeds" if result.validated else
               f"no body of the search scored above 0 cm/s on seed {s.seed} (the table says why), so none was "
               f"validated on {seeds_said}")
        console.print(f"{why}: {safe(str(target))} is the reference ({safe(ref_name)}; raise --designs, --controllers "
                      "or --trials, or widen the ranges)", soft_wrap=True)
    else:
        for line in d.changes(ch.values):
            console.print(f"  {safe(line)}", soft_wrap=True)
    console.print(f"wrote {safe(str(target))} ({len(result.bodies) - 1} bod{'y' if len(result.bodies) == 2 else 'ies'} in {result.seconds:.0f} s)"
                  + (f" and {safe(render)}" if render else "") + f"; stored as design {result.design_id}")
    gait = ch.speeds[s.seed]["gait"]
    print_next(db, [*([f"sanlab render {gait}"] if gait else []), "sanlab studio"],
               (f"sanlab check {target}",))  # check reads no library


def _why(body, seeds) -> str:
    """" (no rung survived the audit; ...)" for a body whose mean on ``seeds`` is 0, else ""."""
    if body.mean(seeds) > 0:
        return ""
    return next((f" ({safe(w)})" for x in seeds if (w := body.why(x))), "")


def _print_values(design, bodies, chosen) -> None:
    """Each body's free values, named (the file's units), in tables as wide as the console: a
    column per free number, as many as fit beside the body's label."""
    names = [f.name + (f" ({u})" if u else "") for f, u in zip(design.free, design.units, strict=True)]
    label = max(len(b.label) + len(" (chosen)") * (b is chosen) for b in bodies) + 3
    width, group, used = max(console.width, 40), [], label
    groups = []
    for i, name in enumerate(names):
        w = max(min(len(name), 24), 9) + 3
        if group and used + w > width:
            groups.append(group)
            group, used = [], label
        group.append(i)
        used += w
    groups.append(group)
    for k, group in enumerate(groups):
        head = "free values" + (f" ({k + 1} of {len(groups)})" if len(groups) > 1 else "")
        table = Table("body", *(safe(names[i]) for i in group), title=head, title_justify="left")
        for b in bodies:
            table.add_row(b.label + (" (chosen)" if b is chosen else ""), *(f"{b.values[i]:.6g}" for i in group))
        console.print(table)


def _render(lib, path: str, bodies: list[tuple[str, dict]], title: str) -> None:
    """A contact sheet of each body's robust gait (its best chain's tuned gait where no rung kept
    its speed), labelled, side by side."""
    from sanlab.cli.render import gait_scene
    from sanlab.render.strobe import contact_sheet

    tiles = []
    for label, rec in bodies:
        gait_id = rec["gait"] or max(rec["chains"], key=lambda c: c["tuned_cm_s"])["tuned"]
        _, gait, sc = gait_scene(lib, gait_id)
        tiles.append((f"{label}   {gait.gait_id}  {gait.speed_cm_s:.1f} cm/s", sc))
    try:
        contact_sheet(tiles, title).save(path, format="PNG")
    except OSError as e:
        raise fail(f"design: --render {path}: cannot write ({e.strerror or e}); the design is stored") from None
