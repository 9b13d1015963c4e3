"""``sanlab render``: contact sheets, plots, default names and bad input, on the cart gaits of
the ``lib_run`` fixture (``tests/conftest.py``); and ``render_top`` behind ``--render DIR``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.cli.render import render_top
from sanlab.library import Library
from sanlab.render import draw, strobe
from sanlab.render.plots import plot_scores, plot_trace
from tests.helpers import FPS

# imageio-ffmpeg starts ffmpeg with subprocess (fork + exec), which JAX warns about: harmless here
pytestmark = pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")
runner = CliRunner()


def cli(*args, cwd=None):
    return runner.invoke(app, ["render", *args])


def test_contact_sheet_has_one_tile_per_gait(lib_run, tmp_path):
    db, run_id = lib_run
    out = tmp_path / "sheet.png"
    r = cli(run_id, "--top", "5", "--out", str(out), "--db", db)
    assert r.exit_code == 0, r.output
    assert "contact sheet" in r.stdout and str(out) in r.stdout
    lay = strobe.sheet_layout(5, 1200)
    assert (lay["cols"], lay["rows"]) == (2, 3)
    with Image.open(out) as im:
        assert im.size == lay["size"]
        img = np.asarray(im.convert("RGB")).astype(int)
    for x0, y0, x1, y1 in lay["boxes"]:
        tile = img[y0:y1, x0:x1]
        label = tile[: lay["label"]]
        pic = tile[lay["label"] :]
        assert (np.abs(label - draw.TEXT).max(-1) < 60).sum() > 20  # the label is written
        creature = [(np.abs(pic - c).max(-1) < 40).sum() for c in (draw.ROOT, draw.LIMBS[0])]
        assert min(creature) > 30, creature  # both links of the newest pose are drawn
    # the sixth slot of the 3 x 2 grid stays empty
    tw, th = lay["tile"]
    x0 = lay["boxes"][1][0]
    y0 = lay["boxes"][4][1]
    assert (np.abs(img[y0 : y0 + th, x0 : x0 + tw] - draw.GRID).max() == 0)


# --------------------------------------------------------------------------- determinism


def test_rendering_twice_gives_identical_files(lib_run, tmp_path):
    db, run_id = lib_run
    for ext in ("gif", "png", "mp4"):
        a, b = tmp_path / f"a.{ext}", tmp_path / f"b.{ext}"
        for path in (a, b):
            r = cli(f"{run_id}/2", "--out", str(path), "--db", db, "--width", "320", "--nodes")
            assert r.exit_code == 0, r.output
        assert a.read_bytes() == b.read_bytes(), ext
        assert a.stat().st_size > 1000


# --------------------------------------------------------------------------- plots


def test_plots_are_written(lib_run, tmp_path):
    db, run_id = lib_run
    with Library(db) as lib:
        info = plot_scores(lib.get_run(run_id), lib.scores(run_id), str(tmp_path / "scores.png"))
        assert info["points"] == 16 and info["best"] == pytest.approx(max(lib.scores(run_id)))
        run = lib.get_run(run_id)
        tune = lib.create_run("tune", run.creature, run.creature_text, {"metric": "distance"}, 0, 20,
                              parent_gait=f"{run_id}/1")
        rng = np.random.default_rng(0)
        best, rows = 0.0, []
        for k in range(20):
            s = float(rng.uniform(0, 0.1))
            rows.append({"trial": k, "score": s, "accepted": s > best})
            best = max(best, s)
        lib.add_trace(tune.run_id, rows)
        info = plot_trace(lib.get_run(tune.run_id), lib.trace(tune.run_id), str(tmp_path / "trace.png"))
        assert info == {"path": str(tmp_path / "trace.png"), "points": 20, "accepted": sum(r["accepted"] for r in rows)}
        with pytest.raises(ValueError, match="no tuning trace"):
            plot_trace(lib.get_run(run_id), lib.trace(run_id), str(tmp_path / "none.png"))
    for name in ("scores.png", "trace.png"):
        with Image.open(tmp_path / name) as im:
            im.load()
            assert im.size[0] > 400 and im.size[1] > 200
            assert len(np.unique(np.asarray(im.convert("RGB")).reshape(-1, 3), axis=0)) > 10  # not blank
    r = cli(tune.run_id, "--plot", "trace", "--out", str(tmp_path / "t2.png"), "--db", db)
    assert r.exit_code == 0 and "20 trials" in r.stdout, r.output
    assert (tmp_path / "t2.png").read_bytes() == (tmp_path / "trace.png").read_bytes()


def test_a_modes_sheet_and_an_archive_plot_of_a_run(lib_run, tmp_path):
    """One tile per mode (sanlab.modes.of_run), named; the archive's heat map agrees with the
    cells it was drawn from."""
    from sanlab.modes import of_run
    from sanlab.search.map_elites import cells

    db, run_id = lib_run
    with Library(db) as lib:
        found, _, _ = of_run(lib, run_id)
        _, _, best = cells(lib, run_id)
    r = cli(run_id, "--modes", "--out", str(tmp_path / "m.png"), "--db", db, "--json")
    assert r.exit_code == 0, r.output
    import json

    info = json.loads(r.stdout)
    assert info["kind"] == "modes sheet" and info["modes"] == [m.name for m in found[:10]]
    with Image.open(tmp_path / "m.png") as im:
        assert tuple(im.size) == tuple(strobe.sheet_layout(len(info["modes"]), 1200)["size"])
    r = cli(run_id, "--plot", "archive", "--out", str(tmp_path / "a.png"), "--db", db, "--json")
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)
    assert info["filled"] == int(np.isfinite(best).sum()) > 0 and info["cells"] == best.size
    assert info["qd_score"] == pytest.approx(float(np.nansum(best)))
    with Image.open(tmp_path / "a.png") as im:
        assert len(np.unique(np.asarray(im.convert("RGB")).reshape(-1, 3), axis=0)) > 10  # not blank


# --------------------------------------------------------------------------- the command


def test_default_output_name_and_summary(lib_run, tmp_path, monkeypatch):
    db, run_id = lib_run
    monkeypatch.chdir(tmp_path)
    r = cli(f"{run_id}/1", "--db", db, "--width", "160")
    assert r.exit_code == 0, r.output
    assert (tmp_path / f"{run_id}_1.gif").exists()
    assert r.stdout.count("\n") == 1 and f"{run_id}_1.gif" in r.stdout and "30 frames" in r.stdout


@pytest.mark.parametrize(
    "args, words",
    [
        (["{run}/99"], "no gait"),
        (["{run}#999"], "no evaluation #999"),
        (["nothex/1"], "malformed gait id"),
        (["{run}/1", "--out", "x.jpg"], "unknown kind '.jpg'"),
        (["{run}", "--out", "x.gif"], "a run is drawn as a contact sheet (.png), not .gif"),
        (["{run}", "--plot", "nope"], "--plot: expected scores, trace or archive"),
        (["{run}/1", "--modes"], "--modes takes a run id"),
        (["{run}", "--modes", "--plot", "scores"], "--modes takes a run id, without --plot"),
        (["{run}/1", "--plot", "scores"], "--plot takes a run id"),
        (["{run}", "--plot", "trace"], "no tuning trace"),
        (["{run}/1", "--camera", "wobbly"], "--camera"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(lib_run, tmp_path, monkeypatch, args, words):
    db, run_id = lib_run
    monkeypatch.chdir(tmp_path)
    r = cli(*[a.format(run=run_id) for a in args], "--db", db)
    assert r.exit_code == 2, r.output
    assert words in r.stderr and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert not list(tmp_path.iterdir())


def test_a_missing_library_is_not_created(tmp_path):
    r = cli("abcd/1", "--db", str(tmp_path / "none.db"))
    assert r.exit_code == 2 and "no such gait library" in r.stderr
    assert not (tmp_path / "none.db").exists()


def test_render_top_writes_gifs_strobes_and_a_sheet(lib_run, tmp_path):
    db, run_id = lib_run
    with Library(db) as lib:
        paths = render_top(lib, run_id, str(tmp_path / "out"), top=2, fps=FPS, width=160)
    names = [p.split("/")[-1] for p in paths]
    assert names == [f"{run_id}_1.gif", f"{run_id}_1.png", f"{run_id}_2.gif", f"{run_id}_2.png", f"{run_id}_top2.png"]
    for p in paths:
        with Image.open(p) as im:
            assert im.size[0] > 0
    with Image.open(paths[0]) as im:
        assert im.n_frames == math.floor(1000 / 33)


def test_the_distance_moved_does_not_depend_on_the_frame_rate(lib_run, tmp_path):
    """The reported displacement is the run's, to its end, not to the last recorded frame."""
    import json

    db, run_id = lib_run
    dx = {}
    for fps in (7, 30):
        r = cli(f"{run_id}/1", "--db", db, "--width", "160", "--fps", str(fps), "--seconds", "4", "-o", str(tmp_path / f"a{fps}.png"),
                "--json")
        assert r.exit_code == 0, r.output
        dx[fps] = json.loads(r.stdout)["replay_dx_m"]  # this replay's; "dx_m" is the stored score's, as in show
    assert abs(dx[7]) > 1e-3  # it moved, so a frame-rate dependence would show
    assert dx[7] == pytest.approx(dx[30], rel=1e-5, abs=1e-7)
    # the line says which number is the score's and which this replay's
    r = cli(f"{run_id}/1", "--db", db, "--width", "160", "--fps", "7", "--seconds", "4", "-o", str(tmp_path / "b.png"))
    words = " ".join(r.output.split())
    assert r.exit_code == 0 and "scored" in words and "this replay" in words and "moved" in words, r.output
