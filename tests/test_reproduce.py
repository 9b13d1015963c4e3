"""`sanlab reproduce` on a small budget: the report's rows, counts and sections come from the run."""

from __future__ import annotations

import re
import subprocess

import pytest

from sanlab.creature import read_source
from sanlab.creature.table1 import TABLE1
from sanlab.library import Library
from tests.helpers import SANLAB


def _rows(text: str) -> dict[str, list[str]]:
    rows = {r[0]: r for r in (line.strip("|").split("|") for line in text.splitlines()
                              if re.match(r"\| (twolink|fish) \| \d", line)) if len(r) == 14}  # not tracking rows
    return {k.strip(): [c.strip() for c in v] for k, v in rows.items()}


@pytest.mark.slow  # about 8 s on 2 busy cores (the pre-commit subset leaves it out)
def test_reproduce_writes_a_table_row_per_creature_and_the_fish_tracking(tmp_path):
    out, db = tmp_path / "t1.md", tmp_path / "t1.db"
    subprocess.run(SANLAB + ["reproduce", "--creatures", "twolink,fish", "--controllers", "8", "--trials", "16",
                             "--seed", "3", "--ensemble", "1", "--no-audit", "--top", "1", "--out", str(out), "--db", str(db)], check=True, capture_output=True)
    text = out.read_text()
    assert text.startswith("<!-- made by: sanlab reproduce --creatures twolink,fish --controllers 8 --trials 16")
    rows = _rows(text)
    assert set(rows) == {"twolink", "fish"}
    with Library(str(db)) as lib:
        for name, r in rows.items():
            assert tuple(int(c) for c in r[1:5]) == TABLE1[name][:4]
            tuned = r[12].split("`")[1]
            assert abs(lib.gait(tuned).speed_cm_s - float(r[7])) < 0.05  # the row is the stored tuned gait
            start = lib.gait(lib.get_run(tuned.split("#")[0]).parent_gait)
            assert abs(start.speed_cm_s - float(r[6])) < 0.05  # ... tuned from the search's best
            # annealing keeps the best it has seen (single samples: the held-out re-evaluation of
            # the best vector is its own score; with an ensemble it is scored on fresh draws). The
            # search and the tuner are two compiled programs (the tuner batches the creature's
            # parameters too), so the same controller's score may differ in its last float32 bits
            assert lib.gait(tuned).score >= start.score * (1 - 1e-6) - 1e-9
            assert lib.audit(tuned) is None and r[8:11] == ["-", "not audited", "not selected"]  # --no-audit
    # only the fish pursues a follow point; it was evaluated for its file's 30 s
    assert "## Tracking" in text and "| fish | 3 | best (" in text and "| twolink |" not in text.split("## Tracking")[1]
    assert "## Robustness" not in text  # that section is the bounder's
    with Library(str(db)) as lib:
        searches = [e for e in lib.runs() if e.kind == "search"]
        assert sorted(r.creature for r in searches) == ["fish", "twolink"]
        assert {r.creature: r.params["seconds"] for r in searches} == {"fish": 30.0, "twolink": 6.0}


