"""Shared set-up and fixtures of the test suite (plain constants are in ``helpers.py``).

JAX is configured once, before any test builds an array, exactly as the CLI does it: one XLA
device per core (so batches are sharded as in real runs) and float64 available.
"""

from __future__ import annotations

import pytest

import sanlab
from sanlab.creature import read_source
from sanlab.library import Library
from tests.helpers import FPS

sanlab.configure()


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


if __import__("os").environ.get("SANLAB_COMPILE_LOG"):
    # Where the suite's time goes (issue 33): each test's seconds of JAX tracing, lowering and
    # XLA compilation, one JSON line a test, appended to $SANLAB_COMPILE_LOG by every worker.
    import json
    import os
    import time

    import jax.monitoring

    _spent: dict[str, float] = {}

    def _count(event: str, duration_secs: float, **_) -> None:
        if event.startswith("/jax/core/compile/") or event.startswith("/jax/compilation_cache/"):
            _spent[event] = _spent.get(event, 0.0) + duration_secs

    jax.monitoring.register_event_duration_secs_listener(_count)

    # which programs each test compiled: the persistent cache's key of every executable written,
    # so that a cold run shows the programs that two tests (or two workers) compiled alike
    from jax._src import compilation_cache as _cc

    _programs: list[list] = []
    _put = _cc.put_executable_and_time

    def _put_logged(cache_key, module_name, executable, backend, compile_time):
        _programs.append([cache_key[-16:], module_name, compile_time])
        return _put(cache_key, module_name, executable, backend, compile_time)

    _cc.put_executable_and_time = _put_logged

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        _spent.clear()
        _programs.clear()
        t0 = time.perf_counter()
        yield
        with open(os.environ["SANLAB_COMPILE_LOG"], "a") as f:
            f.write(json.dumps({"test": item.nodeid, "wall": time.perf_counter() - t0, **_spent,
                                "programs": _programs, "worker": os.environ.get("PYTEST_XDIST_WORKER", "")}) + "\n")
