"""``sanlab render``: animations, strobe pictures, contact sheets and plots from a gait library.

    sanlab render RUN/RANK [--out FILE.gif|FILE.mp4|FILE.png] [--seconds T] [--fps F] [--width W]
                           [--nodes/--no-nodes] [--camera auto|follow|fixed] [--db PATH]
    sanlab render RUN [--top N] [--out sheet.png]          a contact sheet of the run's best gaits
    sanlab render RUN --modes [--top N] [--out modes.png]  one strobe per gait mode, named
    sanlab render RUN --plot scores|trace|archive [--out FILE.png]  sorted scores / tuning trace /
                                                            the repertoire's heat map

The output kind follows the file's extension: .gif or .mp4 is an animation, .png a strobe
picture (for a gait), a contact sheet (for a run) or a plot (with --plot). Default names, in the
current directory: ``<run>_<rank>.gif``, ``<run>_top<N>.png``, ``<run>_<plot>.png``.

:func:`render_top` writes a run's best gaits (GIF + strobe PNG each, and a contact sheet) into a
directory, for ``sanlab search --render DIR`` and ``sanlab tune --render DIR``.

This is where the gait library meets the drawing code: gaits and runs are read here and handed
to ``sanlab.render`` as scenes, scores and traces (``sanlab.render`` reads no library).
"""

from __future__ import annotations

import math
import os
import time
from typing import TYPE_CHECKING, Annotated

import typer

from sanlab.cli._common import (
    DbOpt,
    JsonOpt,
    check_count,
    check_gait,
    check_seconds,
    console,
    dump_json,
    fail,
    open_library,
    output_file,
    record,
    safe,
)
from sanlab.creature import printable

if TYPE_CHECKING:
    from sanlab.gait import Gait
    from sanlab.library import Evaluation, Library, Run
    from sanlab.render.scene import Scene

ANIMATIONS = (".gif", ".mp4")
PLOTS = ("scores", "trace", "archive")
DEFAULT_WIDTH = {".gif": 640, ".mp4": 640, "strobe": 1000, "sheet": 1200, "plot": 0}


def _is_gait(target: str) -> bool:
    return "/" in target or "#" in target


def _moved(sc: Scene) -> str:
    from sanlab.render.strobe import motion

    arrow, words = motion(sc)
    return f", moved {arrow} {words}" if arrow else ""


def _gait_label(rank: int | None, gait: Gait) -> str:
    speed = "" if not math.isfinite(gait.speed_cm_s) else f" {gait.speed_cm_s:.1f} cm/s"
    return (f"rank {rank}   " if rank else "") + f"{gait.gait_id}  {speed}"


def gait_scene(library: Library, gait_id: str, seconds: float | None = None,
               fps: float = 30.0) -> tuple[Evaluation, Gait, Scene]:
    """(evaluation, gait, scene) of ``gait_id`` (RUN/RANK or RUN#IDX): the gait replayed for
    ``seconds`` (default: its run's) at ``fps`` frames per second. Raises LibraryError."""
    from sanlab.gait import Gait
    from sanlab.render.scene import gait_title, scene

    ev = library.gait(gait_id)
    gait = Gait.from_library(library, ev.gait_id)
    return ev, gait, scene(gait, seconds, fps, gait_title(gait, ev.rank))


def render_top(library: Library, run_id: str, out_dir: str, top: int = 10, fps: float = 30.0, width: int = 640,
               seconds: float | None = None, nodes: bool = False) -> list[str]:
    """Write each of the run's ``top`` best gaits as ``<run>_<rank>.gif`` (animation) and
    ``<run>_<rank>.png`` (strobe) into ``out_dir`` (created if needed), and a contact sheet
    ``<run>_top<N>.png``; returns the paths written, in that order."""
    from sanlab.render.film import animate
    from sanlab.render.strobe import contact_sheet, write_strobe

    run = library.get_run(run_id)
    os.makedirs(out_dir, exist_ok=True)
    written, tiles = [], []
    for e in library.top(run.run_id, top):
        _, gait, sc = gait_scene(library, f"{run.run_id}/{e.rank}", seconds, fps)
        base = os.path.join(out_dir, f"{run.run_id}_{e.rank}")
        animate(sc, base + ".gif", width=width, nodes=nodes)
        write_strobe(sc, base + ".png", nodes=nodes)
        written += [base + ".gif", base + ".png"]
        tiles.append((_gait_label(e.rank, gait), sc))
    if tiles:
        path = os.path.join(out_dir, f"{run.run_id}_top{len(tiles)}.png")
        contact_sheet(tiles, _sheet_title(library, run, len(tiles))).save(path, format="PNG")
        written.append(path)
    return written


