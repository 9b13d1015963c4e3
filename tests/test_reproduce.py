"""`sanlab reproduce` on a small budget: the report's rows, counts and sections come from the run."""

from __future__ import annotations

import re
import subprocess

import pytest

from sanlab.creature.table1 import TABLE1
from sanlab.library import Library
from tests.helpers import SANLAB


def _rows(text: str) -> dict[str, list[str]]:
    rows = {r[0]: r for r in (line.strip("|").split("|") for line in text.splitlines()
                              if re.match(r"\| (twolink|fish) \| \d", line)) if len(r) == 14}  # not tracking rows
    return {k.strip(): [c.strip() for c in v] for k, v in rows.items()}


@pytest.mark.slow  # about 2 min: ten compiled models, the fish's 30 s evaluations (audits: the test below)
def test_reproduce_writes_a_table_row_per_creature_and_the_fish_tracking(tmp_path):
    out, db = tmp_path / "t1.md", tmp_path / "t1.db"
    subprocess.run(SANLAB + ["reproduce", "--creatures", "twolink,fish", "--controllers", "8", "--trials", "16",
                             "--seed", "3", "--ensemble", "1", "--no-audit", "--top", "1", "--out", str(out), "--db", str(db)], check=True, capture_output=True)
    text = out.read_text()
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


@pytest.mark.slow  # over 7 s even with a warm compile cache (the pre-commit subset leaves it out)
def test_reproduce_resumes_from_the_library(tmp_path):
    """A second call reuses every stored search, tuning run, audit and selection; an interrupted tuning run
    continues instead of starting again."""
    import sanlab
    from sanlab.reproduce import reproduce

    sanlab.configure()
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


@pytest.mark.parametrize("text, seeds", [("0-4", [0, 1, 2, 3, 4]), ("3", [3]), ("0-1,7,1", [0, 1, 7])])
def test_parse_seeds(text, seeds):
    from sanlab.reproduce import parse_seeds

    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["", "a", "4-2", "1-", "-3", "0-5000", "\u0661"])
def test_parse_seeds_rejects(text):
    from sanlab.reproduce import parse_seeds

    with pytest.raises(ValueError, match="seeds"):
        parse_seeds(text)


@pytest.mark.slow  # two seeds of phase 1 and two chains of phase 2 each
def test_reproduce_over_seeds_spreads_phase_two_over_the_top_gaits(tmp_path):
    import sanlab
    from sanlab.reproduce import reproduce

    sanlab.configure()
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
