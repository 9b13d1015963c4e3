"""``sanlab check`` and ``sanlab creatures``: validate and summarise creature files (no
simulator, except ``check --simulate``, which drops the creature for two seconds: ``sanlab.check``)."""

from __future__ import annotations

import contextlib
from collections import Counter
from typing import Annotated

import typer
from rich.table import Table

from sanlab.cli._common import CreatureArg, DtypeOpt, JsonOpt, check_dtype, console, dump_json, fail, load_or_exit, record, safe
from sanlab.creature import Creature, builtin_names


def _counts(items) -> str:
    kinds = ", ".join(f"{k} {n}" for k, n in Counter(x.kind for x in items).items())
    return f"{len(items)} ({kinds})" if items else "0"


def _sizes(c: Creature) -> dict[str, int]:
    n = dict(links=len(c.links), sensors=len(c.sensors), actuators=len(c.actuators))
    return n | {"hidden": c.n_hidden}


def _summary(c: Creature, where: str) -> dict:
    counts = lambda items: dict(Counter(x.kind for x in items))
    return record("check", {"ok": True, "name": c.name, "description": c.description, "history": list(c.history),
            "source": where, "plane": c.world.plane,
            "links": len(c.links), "dofs": c.dofs, "sensors": counts(c.sensors), "actuators": counts(c.actuators),
            "springs": len(c.springs), "hidden": c.n_hidden, "dt": c.dt, "metric": c.evaluation.metric,
            "metric_direction": c.evaluation.direction, "seconds": c.evaluation.seconds})


def check(
    creature: CreatureArg,
    simulate: Annotated[bool, typer.Option("--simulate", help="Also drop it for two seconds (servos at mid targets, then "
                                           "sweeping) and warn about what only a simulation shows.")] = False,
    dtype: DtypeOpt = "float64",
    strict: Annotated[bool, typer.Option("--strict", help=(
        "Exit 1 when there is any warning (for scripts and CI); the report is printed as usual. It also "
        "builds the creature at both ends of every free range, where plain check stops after 0.5 s."))] = False,
    as_json: JsonOpt = False,
) -> None:
    """Validate a creature file and summarise it; --simulate adds warnings from a short drop."""
    check_dtype(dtype)
    c, where = load_or_exit(creature)
    design = c.design if c.design is not None else _design_or_exit(creature)  # one load: it builds the whole file
    out = _summary(c, where)
    if design.free or design.coupling.any:
        # each end is a creature built from the whole file: plain `check` keeps to about a second
        out |= _free(design, None if simulate or strict else ENDS_BUDGET_S)
    findings = []
    if simulate:
        from sanlab.check import simulate as drop

        with console.status("dropping the creature...", spinner="dots") if not as_json \
                else contextlib.nullcontext():
            findings = drop(c, dtype=dtype)
    else:
        from sanlab.check import static  # no simulator: plain `check` stays fast

        findings = static(c)
    findings += _free_ends(out) + _off_totals(design)
    out["checks"] = [{"check": f.check, "warning": f.warning, "note": f.note, "message": f.message, **f.values}
                     for f in findings]
    out["warnings"] = sum(f.warning for f in findings)
    out["notes"] = sum(f.note for f in findings)
    if as_json:
        typer.echo(dump_json(out))
        _strict(strict, out["warnings"], creature)
        return
    grid = Table.grid(padding=(0, 2))
    grid.add_column(style="bold")
    grid.add_column()
    rows = [
        ("source", safe(where)),
        ("plane", c.world.plane),
        ("links", f"{len(c.links)} ({c.dofs} degrees of freedom)"),
        ("sensors", _counts(c.sensors)),
        ("actuators", _counts(c.actuators)),
        ("hidden nodes", f"{c.n_hidden}" + ("" if c.san.hidden is not None else " (= sensors)")),
        ("dt", f"{c.dt:g} s"),
    ]
    if c.springs:
        rows.insert(5, ("springs", str(len(c.springs))))
    for key, value in rows:
        grid.add_row(key, value)
    about = f": {safe(c.description)}" if c.description else ""
    console.print(f"[green]ok[/green] [bold]{safe(c.name)}[/bold]{about}")
    console.print(grid)
    if c.history:
        n = len(c.history)
        console.print(f"[bold]history[/bold]: {n} change{'s' * (n != 1)} to the file, oldest first")
        for line in c.history:
            console.print(f"  {safe(line)}", soft_wrap=True)
    if findings:
        n, notes = sum(f.warning for f in findings), sum(f.note for f in findings)
        head = "[bold]simulated[/bold] (two seconds, servos at mid targets, then sweeping)" if simulate \
            else "[bold]checked without simulating[/bold] (--simulate says more)"
        console.print(f"{head}: {n} warning{'s' * (n != 1)}" + (f", {notes} note{'s' * (notes != 1)}" if notes else ""))
        for f in findings:  # "ok" only where what was checked held
            mark = "[yellow]warning[/yellow]" if f.warning else "[blue]note[/blue]   " if f.note else "[green]ok[/green]     "
            console.print(f"  {mark} {safe(f.message)}", soft_wrap=True)
    if "free" in out:
        _print_free(out)
    _strict(strict, out["warnings"], creature)


def _design_or_exit(creature: str):
    from sanlab.creature import CreatureError, load_design

    try:
        return load_design(creature)[0]
    except CreatureError as e:
        raise fail(str(e)) from None


# Seconds plain `check` spends building the creature at the ends of free ranges (a build reads the
# whole file: 2 to 80 ms); the ends not reached are listed as not checked, and --strict or
# --simulate check every one.
ENDS_BUDGET_S = 0.5


