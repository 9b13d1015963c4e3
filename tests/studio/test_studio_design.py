"""A design run (`sanlab design`) in the studio: the `designs` and `design` requests against what
the library stores, the gait a body's point opens, their one-line errors, and (Debian's chromium
through Playwright, as in test_studio_browser.py) the library listing a design and the design
page's scatter, whose points open their bodies' gaits."""

from __future__ import annotations

import json
import shutil

import pytest
from studio_helpers import reply, screenshot, ws_url
from websockets.sync.client import connect

from sanlab.library import Library
from sanlab.studio.service import Service, StudioError
from tests.helpers import DATA

pytestmark = pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")

HOPPER = DATA / "hopper_free.toml"
# The small design of docs/design.md (about 10 s on 2 busy cores)
SMALL = {"designs": 3, "generation": 3, "controllers": 16, "trials": 4, "top": 1, "seconds": 2.0, "validate": 1}
FREE = [{"name": "mass", "path": "links[0].mass", "min": 0.5, "max": 1.5, "default": 1.0, "unit": "kg"},
        {"name": "front", "path": "links[1].points[1][1]", "min": -0.35, "max": -0.2, "default": -0.275, "unit": "m"}]
SETTINGS = {"designs": 4, "generation": 2, "strategy": "random", "controllers": 24, "trials": 4, "top": 1,
            "seconds": None, "ensemble": 8, "seed": 0, "validate": 1, "seeds": [1], "prune": 0.5}


@pytest.fixture
def made(library, tmp_path) -> dict:
    """A copy of the studio's library with a design written by hand, its four bodies scored and
    interrupted in its validation: the reference, a body with a robust gait (validated on seed 1
    with the reference), a pruned body (its phase-1 search is the cart's), one whose chain kept no
    robust gait (its tuned gait is opened), and an invalid body (scored 0, nothing run)."""
    db = str(tmp_path / "copy.db")
    shutil.copy(library["db"], db)  # the shared library stays as the other tests expect it
    cart = library["cart"]
    with Library(db) as lib:
        g = [e.gait_id for e in lib.top(cart, 4)]
        d = lib.begin_design("hopper", "hopper.toml", 'name = "hopper"\n', SETTINGS, FREE).design_id
        rec = lambda speed, gait, **kw: {"speed": speed, "gait": gait, "search": cart, "phase1_cm_s": 9.0, "chains": [], **kw}
        lib.add_design_score(d, -1, 0, 0, [1.0, -0.275], rec(20.0, g[0]))
        lib.add_design_score(d, 0, 0, 0, [0.8, -0.3], rec(24.0, g[1]))
        lib.add_design_score(d, 0, 1, 0, [1.4, -0.21], rec(0.0, None, pruned=True))
        lib.add_design_score(d, 1, 1, 0, [0.1, -0.34], rec(0.0, None, pruned=True, invalid="links[0]: mass too small"))
        lib.add_design_score(d, 1, 0, 0, [0.6, -0.34], rec(0.0, None, chains=[
            {"tuned": g[3], "tuned_cm_s": 15.0, "robust": None, "robust_cm_s": 0.0},
            {"tuned": g[2], "tuned_cm_s": 17.0, "robust": None, "robust_cm_s": 0.0}]))
        lib.add_design_score(d, 0, 0, 1, [0.8, -0.3], rec(22.0, g[1]))
        lib.add_design_score(d, -1, 0, 1, [1.0, -0.275], rec(19.0, g[0]))
        lib.end_design(d, "interrupted")
        best = lib.top(cart, 1)[0].gait_id
    return {"db": db, "design": d, "gaits": g, "best": best}


