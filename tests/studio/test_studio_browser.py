"""The studio in a browser (Debian's chromium, headless, through Playwright), against a studio
on a free local port over a small library made by the fixtures. Waits are on conditions in the
page, with generous timeouts (the first replay or live run of a creature compiles)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from studio_helpers import SEARCH, screenshot
from typer.testing import CliRunner

from sanlab.gait import Gait
from sanlab.library import Library

pytestmark = pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")


def gait_url(studio, view: str, gait: str) -> str:
    return f"{studio.url}#/{view}/{gait.replace('/', '%2F').replace('#', '%23')}"


def wait_view(pg, name: str) -> None:
    pg.wait_for_selector(f"body[data-view='{name}']")


def test_library_lists_the_runs_and_new_ones_as_they_land(page, library):
    wait_view(page, "library")
    with Library(library["db"]) as lib:
        runs = {r.run_id: r for r in lib.runs()}
    rows = page.locator("#runs tbody tr")
    assert rows.count() == len(runs)
    assert {rows.nth(i).get_attribute("data-run") for i in range(rows.count())} == set(runs)
    row = page.locator(f"#runs tr[data-run='{library['cart']}']")
    assert "cart" in row.inner_text() and f"{SEARCH['controllers']}/{SEARCH['controllers']}" in row.inner_text()
    page.fill("#filter", "fish")
    assert rows.count() == 1 and rows.first.get_attribute("data-run") == library["fish"].split("/")[0]
    page.fill("#filter", "")
    screenshot(page, "studio-library.png")
    # another writer (a `sanlab search` in another process would be the same): the page shows it
    with Library(library["db"]) as lib:
        run = lib.create_run("search", "cart", "name = 'x'", {"metric": "distance"}, seed=9, total=3)
        lib.add_batch(run.run_id, [{"idx": 0, "encoding": "e", "score": 0.5}])
    page.wait_for_selector(f"#runs tr[data-run='{run.run_id}']")
    assert "1/3" in page.locator(f"#runs tr[data-run='{run.run_id}']").inner_text()
    with Library(library["db"]) as lib:
        lib.add_batch(run.run_id, [{"idx": 1, "encoding": "e", "score": 0.7}])
    page.wait_for_function(f"document.querySelector(\"#runs tr[data-run='{run.run_id}']\").innerText.includes('2/3')")


def test_run_grid_shows_as_many_animations_as_asked(page, studio, library):
    page.goto(f"{studio.url}#/run/{library['cart']}")
    wait_view(page, "run")
    tiles = page.locator("#gait-grid .tile")
    page.wait_for_function("document.querySelectorAll('#gait-grid .tile[data-playing]').length === 10")
    assert tiles.count() == 10
    assert [tiles.nth(i).get_attribute("data-gait") for i in range(10)] == [f"{library['cart']}/{k}" for k in range(1, 11)]
    assert tiles.first.inner_text().startswith("#1")
    page.wait_for_timeout(300)
    screenshot(page, "studio-run-grid.png")
    page.fill("#grid-n", "3")
    page.dispatch_event("#grid-n", "change")
    page.wait_for_function("document.querySelectorAll('#gait-grid .tile').length === 3")
    page.click("#grid-more")  # 3 + 10
    page.wait_for_function("document.querySelectorAll('#gait-grid .tile[data-playing]').length === 13")
    # the tiles animate: two looks at a tile's pixels differ
    shot = lambda: page.locator("#gait-grid .tile canvas").first.screenshot()
    a = shot()
    page.wait_for_function("new Promise(r => setTimeout(() => r(true), 400))")
    assert shot() != a


def test_playback_draws_the_root_link_where_the_recorded_trajectory_puts_it(page, studio, library):
    gait = f"{library['cart']}/1"
    page.goto(gait_url(studio, "gait", gait))
    wait_view(page, "gait")
    page.click("#play")  # pause
    n = int(page.get_attribute("#scrub", "max")) + 1
    k = n // 2
    page.evaluate("k => { const s = document.querySelector('#scrub'); s.value = k; s.dispatchEvent(new Event('input')); }", k)
    page.wait_for_function(f"studio.view.lastDraw && studio.view.lastDraw.frame === {k}")
    drawn = page.evaluate("studio.view.lastDraw")
    # the trajectory, recorded here the same way (30 frames per second)
    from sanlab import sim

    with Library(library["db"]) as lib:
        g = Gait.from_library(lib, gait)
    model = g.model()
    r = g.replay(fps=30.0, model=model)
    q = np.asarray(r.frames.q[0])
    assert q.shape[0] == n
    root = np.asarray(sim.poses(model, q[k])["links"])[0]
    assert drawn["t"] == pytest.approx(float(r.frames.t[k]), abs=1e-6)
    assert drawn["root"] == pytest.approx(root.tolist(), abs=1e-4)
    # ... and the pixels: the middle of the root link's long axis (a segment's ends, or the
    # cart outline's A and B, vertices 0 and 2 of A, D, B, C) is drawn in the root's navy
    pts = np.asarray(g.spec.links[0].shape.points)
    mid = (pts[0] + pts[len(pts) // 2]) / 2
    c, s = math.cos(root[2]), math.sin(root[2])
    x, y = root[0] + c * mid[0] - s * mid[1], root[1] + s * mid[0] + c * mid[1]
    # read in one go with the draw it belongs to: the page may have redrawn the same frame at
    # another size (a late layout change on a busy machine) since ``drawn`` was read
    frame, pixel = page.evaluate("""([x, y]) => {
        const l = studio.view.lastDraw, [w, h] = l.size;
        const u = w / 2 + (x - l.center[0]) * l.scale, v = h / 2 - (y - l.center[1]) * l.scale;
        const c = document.querySelector('#stage'), d = window.devicePixelRatio || 1;
        return [l.frame, Array.from(c.getContext('2d').getImageData(Math.round(u * d), Math.round(v * d), 1, 1).data)]; }""",
        [x, y])
    assert frame == k
    assert max(abs(p - q) for p, q in zip(pixel[:3], (30, 58, 110))) < 40, pixel
    # a frame later the root has moved on the page as in the recording
    page.click("#step-fwd")
    page.wait_for_function(f"studio.view.lastDraw.frame === {k + 1}")
    root2 = np.asarray(sim.poses(model, q[k + 1])["links"])[0]
    assert page.evaluate("studio.view.lastDraw.root") == pytest.approx(root2.tolist(), abs=1e-4)


def _live_distances(page, target, drag: bool, settle: float = 1.0, watch: float = 4.0):
    """Run the fish live; after ``settle`` s of simulated time drag the follow point to
    ``target`` (or leave it still); return the centre of mass's distance to ``target`` when the
    drag lands and ``watch`` simulated seconds later, and the live stats."""
    wait_view(page, "live")
    page.wait_for_function(f"studio.view.shown && studio.view.shown.t > {settle}")
    t0 = page.evaluate("studio.view.shown.t")
    if drag:
        page.locator("#live-stage").scroll_into_view_if_needed()
        box = page.locator("#live-stage").bounding_box()
        u0, v0 = page.evaluate("studio.view.toPx(...studio.view.follow)")
        u1, v1 = page.evaluate(f"studio.view.toPx({target[0]}, {target[1]})")
        page.mouse.move(box["x"] + u0, box["y"] + v0)
        page.mouse.down()
        for f in np.linspace(0, 1, 8)[1:]:
            page.mouse.move(box["x"] + u0 + f * (u1 - u0), box["y"] + v0 + f * (v1 - v0))
        page.mouse.up()
        dropped = page.evaluate("studio.view.follow")  # where the page put it
        assert dropped == pytest.approx(list(target), abs=0.15), (dropped, box)
        target = dropped
        # the drag lands in the simulation when a frame carries the new point
        landed = f"studio.view.track.find(r => r[3] !== null && Math.hypot(r[3] - {target[0]}, r[4] - {target[1]}) < 1e-6)"
        page.wait_for_function(f"!!{landed}")
        t0 = page.evaluate(f"{landed}[0]")
    page.wait_for_function(f"studio.view.track.length && studio.view.track[studio.view.track.length - 1][0] > {t0 + watch}")
    track = np.array(page.evaluate("studio.view.track"), dtype=float)
    at = lambda t: track[np.argmin(np.abs(track[:, 0] - t))]
    d = lambda row: float(np.hypot(row[1] - target[0], row[2] - target[1]))
    return d(at(t0)), d(at(t0 + watch)), page.evaluate("studio.view.stats")


@pytest.mark.slow  # about 11 s on 2 busy cores (the pre-commit subset leaves it out)
def test_live_fish_chases_the_dragged_follow_point(page, studio, library, browser):
    target = (1.2, 0.3)  # ahead and to the left of the fish, which starts at the origin facing +x
    page.goto(gait_url(studio, "live", library["fish"]))
    d0, d1, stats = _live_distances(page, target, drag=True)
    screenshot(page, "studio-live.png")
    assert d1 < d0 - 0.2, (d0, d1)  # it swam towards the point
    # with the follow point left still (where it starts), the fish does not go there
    page.goto(studio.url)
    wait_view(page, "library")
    page.goto(gait_url(studio, "live", library["fish"]))
    s0, s1, _ = _live_distances(page, target, drag=False)
    assert abs(s1 - s0) < 0.1 and s1 > d1 + 0.2, (s0, s1, d1)
    # it ran at (about) real time, and the server could have gone faster
    assert stats is not None and stats["ratio"] > 0.5 and stats["capacity"] > 1.0, stats


def test_a_search_from_the_page_equals_the_cli_search(page, studio, library, tmp_path):
    from sanlab.cli import app

    args = dict(SEARCH, seed=5)
    wait_view(page, "library")
    page.select_option("#search-creature", args["creature"])
    page.fill("#search-n", str(args["controllers"]))
    page.fill("#search-seconds", str(args["seconds"]))
    page.fill("#search-seed", str(args["seed"]))
    page.click("#search-start")
    job = page.locator(".job").first
    page.wait_for_function("document.querySelector('.job') && document.querySelector('.job').dataset.status === 'done'")
    run_id = job.locator("a.job-result").inner_text().split()[-1]
    page.wait_for_selector(f"#runs tr[data-run='{run_id}']")  # the library view shows it without a reload
    cli = CliRunner().invoke(app, ["search", args["creature"], "-n", str(args["controllers"]), "--seconds",
                                   str(args["seconds"]), "--seed", str(args["seed"]), "--db",
                                   str(tmp_path / "cli.db"), "--json"])
    assert cli.exit_code == 0, cli.output
    want = [(r["encoding"], r["score"], r["speed_cm_s"]) for r in json.loads(cli.stdout)["top"]]
    with Library(library["db"]) as lib:
        got = [(e.encoding, e.score, e.speed_cm_s) for e in lib.top(run_id, 10)]
        assert lib.get_run(run_id).seed == args["seed"] and lib.count(run_id) == args["controllers"]
    assert got == want


def test_a_job_cancelled_from_the_page_says_how_to_resume_it(page, studio, library):
    wait_view(page, "library")
    page.select_option("#search-creature", "cart")
    page.fill("#search-n", str(12 * 256))
    page.fill("#search-seconds", "1")
    page.fill("#search-seed", "11")
    page.click("#search-start")
    job = page.locator(".job").first
    page.wait_for_function("(() => { const j = document.querySelector('.job');"
                           " return j && j.dataset.status === 'running' && j.querySelector('a'); })()")
    job.locator("button.job-cancel").click()
    page.wait_for_function("document.querySelector('.job').dataset.status === 'cancelled'")
    assert job.locator("button.job-cancel").count() == 0  # an ended job has no button
    run_id = job.locator("a").first.inner_text().split()[-1]
    assert job.locator("code.job-resume").inner_text() == f"sanlab search --resume {run_id}"
    with Library(library["db"]) as lib:
        assert lib.get_run(run_id).status == "interrupted" and 0 < lib.count(run_id) < 12 * 256


def test_bad_input_is_shown_in_the_page_and_changes_nothing(page, studio, library, tmp_path):
    wait_view(page, "library")
    with Library(library["db"]) as lib:
        before = [(r.run_id, r.count) for r in lib.runs()]
    # a malformed message: an error reply, shown; the next request still works
    page.evaluate("studio.api.sendRaw('{\"op\": \"runs\",')")
    page.wait_for_selector("#errors .error:has-text('malformed message: not JSON')")
    assert len(page.evaluate("studio.api.request('runs')")) == len(before)
    # an unparsable creature file: the loader's one-line error, and no run
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "blob"\n[[links]]\nname = "L1"\nmass = -1\n')
    page.set_input_files("#search-file", str(bad))
    page.wait_for_selector("#errors .error:has-text('bad.toml')")
    page.click("#search-start")
    assert page.locator("#errors .error").count() >= 2
    # a gait that is not in this library
    page.goto(gait_url(studio, "gait", "0badf00d/1"))
    page.wait_for_selector("#errors .error:has-text(\"no run '0badf00d'\")")
    wait_view(page, "gait-error")
    with Library(library["db"]) as lib:
        assert [(r.run_id, r.count) for r in lib.runs()] == before
