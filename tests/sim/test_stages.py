"""Single stages of the kernel against their definitions, beside the end-to-end tests: the
stick-slip law every contact's friction uses (``_kernel/contacts.h``), the ground (``terrain.h``)
and the dense solve (``solve.h``). A small program (tests/sim/stages/stages.cpp) includes the
kernel's headers and runs one stage in plain double; it is built with the kernel's flags."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from sanlab import creature, sim

HERE = Path(__file__).resolve().parent / "stages"


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    if shutil.which("g++") is None:
        pytest.skip("no C++ compiler (g++) to build the stage driver")
    exe = tmp_path_factory.mktemp("stages") / "stages"
    subprocess.run(["g++", "-std=c++17", "-O2", "-march=native", "-ffp-contract=off", "-fno-math-errno", str(HERE / "stages.cpp"),
                    "-o", str(exe)], check=True)

    def run(cmd: str, *numbers) -> np.ndarray:
        text = " ".join(repr(float(x)) for x in numbers)
        out = subprocess.run([str(exe), cmd], input=text, capture_output=True, text=True, check=True).stdout
        return np.array([float(v) for v in out.split()])

    return run


# ---------------------------------------------------------------- the stick-slip law

GK, SLIP, H = 5e4, 0.01, 1e-3


@pytest.mark.parametrize("stretch,v", [(1e-6, 0.0), (-2e-6, 1e-3), (0.0, -4e-3)])
def test_a_contact_inside_the_friction_cone_sticks_as_a_spring_damper_to_its_anchor(stage, stretch, v):
    limit = 0.5 * 20.0  # mu N
    coef, f, held = stage("stick_slip", stretch, v, limit, GK, SLIP, H)
    c = limit / SLIP
    trial = -GK * stretch - c * v
    assert abs(trial) <= limit  # the case is one that sticks
    assert coef == H * c + H * H * GK  # the implicit spring-damper's matrix term
    assert f == trial - H * GK * v  # its predicted force
    assert held == stretch  # the anchor stays where it was


@pytest.mark.parametrize("v", [0.5, -2.0, 0.02])
def test_a_contact_beyond_the_cone_slides_with_coulomb_friction_against_its_velocity(stage, v):
    limit = 3.0
    coef, f, held = stage("stick_slip", 0.0, v, limit, GK, SLIP, H)
    slide = limit / max(abs(v), SLIP)
    assert f == -slide * v and coef == H * slide and held == 0.0
    assert abs(f) == pytest.approx(limit)  # |F| = mu N once sliding faster than the slip speed


def test_no_load_no_friction_and_the_stretch_is_capped_at_the_cone(stage):
    assert stage("stick_slip", 1e-3, 0.0, 0.0, GK, SLIP, H)[1] == 0.0  # a contact off the ground
    coef, f, held = stage("stick_slip", 1.0, 0.0, 10.0, GK, SLIP, H)  # stretched far past limit / gk
    assert held == 10.0 / GK and f == -10.0  # the anchor dragged to the cone's edge, pulling back mu N


# ---------------------------------------------------------------- the ground


def _terrain_model(kind: str, **terrain):
    text, _ = creature.read_source("bounder")
    spec = creature.loads(text, "bounder.toml")
    import dataclasses

    from sanlab.creature.spec import Terrain

    spec = dataclasses.replace(spec, world=dataclasses.replace(spec.world, terrain=Terrain(kind, **terrain)))
    return sim.compile_creature(spec)


@pytest.mark.parametrize("kind,terrain", [("flat", {}), ("slope", {"angle": 0.2}),
                                          ("hill", {"height": 0.1, "width": 0.8, "center": 0.5}),
                                          ("rough", {"height": 0.02, "wavelength": 0.3, "seed": 4})])
def test_the_kernels_ground_is_the_files_terrain_and_its_slope_the_heights_derivative(stage, kind, terrain):
    m = _terrain_model(kind, **terrain)
    p = m.params
    x = np.linspace(-0.6, 1.9, 41)
    rough = np.asarray(p.rough, np.float64)
    out = stage("terrain", ["flat", "slope", "hill", "rough"].index(kind), *np.asarray(p.terrain, np.float64),
                len(rough), *rough.ravel(), len(x), *x).reshape(-1, 2)
    h, dh = sim.terrain_height(m, x)  # NumPy's sin and cos, the file's definition
    np.testing.assert_allclose(out[:, 0], h, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out[:, 1], dh, rtol=0, atol=1e-14)
    e = 1e-6
    up = stage("terrain", ["flat", "slope", "hill", "rough"].index(kind), *np.asarray(p.terrain, np.float64),
               len(rough), *rough.ravel(), len(x), *(x + e)).reshape(-1, 2)[:, 0]
    np.testing.assert_allclose((up - out[:, 0]) / e, out[:, 1], atol=1e-4 * max(1.0, np.abs(out[:, 1]).max()))
    if kind != "flat":
        assert np.ptp(out[:, 0]) > 0


# ---------------------------------------------------------------- the solve


@pytest.mark.parametrize("D", [1, 3, 9])
def test_the_dense_solve_solves_a_symmetric_positive_definite_system(stage, D):
    rng = np.random.default_rng(D)
    J = rng.normal(size=(D, D))
    A = J @ J.T + D * np.eye(D)
    b = rng.normal(size=D)
    x = stage("solve", D, *A.ravel(), *b)
    np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(A @ x, b, rtol=1e-12, atol=1e-12)


def test_the_solve_carries_structural_zeros_as_exact_zeros(stage):
    # a block-diagonal matrix (two bodies that do not touch): the second block's unknowns are
    # those of its own system to the last bit, untouched by the first
    A = np.array([[4.0, 1.0, 0.0, 0.0], [1.0, 3.0, 0.0, 0.0], [0.0, 0.0, 2.0, 0.5], [0.0, 0.0, 0.5, 5.0]])
    b = np.array([1.0, 2.0, 3.0, 4.0])
    x = stage("solve", 4, *A.ravel(), *b)
    alone = stage("solve", 2, *A[2:, 2:].ravel(), *b[2:])
    assert x[2:].tolist() == alone.tolist()