@pytest.mark.slow  # about 6 s on 2 busy cores (the pre-commit subset leaves it out)
def test_reproduce_resumes_from_the_library(tmp_path):
    """A second call reuses every stored search, tuning run, audit and selection; an interrupted tuning run
    continues instead of starting again."""
    from sanlab.reproduce import reproduce

    def call(lib: Library, controllers: int = 8) -> list[str]:
        return _rows(reproduce(lib, ["twolink"], seed=2, controllers=controllers, trials=8, ensemble=1,
                               log=lambda s: None, top=1))["twolink"]

    with Library(str(tmp_path / "r.db")) as lib:
        first = call(lib)
        runs = {r.run_id: r.status for r in lib.runs()}
        # the tuned gait is audited, and its row prints the stored audit
        gaits = first[12].split("`")
        audit = lib.audit(gaits[1])
        assert audit is not None
        assert first[8] == " · ".join(f"{k} {v:.1f}" for k, v in audit.result["speeds"].items())
        assert first[9].startswith(audit.verdict)  # robust, resolution-dependent, undecided or not reproduced
        # ... and its run's audited selection: the robust gait's speed, or that no rung kept its speed
        selected = [e for e in lib.top(gaits[1].split("#")[0], None) if e.idx == 1]
        if selected:
            assert gaits[3] == selected[0].gait_id and first[10].startswith(f"{selected[0].speed_cm_s:.1f} (")
            assert not lib.audit(selected[0].gait_id).flagged
        else:
            assert first[10].startswith("none of") and len(gaits) == 3
        assert sorted(r.kind for r in lib.runs()) == ["search", "tune"]
        second = call(lib)
        assert {r.run_id: r.status for r in lib.runs()} == runs  # nothing run again
        assert second[:13] == first[:13] and second[13].endswith("(resumed)") and not first[13].endswith("(resumed)")
        tune_run = next(r.run_id for r in lib.runs() if r.kind == "tune")
        lib.set_status(tune_run, "interrupted")
        third = call(lib)
        assert {r.run_id: r.status for r in lib.runs()} == runs  # continued to "done", not started anew
        assert third[:13] == first[:13]
        # other settings are another job: a new search
        call(lib, controllers=9)
        assert sum(r.kind == "search" for r in lib.runs()) == 2


@pytest.mark.slow  # about 10 s on 2 busy cores
def test_reproduce_with_the_rhythm_search_searches_in_its_generations_and_resumes(tmp_path):
    from sanlab.reproduce import reproduce
    from sanlab.search.pattern import POPSIZE

    def call(lib: Library) -> list[str]:
        return _rows(reproduce(lib, ["twolink"], seed=2, controllers=40, trials=8, ensemble=1, log=lambda s: None,
                               top=1, audit=False, strategy="rhythm"))["twolink"]

    with Library(str(tmp_path / "r.db")) as lib:
        first = call(lib)
        [search] = [r for r in lib.runs() if r.kind == "search"]
        assert search.params["strategy"] == "rhythm" and search.params["batch"] == POPSIZE
        clocks = [e for e in lib.top(search.run_id, None) if e.idx >= 6]  # after the warm-up's 6 random SANs
        assert len(clocks) == 34 and all("k1" in e.params for e in clocks)
        runs = {r.run_id: r.status for r in lib.runs()}
        assert call(lib)[:13] == first[:13] and {r.run_id: r.status for r in lib.runs()} == runs  # reused


def test_phase_two_adds_a_chain_beside_the_stored_ones_it_still_wants(tmp_path):
    """Issue 56: where phase 2's starts change (a rhythm row now starts its last chain on the
    warm-up's best SAN), the chains already stored for the same start and number are kept and only
    the new one is tuned, under its own number (tests/search/test_tune.py: a chain tuned alone is
    that chain of a run that tuned several)."""
    from sanlab.evaluate.ensemble import default_ensemble
    from sanlab.reproduce import _tune
    from sanlab.search.runner import run_search

    text, source = read_source("twolink")
    ens = default_ensemble(1)
    with Library(str(tmp_path / "r.db")) as lib:
        run_id = run_search(lib, text, source, controllers=8, seed=0, batch=8, ensemble=ens)
        a, b, c = (e.gait_id for e in lib.top(run_id, 3))
        old, _ = _tune(lib, text, [a, b], 0, 6, ens)
        new, stored = _tune(lib, text, [a, c], 0, 6, ens)
        assert stored and new[0] == old[0] and new[1] != old[1]  # chain 0 kept, chain 1 made for c
        assert lib.get_run(new[1].split("#")[0]).parent_gait == c
        assert lib.get_run(new[1].split("#")[0]).params["chain"] == 1  # its stream: chain 1's, as if made with a
        again, stored = _tune(lib, text, [a, c], 0, 6, ens)
        assert stored and again == new  # and both are reused as they are