def render_into(lib: Library, run_ids: list[str], out_dir: str, top: int, quiet: bool) -> None:
    """``--render DIR`` of search and tune: :func:`render_top` of each run, then one summary line
    (unless ``quiet``)."""
    try:
        os.makedirs(out_dir, exist_ok=True)  # its parent exists (check_render_dir)
        paths = [p for rid in run_ids for p in render_top(lib, rid, out_dir, top=top)]
    except OSError as e:  # a full disk, a read-only folder: the run itself is stored already
        raise fail(f"--render {out_dir}: cannot write ({e.strerror or e}); the run is stored, render it "
                   "later with `sanlab render`") from None
    if not quiet:
        console.print(f"rendered {len(paths)} files into {safe(out_dir)}")


def _sheet_title(library: Library, run: Run, n: int) -> str:
    metric = run.metric or "?"
    return f"run {run.run_id}: {run.creature}, best {n} of {library.count(run.run_id)} ({metric})"


def render(
    target: Annotated[str, typer.Argument(metavar="GAIT|RUN_ID", help="A gait (RUN/RANK, e.g. 3fa1c2d0/1, or RUN#IDX) or a run id.")],
    out: Annotated[str | None, typer.Option("--out", "-o", help=(
        "Output file: .gif or .mp4 (animation), .png (strobe picture, contact sheet or plot); default, in the "
        "current folder: RUN_RANK.gif (a gait), RUN_topN.png (a sheet), RUN_PLOT.png."))] = None,
    seconds: Annotated[float | None, typer.Option(help="Replay this long (s); default: the run's evaluation time.")] = None,
    fps: Annotated[float, typer.Option(min=1.0, max=100.0, help="Frames recorded (and played) per second.")] = 30.0,
    width: Annotated[int | None, typer.Option(min=64, max=4096, help="Picture width in pixels; default 640 (animation), 1000 (strobe), 1200 (sheet).")] = None,
    top: Annotated[int, typer.Option(min=1, max=60, help="Gaits on a run's contact sheet.")] = 10,
    db: DbOpt = "sanlab.db",
    nodes: Annotated[bool, typer.Option("--nodes/--no-nodes", help="Add a panel of the SAN's sensor and node outputs over time.")] = False,
    plot: Annotated[str | None, typer.Option("--plot", help=(
        "With a run id: scores (sorted phase-1 scores), trace (tuning score per trial) or archive (the best score "
        "in each cell of the run's MAP-Elites grid; another run's evaluations binned into the default grid)."))] = None,
    modes: Annotated[bool, typer.Option("--modes", help="With a run id: a sheet of its gait modes' best gaits (sanlab modes), named.")] = False,
    camera: Annotated[str, typer.Option(help="Animation camera: auto (follow only if the trajectory does not fit), follow, or fixed.")] = "auto",
    as_json: JsonOpt = False,
) -> None:
    """Draw gaits: animations (.gif/.mp4), strobe pictures and contact sheets (.png), plots."""
    from sanlab.library import LibraryError

    gait = _is_gait(target)
    if gait:
        check_gait(target)
    if not math.isfinite(fps):
        raise fail(f"--fps: expected a number in [1, 100], got {fps}")
    check_count("--width", width if width is not None else 640, 64, 4096)
    check_seconds(seconds)  # the creature's own dt bound is checked when the gait is loaded
    if plot is not None and plot not in PLOTS:
        raise fail(f"--plot: expected scores, trace or archive, got {plot!r}")
    if plot is not None and gait:
        raise fail(f"--plot takes a run id, not a gait ({target!r})")
    if modes and (gait or plot is not None):
        raise fail("--modes takes a run id, without --plot")
    if camera not in ("auto", "follow", "fixed"):
        raise fail(f"--camera: expected auto, follow or fixed, got {camera!r}")
    if out is not None:
        ext = os.path.splitext(out)[1].lower()
        allowed = (*ANIMATIONS, ".png") if gait and plot is None else (".png",)
        if ext not in allowed:
            what = "an animation (.gif, .mp4) or a strobe picture (.png)" if len(allowed) > 1 else (
                "a plot" if plot else "a contact sheet") + " (.png)"
            if ext in ANIMATIONS:  # a kind sanlab writes, but not of a run
                raise fail(f"--out {out}: a run is drawn as {what}, not {ext}")
            raise fail(f"--out {out}: unknown kind {ext or '(no extension)'!r}; expected {what}")
        folder = os.path.dirname(os.path.abspath(out))
        if not os.path.isdir(folder):
            raise fail(f"--out {out}: directory {folder} does not exist")
        if os.path.exists(out) and not os.path.isfile(out):  # before the replay, not after it
            raise fail(f"--out {out}: expected a file to write, got an existing "
                       f"{'folder' if os.path.isdir(out) else 'FIFO, device or socket'}")
    lib = open_library(db, readonly=True)
    try:
        if plot is not None:
            info = _render_plot(lib, target, plot, out)
        elif gait:
            info = _render_gait(lib, target, out, seconds, fps, width, nodes, camera)
        elif modes:
            info = _render_modes(lib, target, out, seconds, fps, width, top)
        else:
            info = _render_sheet(lib, target, out, seconds, fps, width, top)
    except LibraryError as e:
        raise fail(str(e)) from None
    except ValueError as e:
        raise fail(f"render: {e}") from None
    finally:
        lib.close()
    line = info.pop("line")
    typer.echo(dump_json(record("render", info)) if as_json else line)


