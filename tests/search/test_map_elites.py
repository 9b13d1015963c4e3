"""MAP-Elites (sanlab.search.map_elites): mutation, the grid, the archive rebuilt from the
library, and a search killed mid-way that resumes to the uninterrupted result bit for bit."""

from __future__ import annotations

import json
import signal
import subprocess
import time

import numpy as np
import pytest

from sanlab.library import Library
from sanlab.search.base import Grid
from sanlab.search.map_elites import line, mutate, parse_grid, rebuild, resolve
from tests.helpers import SANLAB, interruptible, rows_in


def test_a_mutant_changes_a_few_weights_and_stays_in_range():
    rng = np.random.default_rng(0)
    w = np.random.default_rng(1).integers(-2, 3, (6, 9)).astype(np.int8)
    changed = []
    for _ in range(300):
        c = mutate(w, rng)
        assert c.shape == w.shape and c.dtype == np.int8 and c.min() >= -2 and c.max() <= 2
        changed.append(int(np.sum(c != w)))
    assert min(changed) >= 0 and max(changed) <= 8 and 1.0 < np.mean(changed) < 2.5  # a redraw may keep a weight
    np.testing.assert_array_equal(mutate(w, np.random.default_rng(5)), mutate(w, np.random.default_rng(5)))
    edge = np.full((1, 1), 2, np.int8)  # +-1 at the bound moves inwards, never out
    assert all(mutate(edge, np.random.default_rng(s))[0, 0] in (-2, -1, 0, 1, 2) for s in range(50))


def test_the_line_step_moves_only_where_two_elites_differ():
    rng = np.random.default_rng(0)
    a = np.random.default_rng(1).integers(-2, 3, (6, 9)).astype(np.int8)
    b = a.copy()
    b[0, :4] = [2, -2, 2, -2]  # the elites differ in at most these four weights
    same = a == b
    moved = 0
    for _ in range(200):
        c = line(a, b, rng)
        assert c.shape == a.shape and c.dtype == np.int8 and c.min() >= -2 and c.max() <= 2
        np.testing.assert_array_equal(c[same], a[same])  # no step where the elites agree
        moved += int(np.any(c != a))
    assert 0 < moved < 200  # small steps round to no change, larger ones move
    np.testing.assert_array_equal(line(a, a, np.random.default_rng(3)), a)
    np.testing.assert_array_equal(line(a, b, np.random.default_rng(4)), line(a, b, np.random.default_rng(4)))


def test_the_grid_option_and_its_errors():
    g = parse_grid(None)
    assert g.names == ("vx_cm_s", "airborne") and g.ranges == (None, (0.0, 1.0)) and g.bins == (16, 16)
    g = parse_grid("turns_per_s:-1:1,height_m", bins=8)
    assert g.ranges == ((-1.0, 1.0), None) and g.bins == (8, 8)
    for bad, match in (("speed,airborne", "expected descriptors among"), ("airborne", "two descriptors"),
                       ("airborne:1:0,vx_cm_s", "LO < HI"), ("airborne:a:b,vx_cm_s", "numbers"),
                       ("airborne,airborne", "named twice")):
        with pytest.raises(ValueError, match=match):
            parse_grid(bad)
    assert Grid.from_json(json.loads(json.dumps(g.to_json()))) == g


def test_an_open_range_is_three_times_the_first_generation_extent():
    g = resolve(parse_grid(None, bins=4), [np.array([-1.0, 0.2]), np.array([3.0, 0.4]), np.array([np.nan, 0.3])])
    assert g.ranges[0] == (-5.0, 7.0) and g.ranges[1] == (0.0, 1.0)
    flat = resolve(parse_grid(None, bins=10), [np.array([2.0, 0.5])] * 3)  # no extent: the resolution's
    assert flat.ranges[0] == (-3.0, 7.0)


def test_curiosity_counts_each_parent_s_children_that_entered_the_archive():
    from sanlab.search.base import Problem
    from sanlab.search.map_elites import CURIOSITY_DOWN, CURIOSITY_UP, MapElites
    from tests.search.test_strategies import SPACE, synthetic

    grid = Grid(("vx_cm_s", "airborne"), ((-0.5, 0.5), (0.25, 0.75)), (4, 4))
    me = MapElites(Problem("r", SPACE.san, 48, seed=3, grid=grid, generation=8))
    rows = []
    while not me.done:
        cands = me.ask(8)
        rows += me.tell(cands, synthetic(cands)).evaluations
        if me._gen == 3:  # after three generations: the curiosity of two generations of mutants
            children = [r for r in rows if "parent_idx" in r.extra]
            assert children and all(r.idx >= 8 for r in children)  # the first tenth (one generation) is random
            assert sum(me._curiosity.values()) != 0
            counts = {}
            for r in children:
                counts.setdefault(r.extra["parent_idx"], 0)
                counts[r.extra["parent_idx"]] += 1
            for parent, c in me._curiosity.items():  # each child moved its parent's curiosity once
                n = counts[parent]
                ups = (c + CURIOSITY_DOWN * n) / (CURIOSITY_UP + CURIOSITY_DOWN)
                assert abs(ups - round(ups)) < 1e-9 and 0 <= round(ups) <= n
            assert set(me._curiosity) == set(counts)


@pytest.mark.slow
def test_a_killed_map_elites_search_resumes_to_the_same_rows_and_archive(tmp_path):
    db = tmp_path / "gaits.db"
    args = ["search", "cart", "-n", "640", "--strategy", "map-elites", "--batch", "32", "--seconds", "1",
            "--seed", "4", "--db", str(db)]
    proc = subprocess.Popen(SANLAB + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=interruptible)
    deadline = time.time() + 240
    while rows_in(db) < 160 and time.time() < deadline and proc.poll() is None:  # past the random tenth
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    stored = rows_in(db)
    assert 160 <= stored < 640, "the search should have been killed part-way"
    with Library(str(db)) as lib:
        run = lib.runs()[0].run_id
    resumed = subprocess.run(SANLAB + ["search", "--resume", run, "--db", str(db), "--json"],
                             capture_output=True, text=True, check=True)
    ref = subprocess.run(SANLAB + args[:-1] + [str(tmp_path / "ref.db"), "--json"],
                         capture_output=True, text=True, check=True)
    out, expected = json.loads(resumed.stdout), json.loads(ref.stdout)
    assert out["evaluated"] == 640 and out["archive"] == expected["archive"]
    assert out["archive"]["elites"] > 0 and 0 < out["archive"]["coverage"] <= 1
    with Library(str(db)) as a, Library(str(tmp_path / "ref.db")) as b:
        ra, rb = a.top(run, None), b.top(b.runs()[0].run_id, None)
        rows = lambda evs: sorted((e.idx, e.encoding, e.score, e.speed_cm_s, json.dumps(e.extra, sort_keys=True))
                                  for e in evs)
        assert rows(ra) == rows(rb)
        mutants = [e for e in ra if "parent_idx" in (e.extra or {})]
        assert mutants and all(e.extra["parent_idx"] < e.idx // 32 * 32 for e in mutants)  # from earlier generations
        assert all(e.idx >= 64 for e in mutants)  # the first tenth (two generations of 32) is random
        from sanlab.creature import load
        from sanlab.san import San

        san = San.for_creature(load("cart"))
        grid = Grid.from_json(a.get_run(run).params["grid"])
        arch = rebuild(grid, san.n_weights, ra, san.decode, 32)
        assert int(arch.stats.num_elites) == out["archive"]["elites"]
