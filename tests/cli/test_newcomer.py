"""A newcomer's first creature (issue 49): what got in the way, each checked where it showed.

tune's default batch and its progress in a log; the search's refusal of a creature that can never
move; export's closing lines; help without ``<bool>``; read-only commands leaving no ``-wal`` or
``-shm`` beside the library; a mistyped built-in name answered fast with a suggestion."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.library import Library, TuneSettings
from tests.helpers import BASE, ROOT, SANLAB

runner = CliRunner()


def test_default_batch_is_small_on_the_cpu_and_one_per_chain_beyond():
    from sanlab.search.tune import default_batch

    assert default_batch(1, "cpu") == 8 and default_batch(4, "cpu") == 8
    assert default_batch(20, "cpu") == 20 and default_batch(500, "cpu") == 128
    assert default_batch(1, "gpu") == 128
    with pytest.raises(ValueError, match="chains"):
        default_batch(0, "cpu")


def test_tune_in_a_log_prints_progress_lines_and_how_long_it_will_take(lib_run, tmp_path, monkeypatch):
    import sanlab.cli._common as common
    import sanlab.cli.tune as tune_cli

    src, run_id = lib_run
    db = str(tmp_path / "copy.db")
    shutil.copy(src, db)
    monkeypatch.setattr(tune_cli, "LONG_TUNE_S", 0.0)  # every tune is "long": the estimate is said
    monkeypatch.setenv("COLUMNS", "80")
    r = runner.invoke(app, ["tune", f"{run_id}/1", "--trials", "6", "--ensemble", "1", "--db", db])
    assert r.exit_code == 0, r.output
    with Library(db, readonly=True) as lib:
        parent = lib.gait(f"{run_id}/1").gait_id
        tuned_gait = next(x for x in lib.runs() if x.kind == "tune").run_id + "#0"
    row = next(line for line in r.stdout.splitlines() if tuned_gait in line)  # the table's ids, whole
    assert parent in row and max(len(line) for line in r.stdout.splitlines() if "│" in line) <= 80, r.stdout
    assert "tune: about" in r.stderr and "for 6 trials (1 chain, --batch 8)" in r.stderr, r.stderr
    assert r.stderr.count("tune: 6/6 trials (100 %)") == 1, r.stderr  # a line at the end, once
    assert common.duration(200) == "3 min 20 s" and common.duration(3720) == "1 h 02 min"
    with Library(db, readonly=True) as lib:
        tuned = next(x for x in lib.runs() if x.kind == "tune")
        assert isinstance(tuned.settings, TuneSettings) and tuned.settings.batch == 8  # the CPU's default


CANNOT_MOVE = BASE.replace('min_deg = -90\nmax_deg = 45', 'min_deg = 150\nmax_deg = 170').replace(
    '[[sensors]]\ntype = "touch"\nlink = "L1"\ncontact = 0\n\n', '')


def test_search_refuses_a_creature_that_can_never_move_unless_forced(tmp_path):
    path = tmp_path / "still.toml"
    path.write_text(CANNOT_MOVE)
    db = str(tmp_path / "g.db")
    r = runner.invoke(app, ["search", str(path), "-n", "2", "--seconds", "0.05", "--db", db])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "can never move" in lines[0] and "--force" in lines[0] and "add a sensor" in lines[0]
    assert not os.path.exists(db)  # refused before a library or a run was made
    forced = runner.invoke(app, ["search", str(path), "-n", "2", "--seconds", "0.05", "--ensemble", "1",
                                 "--force", "--db", db])
    assert forced.exit_code == 0, forced.output


def test_check_strict_exits_non_zero_on_warnings(tmp_path):
    path = tmp_path / "still.toml"
    path.write_text(CANNOT_MOVE)
    assert runner.invoke(app, ["check", str(path)]).exit_code == 0  # warnings, not errors
    r = runner.invoke(app, ["check", str(path), "--strict"])
    assert r.exit_code == 1 and "--strict" in r.stderr, r.output
    fine = tmp_path / "fine.toml"
    fine.write_text(BASE)
    ok = runner.invoke(app, ["check", str(fine), "--strict"])
    assert ok.exit_code == 0, ok.output


def test_export_to_a_file_says_what_it_wrote_and_what_next(lib_run, tmp_path):
    db, run_id = lib_run
    out = tmp_path / "best.json"
    r = runner.invoke(app, ["export", f"{run_id}/1", "-o", str(out), "--db", db])
    assert r.exit_code == 0 and out.exists(), r.output
    said = " ".join(r.stdout.split())
    assert f"wrote {out}" in said and "next: sanlab import" in said
    toml = tmp_path / "best.toml"
    r = runner.invoke(app, ["export", f"{run_id}/1", "--toml", "-o", str(toml), "--db", db])
    assert r.exit_code == 0 and f"sanlab check {toml}" in " ".join(r.stdout.split()), r.output


def test_help_shows_no_type_after_plain_flags():
    for args in (["--help"], ["runs", "--help"], ["search", "--help"], ["check", "--help"]):
        r = runner.invoke(app, args, terminal_width=100)
        assert r.exit_code == 0 and "<bool>" not in r.output, r.output
    assert "<int>" in runner.invoke(app, ["search", "--help"], terminal_width=100).output  # values keep theirs


def test_read_only_commands_leave_no_wal_or_shm(lib_run, tmp_path):
    src, run_id = lib_run
    db = str(tmp_path / "g.db")
    shutil.copy(src, db)
    assert sorted(os.listdir(tmp_path)) == ["g.db"]
    with Library(db, readonly=True) as lib:
        assert lib._conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"  # type: ignore[union-attr]
    for leftover in ("g.db-wal", "g.db-shm"):  # what that read left, as read-only commands did (issue 49)
        if os.path.exists(tmp_path / leftover):
            os.unlink(tmp_path / leftover)
    for args in (["runs"], ["show", run_id], ["export", f"{run_id}/1"]):
        r = runner.invoke(app, [*args, "--db", db])
        assert r.exit_code == 0, r.output
        assert sorted(os.listdir(tmp_path)) == ["g.db"], (args, os.listdir(tmp_path))


def test_a_mistyped_builtin_is_answered_fast_with_the_close_name(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # -X importtime: each module imported, one line each on stderr, the message last
    r = subprocess.run(SANLAB[:1] + ["-X", "importtime", "-m", "sanlab", "search", "bouncer", "--db",
                                     str(tmp_path / "g.db")], capture_output=True, text=True, env=env, cwd=tmp_path)
    said = [line for line in r.stderr.splitlines() if not line.startswith("import time:")]
    assert r.returncode == 2 and len(said) == 1 and "did you mean 'bounder'?" in said[0], r.stderr
    # answered before the simulator is imported (with JAX, importing it took the 8.5 s this test was for)
    assert not any(line.rstrip().endswith("| sanlab.sim") for line in r.stderr.splitlines())


def test_tables_never_cut_a_gait_id_at_80_columns(monkeypatch):
    from rich.console import Console

    import sanlab.cli._common as common
    import sanlab.cli.modes as modes_cli
    from sanlab.modes import Gait, Mode

    piped = Console(width=80, force_terminal=False, color_system=None)  # what a pipe or a log gets
    monkeypatch.setattr(common, "console", piped)
    monkeypatch.setattr(modes_cli, "console", piped)
    rows = [{"gait": f"eec9bf55/{k}", "score": 2.5, "speed_cm_s": 43.0, "direction": "-x", "fell": True,
             "nonfinite": True, "reproduced": False, "resolution_dependent": True, "verdict": "undecided"}
            for k in (1, 1234)]
    with piped.capture() as cap:
        common.print_top(rows, "run eec9bf55: a long title " * 3, "m")
    assert "eec9bf55/1234" in cap.get() and "…" not in cap.get().split("┃")[-1], cap.get()
    g = Gait("eec9bf55#12345", 2.0, 40.0, {"vx_cm_s": -40.0})
    mode = Mode("a mode with a long name, shuffling", (g,), {"airborne": 0.0, "period_s": 1.5, "turns_per_s": 0.1},
                None, (), 6.0)
    with piped.capture() as cap:
        modes_cli.print_modes([mode], "run eec9bf55")
    assert "eec9bf55#12345" in cap.get(), cap.get()


def test_the_readme_gives_no_contradictory_advice():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "SANLAB_NO_COMPILE_CACHE" not in readme  # no compile cache since the XLA engine went
    assert "audit again with more --members" not in readme  # the advice that named fewer than it used
