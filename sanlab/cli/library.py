"""``sanlab runs``, ``show``, ``export`` and ``import``: reading and exchanging the gait library.

Reading commands open the library read-only (they work in a read-only folder and never take a
write lock); a damaged run is listed as "damaged" and reading it is a one-line error.
"""

from __future__ import annotations

import json
import shlex
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from sanlab.cli._common import (
    DbOpt,
    JsonOpt,
    console,
    direction,
    dump_json,
    fail,
    id_column,
    library_call,
    open_library,
    output_file,
    print_distribution,
    print_next,
    print_top,
    quoted_gait,
    record,
    safe,
    top_rows,
    warn,
)
from sanlab.creature.spec import SCORE_UNITS

if TYPE_CHECKING:
    from sanlab.library import Library

MAX_IMPORT_BYTES = 64 << 20  # an exported gait is a few kB; a larger file is not one


def runs(db: DbOpt = "sanlab.db", as_json: JsonOpt = False) -> None:
    """List the runs in the gait library, newest first (and its designs, in a line under them)."""
    from sanlab.library import LibraryError

    lib = open_library(db, readonly=True)
    listed = library_call(lambda: lib.runs(check_evaluations=True))
    bad_gaits = library_call(lib.damaged_gaits)  # which gait of each, for the warning
    rows = [
        {"run_id": r.run_id, "kind": r.kind, "creature": r.creature, "status": r.status,
         "evaluated": r.count, "total": r.total, "trials": r.trials, "progress": r.progress, "created": r.created}
        for r in listed
    ]
    for r in listed:
        if r.run_id in bad_gaits:
            try:
                lib.gait(bad_gaits[r.run_id])
                why = f"gait {bad_gaits[r.run_id]} is damaged"
            except LibraryError as e:
                why = str(e).split(": ", 1)[-1].split("; the rest")[0]
            warn(f"{db}: run {r.run_id} is damaged ({why}); the other runs are intact "
                 "(export what you need with `sanlab export`, or restore the file from a backup)")
        elif r.status == "damaged":
            warn(f"{db}: run {r.run_id} is damaged ({lib.damage(r.run_id)}); the other runs are intact "
                 "(export what you need with `sanlab export`, or restore the file from a backup)")
    if as_json:
        typer.echo(dump_json([record("run-entry", {k: v for k, v in r.items() if k != "progress"}) for r in rows]))
        return
    table = Table(id_column("run", [r["run_id"] for r in rows]), "kind", "creature", "status", "progress", "created")
    for r in rows:
        created = r["created"][:19].replace("T", " ")
        done, planned, unit = r["progress"]
        table.add_row(safe(r["run_id"]), safe(r["kind"]), safe(r["creature"]), safe(r["status"]),
                      f"{done}/{'?' if planned is None else planned} {unit}", safe(created))
    console.print(table)
    designs = library_call(lib.designs)  # `sanlab design`'s outer records: the studio draws them
    if designs:
        shown = ", ".join(f"{d.design_id} {d.creature} ({d.status}, {d.scores} score{'s' * (d.scores != 1)})" for d in designs[:5])
        console.print(safe(f"{len(designs)} design{'s' * (len(designs) != 1)}: {shown}{', ...' if len(designs) > 5 else ''} "
                           "(`sanlab studio` shows each as a scatter of its bodies)"), soft_wrap=True)


