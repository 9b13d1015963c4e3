"""Fixtures of the studio's tests: a small gait library, a studio on a free local port, and
Debian's chromium driven headless by Playwright.

The browser: Playwright's own browser download cannot be reached from our machines, so the
tests use Debian's ``chromium`` package. If it is missing and we are root (CI and the developers'
machines are), the session installs it with apt-get once (a minute or two); otherwise the
browser tests are skipped with the command to run, except under CI (``CI`` set), where that is
an error.

Screenshots for the README: set ``SANLAB_STUDIO_SCREENSHOTS=docs/img`` and the browser tests
save the library, a run grid and live steering there.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import tempfile

import pytest
from studio_helpers import DATA, QD_SEARCH, SEARCH

from sanlab.creature import read_source
from sanlab.library import Library
from sanlab.search import run_search


def chromium_path() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def install_chromium() -> str:
    """Debian's chromium, installed with apt-get if missing and we are root."""
    path = chromium_path()
    if path:
        return path
    how = "apt-get install -y chromium"
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        message = f"the studio's browser tests need Debian's chromium ({how}, as root)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    # one install at a time: xdist runs the browser test files in different workers, and a second
    # apt-get beside the first fails on dpkg's lock (seen in a full run); the second waits here,
    # then finds chromium installed
    with open(os.path.join(tempfile.gettempdir(), "sanlab-chromium-install.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        path = chromium_path()
        if path:
            return path
        wait = ["-o", "DPkg::Lock::Timeout=600"]  # another apt-get of the machine's own
        for cmd in (["apt-get", *wait, "update", "-q"], ["apt-get", *wait, "install", "-y", "-q", "chromium"]):
            done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1200)
            if done.returncode != 0:
                pytest.fail(f"{' '.join(cmd)} failed:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
    path = chromium_path()
    if not path:
        pytest.fail(f"{how} succeeded but no chromium is on PATH")
    return path


@pytest.fixture(scope="session")
def library(tmp_path_factory) -> dict:
    """A small library: one seeded search on the cart, an imported fish gait (a phase-1
    gait of `sanlab search fish -n 128 --seed 0` that swims to a point ahead of it), and a short
    MAP-Elites search on the cart (two generations, for the modes and archive views)."""
    import json

    db = str(tmp_path_factory.mktemp("studio") / "gaits.db")
    text, where = read_source(SEARCH["creature"])
    with Library(db) as lib:
        # single samples: its best gait is the one these tests were written against (it moves
        # within live mode's first chunks)
        cart = run_search(lib, text, where, controllers=SEARCH["controllers"], seconds=SEARCH["seconds"],
                          seed=SEARCH["seed"], ensemble=1)
        fish = lib.import_gait(json.loads((DATA / "fish_gait.json").read_text()))
        qd = run_search(lib, text, where, controllers=QD_SEARCH["controllers"], seconds=QD_SEARCH["seconds"],
                        batch=QD_SEARCH["batch"], seed=QD_SEARCH["seed"], strategy="map-elites", ensemble=1)
    return {"db": db, "cart": cart, "fish": fish, "qd": qd}


@pytest.fixture(scope="session")
def studio(library):
    from sanlab.studio.server import StudioServer

    with StudioServer(library["db"], port=0, poll=0.25) as server:
        yield server


@pytest.fixture(scope="session")
def browser():
    path = install_chromium()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=path, headless=True, args=["--no-sandbox"])
        yield b
        b.close()


@pytest.fixture
def page(browser, studio):
    """A fresh page on the studio; fails the test on a JavaScript error."""
    context = browser.new_context(viewport={"width": 1280, "height": 860}, accept_downloads=True)
    pg = context.new_page()
    pg.set_default_timeout(300_000)  # generous: the first replay of a creature compiles, maybe on a busy machine
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto(studio.url)
    yield pg
    context.close()
    assert not errors, f"JavaScript errors: {errors}"
