"""The studio's only door into sanlab: every call it makes into the library, the loader, the
simulator, the search drivers and the renderer goes through this module, so that a change in
those APIs touches this one file.

Everything returned here is plain JSON-able data (dicts, lists, str, int, float, bool, None;
never NaN: a missing or non-finite number is None). Every user-facing failure is raised as a
:class:`StudioError` with one line of text; nothing here writes to the library unless the
request was valid (searches and tunings validate everything before they create a run).

Units as in sanlab: metres, seconds, radians; speeds in cm/s.

Each call opens its own short-lived :class:`~sanlab.library.Library` connection (SQLite
connections belong to one thread, and the server calls from worker threads). The file is in WAL
mode, so these readers never block a ``sanlab search`` writing to the same file, nor wait for it.
"""

from __future__ import annotations

import dataclasses
import math
import os
import threading
import time
from contextlib import contextmanager
from typing import Any, Callable, Iterator

import numpy as np

from sanlab import __version__
from sanlab.creature import CreatureError, builtin_names, loads, printable, read_source
from sanlab.library import Library, LibraryError

# Playback (the run grid and the one-gait view) records this many frames per simulated second:
# the renderer's default, so a gait drawn here and by `sanlab render` replay identically, and
# every replay of one creature and duration shares one compiled rollout.
PLAYBACK_FPS = 30.0
# Live mode streams this many frames per simulated second; with dt = 1 ms a frame is every
# round(1000 / 60) = 17 steps (58.8 frames per simulated second).
LIVE_FPS = 60.0
# Frames simulated per call in live mode (one call of the kernel): 12 frames of 1/60 s, 204 steps
# of 1 ms. A drag takes effect after about one chunk plus the page's buffer (0.4 s).
LIVE_CHUNK = 12
# Terrains live mode offers (vertical plane).
LIVE_TERRAINS = ("flat", "slope", "hill", "rough")
# Work requested from the page is bounded so that a stray click cannot occupy the machine for days.
LIMITS = {"controllers": (1, 100_000), "seconds": (0.05, 120.0), "trials": (1, 100_000),
          "seed": (0, 2**31 - 1), "top": (1, 200), "modes": (1, 200)}
MAX_CREATURE_BYTES = 256 * 1024
RENDER_KINDS = ("gif", "mp4", "png")


class StudioError(Exception):
    """A one-line, user-facing problem with a request (shown in the page as it is)."""


def _num(x: Any, digits: int | None = None) -> float | None:
    """A finite float (rounded to ``digits``) or None: strict JSON has no NaN."""
    if x is None:
        return None
    x = float(x)
    if not math.isfinite(x):
        return None
    return round(x, digits) if digits is not None else x


def _arr(a: Any, digits: int = 5) -> Any:
    """An array as nested lists (a 0-d array as a number), rounded (5 digits: 10 um, 10 urad),
    non-finite as None."""
    a = np.asarray(a, float)
    if np.all(np.isfinite(a)):
        return np.round(a, digits).tolist()
    return [_arr(x, digits) for x in a] if a.ndim else _num(a, digits)  # rare: a blown-up rollout


def _bits(a: Any) -> list:
    """Binary values [F, K] as lists of 0/1 ints."""
    return (np.asarray(a) > 0.5).astype(np.int8).tolist()


def _check_range(name: str, value: Any, kind: type = int) -> Any:
    lo, hi = LIMITS[name]
    if kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok:
        raise StudioError(f"{name}: expected {'an integer' if kind is int else 'a number'}, got {value!r}")
    if not lo <= value <= hi:
        raise StudioError(f"{name}: {value} is out of range [{lo}, {hi}]")
    return kind(value)


