"""The studio's gait page data: a pattern gait says it is one, and every gait carries its
creature's pattern ceiling with the fraction of it the gait reaches."""

from __future__ import annotations

import pytest

from sanlab.creature import read_source
from sanlab.library import Library
from sanlab.search import run_search
from sanlab.search.pattern import POPSIZE
from sanlab.studio.service import Service


@pytest.mark.slow  # two short searches and two replays: about 5 s
def test_playback_names_the_kind_and_the_ceiling(tmp_path):
    db = str(tmp_path / "s.db")
    text, where = read_source("cart")
    with Library(db) as lib:
        san = run_search(lib, text, where, controllers=8, seconds=1.0)
        pattern = run_search(lib, text, where, controllers=POPSIZE, seconds=1.0, strategy="pattern", batch=POPSIZE)
        ceiling_speed = lib.top(pattern, 1)[0].speed_cm_s
        san_speed = lib.top(san, 1)[0].speed_cm_s
    svc = Service(db)
    p = svc.playback(f"{pattern}/1")["gait"]
    assert p["kind"] == "pattern" and p["ceiling"]["gait"] == f"{pattern}#{p['id'].split('#')[1]}"
    s = svc.playback(f"{san}/1")["gait"]
    assert s["kind"] == "san"
    assert s["ceiling"]["speed_cm_s"] == pytest.approx(ceiling_speed)
    assert s["ceiling"]["fraction"] == pytest.approx(san_speed / ceiling_speed)
    assert s["ceiling"]["verdict"] is None  # never audited: the page says it is not vouched for
