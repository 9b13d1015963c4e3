"""docs/top-view-snake.md (issue 49): a horizontal-plane snake written with ``[[repeat]]``, whose
file loads as the page says and whose commands run as written (as docs/tutorial.md's do)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.docs import blocks

PAGE = Path(__file__).resolve().parents[2] / "docs" / "top-view-snake.md"


def test_the_snake_is_a_top_view_chain_written_with_repeat():
    from sanlab.creature import loads

    [text] = [s.text for s in blocks.steps(PAGE) if s.kind == "file"]
    assert "[[repeat]]" in text and text.count("[[links]]") == 1
    spec = loads(text, "snake.toml")
    assert spec.world.plane == "horizontal"
    assert [k.name for k in spec.links] == [f"s{i}" for i in range(8)]
    assert [k.parent for k in spec.links] == [None, *(f"s{i}" for i in range(7))]
    assert [s.name for s in spec.sensors] == [f"straight{i}" for i in range(1, 8)]
    assert [a.name for a in spec.actuators] == [f"m{i}" for i in range(1, 8)]
    commands = [s.text for s in blocks.steps(PAGE) if s.kind == "command"]
    assert [c.split()[1] for c in commands] == ["check", "search", "modes"]


@pytest.mark.slow  # a search of 64 controllers and their modes (about 5 s on 2 cores)
def test_the_snake_page_runs_as_written(tmp_path):
    blocks.run_page(PAGE, tmp_path)
