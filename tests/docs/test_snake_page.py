"""docs/top-view-snake.md (issue 49): a horizontal-plane snake written with ``[[repeat]]``, whose
file loads as the page says and whose commands run as written (as docs/tutorial.md's do)."""

from __future__ import annotations

import os
import subprocess
import sys
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


@pytest.mark.slow  # a search of a new creature: its compile
def test_the_snake_page_runs_as_written(tmp_path):
    env = dict(os.environ, COLUMNS="100", NO_COLOR="1", TERM="dumb")
    env["PATH"] = os.path.dirname(sys.executable) + os.pathsep + env.get("PATH", "")
    ids: dict[str, str] = {}
    for step in blocks.steps(PAGE):
        if step.kind == "file":
            (tmp_path / step.name).write_text(step.text, encoding="utf-8")
            continue
        command = blocks.substitute(step.text, ids)
        r = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, timeout=600)
        assert r.returncode == 0, f"$ {command}\n{r.stdout}"
        missing = blocks.match(step.expected, r.stdout, ids)
        assert not missing, f"$ {command}\nnot in its output (in order): {missing}\n--- output:\n{r.stdout}"
