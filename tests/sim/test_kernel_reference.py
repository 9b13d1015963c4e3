"""The kernel against the XLA engine it replaced, through the engine's stored numbers.

``tests/data/engine_reference.npz`` holds, for every built-in creature on every ground (the
vertical ones on flat, slope, hill and rough ground), the kitchen-sink file and 6- and 12-link
chains with a stop and a spring at every joint, the XLA engine's final state in float64 after
1000 steps of controllers 0..15 of a search seeded 0, each from the start pose (lifted 1 µm on
terrain, see ``test_kernel.py``). It was made by the engine itself just before it was removed
(issue 46; the script is in the body of the commit that added the file).

The two compute sin, cos and 1/sqrt their own way and order some sums differently, so a run that
sits on a binary sensor's or a contact's threshold parts by chaos; the test asks the median
controller to agree within 1e-11 (relative to the state's size) and at least 14 of the 16 within
1e-9, as the live comparison asked of 64.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.engine_report import random_san_params
from sanlab.sim import kernel

DATA = Path(__file__).resolve().parents[1] / "data"
REFERENCE = np.load(DATA / "engine_reference.npz")
CASES = sorted({k.rsplit("/", 1)[0] for k in REFERENCE.files})


def spec_of(case: str):
    from tests.sim.test_kernel import TERRAINS, _on, chain  # the live comparison's cases, written once

    name, terrain = case.split("/")
    if name.startswith("chain"):
        spec = creature.loads(chain(int(name[5:])), source=name)
    elif name == "kitchen_sink":
        spec = creature.load(str(DATA / "kitchen_sink.toml"))
    else:
        spec = creature.load(name)
    assert terrain in TERRAINS
    return _on(spec, terrain)


@pytest.mark.parametrize("case", CASES)
def test_the_kernel_ends_where_the_xla_engine_ended(case):
    spec = spec_of(case)
    m = sim.compile_creature(spec)
    san, sp = random_san_params(spec, 16, 0)
    q0 = REFERENCE[case + "/q0"]
    pk = kernel.pack(m, san.n_hidden)
    q, anchor = kernel.start(pk, np.repeat(q0[None], 16, 0), seat=False)
    N = san.n_nodes
    r = kernel.run_san(pk, sp.weights, sp.k1, sp.k2, q, np.zeros_like(q), anchor, np.zeros((16, N)), np.zeros((16, N)),
                       1000)
    ref = REFERENCE[case + "/q"]
    err = np.abs(ref - r["q"]).max(1) / (1 + np.abs(ref).max(1))
    assert np.median(err) < 1e-11, np.sort(err)
    assert np.sum(err < 1e-9) >= 14, np.sort(err)
    # the run moved: a creature at rest would agree with any engine
    assert np.abs(ref - q0).max() > 1e-3
