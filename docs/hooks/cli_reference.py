"""MkDocs hook: writes ``reference/cli.md`` from the ``sanlab`` command's own click tree.

Every command, argument and option comes from ``typer.main.get_command(sanlab.cli.app)`` at build
time (usage line, help text, each parameter's names, type, default and range as ``--help`` prints
them), so the page cannot drift from the CLI. The page is generated in memory: nothing is written
under ``docs/``. ``render()`` is also what the tests compare the built page against.
"""

from __future__ import annotations

import html
import re

import typer
from mkdocs.structure.files import File, Files

PAGE = "reference/cli.md"


def _text(s: str | None) -> str:
    """Help text as Markdown: Rich's escapes undone, HTML and table syntax escaped."""
    s = (s or "").replace("\\[", "[")
    s = html.escape(s, quote=False).replace("|", "&#124;").replace("*", "\\*")
    return re.sub(r"`([^`]*)`", r"<code>\1</code>", s)


def _paragraphs(s: str | None) -> str:
    parts = [" ".join(p.split()) for p in (s or "").split("\n\n") if p.strip()]
    return "\n\n".join(_text(p) for p in parts)


def _cell(s: str) -> str:
    return _text(" ".join(s.split()))


def render() -> str:
    import sanlab.cli
    from sanlab import __version__

    group = typer.main.get_command(sanlab.cli.app)
    root = group.context_class(group, info_name="sanlab")
    out = [
        "# Command reference",
        "",
        f"Generated from the `sanlab` command itself (sanlab {__version__}) when the site is built, so it",
        "lists exactly what `sanlab COMMAND --help` prints. Every command that reads or writes the gait",
        "library takes `--db PATH` (default `sanlab.db` in the working directory).",
        "",
        "```text",
        root.command.get_usage(root).strip(),
        "```",
        "",
        _paragraphs(group.help),
        "",
        "| option | meaning |",
        "|---|---|",
    ]
    for p in group.params:
        rec = p.get_help_record(root)
        if rec and not getattr(p, "hidden", False):
            out.append(f"| `{rec[0]}` | {_cell(rec[1])} |")
    out += ["", "| command | what it does |", "|---|---|"]
    names = [n for n, c in group.commands.items() if not c.hidden]
    for name in names:
        cmd = group.commands[name]
        first = (cmd.help or "").strip().split("\n\n")[0]
        out.append(f"| [`{name}`](#sanlab-{name}) | {_cell(first)} |")
    for name in names:
        cmd = group.commands[name]
        sub = cmd.context_class(cmd, info_name=name, parent=root)
        out += ["", f"## sanlab {name}", "", "```text", cmd.get_usage(sub).strip(), "```", "", _paragraphs(cmd.help), ""]
        rows = []
        for p in cmd.params:
            rec = p.get_help_record(sub)
            if rec is None or getattr(p, "hidden", False):
                continue
            kind = "argument" if p.param_type_name == "argument" else "option"
            rows.append(f"| `{rec[0]}` | {kind} | {_cell(rec[1])} |")
        if rows:
            out += ["| name | kind | meaning |", "|---|---|---|", *rows]
    return "\n".join(out) + "\n"


def on_files(files: Files, config) -> Files:
    files.append(File.generated(config, PAGE, content=render()))
    return files
