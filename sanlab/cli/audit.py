"""``sanlab audit``: re-score stored gaits with the step halved and quartered and in float64, and
say whether their speed distribution survives (``sanlab.audit``)."""

from __future__ import annotations

import math
from typing import Annotated

import typer
from rich import box
from rich.table import Table

from sanlab.cli._common import (
    AddressOpt,
    BackendOpt,
    DbOpt,
    JsonOpt,
    WorkersOpt,
    backend_or_exit,
    console,
    dump_json,
    fail,
    library_call,
    open_library,
    print_next,
    quoted_gait,
    record,
    safe,
    warn,
)


def audit(
    target: Annotated[str, typer.Argument(metavar="GAIT|RUN_ID", help="A gait (RUN/RANK or RUN#IDX), or a run id to audit its top gaits.")],
    top: Annotated[int | None, typer.Option(min=1, help=(
        "With a run id: audit its K best gaits (default 1); with --select: audit up to K rungs (default 16)."))] = None,
    threshold: Annotated[float, typer.Option(min=0.0, help=(
        "The band: a relative change of the mean speed within it is robust (0.10 = 10 %)."))] = 0.10,
    members: Annotated[int, typer.Option(min=2, max=4096, help=(
        "Perturbed starts the audit draws for itself; more narrow the interval (an undecided audit says how many "
        "would decide it)."))] = 64,  # sanlab.audit.MEMBERS (not imported: --help stays light)
    max_members: Annotated[int, typer.Option(min=2, max=4096, help=(
        "An undecided audit looks again, each time on as many members as the last look said would decide it "
        "(at least twice as many), up to this."))] = 1024,  # sanlab.audit.MAX_MEMBERS
    select: Annotated[bool, typer.Option("--select", help=(
        "With a tuning run: audit the rungs of its climb and store the best-scoring one that no nudge "
        "moves by more than the threshold as its gait RUN#1."))] = False,
    backend: BackendOpt = "local",
    address: AddressOpt = None,
    workers: WorkersOpt = None,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Audit gaits for integrator artefacts (dt/2, dt/4; the kernel steps in float64).

    Each gait is simulated from --members perturbed starts of its own at its step and under each
    nudge, and the relative change of the mean speed is bootstrapped (a 95 % interval over the
    two nudges together): robust when every interval lies inside the band (--threshold),
    resolution-dependent when one lies outside it, undecided otherwise (not a pass). An
    undecided gait is looked at again, on as many starts as would likely decide it (at least
    twice as many, up to --max-members); if that still does not decide it, it names the
    --members that would. A gait whose stored speed is more than the threshold from
    the speed re-scored exactly as stored is flagged not reproduced. The verdict is stored in
    the library (shown by `sanlab show` and carried by exports).

    With --select and a tuning run: up to 16 rungs of its chain's climb (its start, its best and
    the vectors that first reached the scores between) are audited, and the best-scoring robust
    one that is robust again on fresh draws (the start itself, when no tuned rung is) is stored
    as the run's gait RUN#1, the tuned result to quote.

    With --backend ray each look's evaluations (the gait's step and every nudge, and the rungs)
    run side by side on a Ray cluster's workers; the verdicts are the same (docs/ray.md)."""
    from sanlab.audit import SELECT_TOP, audit_and_store

    if not math.isfinite(threshold):
        raise fail(f"audit: --threshold: expected a finite number >= 0, got {threshold}")
    engine = backend_or_exit(backend, address, workers)
    lib = open_library(db)
    if select:
        if "/" in target or "#" in target:
            raise fail("audit --select: give a tuning run id, not a gait")
        run = library_call(lib.get_run, target)
        if run.kind == "tune" and 0 not in library_call(lib.done_indices, run.run_id):  # the command to run names --db
            raise fail(f"audit --select: run {run.run_id} has not finished: resume it first "
                       f"(sanlab tune --resume {run.run_id} --db {db})")
        log = steps(as_json)
        try:
            sel = library_call(lambda r: select_and_report(lib, r, threshold, log, as_json, top or SELECT_TOP, members,
                                                                   max_members, engine),
                               run.run_id)
        except KeyboardInterrupt:
            typer.echo("interrupted; nothing of this selection was stored: run the same command again", err=True)
            raise typer.Exit(130) from None
        if as_json:
            typer.echo(dump_json(sel))
        elif sel["robust_gait"]:  # by its permanent id: its rank is 2 where the chain's best scores higher
            g = sel["robust_gait"]
            print_next(db, [f"sanlab show {g}", f"sanlab render {g}", f"sanlab export {g}"])
        return
    top = top or 1
    if "/" in target or "#" in target:
        gaits = [library_call(lib.gait, target).gait_id]
    else:
        run = library_call(lib.get_run, target)
        gaits = [e.gait_id for e in library_call(lib.top, run.run_id, top)]
    log = steps(as_json)
    results = [library_call(lambda g: audit_and_store(lib, g, threshold=threshold, members=members,
                                                           max_members=max_members, log=log, backend=engine), g)
               for g in gaits]
    if as_json:
        typer.echo(dump_json([audit_record(a) for a in results]))
        return
    print_audits(results, threshold, db, max_members)
    # a tuned gait the audit cannot vouch for: the way to one it can is its run's selection
    hints = []
    for run_id in dict.fromkeys(a.gait_id.split("#")[0] for a in results if a.verdict != "robust"):
        if library_call(lib.get_run, run_id).kind == "tune":
            quoted, selected = quoted_gait(lib, run_id)
            hints += [f"sanlab show {quoted}"] if quoted else [] if selected else [f"sanlab audit {run_id} --select"]
    if hints:
        print_next(db, hints)