def test_summary_over_seeds_takes_median_min_and_max_of_the_robust_speeds():
    """A seed without a robust gait counts 0 in the median; the verdicts and Table 1 hits are tallied."""
    from sanlab.reproduce import Row, summary

    def row(seed, speed, verdict, tracking=None):
        robust = {"gait": None if speed is None else f"r{seed}#1", "speed": speed, "trial": 3, "worst": 0.01,
                  "candidates": 4}
        return Row("twolink", (2, 6, 1, 5), 12.0, f"s{seed}", 10.0, 15.0, f"t{seed}#0", 0.2, 60.0, "distance",
                   {"verdict": verdict}, False, robust, seed=seed, tracking=tracking)

    rows = [row(0, 14.0, "robust"), row(1, None, "resolution-dependent"), row(2, 11.0, "undecided"),
            row(3, 20.0, "undecided"), row(4, 12.0, "robust")]
    [header, _, line] = summary(rows, [0, 1, 2, 3, 4])
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[:7] == ["twolink", "12", "12.0", "0.0", "20.0", "14.0 · 0.0 · 11.0 · 20.0 · 12.0", "3 of 5"]
    assert cells[7] == "robust 2 · undecided 2 · resolution-dependent 1"
    assert cells[8] == "-" and cells[9] == "5.0 min"
    track = {"best": {"mean_distance_m": 0.5}, "median random": {"mean_distance_m": 2.0}}
    [_, _, line] = summary([row(0, 14.0, "robust", track), row(1, 14.0, "robust", {**track, "best": {"mean_distance_m": 1.0}})], [0, 1])
    assert line.strip("|").split("|")[8].strip() == "0.38"  # median of 0.25 and 0.5


def test_shortfalls_name_each_missed_goal_and_whether_tuning_or_the_audit_lost_it():
    from sanlab.reproduce import Row, shortfalls

    def row(name, seed, after, speed, verdict="robust", chains=None, paper=12.0, ratio=None):
        robust = {"gait": f"r{seed}#1", "speed": speed, "trial": 3, "worst": 0.01, "candidates": 4}
        track = None if ratio is None else {"best": {"mean_distance_m": ratio}, "median random": {"mean_distance_m": 1.0}}
        return Row(name, (2, 6, 1, 5), paper, f"s{seed}", 10.0, after, f"t{seed}#0", 0.2, 60.0, "distance",
                   {"verdict": verdict}, False, robust, seed=seed, chains=chains, tracking=track)

    seeds = [0, 1, 2]
    met = [row("met", sd, 15.0, 13.0) for sd in seeds]
    slow = [row("slow", sd, 9.0, 8.0, chains=[9.0, 13.0]) for sd in seeds]  # one chain of six got there
    refused = [row("refused", sd, 16.0, 10.0, verdict="resolution-dependent") for sd in seeds]
    lost = [row("lost", sd, 5.0, 5.0, paper=None, ratio=0.5) for sd in seeds]
    out = shortfalls(met + slow + refused + lost, seeds)
    assert [line.split("**")[1] for line in out] == ["slow", "refused", "lost"]  # "met" meets it
    assert "median 8.0 of 12 cm/s (0 of 3 seeds at it)" in out[0] and "tuning itself falls short" in out[0]
    assert "of all 6 chains, 3 reached 12 (the fastest 13.0)" in out[0]
    assert "the audit refuses it" in out[1] and "3 quoted chain bests at the speed were refused" in out[1]
    assert "resolution-dependent" in out[1] and "Speed" not in out[2]
    assert "Tracking: median ratio 0.50 against a goal below 0.33 (0 of 3 seeds below it)" in out[2]
    assert shortfalls(met, seeds) == []


@pytest.mark.parametrize("text, seeds", [("0-4", [0, 1, 2, 3, 4]), ("3", [3]), ("0-1,7,1", [0, 1, 7])])
def test_parse_seeds(text, seeds):
    from sanlab.reproduce import parse_seeds

    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["", "a", "4-2", "1-", "-3", "0-5000", "\u0661"])
def test_parse_seeds_rejects(text):
    from sanlab.reproduce import parse_seeds

    with pytest.raises(ValueError, match="seeds"):
        parse_seeds(text)


