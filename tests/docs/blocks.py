"""Reading the docs' code blocks, and matching what a command printed against what a page shows.

A page's ```` ```console ```` block holds commands (lines starting with ``$ ``), each followed by
an excerpt of what it prints; ```` ```toml title="NAME" ```` blocks are files to write before the
commands that follow them. The excerpt is checked line by line, in order, against the command's
output (stdout and stderr, interleaved as printed):

* Rich's table borders and runs of spaces do not count;
* every number matches any number (speeds, scores and intervals depend on the machine), but not
  one that is part of a name (``dt/4``, ``float64``, ``S1``, the rank in ``RUN/2``);
* an 8-digit hex id (a run id) matches any such id, and the first match binds it: later lines
  and later commands' ids are then the actual one (commands have the doc's ids replaced);
* arrows (← →), signs of ``+x``/``-x`` and audit verdicts match one another;
* a line ``...`` is a cut, and a line of table borders only is left out: neither is checked.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

FENCE = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```\s*$", re.S | re.M)
BOX = re.compile(r"[│┃┏┓┗┛┡┩┠┨┣┫┳┻╇╈╋━─┼┬┴├┤└┘┌┐═╭╮╰╯]")
ID = re.compile(r"\b[0-9a-f]{8}\b")
# A number, unless it is part of a name (dt/4, float64, S1, A2; "1000x290" is two numbers).
NUMBER = re.compile(r"((?<![A-Za-wyz/_.\d])[-+]?\d+(?:\.\d+)?)")
VERDICTS = ("resolution-dependent", "undecided", "robust")


@dataclass
class Step:
    """One thing a page asks for, in page order: a file to write or a command with its excerpt."""

    kind: str  # "file" or "command"
    text: str  # the file's content, or the command line
    name: str = ""  # the file's name
    expected: list[str] = field(default_factory=list)


def blocks(path: Path) -> list[tuple[str, str, str]]:
    """(language, info after it, body) of every fenced block of a Markdown page, in order."""
    return [(m.group(1), m.group(2).strip(), m.group(3)) for m in FENCE.finditer(path.read_text(encoding="utf-8"))]


def steps(path: Path) -> list[Step]:
    out: list[Step] = []
    for lang, info, body in blocks(path):
        if lang == "toml":
            m = re.search(r'title="([^"]+)"', info)
            if m is None:
                raise ValueError(f"{path.name}: a toml block without title=\"FILE\": {body[:60]!r}")
            out.append(Step("file", body, name=m.group(1)))
        elif lang == "console":
            current: Step | None = None
            for line in body.splitlines():
                if line.startswith("$ "):
                    current = Step("command", line[2:].strip())
                    out.append(current)
                elif current is None:
                    if line.strip():
                        raise ValueError(f"{path.name}: console output before any command: {line!r}")
                elif line.strip():
                    current.expected.append(line)
    return out


def normalise(line: str) -> str:
    return " ".join(BOX.sub(" ", line).split())


def pattern(line: str, ids: dict[str, str]) -> tuple[re.Pattern[str], list[str]]:
    """A regex for one expected line, and the doc ids its groups bind, in order."""
    text = normalise(line)
    parts: list[str] = []
    binds: list[str] = []
    tokens = re.compile(r"(\b[0-9a-f]{8}\b)|" + NUMBER.pattern + r"|([←→])|([-+]x\b)|(" + "|".join(VERDICTS) + ")")
    pos = 0
    for m in tokens.finditer(text):
        parts.append(re.escape(text[pos:m.start()]))
        doc_id, _num, _arrow, _axis, _verdict = m.groups()
        if doc_id is not None:
            if doc_id in ids:
                parts.append(re.escape(ids[doc_id]))
            elif doc_id in binds:
                parts.append(f"(?P=i{binds.index(doc_id)})")
            else:
                parts.append(f"(?P<i{len(binds)}>[0-9a-f]{{8}})")
                binds.append(doc_id)
        elif _num is not None:
            parts.append(r"[-+]?\d+(?:\.\d+)?")
        elif _arrow is not None:
            parts.append("[←→]")
        elif _axis is not None:
            parts.append("[-+]x")
        else:
            parts.append("(?:" + "|".join(VERDICTS) + ")")
        pos = m.end()
    parts.append(re.escape(text[pos:]))
    return re.compile("".join(parts)), binds


def match(expected: list[str], output: str, ids: dict[str, str]) -> list[str]:
    """Check an excerpt against a command's output, binding ids into ``ids``; the lines that were
    not found (in order), empty when it matches."""
    actual = [normalise(line) for line in output.splitlines()]
    missing: list[str] = []
    at = 0
    for line in expected:
        if line.strip() == "..." or not normalise(line):  # a cut, or a table's border
            continue
        rx, binds = pattern(line, ids)
        for i in range(at, len(actual)):
            m = rx.search(actual[i])
            if m:
                for k, doc_id in enumerate(binds):
                    ids[doc_id] = m.group(f"i{k}")
                at = i + 1
                break
        else:
            missing.append(line)
    return missing


def substitute(command: str, ids: dict[str, str]) -> str:
    """The command with every doc id replaced by the actual one it was bound to."""
    def repl(m: re.Match[str]) -> str:
        if m.group(0) not in ids:
            raise KeyError(f"{command!r} uses id {m.group(0)} that no earlier output bound")
        return ids[m.group(0)]

    return ID.sub(repl, command)


def run_page(page: Path, folder: Path, check=None) -> None:
    """Run a page's steps as written in ``folder``: write its files, run its commands in bash
    (the venv's interpreter first on PATH, 100 columns, no colour) and assert each exits 0 and
    prints what the page shows after it, in order. ``check(step, output)``: more assertions on
    each command's output."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, COLUMNS="100", NO_COLOR="1", TERM="dumb")
    env["PATH"] = os.path.dirname(sys.executable) + os.pathsep + env.get("PATH", "")
    ids: dict[str, str] = {}
    for step in steps(page):
        if step.kind == "file":
            (folder / step.name).write_text(step.text, encoding="utf-8")
            continue
        command = substitute(step.text, ids)
        r = subprocess.run(["bash", "-c", command], cwd=folder, env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, timeout=600)
        assert r.returncode == 0, f"$ {command}\n{r.stdout}"
        missing = match(step.expected, r.stdout, ids)
        assert not missing, f"$ {command}\nnot in its output (in order): {missing}\n--- output:\n{r.stdout}"
        if check is not None:
            check(step, r.stdout)
