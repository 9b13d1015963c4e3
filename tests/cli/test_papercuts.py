"""Issue 33, part 4: the command line's papercuts, each with its case. (Those found fixed
already have their tests elsewhere: ``search --resume`` refusing the options it would ignore in
test_search.py, ``creatures --json``'s descriptions in test_creatures.py, render's distance
whatever ``--fps`` in test_render.py.)"""

from __future__ import annotations

import json
import re
import shutil

import pytest
from rich.console import Console
from typer.testing import CliRunner

from sanlab.cli import _common, app
from sanlab.library import Library
from tests.cli.test_library import cart_export

runner = CliRunner()


def words(text: str) -> str:
    return " ".join(text.split())


@pytest.fixture(scope="module")
def tuned(lib_run, tmp_path_factory):
    """(db, search run id, the table ``tune RUN/1`` printed, its parent and tuned gait ids) on a
    copy of the session's cart search."""
    src, run_id = lib_run
    db = str(tmp_path_factory.mktemp("papercuts") / "g.db")
    shutil.copy(src, db)
    r = runner.invoke(app, ["tune", f"{run_id}/1", "--trials", "2", "--batch", "8", "--ensemble", "1", "--db", db],
                      terminal_width=200)
    assert r.exit_code == 0, r.output
    with Library(db) as lib:
        parent = lib.gait(f"{run_id}/1").gait_id
        tune_run = next(x.run_id for x in lib.runs() if x.kind == "tune")
    return db, run_id, r.stdout, parent, f"{tune_run}#0"


def test_the_tune_table_speeds_carry_the_direction_arrow(tuned):
    db, _, text, parent, tuned_gait = tuned
    with Library(db) as lib:
        arrows = [_common.ARROWS[_common.direction((lib.gait(g).extra or {}).get("dx_m"))] for g in (parent, tuned_gait)]
    assert arrows[0] != " "  # the cart's best gait moved: an arrow is due
    row = next(line for line in text.splitlines() if tuned_gait in line)
    speeds = re.findall(r"([→← ]) (-?\d+\.\d) ", row + " ")
    assert [a for a, _ in speeds[-2:]] == arrows, row  # before, after: each its stored gait's direction


def test_show_and_tune_say_what_to_do_next(tuned):
    db, run_id, text, _, tuned_gait = tuned
    assert f"next: sanlab show {tuned_gait} --db {db}" in words(text)
    r = runner.invoke(app, ["show", run_id, "--db", db], terminal_width=100)
    assert r.exit_code == 0
    nxt = [line for line in r.stdout.splitlines() if line.startswith("next: ")]
    assert len(nxt) == 1 and f"sanlab show {run_id}/1 --db {db}" in nxt[0] and f"sanlab audit {run_id}/1 --db {db}" in nxt[0]
    r = runner.invoke(app, ["show", f"{run_id}/1", "--db", db], terminal_width=100)
    assert r.exit_code == 0 and f"sanlab render {tuned[3]} --db {db}" in r.stdout and "sanlab export" in r.stdout
    r = runner.invoke(app, ["show", run_id, "--db", db, "--json"])  # stdout stays JSON
    assert r.exit_code == 0 and "next:" not in r.stdout and json.loads(r.stdout)["run_id"] == run_id


def _audit(gait_id: str, verdict: str, stored: float = 35.3, needed: int | None = None):
    from sanlab.audit import Audit, Shift

    off = verdict in ("resolution-dependent", "undecided")
    shifts = {n: Shift(-0.55 if off else 0.01, -1.0 if off else -0.02, 0.6 if off else 0.03, verdict if off else "robust",
                       needed) for n in ("dt/2", "dt/4", "float64")}
    return Audit(gait_id, stored, 35.3, 35.1, dict.fromkeys(shifts, 123.4), shifts, dict.fromkeys(shifts, False), 0.1,
                 0.001, 8, 32, 0.95)