def test_reproduce_over_seeds_spreads_phase_two_over_the_top_gaits(tmp_path):
    from sanlab.reproduce import reproduce

    with Library(str(tmp_path / "s.db")) as lib:
        def call():
            return reproduce(lib, ["twolink"], seeds=[0, 1], controllers=6, trials=9, ensemble=1, audit=False,
                             top=2, log=lambda s: None)
        text = call()
        assert "## Over 2 seeds" in text and "## Seed 0" in text and "## Seed 1" in text
        assert "spread over the best 2 (4 each" in text
        tunes = [r for r in lib.runs() if r.kind == "tune"]
        assert len(tunes) == 4 and sorted(r.settings.chain for r in tunes) == [0, 0, 1, 1]
        assert all(r.settings.trials == 4 and r.status == "done" for r in tunes)
        for r in tunes:  # chain k tunes the k-th best of its seed's search
            search = next(s for s in lib.runs() if s.kind == "search" and s.seed == r.seed)
            assert r.parent_gait == lib.top(search.run_id, 2)[r.settings.chain].gait_id
        for sd in (0, 1):  # each seed's row stands on one of its own chains
            section = text.split(f"## Seed {sd}")[1].split("## ")[0]
            tuned = _rows(section)["twolink"][12].split("`")[1]
            assert lib.get_run(tuned.split("#")[0]).seed == sd
        runs = {r.run_id: r.status for r in lib.runs()}
        def summary_row(t):
            return next(line for line in t.split("## Over")[1].split("## Seed")[0].splitlines()
                        if line.startswith("| twolink |")).split("|")[1:11]
        again = call()
        assert summary_row(again)[:9] == summary_row(text)[:9]  # all but the wall time
        assert summary_row(again)[9].strip().endswith("(resumed)") and "resumed" not in summary_row(text)[9]
        assert {r.run_id: r.status for r in lib.runs()} == runs  # nothing run again


def _made_row(seed: int, speed: float | None):
    from sanlab.reproduce import Row

    robust = {"gait": None if speed is None else f"r{seed}#1", "speed": speed, "trial": 3, "worst": 0.01, "candidates": 4}
    return Row("twolink", (2, 6, 1, 5), 12.0, f"s{seed}", 10.0, 15.0, f"t{seed}#0", 0.2, 60.0, "distance",
               {"verdict": "robust", "changes": {"dt/2": 0.01}}, False, robust, seed=seed, device="2 x cpu",
               chains=[15.0, 9.5])


def test_a_ledger_gives_back_the_rows_it_was_given_and_names_a_bad_line(tmp_path):
    from sanlab.creature import read_source
    from sanlab.evaluate.ensemble import default_ensemble
    from sanlab.reproduce import Ledger, row_key

    text = read_source("twolink")[0]
    ens = default_ensemble(8)
    keys = [row_key("twolink", text, sd, 200, 1000, ens, 4, True) for sd in (0, 1)]
    path = tmp_path / "rows.jsonl"
    book = Ledger(path)
    assert book.get(keys[0]) is None
    book.add(keys[0], _made_row(0, 14.0))
    book.add(keys[1], _made_row(1, None))
    again = Ledger(path)  # read back from the file
    for sd, key in enumerate(keys):
        got = again.get(key)
        assert got is not None and got.ledger and got.seed == sd and got.counts == (2, 6, 1, 5)
        assert got.robust == _made_row(sd, 14.0 if sd == 0 else None).robust and got.device == "2 x cpu"
        assert got.chains == [15.0, 9.5]
    # another creature file, budget or ensemble is another row
    assert again.get(row_key("twolink", text + "\n# changed\n", 0, 200, 1000, ens, 4, True)) is None
    assert again.get(row_key("twolink", text, 0, 200, 1000, default_ensemble(4), 4, True)) is None
    assert again.get(row_key("twolink", text, 0, 200, 500, ens, 4, True)) is None
    # a row another simulator made (the XLA engine's keys have no engine) is made again
    assert keys[0]["engine"] == "kernel"
    Ledger(tmp_path / "old.jsonl").add({k: v for k, v in keys[0].items() if k != "engine"}, _made_row(0, 14.0))
    assert Ledger(tmp_path / "old.jsonl").get(keys[0]) is None
    with path.open("a") as f:
        f.write('{"key": {}, "row": {"creature": "x", "bogus": 1}}\n')
    with pytest.raises(ValueError, match=r"rows.jsonl: line 3: expected a ledger entry"):
        Ledger(path)


