"""A run's gait modes and its MAP-Elites archive in the studio: the `modes` and `archive`
requests against what ``sanlab.modes`` and ``sanlab.search.map_elites`` compute, their one-line
errors, and the run page showing both (Debian's chromium through Playwright, as in
test_studio_browser.py)."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from studio_helpers import QD_SEARCH, SEARCH, reply, ws_url
from websockets.sync.client import connect

from sanlab import modes
from sanlab.creature import read_source
from sanlab.library import Library
from sanlab.search import map_elites
from sanlab.studio.service import Service, StudioError

pytestmark = pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")


def ask(ws, rid: int, op: str, **args) -> dict:
    ws.send(json.dumps({"id": rid, "op": op, **args}))
    r = reply(ws)
    assert r["id"] == rid
    return r


def test_modes_are_the_runs_modes_best_first(studio, library):
    qd = library["qd"]
    with Library(library["db"]) as lib:
        found, threshold, missing = modes.of_run(lib, qd)
    assert found  # the fixture's search has useful gaits
    with connect(ws_url(studio)) as ws:
        r = ask(ws, 1, "modes", run=qd)
        assert r["ok"], r
        d = r["data"]
        assert (d["run_id"], d["total"], d["missing"]) == (qd, len(found), missing)
        assert d["threshold"] == pytest.approx(threshold)
        assert [(m["name"], m["size"], m["best"]) for m in d["modes"]] == \
            [(m.name, m.size, m.best.gait_id) for m in found[:12]]
        assert d["modes"][0]["speed_cm_s"] == pytest.approx(found[0].best.speed_cm_s)
        assert set(d["modes"][0]["descriptors"]) == set(found[0].summary)
        assert d["units"]["vx_cm_s"] == "cm/s"
        # at most n, the total still counted
        r = ask(ws, 2, "modes", run=qd, n=1)
        assert r["ok"] and len(r["data"]["modes"]) == 1 and r["data"]["total"] == len(found)


def _cells_json(best: np.ndarray) -> list:
    return [[None if math.isnan(v) else v for v in col] for col in best.tolist()]


def test_archive_of_a_map_elites_run_is_its_own_grid(studio, library):
    qd = library["qd"]
    with Library(library["db"]) as lib:
        grid, ranges, best = map_elites.cells(lib, qd)
        elites = map_elites.elites(lib, qd)
        grew = map_elites.progress(lib, qd)
        stats = map_elites.archive_stats(lib, qd)
    assert stats is not None and 0 < len(elites) < best.size  # some cells filled, some empty
    with connect(ws_url(studio)) as ws:
        r = ask(ws, 1, "archive", run=qd)
    assert r["ok"], r
    a = r["data"]
    assert a["own"] is True and a["names"] == list(grid.names) == ["vx_cm_s", "airborne"]
    assert a["units"] == ["cm/s", "fraction"]
    assert a["bins"] == [16, 16] and a["ranges"] == [list(x) for x in ranges]
    assert a["best"] == _cells_json(best)
    assert a["elites"] == elites
    assert all(a["best"][e["cell"][0]][e["cell"][1]] == e["score"] for e in elites)
    assert a["progress"] == grew
    assert [p["evaluations"] for p in grew] == [QD_SEARCH["batch"], QD_SEARCH["controllers"]]  # two generations
    assert a["stats"]["coverage"] == pytest.approx(stats["coverage"]) == pytest.approx(len(elites) / best.size)
    assert a["stats"]["qd_score"] == pytest.approx(stats["qd_score"])
    assert (a["stats"]["elites"], a["stats"]["cells"]) == (len(elites), best.size)


def test_archive_of_a_random_search_is_binned_into_the_default_grid(studio, library):
    cart = library["cart"]
    with Library(library["db"]) as lib:
        _, _, best = map_elites.cells(lib, cart)
        assert map_elites.archive_stats(lib, cart) is None
    with connect(ws_url(studio)) as ws:
        a = ask(ws, 1, "archive", run=cart)["data"]
    assert a["own"] is False and a["names"] == list(map_elites.DEFAULT_DESCRIPTORS)
    assert a["best"] == _cells_json(best)
    filled = int(np.isfinite(best).sum())
    assert 0 < filled <= SEARCH["controllers"] and a["stats"]["elites"] == filled
    assert a["stats"]["coverage"] == pytest.approx(filled / best.size)
    assert a["progress"][-1]["evaluations"] == SEARCH["controllers"]


def test_bad_modes_and_archive_requests_get_one_line_errors(studio, library):
    before = [(r.run_id, r.count) for r in Library(library["db"]).runs()]
    with connect(ws_url(studio)) as ws:
        for rid, (op, args, fault) in enumerate([
            ("modes", {"run": "deadbeef"}, "no run 'deadbeef'"),
            ("archive", {"run": "deadbeef"}, "no run 'deadbeef'"),
            ("archive", {"run": ""}, "no run ''"),
            ("modes", {"run": 7}, "'run' must be a string"),
            ("archive", {}, "missing argument 'run'"),
            ("modes", {"run": library["qd"], "n": 0}, "modes: 0 is out of range"),
            ("modes", {"run": library["qd"], "n": "all"}, "'n' must be an integer"),
            ("archive", {"run": library["qd"], "n": 3}, "unknown argument 'n'"),
            ("archive", {"run": library["fish"].split("/")[0]}, "is a import run; only a search run has an archive"),
        ], 1):
            r = ask(ws, rid, op, **args)
            assert r["ok"] is False and fault in r["error"] and "\n" not in r["error"], (op, args, r)
        # the server keeps serving
        r = ask(ws, 99, "modes", run=library["qd"])
        assert r["ok"] and r["data"]["total"] > 0
    assert [(r.run_id, r.count) for r in Library(library["db"]).runs()] == before


def test_a_tuning_run_has_neither_and_an_old_run_says_it_has_no_descriptors(library, tmp_path):
    db = str(tmp_path / "copy.db")
    shutil.copy(library["db"], db)  # the shared library stays as the other tests expect it
    text, where = read_source("cart")
    with Library(db) as lib:
        tune = lib.create_run("tune", "cart", text, {"metric": "distance"}, seed=0, total=1,
                              parent_gait=f"{library['cart']}/1")
        old = lib.create_run("search", "cart", text, {"metric": "distance", "seconds": 1.0}, seed=0, total=2)
        lib.add_batch(old.run_id, [{"idx": i, "encoding": lib.top(library["cart"], 1)[0].encoding, "score": 0.5 + i}
                                   for i in range(2)])  # stored as before descriptors: no extra
    svc = Service(db)
    for call in (svc.modes, svc.archive):
        with pytest.raises(StudioError, match=f"run {tune.run_id} is a tuning run"):
            call(tune.run_id)
    m = svc.modes(old.run_id)
    assert (m["total"], m["modes"], m["missing"]) == (0, [], 2)
    a = svc.archive(old.run_id)
    assert a["elites"] == [] and all(v is None for col in a["best"] for v in col) and a["stats"]["coverage"] == 0


# -- in the browser ---------------------------------------------------------------------------------


def wait_view(pg, name: str) -> None:
    pg.wait_for_selector(f"body[data-view='{name}']")


def wait_run(pg, run_id: str) -> None:
    """The page shows run ``run_id``, loaded (a hash change routes after goto returns)."""
    pg.wait_for_function(f"studio.view && studio.view.runId === {json.dumps(run_id)} && document.body.dataset.view === 'run'")


PIXEL = """([i, j]) => { const [u, v] = studio.view.heat.cellPx(i, j), c = document.querySelector('#archive-map'),
    d = window.devicePixelRatio || 1;
    return Array.from(c.getContext('2d').getImageData(Math.round(u * d), Math.round(v * d), 1, 1).data).slice(0, 3); }"""


def test_run_page_shows_modes_and_the_archive_and_a_cell_opens_its_elite(page, studio, library):
    qd = library["qd"]
    with Library(library["db"]) as lib:
        found, _, _ = modes.of_run(lib, qd)
        elites = map_elites.elites(lib, qd)
        _, _, best = map_elites.cells(lib, qd)
    page.goto(f"{studio.url}#/run/{qd}")
    wait_run(page, qd)
    # one looping animation per mode, named, best first
    n = min(12, len(found))
    page.wait_for_function(f"document.querySelectorAll('#mode-grid .tile[data-playing]').length === {n}")
    tiles = page.locator("#mode-grid .tile")
    assert [tiles.nth(i).get_attribute("data-mode") for i in range(n)] == [m.name for m in found[:n]]
    first = tiles.first.inner_text()
    assert first.startswith(found[0].name) and found[0].best.gait_id in first and f"{found[0].size} gait" in first
    assert page.locator("#modes-more").is_hidden() == (len(found) <= 12)
    assert page.locator("#extras-note").is_hidden()
    # the archive: its own grid, labelled; the best cell in the top colour, an empty cell blank
    assert page.locator("#archive-head").inner_text().startswith("Archive (MAP-Elites): 16 \u00d7 16 cells of vx_cm_s by airborne")
    stats = page.locator("#archive-stats").inner_text()
    assert f"{len(elites)} of 256 cells filled" in stats and "QD-score" in stats
    top = max(elites, key=lambda e: e["score"])
    empty = next((i, j) for i in range(16) for j in range(16) if np.isnan(best[i, j]))
    assert page.evaluate(PIXEL, top["cell"]) == [253, 231, 37]  # viridis' top
    assert page.evaluate(PIXEL, list(empty)) == [255, 255, 255]
    # a click on a filled cell opens its elite
    page.locator("#archive-map").scroll_into_view_if_needed()
    u, v = page.evaluate("([i, j]) => studio.view.heat.cellPx(i, j)", top["cell"])
    page.locator("#archive-map").click(position={"x": u, "y": v})
    wait_view(page, "gait")
    assert page.url.endswith(f"#/gait/{top['gait'].replace('#', '%23')}")
    assert top["gait"] in page.locator("h2").inner_text()
    # a mode's tile opens its best gait
    page.go_back()
    wait_run(page, qd)
    page.wait_for_selector("#mode-grid .tile")
    page.locator("#mode-grid .tile").first.click()
    wait_view(page, "gait")
    assert found[0].best.gait_id in page.locator("h2").inner_text()


def test_run_pages_say_which_views_a_run_has(page, studio, library):
    # a random search: its evaluations binned into the default grid
    page.goto(f"{studio.url}#/run/{library['cart']}")
    wait_run(page, library["cart"])
    assert "binned into the default grid" in page.locator("#archive-head").inner_text()
    assert page.locator("#mode-grid .tile").count() > 0
    # an imported gait stored before descriptors: no modes, said so; no archive
    fish = library["fish"].split("/")[0]
    page.goto(f"{studio.url}#/run/{fish}")
    wait_run(page, fish)
    assert "stored before sanlab computed behaviour descriptors" in page.locator("#modes-note").inner_text()
    assert page.locator("#mode-grid .tile").count() == 0
    assert page.locator("#archive").is_hidden()
    assert page.locator("#errors .error").count() == 0