def show(
    target: Annotated[str, typer.Argument(metavar="RUN_ID|GAIT", help="A run id (or an unambiguous prefix), or a gait (RUN/RANK, RUN#IDX).")],
    top: Annotated[int, typer.Option(min=1, max=10_000, help="Gaits to show (of a run).")] = 10,
    network: Annotated[bool, typer.Option("--network", help="Also print the weight matrix, by sensor, hidden and actuator name (of a run: its best).")] = False,
    by_mode: Annotated[bool, typer.Option("--modes", help="Of a run: the best gait of each gait mode (as `sanlab modes`), not the --top best.")] = False,
    db: DbOpt = "sanlab.db",
    as_json: JsonOpt = False,
) -> None:
    """Show a run's best gaits, or one gait's parameters (--network: its weights).

    A run: rank, score (and its unit), speed with an arrow for the direction of motion, flags. A
    gait: its parameters in the creature file's units beside the file's own."""
    lib = open_library(db, readonly=True)
    if "/" in target or "#" in target:
        _show_gait(lib, target, network, as_json, db)
        return
    run = library_call(lib.get_run, target)
    if by_mode:
        from sanlab.cli.modes import modes

        modes(run.run_id, min_score=None, top=top, singletons=False, min_cluster=3, rescore=False, db=db, as_json=as_json)
        return
    rows = library_call(top_rows, lib, run.run_id, top)
    if network:
        if not rows:
            raise fail(f"run {run.run_id} has no evaluations yet")
        _show_gait(lib, rows[0]["gait"], True, as_json, db)
        return
    metric = run.params.get("metric", "?")
    if as_json:
        out = record("run", {"run_id": run.run_id, "kind": run.kind, "creature": run.creature, "status": run.status,
                             "evaluated": library_call(lib.count, run.run_id), "params": run.params,
                             "score_unit": SCORE_UNITS.get(metric), "top": rows})
        typer.echo(dump_json(out))
        return
    quoted, selected = quoted_gait(lib, run.run_id)
    rank = library_call(lib.gait, quoted).rank if quoted else None
    print_top(rows, f"run {run.run_id}: {run.creature} ({run.status}), metric {metric}", SCORE_UNITS.get(metric, ""),
              selected=rank)
    if run.kind == "search":  # a tuning's stored gaits (its result, a selection) are no distribution
        print_distribution(library_call(lib.scores, run.run_id))
    if not rows:
        return
    # the hints lead to what can be quoted: a tuning's audited selection, by its permanent id
    # (its rank is not 1 when the chain's unvouched best scores higher; issue 57)
    if quoted:
        console.print(f"{quoted} (rank {rank}) is this tuning's audited selection, the tuned gait to quote"
                      + ("" if rank == 1 else f"; {rows[0]['gait']} is the chain's best by score"
                         + ("" if rows[0]["verdict"] == "robust" else ", which no audit vouched for")))
        print_next(db, [f"sanlab show {quoted}", f"sanlab render {quoted}", f"sanlab export {quoted}"])
        return
    best = rows[0]["gait"]
    if selected:
        console.print(f"the audited selection found no robust rung in this tuning's climb: no gait of run {run.run_id} "
                      "is vouched for")
    elif run.kind == "tune":
        print_next(db, [f"sanlab audit {run.run_id} --select", f"sanlab show {best}", f"sanlab render {best}"])
        return
    print_next(db, [f"sanlab show {best}", f"sanlab render {best}", f"sanlab tune {best}", f"sanlab audit {best}"])


