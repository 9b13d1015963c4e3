"""Shared fixtures of the test suite (plain constants are in ``helpers.py``)."""

from __future__ import annotations

import logging

import pytest

from sanlab.creature import read_source
from sanlab.library import Library
from tests.helpers import FPS


@pytest.fixture(scope="session")
def lib_run(tmp_path_factory) -> tuple[str, str]:
    """(library path, run id) of one tiny seeded phase-1 search on the cart (16 controllers, 1 s,
    single samples: its best gait is the one the picture tests were written against)."""
    from sanlab.search import run_search

    db = tmp_path_factory.mktemp("render") / "gaits.db"
    text, where = read_source("cart")
    with Library(str(db)) as lib:
        run_id = run_search(lib, text, where, controllers=16, seconds=1.0, batch=16, ensemble=1)
    return str(db), run_id


@pytest.fixture(scope="session")
def scene1(lib_run):
    """The best gait of ``lib_run`` replayed as a scene at ``FPS`` (as ``sanlab render`` does)."""
    from sanlab.gait import Gait
    from sanlab.render.scene import gait_title, scene

    db, run_id = lib_run
    with Library(db) as lib:
        ev = lib.gait(f"{run_id}/1")
        gait = Gait.from_library(lib, ev.gait_id)
    return scene(gait, None, FPS, gait_title(gait, ev.rank))


@pytest.fixture(scope="session")
def bounder_run(tmp_path_factory):
    """(library path, run id) of a seeded phase-1 search on the bounder (64 controllers, 2 s),
    the starting gaits of the tuning tests."""
    from sanlab.search import run_search

    db = tmp_path_factory.mktemp("tune") / "gaits.db"
    text, where = read_source("bounder")
    with Library(str(db)) as lib:
        run_id = run_search(lib, text, where, controllers=64, seconds=2.0, seed=1, batch=64)
    return db, run_id


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster in this process for the module's tests (2 CPUs, a small object store),
    stopped after them; the test is skipped where Ray is not installed."""
    ray = pytest.importorskip("ray")
    ray.init(address="local", num_cpus=2, object_store_memory=80 * 1024 * 1024, include_dashboard=False, log_to_driver=False,
             logging_level=logging.WARNING)
    yield ray
    ray.shutdown()