def steps(as_json: bool):
    """Where the audit's steps go as it makes them (a rung or a look on more members can take a
    minute): under the table's way on stdout, or with ``--json`` (stdout is the record) on stderr
    when that is no terminal, as the other long commands report progress; nowhere otherwise."""
    if not as_json:
        return lambda m: console.print(f"[dim]{safe(m)}[/dim]")
    return None if console.is_terminal else (lambda m: warn(f"audit: {m}"))


def audit_record(a) -> dict:
    """One :class:`sanlab.audit.Audit` as the ``audit`` record of ``--json``."""
    return record("audit", {"gait": a.gait_id, "verdict": a.verdict, "flagged": a.flagged,
                            "resolution_dependent": a.resolution_dependent, "reproduced": a.reproduced,
                            "worst": a.worst if math.isfinite(a.worst) else None,
                            **{k: v for k, v in a.to_json().items() if k not in ("verdict", "resolution_dependent", "reproduced")}})


def print_audits(results: list, threshold: float, db: str = "sanlab.db", max_members: int | None = None) -> None:
    """The audit table (and what its flags mean) of ``results`` (:class:`sanlab.audit.Audit`);
    an undecided gait gets the command that would likely decide it (``db``: its library;
    ``max_members``: the audit's --max-members, default ``sanlab.audit.MAX_MEMBERS``)."""
    from sanlab.audit import MAX_MEMBERS, MAX_MEMBERS_ADVISED, advice

    max_members = MAX_MEMBERS if max_members is None else max_members

    db_opt = "" if db == "sanlab.db" else f" --db {db}"
    names = list(results[0].speeds) if results else []
    # borderless, and every cell at most 11 characters a line (a verdict or an interval on lines
    # of its own): the columns fit 80 characters, piped output included; a narrower terminal
    # folds cells rather than cutting off the verdict ("resoluti…")
    table = Table(title="audit: mean speed (cm/s) of the audit's perturbed starts under each nudge, "
                        "its change and 95 % interval",
                  box=box.SIMPLE_HEAD, padding=(0, 0), show_edge=False)
    table.add_column("gait", no_wrap=True, min_width=max((len(a.gait_id) for a in results), default=0))
    for name in ("stored", "rescored", "at dt", *names, "verdict"):
        table.add_column(name, overflow="fold")
    for a in results:
        cells = [shift_cell(a.speeds[n], a.shifts[n]) for n in names]
        table.add_row(a.gait_id, f"{a.stored_cm_s:.1f}", f"{a.nominal_cm_s:.1f}",
                      f"{a.reference_cm_s:.1f}\n({a.audit_members})", *cells,
                      verdict_cell(a.verdict, a.needed))
    console.print(table)
    if any(not a.reproduced for a in results):
        console.print(f"not reproduced: the stored speed is more than {100 * threshold:.0f} % from what this sanlab "
                      "re-scores (a score from another engine, or edited): quote the re-scored speed, or search again")
    if any(a.resolution_dependent for a in results):
        console.print(f"resolution-dependent: a nudge moved the mean speed outside ±{100 * threshold:.0f} % "
                      "(its whole interval); `sanlab show` and exports say so")
    undecided = [a for a in results if a.verdict == "undecided"]
    if undecided:
        last = max(a.audit_members for a in undecided)
        # a further look is made only up to --max-members, and only when it asked for at most twice that
        why = (f"--max-members ({max_members:,})" if last >= max_members else
               f"below --max-members ({max_members:,}): a further look is made only when the last asks for at most "
               f"{2 * max_members:,}")
        console.print(f"undecided: an interval straddles ±{100 * threshold:.0f} % (the gait is not vouched for); its "
                      f"last look was on {last:,} members, {why}")
        for a in undecided:
            n = advice(a.audit_members, a.needed)
            if n is not None:  # the command on a line of its own: never folded inside
                console.print(f"  {a.gait_id}: about {a.needed} members would likely decide it:")
                console.print(f"    sanlab audit {a.gait_id} --members {n}{db_opt}", soft_wrap=True)
            else:
                console.print(f"  {a.gait_id}: more than {MAX_MEMBERS_ADVISED} members would be needed to decide it: "
                              "take it as not vouched for (or --threshold wider)")