def _show_gait(lib: Library, gait_id: str, network: bool, as_json: bool, db: str = "sanlab.db") -> None:
    """One gait: score, speed, direction, flags, its parameters in file units (and weights)."""
    from sanlab.gait import Gait
    from sanlab.tuned import file_values, network_table

    ev = library_call(lib.gait, gait_id)
    run = library_call(lib.get_run, ev.run_id)
    try:
        gait = Gait.from_library(lib, ev.gait_id)
    except ValueError as e:  # a stored creature text or encoding today's sanlab cannot read
        raise fail(f"{lib.path}: gait {ev.gait_id} cannot be decoded ({e})") from None
    dx = (ev.extra or {}).get("dx_m")
    values = file_values(gait)
    audit = library_call(lib.audit, ev.gait_id)
    flagged = audit is not None and audit.flagged
    found, ceiling = _ceiling(lib, gait, ev.speed_cm_s)
    if network and gait.kind == "pattern":
        raise fail(f"--network: gait {ev.gait_id} is an open-loop pattern (the pattern ceiling): it has no SAN to show")
    summary = record("gait", {"gait": ev.gait_id, "kind": gait.kind, "rank": ev.rank, "creature": gait.spec.name, "metric": gait.metric,
               "score": ev.score, "score_unit": SCORE_UNITS.get(gait.metric), "speed_cm_s": ev.speed_cm_s,
               "dx_m": dx if isinstance(dx, (int, float)) else None, "direction": direction(dx),
               "fell": ev.fell, "nonfinite": ev.nonfinite, "encoding": ev.encoding, "parameters": values,
               "ceiling": ceiling,
               "audit": None if audit is None else {"verdict": audit.verdict, "flagged": audit.flagged,
                                                     "resolution_dependent": audit.resolution_dependent,
                                                     "reproduced": audit.reproduced, "worst": audit.worst,
                                                     "created": audit.created, "result": audit.result}})
    if network:
        summary["network"] = network_table(gait)
    if as_json:
        typer.echo(dump_json(summary))
        return
    arrow = {"+x": " → (+x)", "-x": " ← (-x)"}.get(summary["direction"] or "", "")
    flags = ", ".join(f for f, on in (("pattern (open loop, no SAN)", gait.kind == "pattern"), ("fell", ev.fell),
                                      ("non-finite", ev.nonfinite),
                                      ("not reproduced", audit is not None and not audit.reproduced),
                                      ("resolution-dependent", audit is not None and audit.resolution_dependent),
                                      ("audit undecided", audit is not None and audit.verdict == "undecided"),
                                      ("audited: robust", audit is not None and not flagged)) if on) or "-"
    console.print(f"[bold]gait {safe(ev.gait_id)}[/bold] (rank {ev.rank} of run {safe(run.run_id)}), "
                  f"{safe(gait.spec.name)}, metric {safe(gait.metric)}: score {ev.score:.3f} "
                  f"{SCORE_UNITS.get(gait.metric, '')}, speed {ev.speed_cm_s:.1f} cm/s{arrow}, flags {flags}")
    if ceiling is None:
        console.print(f"[dim]no pattern ceiling stored for this creature file: sanlab ceiling {safe(gait.source or gait.spec.name)}"
                      " measures how fast an open loop drives the body[/dim]")
    elif gait.kind == "san" and ceiling["fraction"] is not None:
        vouched = "audited: robust" if found is not None and found.robust else "not vouched for by an audit"
        console.print(f"{100 * ceiling['fraction']:.0f} % of its pattern ceiling ({ceiling['speed_cm_s']:.1f} cm/s, "
                      f"gait {ceiling['gait']}, {vouched})")
    _print_values(values)
    if network:
        _print_network(summary["network"])
    gid = ev.gait_id
    quoted, _ = quoted_gait(lib, run.run_id)
    if quoted and quoted != gid:  # the chain's unvouched best (RUN#0, often RUN/1): say which to quote
        console.print(f"run {safe(run.run_id)}'s audited selection is {quoted}, the tuned gait to quote")
        print_next(db, [f"sanlab show {quoted}", f"sanlab render {quoted}", f"sanlab export {quoted}"])
        return
    audit_next = [f"sanlab audit {gid}"] if audit is None else []  # audited: its verdict is in the flags already
    if audit is not None and audit.flagged and run.kind == "tune" and quoted is None:
        audit_next = [f"sanlab audit {run.run_id} --select"]  # the climb may hold a rung that survives
    san_next = [f"sanlab tune {gid}"] if gait.kind == "san" else []  # a pattern has no SAN to tune or export
    print_next(db, [f"sanlab render {gid}", *san_next, *audit_next, *[f"sanlab export {gid}"] * (gait.kind == "san")])


def _ceiling(lib: Library, gait, speed_cm_s: float):
    """The creature's pattern ceiling in this library (``sanlab.search.ceiling.find``), and it
    with the fraction of it ``speed_cm_s`` is, as ``show --json`` prints it; (None, None) without one."""
    from sanlab.search.ceiling import find

    c = library_call(find, lib, gait.creature_text, gait.metric, gait.seconds)
    return c, None if c is None else {**c.to_json(), "fraction": c.fraction(speed_cm_s)}


