"""docs/tutorial.md runs as written: its files are written, its commands run in order in a fresh
folder (a library of its own), and what each prints must contain the excerpt the page shows
(``blocks.match``: numbers and run ids may differ, lines and words may not)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from tests.docs import blocks

PAGE = Path(__file__).resolve().parents[2] / "docs" / "tutorial.md"


def test_the_page_has_files_commands_and_excerpts():
    steps = blocks.steps(PAGE)
    files = [s.name for s in steps if s.kind == "file"]
    commands = [s.text for s in steps if s.kind == "command"]
    assert files == ["inchworm.toml", "broken.toml"]
    for verb in ("check", "search", "show", "tune", "audit", "render"):
        assert any(c.startswith(f"sanlab {verb} ") for c in commands), verb
    assert all(s.expected for s in steps if s.kind == "command"), "every command shows what it prints"


def test_its_creature_files_load_or_fail_as_the_page_says():
    from sanlab.creature import CreatureError, loads

    texts = {s.name: s.text for s in blocks.steps(PAGE) if s.kind == "file"}
    spec = loads(texts["inchworm.toml"], "inchworm.toml")
    assert (len(spec.links), len(spec.sensors), len(spec.actuators)) == (3, 3, 2)
    with pytest.raises(CreatureError, match=r"links\[0\]\.mas: unknown field; did you mean 'mass'"):
        loads(texts["broken.toml"], "broken.toml")


def test_the_commands_it_only_shows_exist():
    """The ```sh blocks are shown, not run (the studio serves until stopped): each sanlab line must
    still name a real command and real options."""
    import typer

    import sanlab.cli

    group = typer.main.get_command(sanlab.cli.app)
    shown = [line for lang, _, body in blocks.blocks(PAGE) if lang == "sh" for line in body.splitlines()
             if line.startswith("sanlab ")]
    assert shown == ["sanlab studio --db sanlab.db"]
    for line in shown:
        argv = shlex.split(line)[1:]
        cmd = group.commands[argv[0]]
        opts = {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)}
        assert {a for a in argv[1:] if a.startswith("-")} <= opts, line


def test_the_matcher_fails_on_what_differs():
    ids: dict[str, str] = {}
    out = " run 1234abcd: inchworm, 32 controllers\n│ 1 │ 1234abcd/1 │ 0.5 │ → 3.1 │ - │\n"
    assert blocks.match(["run aeb040c0: inchworm, 32 controllers", "│ 1 │ aeb040c0/1 │ 0.231 │ ← 11.5 │ - │"], out, ids) == []
    assert ids == {"aeb040c0": "1234abcd"}
    assert blocks.substitute("sanlab show aeb040c0/1", ids) == "sanlab show 1234abcd/1"
    assert blocks.match(["run aeb040c0: crawler, 32 controllers"], out, dict(ids)) != []  # a word differs
    assert blocks.match(["│ 1 │ aeb040c0/1 │ 0.231 │ ← 11.5 │ - │", "run aeb040c0: inchworm"], out, dict(ids)) != []  # order
    with pytest.raises(KeyError):
        blocks.substitute("sanlab show deadbeef/1", ids)
    audit = "1234abcd#0: 13.9 cm/s at dt/4 (change -3 %, interval -5 .. -1 %: robust)\n"
    line = "aeb040c0#0: 13.2 cm/s at dt/4 (change -11 %, interval -11 .. -10 %: undecided)"
    assert blocks.match([line], audit, dict(ids)) == []  # numbers and verdicts are the machine's
    assert blocks.match([line.replace("dt/4", "dt/2")], audit, dict(ids)) == [line.replace("dt/4", "dt/2")]
    assert blocks.match(["┏━━━┳━━━┓", "...", line], audit, dict(ids)) == []  # borders and cuts are not checked


# Numbers in an excerpt match any number; these are the ones the page's words depend on.
EXACT = {
    "sanlab check broken.toml": ["exit status 2"],
    "sanlab check inchworm.toml --simulate": ["then sweeping): 0 warnings"],
    "sanlab search inchworm.toml": ["inchworm, 32 controllers", ": 32 controllers,"],
    "sanlab tune": [" x 16 trials"],
    "sanlab audit": ["over the audit's 8 members"],
}


@pytest.mark.slow
def test_the_tutorial_runs_as_written(tmp_path):
    def exact(step, output):
        for prefix, phrases in EXACT.items():
            if step.text.startswith(prefix):
                assert all(p in output for p in phrases), (step.text, phrases, output)

    blocks.run_page(PAGE, tmp_path, exact)
    # What the page says the commands did, beyond their words:
    assert (tmp_path / "sanlab.db").is_file()
    png = (tmp_path / "inchworm.png").read_bytes()
    assert png.startswith(b"\x89PNG")
