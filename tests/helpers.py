"""Constants the test modules share (fixtures are in ``conftest.py``)."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent  # the checkout (PYTHONPATH for subprocesses)
DATA = Path(__file__).resolve().parent / "data"  # creature files made for the tests
SANLAB = [sys.executable, "-m", "sanlab"]  # the command line, in a fresh process
FPS = 30.0  # frames per second of every replay in the render tests (the rollout compiles once)

# A small valid creature: two jointed segments, a touch and an angle sensor, one servo; the
# creature tests derive their bad files from it.
BASE = """\
[[links]]
name = "L1"
mass = 0.1
shape = "segment"
points = [[0, 0], [0.2, 0]]
angle_deg = 90

[[links]]
name = "L2"
mass = 0.1
shape = "segment"
points = [[0, 0], [0.2, 0]]
parent = "L1"
anchor = [0.2, 0]
angle_deg = -45

[[sensors]]
type = "touch"
link = "L1"
contact = 0

[[sensors]]
type = "angle"
link = "L2"
min_deg = -90
max_deg = 45

[[actuators]]
type = "angular"
joint = "L2"
min_deg = -90
max_deg = 90
ks = 0.002
kd = 0.0002
"""
