"""Issue 57, item 10: every long command reports progress on stderr when its output is not a
terminal (a pipe, a log file), with the one reporter ``tune`` uses (``ProgressLines``): ``search``
(24 s for 1,000 SANs printed nothing), ``reproduce`` (tens of minutes a row printed a row only
when it ended) and ``audit --json`` (its steps went nowhere). The runner's output is no terminal."""

from __future__ import annotations

import re
import shutil

import pytest
from typer.testing import CliRunner

from sanlab.cli import app

runner = CliRunner()

LINE = re.compile(r"(\d+)/(\d+) (controllers|trials) \((\d+) %\), [\d.]+ eval/s, best -?[\d.]+, .* elapsed")


def parsed(line: str) -> tuple[str, ...]:
    """(done, total, unit, percent) of a progress line; fails on a line of another form."""
    m = LINE.search(line)
    assert m is not None, line
    return m.groups()


def test_search_in_a_log_prints_progress_lines(tmp_path):
    db = str(tmp_path / "g.db")
    r = runner.invoke(app, ["search", "cart", "-n", "24", "--batch", "8", "--seconds", "0.5", "--ensemble", "1",
                            "--db", db, "--json"])
    assert r.exit_code == 0, r.output
    lines = [line for line in r.stderr.splitlines() if line.startswith("search: ")]
    done = [int(parsed(line)[0]) for line in lines]
    assert done == [8, 16, 24], r.stderr  # a line a batch here (each is a tenth or more), the last at the end
    assert "about" in lines[1] and "left" in lines[1] and "left" not in lines[-1]
    assert r.stdout.lstrip().startswith("{")  # stdout stays the JSON record


REPRODUCE = ["reproduce", "--creatures", "twolink", "--controllers", "16", "--trials", "8", "--top", "1",
             "--ensemble", "1"]


def test_reproduce_in_a_log_prints_each_step_as_it_goes(tmp_path):
    db, out = str(tmp_path / "t.db"), str(tmp_path / "r.md")
    r = runner.invoke(app, [*REPRODUCE, "--no-audit", "--db", db, "--out", out])
    assert r.exit_code == 0, r.output
    err = r.stderr.splitlines()
    search = [line for line in err if line.startswith("reproduce: twolink (seed 0): search: ")]
    tune = [line for line in err if line.startswith("reproduce: twolink (seed 0): tune: ")]
    assert search and parsed(search[-1])[:3] == ("16", "16", "controllers"), r.stderr
    assert tune and parsed(tune[-1])[:3] == ("8", "8", "trials"), r.stderr
    assert err.index(search[-1]) < err.index(tune[0])
    assert "twolink (seed 0):" in r.stdout and "wrote" in r.stdout  # the row and the report, on stdout


@pytest.mark.slow  # an audit and a selection on 64 members each, twice: about 4 s on 2 cores
def test_reproduce_in_a_log_says_its_audits_steps(tmp_path):
    db, out = str(tmp_path / "t.db"), str(tmp_path / "r.md")
    r = runner.invoke(app, [*REPRODUCE, "--db", db, "--out", out])
    assert r.exit_code == 0, r.output
    err = r.stderr.splitlines()
    assert any(line.startswith("reproduce: twolink (seed 0): audit of chain 0: ") for line in err), r.stderr
    assert any(line.startswith("reproduce: twolink (seed 0): selection of chain 0: ") for line in err), r.stderr
    # again: every step is reused from the library, and nothing runs that would report
    again = runner.invoke(app, [*REPRODUCE, "--db", db, "--out", out])
    assert again.exit_code == 0, again.output
    assert "audit of chain" not in again.stderr and "selection of chain" not in again.stderr
    assert "search: " not in again.stderr and "tune: " not in again.stderr


def test_audit_json_in_a_log_says_its_steps_on_stderr(lib_run, tmp_path):
    src, run_id = lib_run
    db = str(tmp_path / "g.db")
    shutil.copy(src, db)
    r = runner.invoke(app, ["audit", f"{run_id}/1", "--members", "4", "--max-members", "4", "--db", db, "--json"])
    assert r.exit_code == 0, r.output
    assert r.stdout.lstrip().startswith("[")
    steps = r.stderr.splitlines()
    assert steps and all(line.startswith("audit: ") for line in steps), r.stderr
    assert any("re-scored as stored" in line for line in steps) and any("at dt/2" in line for line in steps)