def _free(design, budget_s: float | None = None) -> dict:
    """The --json fields of a file's free numbers (their ranges, the total mass at both ends,
    within ``budget_s`` seconds: ``ends_checked`` false beyond it) and couplings (paper §6.3;
    docs/creature-format.md, "Free numbers")."""
    rows = [{"name": f.name, "path": f.path, "min": f.min, "max": f.max, "default": f.default, "uses": list(f.uses),
             "mass_at_min": _finite(e[0]) if e else None, "mass_at_max": _finite(e[1]) if e else None,
             "ends_checked": e is not None} for f, e in zip(design.free, design.ends(budget_s), strict=True)]
    cp = design.coupling
    couplings = {"density": list(cp.density), "strength_mass": cp.strength_mass,
                 "total_mass": cp.total_mass, "totals": [{"of": list(t.of), "value": t.value} for t in cp.totals]}
    return {"free": rows, "couplings": couplings, "mass": design.total_mass()}


def _kg(x: float | None) -> str:
    return "no valid creature" if x is None else f"{x:.4g} kg"


def _finite(x: float) -> float | None:
    return x if x == x else None  # NaN (no valid creature at that end): null in JSON


def _print_free(out: dict) -> None:
    """The free numbers, one line each with the word "free", and the couplings."""
    n = len(out["free"])
    console.print(f"[bold]free numbers[/bold]: {n} (the file loads at each default; total mass {out['mass']:.4g} kg)")
    for f in out["free"]:
        shared = f" (also {', '.join(safe(u) for u in f['uses'][1:])})" if len(f["uses"]) > 1 else ""
        ends = (f"total mass {_kg(f['mass_at_min'])} at min, {_kg(f['mass_at_max'])} at max" if f["ends_checked"]
                else "ends not checked")
        console.print(f"  {safe(f['name'])}: free in [{f['min']:g}, {f['max']:g}], default {f['default']:g}{shared}; "
                      f"{ends}", soft_wrap=True)
    unchecked = sum(not f["ends_checked"] for f in out["free"])
    if unchecked:
        console.print(f"  the ends of {unchecked} of {n} free numbers were not checked (each end builds the whole "
                      f"creature; plain check stops after {ENDS_BUDGET_S:g} s): --strict checks every end", soft_wrap=True)
    cp = out["couplings"]
    lines = []
    if cp["density"]:
        who = "every link" if cp["density"] == ["*"] else ", ".join(safe(x) for x in cp["density"])
        lines.append(f"density: mass follows size (segment length, polygon area) for {who}")
    if cp["strength_mass"]:
        lines.append(f"strength_mass: {cp['strength_mass']:g} kg per N·m/deg of ks above its default, on the link "
                     "each angular actuator moves")
    if cp["total_mass"] is not None:
        total = "the stated total" if cp["total_mass"] == "stated" else f"{cp['total_mass']:g} kg"
        lines.append(f"total_mass: link masses scaled to {total}")
    lines += [f"total: {' + '.join(safe(x) for x in t['of'])} = {t['value']:g}" for t in cp["totals"]]
    console.print(f"[bold]couplings[/bold]: {len(lines) or 'none'}")
    for line in lines:
        console.print(f"  {line}", soft_wrap=True)


def _free_ends(out: dict) -> list:
    """A warning for each end of a free range where the file is no valid creature: a design
    search would propose bodies there and lose them (check --strict refuses such a file)."""
    from sanlab.check import Finding

    found = []
    for f in out.get("free", []):
        for end in ("min", "max"):
            if f["ends_checked"] and f[f"mass_at_{end}"] is None:
                found.append(Finding("free", True, f"free number {f['name']}: at its {end} ({f[end]:g}) the file is no "
                                                   "valid creature (`sanlab check` of the file with that value says "
                                                   "why); narrow its range", {"name": f["name"], "end": end}))
    return found


def _off_totals(design) -> list:
    """A warning for each [[design.total]] its numbers' defaults do not sum to: the file loads at
    the defaults, while every body `sanlab design` makes, its reference too, keeps the total."""
    from sanlab.check import Finding

    found = []
    for k, total in design.off_totals():
        t = design.coupling.totals[k]
        found.append(Finding("free", True, f"design.total[{k}]: the defaults of {' + '.join(t.of)} sum to {total:.6g}, "
                             f"not its value {t.value:.6g}: the file loads at its defaults, while `sanlab design` "
                             "starts from them moved onto the total; make the defaults sum to its value",
                             {"total": k, "sum": total, "value": t.value}))
    return found


def _strict(strict: bool, warnings: int, creature: str) -> None:
    """With --strict, a warning ends the command with exit status 1 (bad input stays 2)."""
    if strict and warnings:
        raise fail(f"check --strict: {creature}: {warnings} warning{'s' * (warnings != 1)} (listed above)", code=1)


def creatures(as_json: JsonOpt = False) -> None:
    """List the built-in creatures."""
    loaded = {name: load_or_exit(name)[0] for name in builtin_names()}
    rows = [record("creature-entry", {"name": n, **_sizes(c), "description": c.description}) for n, c in loaded.items()]
    if as_json:
        typer.echo(dump_json(rows))
        return
    table = Table("name", "links", "sensors", "actuators", "hidden", "description")
    for r in rows:
        sizes = (str(v) for k, v in r.items() if k not in ("schema", "name", "description"))
        table.add_row(safe(r["name"]), *sizes, safe(r["description"]))
    console.print(table)
