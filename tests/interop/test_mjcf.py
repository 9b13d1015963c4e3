"""The MJCF exporter without MuJoCo: NumPy only, and its numbering and kinematics agree with the
spec's (the MuJoCo comparisons themselves are in the simulator's tests)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from sanlab.creature import initial_frames, load
from sanlab.interop import mjcf
from tests.helpers import ROOT


def test_the_exporter_never_imports_jax():
    code = "import sys, sanlab.interop.mjcf; print('jax' in sys.modules)"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert r.stdout.strip() == "False", r.stderr


@pytest.mark.parametrize("name", ["bounder", "walker", "luxo"])
def test_initial_coordinates_pose_the_links_as_the_file_does(name):
    spec = load(name)
    q = mjcf.initial_q(spec)
    assert q.shape == (spec.dofs,)
    X, th = mjcf.link_poses(spec, q)
    frames = initial_frames(spec)
    np.testing.assert_allclose(X, [frames[l.name][:2] for l in spec.links], atol=1e-12)
    np.testing.assert_allclose(th, [frames[l.name][2] for l in spec.links], atol=1e-12)
    rot = mjcf.rotation_dofs(spec)
    assert sorted(rot) == sorted(l.name for l in spec.links)
    assert all(q[rot[l.name]] == pytest.approx(l.angle) for l in spec.links if l.parent is not None)
    assert len(mjcf.joint_names(spec)) == spec.dofs
    assert mjcf.to_mjcf(spec).startswith(f'<mujoco model="{name}">')
