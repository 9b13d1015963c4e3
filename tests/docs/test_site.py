"""The documentation site builds with ``mkdocs build --strict`` (a broken link, a page missing
from the nav, a bad anchor or a docstring mkdocstrings cannot render fails it), and its generated
pages hold what they are generated from: every command and option of the CLI, and the public
modules' API."""

from __future__ import annotations

import html
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("material") is None,
    reason="the docs extra is not installed: pip install -e '.[docs]'",
)


def _commands():
    import typer

    import sanlab.cli

    group = typer.main.get_command(sanlab.cli.app)
    return {name: cmd for name, cmd in group.commands.items() if not cmd.hidden}


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    return out


def test_every_command_and_option_is_on_the_cli_page(site):
    page = html.unescape((site / "reference" / "cli" / "index.html").read_text(encoding="utf-8"))
    for name, cmd in _commands().items():
        assert f'id="sanlab-{name}"' in page, name
        for p in cmd.params:
            if getattr(p, "hidden", False):
                continue
            for opt in (*p.opts, *p.secondary_opts):
                if opt.startswith("-"):
                    assert opt in page, (name, opt)


def test_the_cli_page_is_the_clis_own_help():
    """Each option's line is the help record click builds for ``--help`` (defaults and ranges
    included), so a changed default changes the page."""
    sys.path.insert(0, str(ROOT / "docs" / "hooks"))
    try:
        import cli_reference
    finally:
        sys.path.pop(0)
    text = cli_reference.render()
    search = _commands()["search"]
    ctx = search.context_class(search, info_name="search")
    record = next(p for p in search.params if "--controllers" in p.opts).get_help_record(ctx)
    assert record is not None
    assert f"| `{record[0]}` | option | {cli_reference._cell(record[1])} |" in text
    assert "[default: 200; x&gt;=1]" in text


@pytest.mark.parametrize("obj", ["sanlab.creature.load", "sanlab.sim.compile_creature", "sanlab.library.Library",
                                 "sanlab.san", "sanlab.evaluate", "sanlab.search", "sanlab.audit", "sanlab.modes"])
def test_the_api_page_documents_the_public_modules(site, obj):
    page = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    assert f'id="{obj}"' in page


def test_the_tutorial_and_how_to_pages_are_built(site):
    for page in ("tutorial", "creature-format", "trusting-scores", "tuning", "follow-point", "studio", "ray",
                 "gpu", "reproduce", "library", "render", "san", "simulator", "engine-history", "layout"):
        assert (site / page / "index.html").is_file(), page