def _render_gait(lib: Library, target: str, out: str | None, seconds: float | None, fps: float,
                 width: int | None, nodes: bool, camera: str) -> dict:
    from sanlab.creature.spec import MAX_STEPS
    from sanlab.render.film import animate
    from sanlab.render.strobe import motion, write_strobe

    ev = lib.gait(target)  # fail early on an unknown gait, before compiling anything
    path = out or f"{ev.run_id}_{ev.rank}.gif"
    ext = os.path.splitext(path)[1].lower()
    t0 = time.perf_counter()
    from sanlab.gait import Gait

    spec = Gait.from_library(lib, ev.gait_id).spec
    if seconds is not None and seconds > MAX_STEPS * spec.dt:
        raise ValueError(f"--seconds: expected at most {MAX_STEPS * spec.dt:g} s for {spec.name} "
                         f"({MAX_STEPS:,} steps of {spec.dt:g} s), got {seconds:g}")
    _, gait, sc = gait_scene(lib, ev.gait_id, seconds, fps)
    t1 = time.perf_counter()
    # The stored speed is the score's statistic (the median over the ensemble's perturbed copies);
    # the picture is one replay (the unperturbed start, member 0): say which number is which.
    K = gait.ensemble.members
    scored = "" if not math.isfinite(gait.speed_cm_s) else (
        f", scored {gait.speed_cm_s:.1f} cm/s" + (f" (median of {K} perturbed copies)" if K > 1 else ""))
    moved = _moved(sc)
    replay = f"; this replay{' (unperturbed)' if K > 1 else ''}{moved.removeprefix(',')}" if moved else ""
    about = f"gait {ev.gait_id} (rank {ev.rank}{scored}{replay})"
    arrow, words = motion(sc)
    stored_dx = (ev.extra or {}).get("dx_m")
    base = {"path": path, "gait": ev.gait_id, "rank": ev.rank, "speed_cm_s": gait.speed_cm_s,
            "dx_m": stored_dx if isinstance(stored_dx, (int, float)) and math.isfinite(stored_dx) else None,
            "replay_dx_m": sc.dx, "direction": words.split(" ")[0] if arrow else None}
    if ext == ".png":
        with output_file(path) as tmp:
            info = write_strobe(sc, tmp, width or DEFAULT_WIDTH["strobe"], nodes=nodes)
        w, h = info["size"]
        n = info["exposures"]
        return {**base, "kind": "strobe", "size": [w, h], "exposures": n, "seconds": sc.duration,
                "line": f"wrote {printable(path)}: strobe picture {w}x{h}, {n} exposure{'s' * (n != 1)} over "
                        f"{sc.duration:.1f} s, {about}"}
    with output_file(path) as tmp:
        info = animate(sc, tmp, width or DEFAULT_WIDTH[ext], nodes=nodes, camera_mode=camera)
    t2 = time.perf_counter()
    w, h = info["size"]
    return {**base, "kind": "animation", "size": [w, h], "frames": info["frames"], "fps": fps, "seconds": info["seconds"],
            "line": f"wrote {printable(path)}: {info['frames']} frames {w}x{h} at {fps:g} fps ({info['seconds']:.1f} s), "
                    f"{about}; simulated in {t1 - t0:.1f} s, drawn in {t2 - t1:.1f} s"}