class Service:
    """Read and write one gait library; replay gaits; run searches, tunings and live sessions.

    ``path``: the SQLite file (created as an empty library if absent). Raises StudioError if it
    cannot be a gait library.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = os.path.abspath(os.fspath(path))
        with self._lib():
            pass
        self._compiled: dict = {}  # (creature text, terrain kind, overrides) -> sim.Model
        self._lock = threading.Lock()

    @contextmanager
    def _lib(self) -> Iterator[Library]:
        try:
            lib = Library(self.path)
        except LibraryError as e:
            raise StudioError(str(e)) from None
        try:
            yield lib
        except LibraryError as e:
            raise StudioError(str(e)) from None
        except CreatureError as e:  # a stored creature file this sanlab no longer reads
            raise StudioError(str(e)) from None
        finally:
            lib.close()

    # -- the library ---------------------------------------------------------------------------

    def info(self) -> dict:
        """What the page shows in its header and offers in its forms."""
        return {"library": self.path, "version": __version__, "builtins": self.builtins(),
                "terrains": list(LIVE_TERRAINS), "render_kinds": list(RENDER_KINDS), "limits": LIMITS}

    def fingerprint(self) -> list:
        """A cheap summary that changes whenever a run is added or changes status or count:
        [[run_id, status, count, trials], ...]. Polled to push changes to the pages."""
        with self._lib() as lib:
            return [[r.run_id, r.status, r.count, r.trials] for r in lib.runs()]

    def runs(self) -> list[dict]:
        """Every run, newest first: run_id, kind, creature, seed, status, evaluated, total,
        best_score, best_speed_cm_s (of the best gait), created (ISO 8601 UTC), parent (RUN#IDX),
        metric, seconds (evaluation time, s)."""
        out = []
        with self._lib() as lib:
            for r in lib.runs(check_evaluations=True):
                try:
                    best = lib.top(r.run_id, 1)
                except LibraryError:  # its best row is damaged: listed as such, the rest still reads
                    best, r = [], dataclasses.replace(r, status="damaged")
                out.append(self._run_row(r, best[0] if best else None))
        return out

    @staticmethod
    def _run_row(r, best) -> dict:
        return {
            "run_id": r.run_id, "kind": r.kind, "creature": r.creature, "seed": r.seed,
            "status": r.status, "evaluated": r.count, "total": r.total,
            "trials": r.trials, "progress": dict(zip(("done", "planned", "unit"), r.progress)),
            "best_score": _num(best.score) if best else None,
            "best_speed_cm_s": _num(best.speed_cm_s) if best else None,
            "created": r.created, "parent": r.parent_gait,
            "metric": r.params.get("metric"), "seconds": _num(r.params.get("seconds")),
            "method": r.params.get("method"),
        }

    def run(self, run_id: str) -> dict:
        """One run: its row (see :meth:`runs`), its params, every score in idx order (None where
        not a number) and, for a tuning run, its trace [[trial, score, accepted], ...]."""
        with self._lib() as lib:
            r = lib.get_run(run_id)
            best = lib.top(r.run_id, 1)
            row = self._run_row(r, best[0] if best else None)
            row["params"] = _strict(r.params)
            row["scores"] = [_num(s) for s in lib.scores(r.run_id)]
            row["trace"] = [[t.trial, _num(t.score), t.accepted] for t in lib.trace(r.run_id)]
            row["device"], row["dtype"], row["sanlab_version"] = r.device, r.dtype, r.sanlab_version
        return row

    def top(self, run_id: str, n: int = 10) -> list[dict]:
        """The run's best ``n`` gaits, best first (see :meth:`_gait_row`)."""
        n = _check_range("top", n)
        with self._lib() as lib:
            rid = lib.get_run(run_id).run_id
            audits = lib.audits(rid)
            return [self._gait_row(e, rid, audits.get(e.idx)) for e in lib.top(rid, n)]

    @staticmethod
    def _gait_row(e, run_id: str, audit=None) -> dict:
        """resolution_dependent, reproduced: the verdicts of the gait's stored audit (`sanlab
        audit`), None when it was never audited."""
        return {"gait": f"{run_id}/{e.rank}", "id": e.gait_id, "run_id": run_id, "rank": e.rank,
                "score": _num(e.score), "speed_cm_s": _num(e.speed_cm_s), "fell": e.fell,
                "nonfinite": e.nonfinite, "parent": e.parent,
                "audit": None if audit is None else audit.verdict,
                "resolution_dependent": None if audit is None else audit.resolution_dependent,
                "reproduced": None if audit is None else audit.reproduced}

    def modes(self, run_id: str, n: int = 12) -> dict:
        """The run's gait modes (``sanlab.modes.of_run``, as `sanlab modes` groups them), best
        first: {run_id, modes: the first ``n`` [{name, size, best (RUN#IDX), score, speed_cm_s,
        signature, turns, descriptors (medians), duty}], total (modes found), threshold (the
        score a gait needs to be grouped), missing (useful gaits stored without descriptors: a
        run stored before sanlab computed them), units (of the descriptors)}. A tuning run has
        no modes (its gaits are one gait's tuned copies): StudioError."""
        from sanlab.descriptors import UNITS
        from sanlab.modes import of_run

        n = _check_range("modes", n)
        with self._lib() as lib:
            r = lib.get_run(run_id)
            if r.kind == "tune":
                raise StudioError(f"modes: run {r.run_id} is a tuning run (one gait's tuned copies): it has no modes")
            try:
                found, threshold, missing = of_run(lib, r.run_id)
            except ValueError as e:
                raise StudioError(f"modes of run {r.run_id}: {e}") from None
        rows = []
        for m in found[:n]:
            row = m.to_json()
            del row["gaits"]  # the members' ids: the size says enough, and a big run has thousands
            rows.append(_strict(row))
        return {"run_id": r.run_id, "modes": rows, "total": len(found), "threshold": _num(threshold),
                "missing": int(missing), "units": dict(UNITS)}

    def archive(self, run_id: str) -> dict:
        """A search run's MAP-Elites archive, rebuilt from its stored evaluations
        (``sanlab.search.map_elites``): a map-elites run's own grid, any other search's
        evaluations binned into the default grid (``own`` false). {run_id, own, names (the two
        descriptors), units, bins [bx, by], ranges [[lo, hi], [lo, hi]], best [bx][by] (each
        cell's best score, None where empty), elites [{cell [i, j], gait RUN#IDX, score,
        measures [x, y]}], progress [{evaluations, coverage, qd_score}] (after each generation),
        stats {elites, cells, coverage (share of cells filled), qd_score (sum of the elites'
        scores)}}. Tuning and imported runs have none: StudioError."""
        from sanlab.descriptors import UNITS
        from sanlab.search import map_elites

        with self._lib() as lib:
            r = lib.get_run(run_id)
            if r.kind != "search":
                raise StudioError(f"archive: run {r.run_id} is a {'tuning' if r.kind == 'tune' else r.kind} run; "
                                  "only a search run has an archive")
            try:
                v = map_elites.view(lib, r.run_id)  # one rebuild of the archive for all of it
            except ValueError as e:
                raise StudioError(f"archive of run {r.run_id}: {e}") from None
        best = np.asarray(v["best"], float)
        grid = v["grid"]
        stats = {**v["stats"], "cells": int(best.size)}
        return _strict({
            "run_id": r.run_id, "own": v["own"], "names": list(grid.names),
            "units": [UNITS.get(k, "") for k in grid.names], "bins": [int(b) for b in best.shape],
            "ranges": [[lo, hi] for lo, hi in grid.ranges], "best": best.tolist(), "elites": v["elites"],
            "progress": v["progress"], "stats": stats})

    # -- designs (`sanlab design`) --------------------------------------------------------------

    def design_fingerprint(self) -> list:
        """[[design_id, status, scores], ...]: changes whenever a design scores a body or changes
        status (polled beside :meth:`fingerprint`)."""
        with self._lib() as lib:
            return [[d.design_id, d.status, d.scores] for d in lib.designs()]

    def designs(self) -> list[dict]:
        """Every design (``sanlab design``), newest first: design_id, creature, source, status,
        created, updated (ISO 8601 UTC), free (the free numbers' names), bodies (bodies of the
        search scored, the reference not counted), planned (bodies the search asks), best_speed_cm_s
        (the best robust tuned speed of the search, cm/s; None before any), reference_cm_s (the
        reference's on the search's seed), chosen (a body was chosen: the design is done). A
        damaged design is listed with status "damaged" and what of it could be read."""
        out = []
        with self._lib() as lib:
            for d in lib.designs():
                try:
                    seed, _ = _design_seeds(d, lib.path) if d.status != "damaged" else (0, [])
                    scores = [x for x in lib.design_scores(d.design_id) if x.seed == seed] if d.status != "damaged" else []
                except (LibraryError, StudioError):
                    scores, d = [], dataclasses.replace(d, status="damaged")
                search = [x.speed_cm_s for x in scores if x.round >= 0]
                ref = [x.speed_cm_s for x in scores if x.round < 0]
                out.append({"design_id": d.design_id, "creature": d.creature, "source": d.source, "status": d.status,
                            "created": d.created, "updated": d.updated, "free": [f.get("name") for f in d.free],
                            "bodies": len(search), "planned": d.settings.get("designs"),
                            "best_speed_cm_s": _num(max(search)) if search else None,
                            "reference_cm_s": _num(ref[0]) if ref else None, "chosen": d.chosen is not None})
        return _strict(out)

    def design(self, design_id: str) -> dict:
        """One design, for its scatter: {design_id, creature, source, status, created, updated,
        settings (``sanlab.design.DesignSettings``'s fields), seed (the search's), seeds (the
        validation's), free [{name, path, min, max, default, unit}] (the file's units), chosen
        {round, index} or None (not done yet), seconds (wall time of the run that finished it, s,
        or None), points}. ``points``: each body scored so far, the reference first, then by
        round and place: {body ("reference" or "rROUNDbINDEX", as `sanlab design` names it: "r2b0"), round (-1: the reference), index,
        values [D] (its free values, in the order of ``free``), score (its robust tuned speed on
        the search's seed, cm/s; None not yet scored), pruned (phase 2 skipped: score 0), invalid
        (why the body could not be built, the loader's message, or None: an invalid body is pruned), gait
        (its robust gait RUN#IDX, None where no rung kept its speed), open and open_kind (the gait
        a click shows: the robust gait, else its best chain's "tuned" gait, else its phase-1
        search's best, "phase 1"; None where none is in this library), validation {seed: cm/s}
        (validated bodies and the reference), validation_mean (cm/s or None), reference, chosen
        (bools)}. A design not in this library, or damaged: StudioError."""
        if not isinstance(design_id, str):
            raise StudioError(f"expected a design id (8 hex digits), got {_short(repr(design_id))}")
        if len(design_id) > MAX_ID:  # never echoed back whole: a page shows the message
            raise StudioError(f"no design {printable(design_id[:16])!r}... in {self.path}: expected a design id of 8 "
                              f"hex digits (or their first few), got one of {len(design_id):,} characters")
        with self._lib() as lib:
            d = lib.get_design(design_id)
            rows = lib.design_scores(d.design_id)
            seed, seeds = _design_seeds(d, lib.path)
            seconds = (d.result or {}).get("seconds")
            if seconds is not None and (isinstance(seconds, bool) or not isinstance(seconds, int | float)):
                raise _damaged(lib.path, f"design {d.design_id}", f"its result: seconds: a number was expected, "
                                                                  f"it holds {_short(repr(seconds))}")
            bodies: dict[tuple[int, int], list] = {}
            for x in rows:
                bodies.setdefault((x.round, x.index), []).append(x)
            points = []
            for (rnd, idx), scored in bodies.items():
                by_seed = {x.seed: x for x in scored}
                mine = by_seed.get(seed)
                valid = {str(k): _num(x.speed_cm_s) for k, x in by_seed.items() if k != seed}
                means = [by_seed[k].speed_cm_s for k in seeds if k in by_seed]
                opened, kind = self._design_gait(lib, [x for x in (mine, *(by_seed.get(k) for k in seeds)) if x is not None])
                points.append({
                    "body": "reference" if rnd < 0 else f"r{rnd}b{idx}", "round": rnd, "index": idx,
                    "values": list(scored[0].values), "score": None if mine is None else _num(mine.speed_cm_s),
                    "pruned": bool(mine is not None and mine.pruned), "gait": None if mine is None else mine.gait,
                    "invalid": None if mine is None else mine.record.get("invalid"),
                    "open": opened, "open_kind": kind, "validation": valid,
                    "validation_mean": _num(float(np.mean(means))) if seeds and len(means) == len(seeds) else None,
                    "reference": rnd < 0, "chosen": d.chosen == (rnd, idx)})
        return _strict({
            "design_id": d.design_id, "creature": d.creature, "source": d.source, "status": d.status,
            "created": d.created, "updated": d.updated, "settings": d.settings, "seed": seed, "seeds": seeds,
            "free": [dict(f) for f in d.free],
            "chosen": None if d.chosen is None else {"round": d.chosen[0], "index": d.chosen[1]},
            "seconds": _num(seconds), "points": points})

    @staticmethod
    def _design_gait(lib, scores) -> tuple[str | None, str | None]:
        """The gait a body's point opens, from its scores (the search's seed first): its robust
        gait; else its best chain's tuned gait; else the best of its phase-1 search; (None, None)
        where none is in the library."""
        for x in scores:
            if x.gait:
                return x.gait, "robust"
        for x in scores:
            chains = [c for c in x.record.get("chains") or [] if isinstance(c, dict) and isinstance(c.get("tuned"), str)]
            if chains:
                speed = lambda c: float(c["tuned_cm_s"]) if isinstance(c.get("tuned_cm_s"), (int, float)) else -math.inf
                best = max(chains, key=speed)
                return best["tuned"], "tuned"
        for x in scores:
            search = x.record.get("search")
            if isinstance(search, str):
                try:
                    top = lib.top(search, 1)
                except LibraryError:
                    continue
                if top:
                    return top[0].gait_id, "phase 1"
        return None, None

    def export(self, gait_id: str) -> dict:
        """The gait as `sanlab export` writes it."""
        with self._lib() as lib:
            return lib.export_gait(_gait_id(gait_id))

    # -- replay --------------------------------------------------------------------------------

    def _gait(self, lib, gait_id: str):
        from sanlab.gait import Gait

        return Gait.from_library(lib, _gait_id(gait_id))

    def playback(self, gait_id: str) -> dict:
        """Replay a gait (the same compiled step as the search, recording PLAYBACK_FPS frames
        per second for its run's evaluation time) and return all a page needs to draw it:

        gait: the gait's row plus encoding, params, run_params, kind ("san" or "pattern") and
        ceiling (the creature's pattern ceiling, ``sanlab.search.ceiling.find``, with the
        ``fraction`` of it this gait's speed is; None when none is stored); creature: see :func:`geometry`;
        frames: t [F] s, links [F, L, 3] (origin x, y m, absolute angle rad), contacts [F, C, 2],
        touching [F, C] (0/1), com [F, 2], bits [F, S], nodes [F, H + A] (0/1), u [F, A] in
        [0, 1], follow [F, 2] or None; terrain: the ground (see :func:`terrain_profile`).
        """
        from sanlab.render.scene import scene

        with self._lib() as lib:
            e = lib.gait(_gait_id(gait_id))
            gait = self._gait(lib, e.gait_id)
            row = self._gait_row(e, e.run_id, lib.audit(e.gait_id))
            run_params = lib.get_run(e.run_id).params
            from sanlab.search.ceiling import find

            c = find(lib, gait.creature_text, gait.metric, gait.seconds)
            row["ceiling"] = None if c is None else _strict({**c.to_json(), "fraction": c.fraction(e.speed_cm_s)})
        try:
            sc = scene(gait, None, PLAYBACK_FPS)
        except ValueError as err:  # e.g. too short to record a frame
            raise StudioError(f"cannot replay {gait_id}: {err}") from None
        row.update(encoding=gait.san.encode(gait.weights), params=_strict(gait.params.to_json()), kind=gait.kind,
                   run_params=_strict(run_params), creature=gait.spec.name,
                   seconds=gait.seconds, metric=gait.metric)
        x0, _, x1, _ = sc.bounds()
        return {
            "gait": row,
            "creature": geometry(gait, sc.model),
            "frames": {
                "fps": PLAYBACK_FPS, "t": _arr(sc.t), "links": _arr(sc.links), "contacts": _arr(sc.contacts),
                "touching": _bits(sc.depth > 0), "com": _arr(sc.com), "bits": _bits(sc.bits),
                "nodes": _bits(sc.nodes), "u": _arr(sc.u, 3),
                "follow": None if sc.follow is None else _arr(sc.follow),
            },
            "terrain": terrain_profile(sc.model, x0 - 4.0, x1 + 4.0),
        }

    def render(self, gait_id: str, kind: str, out_dir: str) -> str:
        """Render a gait with sanlab's renderer into ``out_dir``: an animation (gif, mp4) or a
        strobe picture (png), as `sanlab render` does. Returns the file's path."""
        if kind not in RENDER_KINDS:
            raise StudioError(f"render: expected one of {', '.join(RENDER_KINDS)}, got {kind!r}")
        from sanlab.render.film import animate
        from sanlab.render.scene import gait_title, scene
        from sanlab.render.strobe import write_strobe

        with self._lib() as lib:
            e = lib.gait(_gait_id(gait_id))
            gait = self._gait(lib, e.gait_id)
        try:  # as `sanlab render` draws it: the run's evaluation time, titled with the rank
            sc = scene(gait, None, PLAYBACK_FPS, gait_title(gait, e.rank))
        except ValueError as err:
            raise StudioError(f"render: {err}") from None
        os.makedirs(out_dir, exist_ok=True)
        path = os.path.join(out_dir, f"{e.run_id}_{e.rank}.{kind}")
        if kind == "png":
            write_strobe(sc, path)
        else:
            animate(sc, path)
        return path

    # -- creatures -----------------------------------------------------------------------------

    def builtins(self) -> list[dict]:
        """The built-in creatures: name, description, plane, eyes (has eye sensors), seconds."""
        out = []
        for name in builtin_names():
            text, where = read_source(name)
            out.append(_creature_row(loads(text, where)))
        return out

    def check_creature(self, text: Any, filename: Any = "uploaded.toml") -> dict:
        """Validate a creature file's text with the loader (the same one-line errors as
        `sanlab check`); returns its summary. Raises StudioError with the loader's message."""
        if not isinstance(text, str):
            raise StudioError("creature file: expected the file's text")
        if not isinstance(filename, str) or not filename.strip():
            filename = "uploaded.toml"
        if len(text.encode("utf-8", "replace")) > MAX_CREATURE_BYTES:
            raise StudioError(f"{filename}: too large for a creature file (over {MAX_CREATURE_BYTES // 1024} KiB)")
        try:
            return _creature_row(loads(text, filename))
        except CreatureError as e:
            raise StudioError(str(e)) from None

    # -- work ----------------------------------------------------------------------------------

    def prepare_search(self, *, creature: Any = None, text: Any = None, filename: Any = None,
                       controllers: Any = 200, seconds: Any = None, seed: Any = 0) -> dict:
        """Validate a phase-1 search request (a built-in name, or a file's text) without
        touching the library; returns the arguments for :meth:`search`."""
        if (creature is None) == (text is None):
            raise StudioError("search: give a built-in creature or a creature file (one of them)")
        if creature is not None:
            if not isinstance(creature, str) or creature not in builtin_names():
                raise StudioError(f"search: no built-in creature {creature!r} "
                                  f"(built-ins: {', '.join(builtin_names())})")
            text, where = read_source(creature)
        else:
            where = filename if isinstance(filename, str) and filename.strip() else "uploaded.toml"
        summary = self.check_creature(text, where)
        args = {"text": text, "where": where, "controllers": _check_range("controllers", controllers),
                "seed": _check_range("seed", seed),
                "seconds": None if seconds is None else _check_range("seconds", seconds, float)}
        return {"args": args, "creature": summary["name"]}

    def search(self, args: dict, reporter: Callable[[dict], None]) -> str:
        """Run a phase-1 search (``args`` from :meth:`prepare_search`) as `sanlab search` does,
        committing each batch; ``reporter`` gets {run_id, done, total, best, rate, finished} after
        each batch (``finished``: the run has ended); an exception it raises stops the search,
        which leaves the run interrupted (resumable) and re-raises it. Returns the run id."""
        from sanlab.search import run_search

        def report(p) -> None:
            reporter({"run_id": p.run_id, "done": p.evaluated, "total": p.total,
                      "best": _num(p.best), "rate": _num(p.rate), "finished": p.done})

        with self._lib() as lib:
            lib.check_intact()  # a damaged file takes no new run
            try:
                return run_search(lib, args["text"], args["where"], controllers=args["controllers"],
                                  seconds=args["seconds"], seed=args["seed"], reporter=report)
            except ValueError as e:
                raise StudioError(f"search: {e}") from None

    def prepare_tune(self, *, gait: Any, method: Any = "sa", trials: Any = 1000, seed: Any = 0,
                     terrain: Any = "flat") -> dict:
        """Validate a tuning request without touching the library; returns :meth:`tune`'s args."""
        from sanlab.search.tune import METHODS, TERRAINS

        if method not in METHODS:
            raise StudioError(f"tune: method must be one of {', '.join(METHODS)}, not {method!r}")
        if terrain not in TERRAINS:
            raise StudioError(f"tune: terrain must be one of {', '.join(TERRAINS)}, not {terrain!r}")
        with self._lib() as lib:
            e = lib.gait(_gait_id(gait))
            g = self._gait(lib, e.gait_id)
        if terrain != "flat" and g.spec.world.plane != "vertical":
            raise StudioError("tune: only creatures in the vertical plane walk on terrain")
        return {"gait": e.gait_id, "method": method, "trials": _check_range("trials", trials),
                "seed": _check_range("seed", seed), "terrain": terrain}

    def tune(self, args: dict, reporter: Callable[[dict], None]) -> str:
        """Tune one gait (``args`` from :meth:`prepare_tune`) as `sanlab tune` does; ``reporter``
        gets {run_id, done, total, best, rate, finished} after each round (run_id: the tuning
        run's, as a search job reports its run; an exception it raises stops the tuning as for
        :meth:`search`). Returns the tuned gait's id RUN#0."""
        from sanlab.search.tune import tune

        def report(p) -> None:
            reporter({"run_id": p.run_ids[0] if p.run_ids else None, "done": p.trials, "total": p.total,
                      "best": _num(p.best), "rate": _num(p.rate), "finished": p.done})

        with self._lib() as lib:
            lib.check_intact()  # a damaged file takes no new run
            try:
                res = tune(lib, [args["gait"]], method=args["method"], trials=args["trials"],
                           seed=args["seed"], terrain=args["terrain"], reporter=report)
            except ValueError as e:
                raise StudioError(f"tune: {e}") from None
        return res[0].tuned_gait

    # -- live ----------------------------------------------------------------------------------

    def live(self, gait_id: str, terrain: str | None = None) -> "LiveSession":
        """A live session of a gait (see :class:`LiveSession`)."""
        with self._lib() as lib:
            e = lib.gait(_gait_id(gait_id))
            gait = self._gait(lib, e.gait_id)
            row = self._gait_row(e, e.run_id)
        return LiveSession(self, gait, row, terrain)

    def _model(self, gait, terrain: str | None):
        """The compiled creature of ``gait`` on ``terrain`` (None: its own), cached: building a
        model is cheap, but equal models let the rollout reuse its compiled program."""
        spec = gait.spec
        if terrain is not None and spec.world.plane == "vertical":
            spec = dataclasses.replace(spec, world=dataclasses.replace(spec.world, terrain=_terrain(terrain)))
        key = (spec, repr(sorted(gait.params.model.items())))
        with self._lock:
            if key not in self._compiled:
                self._compiled[key] = dataclasses.replace(gait, spec=spec).model()
            return self._compiled[key]


def _terrain(kind: str):
    """The grounds live mode offers: a 5-degree slope up in +x; a smooth hill 8 cm high and 1 m
    wide 0.7 m ahead; rough ground of RMS height 1.5 cm and shortest wavelength 25 cm (the ground
    `sanlab tune --terrain rough` uses first)."""
    from sanlab.creature import Terrain

    if kind not in LIVE_TERRAINS:
        raise StudioError(f"terrain: expected one of {', '.join(LIVE_TERRAINS)}, got {kind!r}")
    return {
        "flat": Terrain(),
        "slope": Terrain(kind="slope", angle=math.radians(5.0)),
        "hill": Terrain(kind="hill", height=0.08, width=1.0, center=0.7),
        "rough": Terrain(kind="rough", height=0.015, wavelength=0.25, seed=1),
    }[kind]


class LiveSession:
    """A gait running in real time, chunk by chunk, on the simulator's kernel.

    Each :meth:`step` continues the run exactly where the last one ended, for LIVE_CHUNK frames
    of 1/LIVE_FPS s, through ``sim.rollout(..., state0=, cstate0=)``: a chunk is one call of the
    kernel, so the live run is the replay's run, bit for bit. For a creature with a follow point the point is
    held still where the user put it (:meth:`set_follow`), by overriding the model's follow table
    through its parameters (no recompilation); it starts at the start of the creature's follow
    path. :meth:`set_terrain` changes the ground (vertical plane) and starts the creature again
    from rest: its old pose may lie under the new ground.
    """

    def __init__(self, service: Service, gait, row: dict, terrain: str | None):
        from sanlab import sim

        self.service, self.gait, self.row = service, gait, row
        self.spec = gait.spec
        self.vertical = self.spec.world.plane == "vertical"
        self.terrain = None
        self.params = gait.san_params()  # one controller: a batch of one
        base = service._model(gait, None)
        self.has_follow = bool(base.structure.follow)
        self.dt = float(base.structure.dt)
        self.every = max(1, int(round(1.0 / (LIVE_FPS * self.dt))))
        self.steps = self.every * LIVE_CHUNK
        self.frame_dt = self.every * self.dt
        self.follow: tuple[float, float] | None = None
        if self.has_follow:
            fx, fy = sim.follow_point(base, 0.0)
            self.follow = (float(fx), float(fy))
        self.set_terrain(terrain)

    @property
    def chunk_seconds(self) -> float:
        return self.steps * self.dt

    def check_terrain(self, terrain: str | None) -> None:
        """Raise StudioError unless :meth:`set_terrain` would take ``terrain`` (changes nothing)."""
        if terrain is not None and not self.vertical:
            raise StudioError("terrain: this creature lives in the horizontal plane (no ground to change)")
        if terrain is not None:
            _terrain(terrain)

    def set_terrain(self, terrain: str | None) -> None:
        self.check_terrain(terrain)  # before changing anything
        self.terrain = terrain
        self.model = self.service._model(self.gait, terrain)
        self.reset()

    def reset(self) -> None:
        """Back to the creature's start pose, at rest, with the controller's initial state."""

        self.state = None  # the creature's start at rest (sim.rollout's default)
        self.cstate = None
        self.t = 0.0

    def set_follow(self, x: Any, y: Any) -> None:
        if not self.has_follow:
            raise StudioError("this creature has no follow point (it has no eyes)")
        for v in (x, y):
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or abs(v) > 1e4:
                raise StudioError(f"follow point: expected two numbers within 10 km of the origin (m), got {x!r}, {y!r}")
        self.follow = (float(x), float(y))

    def _stepped_model(self):
        if not self.has_follow:
            return self.model
        m = self.model
        table = np.broadcast_to(np.asarray(self.follow, m.dtype), np.shape(m.params.follow))
        return m.with_params(follow=table, follow_speed=np.zeros((), m.dtype))

    def step(self) -> dict:
        """Simulate the next LIVE_CHUNK frames. Returns {t [K] s, links [K, L, 3], contacts,
        touching, com, bits, nodes, follow [2] or None, finite, compute_s (wall time of this
        call)}; a run that went non-finite starts again from rest."""
        from sanlab import sim

        t0 = time.perf_counter()
        follow = self.follow
        model = self._stepped_model()
        r = sim.rollout(model, self.gait.san, self.params, steps=self.steps, record_fps=LIVE_FPS, state0=self.state,
                        cstate0=self.cstate)
        assert r.frames is not None
        q = r.frames.q[0]
        finite = bool(r.finite[0]) and bool(np.all(np.isfinite(q)))
        t = self.t + np.arange(q.shape[0]) * self.frame_dt
        if not finite:
            self.reset()
            return {"t": _arr(t), "finite": False, "compute_s": time.perf_counter() - t0}
        self.state, self.cstate, self.t = r.state, r.cstate, float(r.state.t[0])
        P = sim.poses(model, q)
        return {
            "t": _arr(t), "links": _arr(P["links"]), "contacts": _arr(P["contacts"]),
            "touching": _bits(P["depth"] > 0), "com": _arr(P["com"]),
            "bits": _bits(r.frames.bits[0]), "nodes": _bits(r.frames.cstate.out[0]),
            "follow": None if follow is None else [follow[0], follow[1]], "finite": True,
            "compute_s": time.perf_counter() - t0,
        }

    def describe(self) -> dict:
        """What the page needs to draw this session: gait row, creature geometry, terrain."""
        return {"gait": self.row, "creature": geometry(self.gait, self.model), "terrain_kind": self.terrain,
                "terrain": terrain_profile(self.model, -12.0, 12.0), "frame_dt": self.frame_dt,
                "chunk": LIVE_CHUNK, "follow": None if self.follow is None else list(self.follow),
                "vertical": self.vertical}


# -- drawing data ----------------------------------------------------------------------------


def geometry(gait, model) -> dict:
    """A creature's drawing data (link frames, SI): name, plane, links [{name, kind (segment,
    polygon, point), points [[x, y], ...] (scaled as tuned), parent (index or None)}],
    touch [{sensor, contact}] (contact index into the frames' contacts), eyes [{sensor, link,
    at [x, y], axis [from, to] or None, min, max (rad)}], springs and muscles (linear actuators)
    [{a: [link, [x, y]], b: ..., actuator}], sensors / hidden / actuators: names of the raster's
    rows, follow_path [[x, y], ...] or None, size (m, the largest link extent)."""
    spec = gait.spec
    names = {l.name: i for i, l in enumerate(spec.links)}
    scale = gait.params.scale
    p = model.params
    links = []
    for i, l in enumerate(spec.links):
        k = float(scale[i]) if scale else 1.0
        pts = [[x * k, y * k] for x, y in l.shape.points] if l.shape.kind != "point" else [[0.0, 0.0]]
        links.append({"name": l.name, "kind": l.shape.kind, "points": _arr(pts),
                      "parent": None if l.parent is None else names[l.parent]})
    contact_index, k = {}, 0
    for i, l in enumerate(spec.links):
        for j in range(len(l.contacts)):
            contact_index[(i, j)] = k
            k += 1
    touch, eyes = [], []
    sens_min, sens_max, sens_pts = (np.asarray(a, float) for a in (p.sens_min, p.sens_max, p.sens_pts))
    for s_i, s in enumerate(spec.sensors):
        if s.kind == "touch":
            touch.append({"sensor": s_i, "contact": contact_index[(names[s.link], s.contact)]})
        elif s.kind == "eye":
            eyes.append({"sensor": s_i, "link": names[s.at.link], "at": _arr(sens_pts[s_i, 0]),
                         "axis": [names[s.axis[0]], names[s.axis[1]]] if s.axis else None,
                         "min": _num(sens_min[s_i], 5), "max": _num(sens_max[s_i], 5)})

    def ref(r):
        i = names[r.link]
        k = float(scale[i]) if scale else 1.0
        return [i, [r.at[0] * k, r.at[1] * k]]

    springs = [{"a": ref(s.a), "b": ref(s.b)} for s in spec.springs]
    muscles = [{"a": ref(a.a), "b": ref(a.b), "actuator": i} for i, a in enumerate(spec.actuators) if a.kind == "linear"]
    san = gait.san
    size = max([abs(c) for l in links for pt in l["points"] for c in pt] + [0.05])
    return {
        "name": spec.name, "plane": spec.world.plane, "links": links, "touch": touch, "eyes": eyes,
        "springs": springs, "muscles": muscles,
        "sensors": [s.name for s in spec.sensors],
        "hidden": [f"H{i + 1}" for i in range(san.n_hidden)],
        "actuators": [a.name for a in spec.actuators],
        "follow_path": _arr(np.asarray(p.follow)[::4]) if model.structure.follow else None,
        "size": size,
    }


def terrain_profile(model, x0: float, x1: float) -> dict:
    """The ground under [x0, x1] (m): {kind, x0, dx, h [n] (m)} sampled every 2 cm, or
    {kind: "none"} in the horizontal plane."""
    from sanlab.sim import terrain_height

    st = model.structure
    if st.plane != "vertical":
        return {"kind": "none"}
    if st.terrain == "flat":
        return {"kind": "flat"}
    n = int(min(4000, max(2, (x1 - x0) / 0.02)))
    xs = np.linspace(x0, x1, n)
    h, _ = terrain_height(model, xs)
    h = np.broadcast_to(np.asarray(h, float), xs.shape)
    return {"kind": st.terrain, "x0": float(x0), "dx": float(xs[1] - xs[0]), "h": _arr(h, 4)}


def _creature_row(c) -> dict:
    return {"name": c.name, "description": c.description, "plane": c.world.plane,
            "eyes": any(s.kind == "eye" for s in c.sensors), "seconds": c.evaluation.seconds,
            "links": len(c.links), "sensors": len(c.sensors), "actuators": len(c.actuators)}


# Characters of an id a request may give: a run or design id is 8 hex digits, a gait id a few more
# (RUN/RANK, RUN#IDX); a longer one is no id, and is never echoed back whole.
MAX_ID = 64


def _short(text: str, keep: int = 40) -> str:
    """``text`` cut to ``keep`` characters with "..." and its length: what a message quotes of
    something a request sent, however long."""
    return text if len(text) <= keep else f"{text[:keep]}... ({len(text):,} characters)"


def _damaged(path: str, what: str, why: str) -> StudioError:
    """The library's message for a damaged record (``Library._damaged``), for damage only the
    studio's reading finds: a cell of the right JSON type holding the wrong thing."""
    return StudioError(f"{path}: {what} is damaged ({why}); the rest of the library is intact: "
                       "restore this file from a backup to read it, or leave it be")


def _design_seeds(d, path: str) -> tuple[int, list[int]]:
    """A design's seeds from its stored settings: the search's (``seed``, default 0) and the
    validation's (``seeds``); StudioError naming the design as damaged where they are not
    integers."""
    seed, seeds = d.settings.get("seed", 0), d.settings.get("seeds") or []
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise _damaged(path, f"design {d.design_id}", f"its settings: seed: an integer was expected, it holds "
                                                      f"{_short(repr(seed))}")
    if not isinstance(seeds, list) or not all(isinstance(x, int) and not isinstance(x, bool) for x in seeds):
        raise _damaged(path, f"design {d.design_id}", f"its settings: seeds: a list of integers was expected, it "
                                                      f"holds {_short(repr(seeds))}")
    return seed, list(seeds)


def _gait_id(gait_id: Any) -> str:
    if not isinstance(gait_id, str):
        raise StudioError(f"expected a gait id RUN/RANK or RUN#IDX, got {gait_id!r}")
    return gait_id


def _strict(obj: Any) -> Any:
    """``obj`` with NaN and infinities as None (strict JSON)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): _strict(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_strict(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _strict(obj.tolist())
    if isinstance(obj, np.generic):
        return _strict(obj.item())
    return obj