def _print_values(values: dict) -> None:
    """The parameters table: each in the creature file's units, the file's value beside it."""
    table = Table("part", "parameter", "this gait", "creature file", "unit", title="parameters (creature file units)")
    tuned = 0
    for row in values["rows"]:
        same = row["file"] is None or row["value"] == row["file"] or abs(row["value"] - row["file"]) <= 1e-9 * max(1.0, abs(row["file"]))
        style = "" if same else "bold"
        tuned += not same
        shown = f"[{style}]{row['value']:.6g} *[/{style}]" if style else f"{row['value']:.6g}"  # '*': seen without bold too
        table.add_row(safe(row["part"]), safe(row["name"]), shown, "-" if row["file"] is None else f"{row['file']:.6g}", row["unit"])
    console.print(table)
    if tuned:  # the legend only where there is something bold
        console.print("[dim]*: tuned away from the creature file[/dim]")


def _print_network(net: dict) -> None:
    """The weight matrix; split into column groups (sensors, hidden nodes, actuator nodes, and
    narrower if need be) when it is wider than the terminal."""
    inputs, colours = list(net["inputs"]), {-2: "red", -1: "red", 0: "dim", 1: "green", 2: "green"}

    def table(cols: list[int], title: str) -> Table:
        t = Table("node", *[safe(inputs[c]) for c in cols], title=title)
        for name, row in zip(net["nodes"], net["weights"]):
            t.add_row(safe(name), *[f"[{colours[row[c]]}]{row[c]:+d}[/{colours[row[c]]}]" if row[c] else "[dim]0[/dim]"
                                    for c in cols])
        return t

    wide = console.options.update_width(10_000)  # measure unclamped: Rich caps a measurement at the width
    fits = lambda cols: console.measure(table(cols, ""), options=wide).maximum <= console.width
    everything = list(range(len(inputs)))
    if fits(everything):
        console.print(table(everything, "weights (rows: nodes; columns: inputs)"))
    else:
        kinds: dict[str, list[int]] = {}  # S, H, A: sensors, hidden nodes, actuator nodes
        for c, name in enumerate(inputs):
            kinds.setdefault(str(name)[:1], []).append(c)
        groups: list[list[int]] = []
        for cols in kinds.values():  # neighbouring kinds share a table when they fit together
            if groups and fits(groups[-1] + cols):
                groups[-1] += cols
            else:
                groups.append(list(cols))
        for cols in groups:
            while cols:
                n = len(cols)
                while n > 1 and not fits(cols[:n]):
                    n -= 1
                part, cols = cols[:n], cols[n:]
                console.print(table(part, f"weights from {safe(inputs[part[0]])}-{safe(inputs[part[-1]])} (rows: nodes)"))
    console.print("[dim]inputs: sensors, then hidden nodes, then actuator nodes (their outputs); "
                  "each node switches on while its weighted sum is positive (after its delay)[/dim]")