def test_a_designs_points_are_its_bodies_and_open_their_best_gaits(made):
    svc = Service(made["db"])
    d, g = made["design"], made["gaits"]
    [row] = svc.designs()
    assert row == {"design_id": d, "creature": "hopper", "source": "hopper.toml", "status": "interrupted",
                   "created": row["created"], "updated": row["updated"], "free": ["mass", "front"], "bodies": 4,
                   "planned": 4, "best_speed_cm_s": 24.0, "reference_cm_s": 20.0, "chosen": False}
    out = svc.design(d[:5])  # an unambiguous prefix
    json.dumps(out, allow_nan=False)  # strict JSON
    assert (out["design_id"], out["status"], out["chosen"], out["seed"], out["seeds"]) == (d, "interrupted", None, 0, [1])
    assert [f["unit"] for f in out["free"]] == ["kg", "m"] and out["settings"] == SETTINGS
    pts = {p["body"]: p for p in out["points"]}
    assert list(pts) == ["reference", "r0b0", "r0b1", "r1b0", "r1b1"]  # the reference first, then by round and place
    ref, best, pruned, tuned, invalid = pts.values()
    assert (ref["reference"], ref["values"], ref["score"], ref["validation"], ref["validation_mean"]) == \
        (True, [1.0, -0.275], 20.0, {"1": 19.0}, 19.0)
    assert (best["open"], best["open_kind"], best["gait"], best["validation_mean"]) == (g[1], "robust", g[1], 22.0)
    assert (pruned["pruned"], pruned["score"], pruned["gait"], pruned["validation_mean"]) == (True, 0.0, None, None)
    assert (pruned["open"], pruned["open_kind"]) == (made["best"], "phase 1")  # its phase-1 search's best
    assert pruned["invalid"] is None and best["invalid"] is None
    assert (invalid["pruned"], invalid["score"], invalid["invalid"]) == (True, 0.0, "links[0]: mass too small")
    assert (tuned["open"], tuned["open_kind"]) == (g[2], "tuned")  # the faster chain's tuned gait
    assert not any(p["chosen"] for p in out["points"])
    # done: the chosen body marked
    with Library(made["db"]) as lib:
        lib.end_design(d, "done", {"chosen": {"round": 0, "index": 0}, "seconds": 12.5, "text": "# x\n"})
    out = svc.design(d)
    assert out["chosen"] == {"round": 0, "index": 0} and out["seconds"] == 12.5
    assert [p["body"] for p in out["points"] if p["chosen"]] == ["r0b0"]
    assert svc.designs()[0]["chosen"] is True and svc.design_fingerprint() == [[d, "done", 7]]


@pytest.mark.parametrize("ref, needle", [("zz", "no design 'zz'"), ("0123abcd", "no design '0123abcd'"), (7, "expected a design id")])
def test_a_design_not_in_the_library_is_a_one_line_error(made, ref, needle):
    with pytest.raises(StudioError) as err:
        Service(made["db"]).design(ref)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_an_id_far_longer_than_any_is_not_echoed_back_whole(made):
    with pytest.raises(StudioError) as err:
        Service(made["db"]).design("z" * 100_000)
    msg = str(err.value)
    assert msg.startswith("no design 'zzzzzzzzzzzzzzzz'... in ") and len(msg) < 300
    assert msg.endswith("expected a design id of 8 hex digits (or their first few), got one of 100,000 characters")


@pytest.mark.parametrize("cell, value, damage", [
    ("settings", {**SETTINGS, "seeds": "ab"}, "its settings: seeds: a list of integers was expected, it holds 'ab'"),
    ("settings", {**SETTINGS, "seeds": 5}, "its settings: seeds: a list of integers was expected, it holds 5"),
    ("settings", {**SETTINGS, "seeds": ["x"]}, "its settings: seeds: a list of integers was expected"),
    ("settings", {**SETTINGS, "seed": [1]}, "its settings: seed: an integer was expected, it holds [1]"),
    ("result", {"chosen": {"round": 0, "index": 0}, "seconds": "x"}, "its result: seconds: a number was expected, it holds 'x'"),
])
def test_a_damaged_design_cell_is_named_as_damaged_not_an_internal_error(made, cell, value, damage):
    """Cells of the right JSON type holding the wrong thing (a fuzzer's edits, issue 57 item 9):
    each was a ValueError, TypeError or OverflowError, "internal error" with a traceback."""
    import sqlite3

    con = sqlite3.connect(made["db"])
    con.execute(f"UPDATE designs SET {cell} = ? WHERE design_id = ?", (json.dumps(value), made["design"]))
    con.commit()
    con.close()
    svc = Service(made["db"])
    with pytest.raises(StudioError) as err:
        svc.design(made["design"])
    assert str(err.value).startswith(f"{made['db']}: design {made['design']} is damaged ({damage}")
    assert str(err.value).endswith("the rest of the library is intact: restore this file from a backup to read it, "
                                   "or leave it be")
    if cell == "settings":  # the listing shows it as damaged, and the rest
        [row] = svc.designs()
        assert row["status"] == "damaged"


