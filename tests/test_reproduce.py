"""`sanlab reproduce` on a small budget: the report's rows, counts and sections come from the run."""

from __future__ import annotations

import re
import subprocess

import pytest

from sanlab.creature.table1 import TABLE1
from sanlab.library import Library
from tests.helpers import SANLAB


@pytest.mark.slow  # about 2 min: ten compiled models, the fish's 30 s evaluations
def test_reproduce_writes_a_table_row_per_creature_and_the_fish_tracking(tmp_path):
    out, db = tmp_path / "t1.md", tmp_path / "t1.db"
    subprocess.run(SANLAB + ["reproduce", "--creatures", "twolink,fish", "--controllers", "8", "--trials", "16",
                             "--seed", "3", "--ensemble", "1", "--out", str(out), "--db", str(db)], check=True, capture_output=True)
    text = out.read_text()
    rows = {r[0]: r for r in (line.strip("|").split("|") for line in text.splitlines()
                              if re.match(r"\| (twolink|fish) \| \d", line))}
    rows = {k.strip(): [c.strip() for c in v] for k, v in rows.items()}
    assert set(rows) == {"twolink", "fish"}
    with Library(str(db)) as lib:
        for name, r in rows.items():
            assert tuple(int(c) for c in r[1:5]) == TABLE1[name][:4]
            tuned = r[9].strip("`")
            assert abs(lib.gait(tuned).speed_cm_s - float(r[7])) < 0.05  # the row is the stored tuned gait
            start = lib.gait(lib.get_run(tuned.split("/")[0]).parent_gait)
            assert abs(start.speed_cm_s - float(r[6])) < 0.05  # ... tuned from the search's best
            # annealing keeps the best it has seen (single samples: the held-out re-evaluation of
            # the best vector is its own score; with an ensemble it is scored on fresh draws). The
            # search and the tuner are two compiled programs (the tuner batches the creature's
            # parameters too), so the same controller's score may differ in its last float32 bits
            assert lib.gait(tuned).score >= start.score * (1 - 1e-6) - 1e-9
    # only the fish pursues a follow point; it was evaluated for its file's 30 s
    assert "## Tracking" in text and "| fish | best (" in text and "| twolink |" not in text.split("## Tracking")[1]
    assert "## Robustness" not in text  # that section is the bounder's
    with Library(str(db)) as lib:
        searches = [e for e in lib.runs() if e.kind == "search"]
        assert sorted(r.creature for r in searches) == ["fish", "twolink"]
        assert {r.creature: r.params["seconds"] for r in searches} == {"fish": 30.0, "twolink": 6.0}