def _render_sheet(lib: Library, target: str, out: str | None, seconds: float | None, fps: float,
                  width: int | None, top: int) -> dict:
    from sanlab.render.strobe import contact_sheet, sheet_layout

    run = lib.get_run(target)
    best = lib.top(run.run_id, top)
    if not best:
        raise ValueError(f"run {run.run_id} has no evaluations yet")
    path = out or f"{run.run_id}_top{len(best)}.png"
    tiles = []
    for e in best:
        _, gait, sc = gait_scene(lib, f"{run.run_id}/{e.rank}", seconds, fps)
        tiles.append((_gait_label(e.rank, gait), sc))
    w = width or DEFAULT_WIDTH["sheet"]
    with output_file(path) as tmp:
        contact_sheet(tiles, _sheet_title(lib, run, len(tiles)), w).save(tmp, format="PNG")
    lay = sheet_layout(len(tiles), w)
    W, H = lay["size"]
    return {"path": path, "kind": "contact sheet", "run_id": run.run_id, "size": [W, H], "gaits": len(tiles),
            "tiles": [lay["rows"], lay["cols"]],
            "line": f"wrote {printable(path)}: contact sheet {W}x{H} of the best {len(tiles)} gaits of run {run.run_id} "
                    f"({lay['rows']} x {lay['cols']} tiles)"}


def _render_modes(lib: Library, target: str, out: str | None, seconds: float | None, fps: float,
                  width: int | None, top: int) -> dict:
    from sanlab.modes import of_run
    from sanlab.render.strobe import contact_sheet, sheet_layout

    run = lib.get_run(target)
    found, _, missing = of_run(lib, run.run_id)
    if not found:
        raise ValueError(f"run {run.run_id} has no modes to draw" + (" (no behaviour descriptors stored)" if missing else ""))
    shown = found[:top]
    path = out or f"{run.run_id}_modes.png"
    tiles = []
    for m in shown:
        _, gait, sc = gait_scene(lib, m.best.gait_id, seconds, fps)
        size = f"{m.size} gait{'s' * (m.size != 1)}"
        tiles.append((f"{m.name} ({size})   {gait.gait_id}  {gait.speed_cm_s:.1f} cm/s", sc))
    w = width or DEFAULT_WIDTH["sheet"]
    title = f"run {run.run_id}: {run.creature}, {len(shown)} of {len(found)} modes (best gait of each)"
    with output_file(path) as tmp:
        contact_sheet(tiles, title, w).save(tmp, format="PNG")
    lay = sheet_layout(len(tiles), w)
    W, H = lay["size"]
    return {"path": path, "kind": "modes sheet", "run_id": run.run_id, "size": [W, H], "modes": [m.name for m in shown],
            "line": f"wrote {printable(path)}: {len(shown)} of {len(found)} modes of run {run.run_id}, {W}x{H}"}


def _render_plot(lib: Library, target: str, plot: str, out: str | None) -> dict:
    from sanlab.render.plots import plot_archive, plot_scores, plot_trace

    run = lib.get_run(target)
    path = out or f"{run.run_id}_{plot}.png"
    if plot == "archive":
        from sanlab.descriptors import UNITS
        from sanlab.search.map_elites import cells

        grid, ranges, best = cells(lib, run.run_id)
        with output_file(path) as tmp:
            info = plot_archive(run, grid.names, ranges, best, tmp, UNITS)
        return {"path": path, "kind": "archive plot", "run_id": run.run_id, "grid": list(grid.names), "cells": info["cells"],
                "filled": info["filled"], "coverage": info["coverage"], "qd_score": info["qd_score"],
                "line": f"wrote {printable(path)}: archive of run {run.run_id} over {' x '.join(grid.names)}, "
                        f"{info['filled']} of {info['cells']} cells, QD-score {info['qd_score']:.4g}"}
    if plot == "scores":
        with output_file(path) as tmp:
            info = plot_scores(run, lib.scores(run.run_id), tmp)
        return {"path": path, "kind": "scores plot", "run_id": run.run_id, "points": info["points"], "best": info["best"],
                "line": f"wrote {printable(path)}: {info['points']} sorted scores of run {run.run_id} (best {info['best']:.3f})"}
    with output_file(path) as tmp:
        info = plot_trace(run, lib.trace(run.run_id), tmp)
    return {"path": path, "kind": "trace plot", "run_id": run.run_id, "points": info["points"], "accepted": info["accepted"],
            "line": f"wrote {printable(path)}: tuning trace of run {run.run_id}, {info['points']} trials, "
                    f"{info['accepted']} accepted"}