def test_reproduce_refuses_a_malformed_ledger_before_any_run(tmp_path):
    from typer.testing import CliRunner

    from sanlab.cli import app

    bad, db = tmp_path / "rows.jsonl", tmp_path / "g.db"
    bad.write_text("not json\n")
    r = CliRunner().invoke(app, ["reproduce", "--creatures", "cart", "--ledger", str(bad), "--db", str(db)])
    assert r.exit_code == 2 and "rows.jsonl: line 1: expected a ledger entry" in r.stderr, r.output
    assert len(r.stderr.strip().splitlines()) == 1 and not db.exists()


@pytest.mark.slow  # phase 1 and 2 of the two-link chain on a tiny budget, then the same from the ledger
def test_a_table_made_in_pieces_is_the_table_made_at_once(tmp_path):
    """Rows in the ledger are taken from it without the library: a second call on an empty
    library runs nothing and writes the same tables; the bounder's §6.2 section travels too."""
    from sanlab.reproduce import reproduce

    ledger = tmp_path / "rows.jsonl"
    kw = dict(controllers=6, trials=4, ensemble=1, audit=False, top=1, log=lambda s: None, ledger=ledger)
    with Library(str(tmp_path / "a.db")) as lib:
        first = reproduce(lib, ["twolink", "bounder"], seeds=[0, 1], **kw)
    assert len(ledger.read_text().splitlines()) == 4
    with Library(str(tmp_path / "b.db")) as lib:
        second = reproduce(lib, ["twolink", "bounder"], seeds=[0, 1], **kw)
        assert lib.runs() == []  # nothing run: every row came from the ledger
    body = lambda t: t.split("\n", 3)[3]  # all but the heading line with the wall time
    assert body(second) == body(first) and "## Robustness" in second and "rows made in pieces" in second
    assert len(ledger.read_text().splitlines()) == 4  # nothing appended again
    with Library(str(tmp_path / "b.db")) as lib:  # a new seed is made and appended; the others still come from the file
        reproduce(lib, ["twolink"], seeds=[0, 2], **kw)
        assert sorted(r.seed for r in lib.runs()) == [2, 2]
    assert len(ledger.read_text().splitlines()) == 5


