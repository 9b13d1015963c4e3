"""``sanlab tune`` in a fresh process: the JSON it prints, and a bad method as one line."""

from __future__ import annotations

import json
import subprocess

from tests.helpers import SANLAB


def test_tune_cli_json(bounder_run):
    db, run_id = bounder_run
    r = subprocess.run(SANLAB + ["tune", f"{run_id}/1", "--method", "sga", "--trials", "5", "--batch", "64",
                                 "--db", str(db), "--json"], capture_output=True, text=True, check=True)
    out = json.loads(r.stdout)
    assert set(out) == {"gait", "tuned_gait", "before", "after", "trials"}
    assert out["trials"] == 5 and out["after"]["score"] >= out["before"]["score"]
    assert set(out["before"]) == {"score", "speed_cm_s"}
    bad = subprocess.run(SANLAB + ["tune", f"{run_id}/1", "--method", "newton", "--db", str(db)],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
