"""The kernel's tables are declared once (sanlab/sim/layout.py): the C++ view, the Python
constants, the packing and the ctypes signatures are made from that declaration, or fail here."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from sanlab import creature, sim
from sanlab.sim import kernel, layout, native
from sanlab.sim.state import packed

KERNEL = Path(layout.__file__).parent / "_kernel"


def test_the_cpp_header_is_the_one_the_declaration_writes():
    # after editing layout.py: python -m sanlab.sim.layout (and reinstall: pip install -e .)
    assert (KERNEL / "layout.h").read_text() == layout.header()


def _enumerators(text: str) -> set[str]:
    return {n.split("=")[0].strip() for body in re.findall(r"enum\s*\{([^}]*)\}", text) for n in body.split(",")
            if n.strip()}


def test_no_source_restates_the_declarations_constants():
    declared = _enumerators(layout.header())
    assert {"DIM_LINKS", "K_PATTERN", "A_GAP0", "S_EYE", "TERRAIN_ROUGH", "O_N_TOUCH"} <= declared
    for path in KERNEL.glob("*.[hc]*"):
        if path.name == "layout.h":
            continue
        again = _enumerators(path.read_text()) & declared
        assert not again, f"{path.name} restates {sorted(again)}: use layout.h's"


def test_the_kernel_reads_its_tables_by_column_name_not_by_position():
    # a row of a table is read through layout.h's struct (t.actuator(a).ks), never as f[2]
    for path in KERNEL.glob("*.[hc]*"):
        text = re.sub(r"//[^\n]*", "", path.read_text())
        raw = re.findall(r"\b(?:m|t)\.(li|ti|si|ai|pi|wi|lf|cf|sf|af|pf|ef|wf|rough)\s*(?:\[|\+)", text)
        assert not raw, f"{path.name} indexes tables {sorted(set(raw))} by position"


def _signature(name: str) -> list[tuple[str, str]]:
    text = (KERNEL / "kernel.cpp").read_text()
    m = re.search(rf"void {name}\(([^)]*)\)\s*\{{", text)
    assert m, name
    out = []
    for arg in m.group(1).split(","):
        arg = " ".join(arg.split())
        k = len(arg) - len(re.search(r"(\w+)$", arg).group(1))
        out.append((arg[k:], arg[:k].strip().replace(" *", " *").replace("* ", "*")))
    return out


@pytest.mark.parametrize("name", sorted(kernel.ENTRY_POINTS))
def test_the_ctypes_signatures_are_the_cpp_entry_points(name):
    norm = lambda c: c.replace(" ", "")
    assert [(a, norm(c)) for a, c in _signature(name)] == [(a, norm(c)) for a, c in kernel.ENTRY_POINTS[name]]


def test_a_call_with_a_missing_or_unknown_argument_is_refused_before_the_kernel():
    with pytest.raises(TypeError, match=r"sanlab_start: expected arguments \['dims'"):
        native._call("sanlab_start", dims=0)


def test_the_packed_tables_put_each_number_in_its_declared_column():
    spec = creature.load("tests/data/kitchen_sink.toml")
    m = sim.compile_creature(spec)
    pk, p = packed(m, 3), m.params
    for t in layout.TABLES:
        a = np.asarray(getattr(pk, t.name))
        assert a.dtype == np.dtype(t.dtype) and (a.shape[-1] == t.width or (t.width == 1 and a.ndim == 1)), t.name
    col = lambda table, name: np.asarray(getattr(pk, table))[..., layout.TABLE[table].at(name)]
    np.testing.assert_array_equal(col("lf", "mass"), p.mass)
    np.testing.assert_array_equal(col("lf", "mu_backward"), np.asarray(p.mu)[:, 1])
    np.testing.assert_array_equal(col("lf", "limit_k"), np.asarray(p.limit)[:, 2])
    np.testing.assert_array_equal(col("af", "kd"), p.act_kd)
    np.testing.assert_array_equal(col("af", "point_b_y"), np.asarray(p.act_pts)[:, 1, 1])
    np.testing.assert_array_equal(col("pf", "rest"), np.asarray(p.spr)[:, 2])
    np.testing.assert_array_equal(col("sf", "point_b_x"), np.asarray(p.sens_pts)[:, 1, 0])
    assert col("wf", "dt") == p.dt and col("wf", "hill_centre") == np.asarray(p.terrain)[3]
    assert col("wi", "hidden") == 3 and col("wi", "plane") == layout.PLANES.index("horizontal")
    st = m.structure
    assert col("li", "parent").tolist() == [ls.parent for ls in st.links]
    assert col("li", "dof_rot").tolist() == [ls.dof_rot for ls in st.links]
    kinds = col("si", "kind").tolist()
    assert [layout.SENSORS[k] for k in kinds] == [s[0] for s in st.sensors]
    assert [layout.ACTUATORS[k] for k in col("ai", "kind")] == [a[0] for a in st.actuators]


def test_the_python_constants_are_the_declarations_offsets():
    assert kernel.TABLES == layout.ORDER and set(layout.TABLE) | set(layout.CHAINS) == set(layout.ORDER)
    assert kernel.F_MASS == layout.TABLE["lf"].at("mass") and kernel.W_DT == layout.TABLE["wf"].at("dt")
    assert kernel.KINDS == {"san": 0, "hold": 1, "sine": 2, "reflex": 3, "pattern": 4}
    assert list(kernel.Packed._fields[:len(layout.ORDER)]) == list(layout.ORDER)
    with pytest.raises(KeyError, match="lf has no column 'mas'"):
        layout.TABLE["lf"].at("mas")
    with pytest.raises(KeyError, match=r"columns missing \['load'\], not declared \['lod'\]"):
        layout.TABLE["cf"].build((), 1, point=np.zeros((1, 2)), lod=np.zeros(1))
