"""Property-based fuzzing of gait import (issue 12, kind 4): valid exports (a phase-1 cart gait and
a tuned bounder gait with model overrides and link scales), mutated (``tests/fuzz.py``), are
either imported as gaits that replay (their creature loads, their network decodes, their
parameters fit) or refused with one line, writing nothing; never another exception."""

from __future__ import annotations

import functools
import json
import math
import tempfile
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import given, seed, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from sanlab.cli import app
from sanlab.gait import Gait, check_params
from sanlab.library import Library, LibraryError
from tests.creature.test_fuzz import FUZZ
from tests.fuzz import creature_texts, mutated
from tests.helpers import time_limit

runner = CliRunner()


@functools.cache
def valid_exports() -> tuple[dict, ...]:
    from tests.cli.test_library import cart_export
    from tests.test_tuned import tuned

    folder = Path(tempfile.mkdtemp(prefix="sanlab-fuzz-"))
    cart = cart_export(folder)
    path, gid = tuned(folder)
    with Library(path) as lib:
        bounder = lib.export_gait(gid)
    return cart, bounder


@st.composite
def exports(draw) -> dict:
    """A valid export, mutated as a document; now and then with a mutated creature file."""
    data = json.loads(json.dumps(draw(st.sampled_from(valid_exports()))))
    if draw(st.integers(0, 4)) == 0:
        data["creature_text"] = draw(creature_texts())
        data.pop("creature_hash", None)
    if draw(st.booleans()):
        data = draw(mutated(data))
    return data


def outcome(data) -> str:
    """"imported" (and the gait replays) or "error" (one line, nothing written)."""
    with tempfile.TemporaryDirectory() as tmp, Library(Path(tmp) / "g.db") as lib, time_limit(cpu=20, wall=120):
        try:
            gid = lib.import_gait(data)
        except LibraryError as e:
            msg = str(e)
            assert "\n" not in msg and msg.isprintable() and len(msg) < 2000, repr(msg)
            assert lib.runs() == [], "a refused import wrote a run"
            return "error"
        g = Gait.from_library(lib, gid)  # the creature loads, the network decodes ...
        check_params(g.spec, g.params.to_json())  # ... the parameters fit it
        p = g.san_params()
        assert p.weights.shape[-2:] == g.weights.shape and all(math.isfinite(float(x)) for x in p.k1.reshape(-1))
        assert g.seconds > 0 and g.metric
    return "imported"


@pytest.mark.slow  # about 14 s on 2 busy cores (the pre-commit subset leaves it out)
@settings(max_examples=300, **FUZZ)
@given(exports())
def test_mutated_exports_import_whole_or_not_at_all(data):
    outcome(data)


@settings(max_examples=30, **FUZZ)
@given(exports(), st.sampled_from(["json", "bom", "latin-1", "truncated"]))
def test_sanlab_import_exits_0_or_2_with_one_line(tmp_path_factory, data, form):
    folder = tmp_path_factory.mktemp("fuzz")
    text = json.dumps(data)
    raw = {"json": text.encode("utf-8", "surrogatepass"), "bom": b"\xef\xbb\xbf" + text.encode("utf-8", "surrogatepass"),
           "latin-1": text.encode("latin-1", "replace"), "truncated": text.encode("utf-8", "surrogatepass")[: len(text) // 2]}[form]
    (folder / "gait.json").write_bytes(raw)
    with time_limit(cpu=30, wall=120):
        r = runner.invoke(app, ["import", str(folder / "gait.json"), "--db", str(folder / "g.db")])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    assert r.exit_code in (0, 2), r.output
    if r.exit_code == 2:
        assert r.stderr.count("\n") == 1 and r.stderr.rstrip("\n").isprintable()


def campaign(n: int, seed_: int = 1) -> Counter:
    """``n`` mutated exports: tried, imported, error (one line, nothing written), other (must be 0)."""
    counts: Counter = Counter()

    @seed(seed_)
    @settings(max_examples=n, **{**FUZZ, "derandomize": False})
    @given(exports())
    def one(data):
        counts["tried"] += 1
        try:
            counts[outcome(data)] += 1
        except BaseException as e:  # counted, not raised: the campaign goes on
            if isinstance(e, KeyboardInterrupt):
                raise
            counts["other"] += 1
            print("OTHER:", type(e).__name__, str(e)[:300])

    one()
    return counts