def test_design_requests_over_the_websocket(studio, library):
    with connect(ws_url(studio)) as ws:
        ws.send(json.dumps({"id": 1, "op": "designs"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (1, True) and isinstance(r["data"], list)
        ws.send(json.dumps({"id": 2, "op": "design", "design": "deadbeef"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (2, False) and "no design 'deadbeef'" in r["error"]
        ws.send(json.dumps({"id": 3, "op": "design"}))
        r = reply(ws)
        assert (r["id"], r["ok"]) == (3, False) and "missing argument 'design'" in r["error"]


# -- in the browser: a real small design ----------------------------------------------------------


@pytest.fixture(scope="module")
def designed(tmp_path_factory) -> dict:
    """The small design of docs/design.md on the hopper with free numbers, in its own library."""
    from sanlab.creature import load_design, read_source
    from sanlab.design import DesignSettings, run_design

    db = str(tmp_path_factory.mktemp("design") / "design.db")
    text, _ = read_source(str(HOPPER))
    design, _ = load_design(str(HOPPER))
    with Library(db) as lib:  # the file named as from the checkout (the page shows it)
        result = run_design(lib, design, text, "tests/data/hopper_free.toml", DesignSettings(**SMALL))
    return {"db": db, "result": result}


@pytest.fixture(scope="module")
def design_studio(designed):
    from sanlab.studio.server import StudioServer

    with StudioServer(designed["db"], port=0, poll=0.25) as server:
        yield server


@pytest.fixture
def design_page(browser, design_studio):
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    pg = context.new_page()
    pg.set_default_timeout(300_000)
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto(design_studio.url)
    yield pg
    context.close()
    assert not errors, f"JavaScript errors: {errors}"


RING = """(body) => { const [u, v] = studio.view.pointPx(body), c = document.querySelector('#design-plot'),
    d = window.devicePixelRatio || 1;
    return Array.from(c.getContext('2d').getImageData(Math.round((u + 10) * d), Math.round(v * d), 1, 1).data).slice(0, 3); }"""


@pytest.mark.slow  # the small design (about 10 s on 2 busy cores) and a replay of the hopper
def test_the_studio_shows_a_design_as_a_scatter_whose_points_open_their_gaits(design_page, designed):
    pg, result = design_page, designed["result"]
    bodies = {b.label: b for b in result.bodies}
    chosen = result.chosen.label
    # the library lists the design; its row opens it
    pg.wait_for_selector(f"#designs tr[data-design='{result.design_id}']")
    row = pg.locator(f"#designs tr[data-design='{result.design_id}']")
    assert "hopper" in row.inner_text() and "3/3" in row.inner_text() and "done" in row.inner_text()
    row.click()
    pg.wait_for_selector("body[data-view='design']")
    assert pg.locator("h2").inner_text().startswith(f"Design {result.design_id}: hopper")
    assert f"chosen: body {chosen}" in pg.locator("#design-summary").inner_text()
    assert pg.locator("#design-meta").inner_text().startswith("tests/data/hopper_free.toml · cma-es · 3 of 3 bodies scored")
    # one point per body, as stored; the axes offer the free numbers (with units) and the score
    points = pg.evaluate("studio.view.design.points")
    assert {p["body"]: (p["values"], p["score"]) for p in points} == \
        {k: (b.values, pytest.approx(b.speed(result.settings.seed))) for k, b in bodies.items()}
    assert [p["body"] for p in points if p["chosen"]] == [chosen] and [p["body"] for p in points if p["reference"]] == ["reference"]
    options = pg.locator("#design-x option").all_inner_texts()
    assert options == ["links[0].mass (kg)", "front (m)", "back (m)", "actuators[0].ks (N·m/deg)", "robust tuned speed (cm/s)"]
    assert (pg.input_value("#design-x"), pg.input_value("#design-y")) == ("0", "1")
    assert pg.locator("#design-bodies tbody tr").count() == len(bodies)
    # the chosen body is ringed in red (drawn last, on top)
    pg.locator("#design-plot").scroll_into_view_if_needed()
    ring = pg.evaluate(RING, chosen)
    assert max(abs(a - b) for a, b in zip(ring, (214, 39, 40))) < 40, ring
    # score on y: the fastest body is the highest point
    pg.select_option("#design-y", "score")
    pg.wait_for_function("studio.view.axes[1] === 'score'")
    fastest = max(points, key=lambda p: p["score"])["body"]
    ys = {p["body"]: pg.evaluate("b => studio.view.pointPx(b)[1]", p["body"]) for p in points}
    assert min(ys, key=ys.get) == fastest
    screenshot(pg, "studio-design.png")
    # a click on the chosen point opens its robust gait
    want = result.chosen.speeds[result.settings.seed]["gait"] or result.chosen.speeds[result.settings.seeds[0]]["gait"]
    u, v = pg.evaluate("b => studio.view.pointPx(b)", chosen)
    pg.locator("#design-plot").click(position={"x": u, "y": v})
    pg.wait_for_selector("body[data-view='gait']")
    assert pg.url.endswith(f"#/gait/{want.replace('#', '%23')}")
    assert want in pg.locator("h2").inner_text()


def test_the_design_page_of_a_100000_character_id_shows_it_cut(page, studio):
    """Issue 57, item 9: the page put the whole id in its heading, and the server's message
    quoted 600 characters of it. Both now quote its start and its length."""
    page.goto(f"{studio.url}#/design/{'z' * 100_000}")
    page.wait_for_selector("body[data-view='design-error']")
    head = page.locator("h2").inner_text()
    assert head == "Design zzzzzzzzzzzzzzzzzzzzzzzz… (100,000 characters)"
    error = page.locator("#errors .error-text").first.inner_text()
    assert error.startswith("no design 'zzzzzzzzzzzzzzzz'... in ") and len(error) < 300