def test_the_audit_verdict_is_never_cut_at_80_columns_piped(monkeypatch):
    import sanlab.cli.audit as audit_cli

    results = [_audit("3fa1c2d0#117", "resolution-dependent"), _audit("3fa1c2d0#2", "robust"),
               _audit("3fa1c2d0#3", "undecided", needed=640), _audit("3fa1c2d0#4", "robust", stored=99.0)]
    assert [a.verdict for a in results] == ["resolution-dependent", "robust", "undecided", "not reproduced"]
    piped = Console(width=80, force_terminal=False, color_system=None)  # what a pipe gets
    monkeypatch.setattr(audit_cli, "console", piped)
    with piped.capture() as cap:
        audit_cli.print_audits(results, 0.1)
    text = cap.get()
    assert "…" not in text and all(len(line) <= 80 for line in text.splitlines()), text
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("gait "))
    col = lines[head].index("verdict")
    rows = [line for line in lines[head + 2:] if line.startswith((" ", "3fa1c2d0"))]  # the notes under it start otherwise
    column = "".join(f if f.endswith("-") else f + " " for f in (line[col:].strip() for line in rows) if f)
    assert column.split() == "resolution-dependent robust undecided (~640 members) not reproduced".split(), column
    assert "[-100,+60]" in text  # the widest interval, whole
    # issue 49: the advice names the command, with more members than the audit used (32)
    assert "sanlab audit 3fa1c2d0#3 --members 800" in text and "with more --members" not in text


def test_a_network_is_readable_at_80_columns(monkeypatch):
    """A bounder's 20 inputs (8 sensors, 8 hidden nodes, 4 actuator nodes) do not fit in 80
    columns in one table: split by kind, every table within 80 columns, every weight shown."""
    import sanlab.cli.library as library_cli

    inputs = [f"S{i}" for i in range(1, 9)] + [f"H{i}" for i in range(1, 9)] + [f"A{i}" for i in range(1, 5)]
    nodes = inputs[8:]
    weights = [[(i * 7 + j * 3) % 5 - 2 for j in range(len(inputs))] for i in range(len(nodes))]
    narrow = Console(width=80, force_terminal=False, color_system=None)
    monkeypatch.setattr(library_cli, "console", narrow)
    with narrow.capture() as cap:
        library_cli._print_network({"inputs": inputs, "nodes": nodes, "weights": weights})
    text = cap.get()
    assert all(len(line) <= 80 for line in text.splitlines()), text
    assert 2 <= sum("weights from" in line for line in text.splitlines()) <= 3
    cells = sum(len(re.findall(r"(?<=│ )([+-][12]|0)(?= +│)", line)) for line in text.splitlines() if re.match(r"│ (H|A)\d", line))
    assert cells == len(nodes) * len(inputs)


@pytest.mark.parametrize("gait, bad", [("zzzz1234/1", "'z'"), ("3fa1g2d0#4", "'g'"), ("xyz/2", "'x', 'y', 'z'")])
def test_a_gait_id_whose_run_part_is_not_hex_says_so(tmp_path, gait, bad):
    Library(str(tmp_path / "g.db")).close()
    for cmd in (["show", gait], ["render", gait], ["export", gait]):
        r = runner.invoke(app, [*cmd, "--db", str(tmp_path / "g.db")])
        assert r.exit_code == 2, r.output
        assert r.stderr.removeprefix("GAIT: ").startswith(f"malformed gait id {gait!r}: its run part {gait[:-2]!r} has {bad}, which no run id has "
                                   "(run ids are hexadecimal: 0-9 and a-f, e.g. 3fa1c2d0)"), (cmd, r.stderr)
        assert r.stderr.count("\n") == 1
    r = runner.invoke(app, ["show", "abc/x", "--db", str(tmp_path / "g.db")])  # not of that shape: the general line
    assert r.exit_code == 2 and "expected RUN/RANK" in r.stderr


@pytest.mark.parametrize("change, says", [
    (lambda d: d.pop("format"), 'it has no "format" field (an exported gait has "format": "sanlab-gait"'),
    (lambda d: d.update(format=None), 'it has no "format" field'),
    (lambda d: d.update(format="other"), '"format" is \'other\', expected \'sanlab-gait\''),
    (lambda d: d.update(format=3), '"format" is 3, expected'),
])  # fmt: skip
def test_an_import_without_its_format_field_says_so_plainly(tmp_path, change, says):
    data = cart_export(tmp_path)
    change(data)
    path = tmp_path / "gait.json"
    path.write_text(json.dumps(data))
    r = runner.invoke(app, ["import", str(path), "--db", str(tmp_path / "new.db")])
    assert r.exit_code == 2 and r.stderr.startswith(f"{path}: not a sanlab gait: ") and says in r.stderr, r.stderr
    assert "is None" not in r.stderr and r.stderr.count("\n") == 1
    assert not (tmp_path / "new.db").exists()