def test_the_report_says_which_creature_files_changed_and_why(tmp_path):
    """Issue 47: a "Creature files" section, a row per creature: its file's SHA-256, whether the
    ledger holds rows of an earlier file of it (same seeds and budget, any simulator), and the
    file's history entries since those rows."""
    import json
    from dataclasses import asdict

    from sanlab.creature import loads, read_source
    from sanlab.evaluate.ensemble import default_ensemble
    from sanlab.reproduce import Ledger, creature_files, markdown, row_key

    ens = default_ensemble(8)
    history = ("2026-11-01: the paper's chain; the first version", "2026-12-03: the heavy bar 5 % heavier; faster",
               "2026-12-04: hip range +-100 deg | was +-90; robust at dt/4")
    old = read_source("twolink")[0]
    new = "history = [\n" + "".join(f'    "{h}",\n' for h in history) + "]\n" + old
    assert loads(new).history == history

    def keys(text, trials=1000, engine=True):
        ks = [row_key("twolink", text, sd, 200, trials, ens, 4, True) for sd in (0, 1)]
        return ks if engine else [{k: v for k, v in key.items() if k != "engine"} for key in ks]

    oldest = old + "\n# the XLA engine's file\n"
    path = tmp_path / "rows.jsonl"
    lines = [(keys(oldest, engine=False)[0], _made_row(0, 30.0), "2026-11-20T09:00:00Z"),  # before issue 46
             (keys(old)[0], _made_row(0, 14.0), "2026-12-03T10:00:00Z"),
             (keys(old)[1], _made_row(1, 12.0), "2026-12-03T11:00:00Z"),
             (keys(old, trials=500)[0], _made_row(0, 99.0), "2026-12-04T09:00:00Z"),  # another budget: not counted
             (keys(new)[0], _made_row(0, 20.0), "2026-12-05T10:00:00Z"),
             (keys(new)[1], _made_row(1, 21.0), "2026-12-05T11:00:00Z"),
             (keys(new)[1], _made_row(1, 22.0), "2026-12-06T11:00:00Z")]  # made again: the later line wins
    path.write_text("".join(json.dumps({"key": k, "row": asdict(r), "sanlab": "0.1.0", "made": m}) + "\n"
                            for k, r, m in lines))
    book = Ledger(path)
    assert len(book.entries) == 7 and book.get(keys(new)[1]).robust_speed == 22.0  # get as before: the later line
    [before, earlier, now] = book.files(keys(new))
    assert (before.sha256, len(before.rows), earlier.sha256) == (keys(oldest)[0]["creature_sha256"], 1,
                                                                 keys(old)[0]["creature_sha256"])
    assert [r.robust_speed for r in now.rows] == [20.0, 22.0] and (now.first, now.last) == (lines[4][2], lines[6][2])

    [f] = creature_files(book, {"twolink": keys(new)}, {"twolink": history})
    assert f.changed() == (f"changed: earlier file {earlier.sha256[:12]} (2 rows, made 2026-12-03, median 13.0 cm/s), "
                           "and 1 older file")
    assert f.why() == list(history[1:])  # made on or after the earlier rows' day
    rows = [_made_row(0, 20.0), _made_row(1, 22.0)]
    text = markdown(rows, [0, 1], 200, 1000, 0.0, files=[f])
    section = text.split("## Creature files")[1].split("## Seed 0")[0]
    assert text.index("### Where the goal is not met") < text.index("## Creature files") < text.index("## Seed 0")
    [row] = [ln for ln in section.splitlines() if ln.startswith("| twolink |")]
    cells = [c.strip() for c in row.strip("|").split(" | ")]
    assert cells == ["twolink", f"`{now.sha256[:12]}`", f.changed(),
                     f"{history[1]} · 2026-12-04: hip range +-100 deg \\| was +-90; robust at dt/4"]

    # unchanged: its first rows' day, every entry; no ledger; a file without history
    [same] = creature_files(Ledger(tmp_path / "fresh.jsonl"), {"twolink": keys(new)}, {"twolink": history})
    assert same.changed() == "no rows in the ledger yet" and same.why() == list(history)
    book = Ledger(tmp_path / "fresh.jsonl")
    book.add(keys(new)[0], rows[0])
    [same] = creature_files(book, {"twolink": keys(new)}, {"twolink": history})
    assert re.fullmatch(r"unchanged since its first rows in the ledger \(\d{4}-\d\d-\d\d\)", same.changed())
    [none] = creature_files(None, {"twolink": keys(old)}, {})
    assert none.changed() == "no ledger" and none.why() == []
    # one seed: the files first, then the seed's table under a heading of its own
    one = markdown(rows[:1], 0, 200, 1000, 0.0, files=[none])
    assert "| twolink | `" + keys(old)[0]["creature_sha256"][:12] + "` | no ledger | - |" in one
    assert one.index("## Creature files") < one.index("## Seed 0") < one.index("| twolink | 2 | 6 |")
    assert "## Creature files" not in markdown(rows[:1], 0, 200, 1000, 0.0)  # not given: as before


