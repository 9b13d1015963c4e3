"""The spec's counts agree with the compiled structure's (two places that number dofs)."""

from __future__ import annotations

import pytest

from sanlab import creature, sim
from tests.helpers import DATA


@pytest.mark.parametrize("name", creature.builtin_names() + ["kitchen_sink"])
def test_spec_dofs_match_the_compiled_structure(name):
    spec = creature.load_file(DATA / "kitchen_sink.toml") if name == "kitchen_sink" else creature.load(name)
    st = sim.compile_creature(spec).structure
    assert spec.dofs == st.ndof
    assert [l.dofs for l in spec.links] == [
        0 if ls.dof_x < 0 and ls.dof_rot < 0 else (1 if ls.parent >= 0 else (2 if ls.point else 3))
        for ls in st.links
    ]