def shift_cell(speed: float, sh) -> str:
    """"35.3 -69%" over "[-75,-60]": a nudge's mean speed and change, and under them the
    interval (percent), on two lines so that an 80-column table does not cut the interval."""
    pct = lambda x: "inf" if not math.isfinite(x) else f"{100 * x:+.0f}"
    return f"{speed:.1f} {pct(sh.change)}%\n[{pct(sh.lo)},{pct(sh.hi)}]"


def verdict_cell(verdict: str, needed: int | None = None) -> str:
    """The verdict in colour, on lines of at most 11 characters ("resolution-" over
    "dependent"), so that a table of 80 columns never has to cut it."""
    if verdict == "robust":
        return "[green]robust[/green]"
    if verdict == "undecided":
        return "[yellow]undecided[/yellow]" + (f"\n(~{needed}\nmembers)" if needed else "")
    return f"[red]{verdict.replace('-', '-' + chr(10)).replace(' ', chr(10))}[/red]"


def select_and_report(lib, run_id: str, threshold: float = 0.10, log=None, quiet: bool = False, top: int = 16,
                      members: int = 64, max_members: int = 1024, backend=None) -> dict:
    """``sanlab.audit.select_robust`` on one tuning run, printed as a table of its rungs unless
    ``quiet``; returns its JSON summary, the ``selection`` record ({"schema", "run_id", "robust_gait", "trial", "speed_cm_s", "worst",
    "candidates": [...]}). ``backend``: where the rungs are scored (default: here)."""
    from sanlab.audit import combine, rung_name, select_robust

    sel = select_robust(lib, run_id, threshold=threshold, log=log, top=top, members=members, max_members=max_members,
                        backend=backend)
    c = sel.chosen
    out = record("selection", {"run_id": sel.run_id, "robust_gait": sel.gait_id, "trial": None if c is None else c.trial,
           "speed_cm_s": None if c is None else c.nominal_cm_s, "worst": None if c is None else c.worst,
           "threshold": threshold, "candidates": [x.to_json() for x in sel.candidates]})
    if quiet:
        return out
    names = list(sel.candidates[0].speeds) if sel.candidates else []
    table = Table(title=f"run {sel.run_id}: the rungs of its climb, audited on perturbed starts of their own "
                        "(mean cm/s; change and 95 % interval)", box=box.SIMPLE_HEAD, collapse_padding=True,
                  pad_edge=False)
    for name in ("trial", "chain score", "held out", "at dt", *names, "verdict"):
        table.add_column(name, overflow="fold")
    for x in sel.candidates:
        mark = verdict_cell(x.verdict)
        if x.confirmed is not None:
            again = combine(x.confirmed)
            mark += ", confirmed" if again == "robust" else f", not on fresh draws ({again})"
        if x is c:
            mark = "[bold green]chosen[/bold green] " + mark
        table.add_row(rung_name(x.trial).removeprefix("trial "), f"{x.chain_score:.2f}", f"{x.nominal_cm_s:.1f}",
                      f"{x.reference_cm_s:.1f}", *[shift_cell(x.speeds[n], x.shifts[n]) for n in names], mark)
    console.print(table)
    if c is None:
        console.print(f"no rung keeps its mean speed within ±{100 * threshold:.0f} % under every nudge, "
                      "confirmed on fresh draws: this run has no robust tuned gait")
    else:
        console.print(f"robust tuned gait: {sel.gait_id}, {c.nominal_cm_s:.1f} cm/s "
                      f"({rung_name(c.trial)}, worst change {100 * c.worst:.0f} %)")
    return out