def test_the_reports_notes_say_the_audits_nudges_and_members():
    from sanlab.audit import MAX_MEMBERS, MEMBERS, NUDGES
    from sanlab.reproduce import markdown

    [note] = [ln for ln in markdown([], [0], 200, 1000, 0.0).splitlines() if ln.startswith("*Tuned gait nudged*")]
    assert [n for n, _, _ in NUDGES] == ["dt/2", "dt/4"] and "with the step at dt/2 and dt/4" in note
    assert f"({MEMBERS}, and up to {MAX_MEMBERS} in further looks" in note and "over the 2 nudges together" in note
    assert "32" not in note and "and in float64" not in note  # the XLA engine's audit: 32 starts, a float64 nudge


def test_standing_still_tracks_as_the_kernel_scores_a_still_creature():
    # "moved usefully" under tracking compares a SAN's score with standing still's, worked out on
    # the host from the follow path: it must be the kernel's score of a creature that stays put
    from sanlab.creature.spec import Creature, Evaluation, Follow, Ground, Link, Shape, World
    from sanlab.reproduce import _still_tracking
    from tests.test_metrics import evaluate

    dot = Link("dot", 1.0, 0.0, (0.2, -0.1), Shape("point"), contacts=())
    world = World(plane="horizontal", ground=Ground(friction=0.0), follow=Follow(((1.0, 0.0), (2.0, 1.0), (3.0, 0.0)), 0.4))
    spec = Creature("dot", (dot,), world=world, evaluation=Evaluation(metric="tracking"))
    still = evaluate(spec, None, seconds=3.0)["score"]
    assert _still_tracking(spec, 3.0) == pytest.approx(still, rel=1e-9)
    assert 0.3 < still < 0.9  # the point drew away from it


@pytest.mark.slow  # about 20 s on 2 busy cores: two budgets, a ceiling and the crawler's 30 s rollouts
def test_a_second_budget_is_made_beside_the_first_and_the_report_opens_with_both(tmp_path):
    """Issue 56: Table 1 at two budgets. The second budget's rows are made for the creatures scored
    by a speed only (the crawler tracks a point: no second row, no pattern ceiling), kept in the
    same ledger under their own keys, and the report opens with both side by side, each budget's
    median over the creature's best ceiling."""
    from sanlab.reproduce import reproduce

    ledger = tmp_path / "rows.jsonl"
    kw = dict(seeds=[0], controllers=4, trials=2, ensemble=1, audit=False, top=1, log=lambda s: None, ledger=ledger,
              also=("random", 6), ceiling=32)
    with Library(str(tmp_path / "a.db")) as lib:
        text = reproduce(lib, ["twolink", "crawler"], **kw)
        searches = sorted((r.creature, r.params["controllers"]) for r in lib.runs()
                          if r.kind == "search" and r.params.get("strategy", "random") == "random")
        patterns = [r.creature for r in lib.runs() if r.kind == "search" and r.params.get("strategy") == "pattern"]
    assert searches == [("crawler", 4), ("twolink", 4), ("twolink", 6)]
    assert patterns == ["twolink"]  # one ceiling, measured once for both of twolink's rows
    lines = ledger.read_text().splitlines()
    assert len(lines) == 3
    head = text.split("## Two budgets, over seed 0\n\n")[1].split("\n\n")[0].splitlines()
    assert "4 random SANs: robust, median" in head[0] and "6 random SANs: robust, median" in head[0]
    twolink = [c.strip() for c in next(x for x in head if x.startswith("| twolink")).strip("|").split("|")]
    crawler = [c.strip() for c in next(x for x in head if x.startswith("| crawler")).strip("|").split("|")]
    assert crawler[1] == "U" and crawler[4:] == ["-", "-", "-", "-", "-"]  # no second row, no ceiling
    ceiling = float(twolink[6].split()[0])
    assert ceiling > 0 and twolink[7] == f"{float(twolink[2]) / ceiling:.2f}" and twolink[8] == f"{float(twolink[4]) / ceiling:.2f}"
    assert "### 4 random SANs" in text and "### 6 random SANs" in text
    with Library(str(tmp_path / "b.db")) as lib:  # from the ledger alone: nothing run, the same report
        again = reproduce(lib, ["twolink", "crawler"], **kw)
        assert lib.runs() == []
    body = lambda t: t.split("\n", 3)[3]
    assert body(again) == body(text)