# -- issue 57 item 13 ----------------------------------------------------------------------------


def test_every_usage_line_names_its_arguments_alike():
    """Usage lines mixed `[creature]`, `{creature}` and `{RUN_ID}`: now every argument is named in
    capitals, bare when required and in brackets when optional, as Click and most tools write it."""
    import typer

    group = typer.main.get_command(app)
    seen = {}
    for name in group.commands:  # type: ignore[attr-defined]
        r = runner.invoke(app, [name, "--help"], terminal_width=200)
        (usage,) = [ln.strip() for ln in r.stdout.splitlines() if "Usage:" in ln]
        seen[name] = usage.split("[OPTIONS]", 1)[1].strip()
    assert all("{" not in a and "}" not in a and a == a.upper().replace(".XML", ".xml") for a in seen.values()), seen
    assert seen["check"] == "CREATURE" and seen["search"] == "[CREATURE]" and seen["tune"] == "[GAIT|RUN_ID]"
    assert seen["modes"] == "RUN_ID" and seen["export"] == "GAIT" and seen["audit"] == "GAIT|RUN_ID"


def test_the_host_help_points_at_a_page_that_speaks_of_it():
    """`--host` pointed at the README, which says nothing of it."""
    from pathlib import Path

    r = runner.invoke(app, ["studio", "--help"], terminal_width=400)
    text = words(r.stdout.replace("│", " "))
    assert "(see README)" not in text and 'docs/studio.md, "On a network"' in text, text
    page = (Path(__file__).resolve().parents[2] / "docs" / "studio.md").read_text()
    assert "## On a network" in page and "`--host 0.0.0.0`" in page


def test_the_audit_footer_says_why_it_stopped_below_max_members(monkeypatch):
    """Audit's footer named `--max-members` beside 64 when that option was 1,024 and it had
    stopped because more than 4,096 would be needed."""
    import sanlab.cli.audit as audit_cli

    wide = Console(width=400, force_terminal=False, color_system=None)
    monkeypatch.setattr(audit_cli, "console", wide)
    far = _audit("3fa1c2d0#3", "undecided", needed=9000)  # its one look: 32 members
    with wide.capture() as cap:
        audit_cli.print_audits([far], 0.1, max_members=1024)
    text = words(cap.get())
    assert "32 members (--max-members)" not in text
    assert ("its last look was on 32 members, below --max-members (1,024): a further look is made only when the last "
            "asks for at most 2,048") in text, text
    assert "more than 4096 members would be needed to decide it" in text
    with wide.capture() as cap:
        audit_cli.print_audits([far], 0.1, max_members=32)
    assert "its last look was on 32 members, --max-members (32)" in words(cap.get())


def test_a_row_scored_0_without_a_flag_says_why(monkeypatch):
    """An imported walker2d's rank 3 printed score 0.000, no flag and "← -8.9" with nothing
    saying why (its dt/2 members fell or went backwards: that group's median scored 0, while
    only 4 of its 8 members fell, short of the "fell" flag)."""
    wide = Console(width=400, force_terminal=False, color_system=None)
    monkeypatch.setattr(_common, "console", wide)
    row = lambda score, speed, fell: {"gait": "1eeeee72/1", "score": score, "speed_cm_s": speed, "direction": "-x" if speed < 0 else "+x",
                                      "fell": fell, "nonfinite": False}
    with wide.capture() as cap:
        _common.print_top([row(0.424, 7.1, False), row(0.0, -8.9, False), row(0.0, -9.4, True)], "run 1eeeee72", "m")
    text = words(cap.get())
    assert "score 0.000 without a flag (rank 2): a score is the median over the gait's perturbed members" in text, text
    assert "it fell, or did not move the way the file scores" in text and "may point the way that scores nothing" in text
    with wide.capture() as cap:
        _common.print_top([row(0.424, 7.1, False), row(0.0, -9.4, True)], "run 1eeeee72", "m")
    assert "without a flag" not in cap.get()  # "fell" says why already