def export_(
    gait: Annotated[str, typer.Argument(metavar="GAIT", help="RUN/RANK, e.g. 3fa1c2d0/1 (or RUN#IDX).")],
    out: Annotated[str | None, typer.Option("--out", "-o", help="Write to this file instead of stdout (whole or not at all).")] = None,
    toml: Annotated[bool, typer.Option("--toml", help=(
        "Write the creature file with this gait's tuned parameters applied, instead of the gait (node "
        "delays only where every node has the same; else a warning)."))] = False,
    c: Annotated[bool, typer.Option("--c", help=(
        "Write the gait's network as a dependency-free C99 header (san_init, san_step: sensor bits "
        "in, actuator targets out in rad or m; double precision, bit for bit as sanlab's simulation)."))] = False,
    db: DbOpt = "sanlab.db",
) -> None:
    """Export a gait as JSON, --toml its creature file with the gait applied, or --c its SAN in C.

    JSON: creature, encoding, parameters, score. --toml: the creature file the gait was found
    with, its comments kept, with the gait's tuned parameters written into it. --c: a C99 header
    (stdint.h and float.h only, double precision) with the weights, node rates and actuator
    ranges as constants and Figure 7's node in san_step, for a microcontroller (see the README)."""
    if toml and c:
        raise fail("--toml and --c: expected one of them (a creature file or a C header), got both")
    lib = open_library(db, readonly=True)
    if c:
        from sanlab.gait import Gait
        from sanlab.interop.san_c import header

        ev = library_call(lib.gait, gait)
        try:
            data = header(Gait.from_library(lib, ev.gait_id))
        except ValueError as e:
            raise fail(f"{lib.path}: gait {ev.gait_id} cannot be written as a C header ({e})") from None
    elif toml:
        from sanlab.gait import Gait
        from sanlab.tuned import apply_to_file, per_node_delays

        ev = library_call(lib.gait, gait)
        try:
            stored = Gait.from_library(lib, ev.gait_id)
            data = apply_to_file(stored)
        except ValueError as e:
            raise fail(f"{lib.path}: gait {ev.gait_id} cannot be written as a creature file ({e})") from None
        if per_node_delays(stored):
            warn(f"gait {ev.gait_id}'s node delays differ between nodes, which a creature file cannot say: "
                 "the file keeps its [san] delays (the gait's are in a comment), so it is not exactly the gait")
    else:
        data = json.dumps(library_call(lib.export_gait, gait), indent=2, allow_nan=False) + "\n"
    if out:
        with output_file(out, "--out") as path, open(path, "w", encoding="utf-8") as f:
            f.write(data)
        what = "C header" if c else "creature file" if toml else "gait (JSON)"
        console.print(f"wrote {safe(out)}: the {what} of gait {safe(gait)}, {len(data.encode()):,} bytes", soft_wrap=True)
        q = shlex.quote(out)
        db_opt = "" if db == "sanlab.db" else f" --db {shlex.quote(db)}"
        steps = ([f"#include {q} in a C program (docs/san-in-c.md)"] if c else
                 [f"sanlab check {q}", f"sanlab search {q}{db_opt}"] if toml else
                 [f"sanlab import {q} --db OTHER.db (another library)"])
        console.print("next: " + "    ".join(safe(x) for x in steps), soft_wrap=True)
    else:
        typer.echo(data, nl=False)


def import_(
    file: Annotated[str, typer.Argument(metavar="FILE", help="A JSON file written by `sanlab export`.")],
    db: DbOpt = "sanlab.db",
) -> None:
    """Import a gait exported by `sanlab export`; prints its new gait id.

    The gait is checked completely (its creature, its network against the creature, every
    parameter, no unknown field) before anything is written: a bad file leaves the library as it
    was. An audit in the file is not imported (`sanlab audit` re-runs it on this machine)."""
    from sanlab.creature.files import NotRegularFile, TooLarge, read_regular_file

    try:
        raw = read_regular_file(file, MAX_IMPORT_BYTES)
    except FileNotFoundError:
        raise fail(f"{file}: no such file") from None
    except NotRegularFile as e:
        raise fail(f"{file}: expected an exported gait (a JSON file), got {e.kind}") from None
    except TooLarge:
        raise fail(f"{file}: expected an exported gait, got a file over {MAX_IMPORT_BYTES >> 20} MiB") from None
    except OSError as e:
        raise fail(f"{file}: cannot read ({e.strerror or e})") from None
    try:
        data = json.loads(raw.decode("utf-8-sig"))  # a byte-order mark, as some editors write, is fine
    except UnicodeDecodeError as e:
        raise fail(f"{file}: expected UTF-8 JSON, got undecodable bytes at byte {e.start} (save it as UTF-8)") from None
    except json.JSONDecodeError as e:
        raise fail(f"{file}: expected JSON, got a syntax error at line {e.lineno}, column {e.colno} ({e.msg})") from None
    except RecursionError:
        raise fail(f"{file}: expected an exported gait, got JSON nested too deep to read") from None
    from sanlab.library import LibraryError
    from sanlab.library.exchange import validate_gait

    try:  # before the library is opened: a bad file creates no library either
        validate_gait(data)
    except LibraryError as e:
        raise fail(f"{file}: {e}") from None
    lib = open_library(db, create=True)  # an import starts a run: it may start the library too
    gait = library_call(lib.import_gait, data)
    typer.echo(gait)
    if isinstance(data.get("audit"), dict):
        said = "flagged" if data["audit"].get("flagged") else "not flagged"
        warn(f"the file's audit ({said}) is the exporting sanlab's and was not imported: "
             f"`sanlab audit {gait}` audits the gait here")
