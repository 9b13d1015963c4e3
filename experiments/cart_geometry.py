"""Design the cart's lost geometry by a search over shapes, scored robustly (issue 30; paper §6.3).

Figure 11 of van de Panne & Fiume fixes the cart's masses (0.1 kg a link), its sensors (four
touch sensors, two per link, and two joint-angle sensors at +-120..180 deg), its actuator (targets
in [-140, 140] deg, ks 0.002 N m/deg, kd 0.0001 N m s/deg) and its 5 hidden nodes; its drawing,
the geometry, did not survive. This script searches that geometry:

- each link is a quadrilateral: a long axis from A = (0, 0) to B = (length, 0) and two bumps,
  C = (a length, h_top) above and D = (b length, -h_bottom) below it, vertices A, D, B, C (convex;
  every vertex is a contact point, so the whole outline meets the ground); S1/S3 sense the
  contact at A, S2/S4 the contact at B of L1/L2, as the paper's four touch sensors at the ends;
- the joint sits at (s length1, t) on L1 (anywhere along its axis, off it by t) and at
  (u length2, 0) on L2 (L2's outline shifted so that its frame's origin is the joint);
- the start: L1 flat, the joint at ``start_deg``, the whole cart lowered onto the ground;
- a link is a uniform lamina (the format's default inertia and centre of mass for a polygon).

Every candidate has the same structure (two links of four contacts, the same sensors), so all of
them run in one compiled program: a candidate is one row of a batched model, as tuning batches
link lengths (``sanlab.search.space``). A candidate's score is what phase 1 would give it, made
robust: the same ``--controllers`` random SANs for every candidate (``San.random_weights``: the
SANs of a ``sanlab search cart`` of the same seed), each scored by the default ensemble (8
perturbed starts, the lower of the medians at dt and dt/2); the top ``CONFIRM`` SANs of each
candidate are scored again on a held-out ensemble, and the best held-out speed is the
candidate's. Round 1 draws ``--candidates`` shapes uniformly; each later round perturbs the best
``KEEP`` found so far (10 % of each range, clipped). Results go to a JSON-lines file, one line a
candidate, so a killed run resumes where it stopped (``--out``; a candidate is never scored
twice).

    python experiments/cart_geometry.py --out cart_geometry.jsonl --candidates 64 --rounds 3
    python experiments/cart_geometry.py --out cart_geometry.jsonl --write best_cart.toml

The second form writes the best candidate as a creature file (the built-in cart's geometry came
from such a file; its comments say which run). ``cart_geometry.jsonl`` beside this script holds
the run behind the built-in cart (``--candidates 96 --rounds 3``, seed 0, made again on
2026-12-03 to the same result: 288 shapes, median held-out speed 11.5, 16.2 and 20.8 cm/s in
rounds 0, 1 and 2, the best round 2's candidate 13 at 42.6 cm/s).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from design import CONFIRM, KEEP, STEP, Design, compile_all, load_results, score
from design import Designs as Shapes
from design import main as run_design

# name, low, high: the shape's free numbers (metres, degrees; fractions of a link's length)
RANGES: tuple[tuple[str, float, float], ...] = (
    ("length1", 0.10, 0.40),
    ("a1", 0.0, 1.0),
    ("top1", 0.005, 0.15),
    ("b1", 0.0, 1.0),
    ("bottom1", 0.005, 0.15),
    ("length2", 0.10, 0.40),
    ("a2", 0.0, 1.0),
    ("top2", 0.005, 0.15),
    ("b2", 0.0, 1.0),
    ("bottom2", 0.005, 0.15),
    ("s", 0.0, 1.0),        # the joint along L1's axis (fraction of length1)
    ("t", -0.05, 0.05),     # the joint off L1's axis (m)
    ("u", 0.0, 1.0),        # the joint along L2's axis (fraction of length2)
    ("start_deg", -90.0, 90.0),
)
NAMES = tuple(r[0] for r in RANGES)


def outline(length: float, a: float, top: float, b: float, bottom: float, shift: float) -> list[list[float]]:
    """The four vertices A, D, B, C of one link (m, link frame), shifted by -shift along x."""
    pts = [(0.0, 0.0), (b * length, -bottom), (length, 0.0), (a * length, top)]
    return [[round(x - shift, 6), round(y, 6)] for x, y in pts]


def toml_text(g: dict[str, float], note: str = "") -> str:
    """The creature file of geometry ``g`` (a dict over :data:`NAMES`)."""
    l1 = outline(g["length1"], g["a1"], g["top1"], g["b1"], g["bottom1"], 0.0)
    l2 = outline(g["length2"], g["a2"], g["top2"], g["b2"], g["bottom2"], g["u"] * g["length2"])
    anchor = [round(g["s"] * g["length1"], 6), round(g["t"], 6)]
    # lower the cart so that its lowest contact starts on the ground (L1 flat, joint at start_deg)
    c, s_ = math.cos(math.radians(g["start_deg"])), math.sin(math.radians(g["start_deg"]))
    ys = [p[1] for p in l1] + [anchor[1] + s_ * x + c * y for x, y in l2]
    y0 = round(-min(ys), 6)
    head = "".join(f"# {line}\n" for line in note.splitlines()) if note else ""
    return f'''{head}name = "cart"
description = "Figure 11 of van de Panne & Fiume 1993: two links, five gaits including cartwheels."
dt = 0.001

[world]
plane = "vertical"
gravity = 9.81
[world.ground]
stiffness = 10000.0
damping = 20.0
friction = 0.6

[san]
hidden = 5
delay_on = 0.1
delay_off = 0.1

[evaluation]
metric = "distance"
seconds = 6.0

[[links]]
name = "L1"
mass = 0.10
shape = "polygon"
points = {l1}
position = [0.0, {y0}]
angle_deg = 0

[[links]]
name = "L2"
mass = 0.10
shape = "polygon"
points = {l2}
parent = "L1"
anchor = {anchor}
angle_deg = {g["start_deg"]:.3f}

[[sensors]]
name = "S1"
type = "touch"
link = "L1"
contact = 0

[[sensors]]
name = "S2"
type = "touch"
link = "L1"
contact = 2

[[sensors]]
name = "S3"
type = "touch"
link = "L2"
contact = 0

[[sensors]]
name = "S4"
type = "touch"
link = "L2"
contact = 2

[[sensors]]
name = "S5"
type = "angle"
link = "L2"
min_deg = -180
max_deg = -120

[[sensors]]
name = "S6"
type = "angle"
link = "L2"
min_deg = 120
max_deg = 180

[[actuators]]
name = "A1"
type = "angular"
joint = "L2"
min_deg = -140
max_deg = 140
ks = 0.002
kd = 0.0001
'''


DESIGN = Design("cart_geometry", RANGES, toml_text)
as_dict, as_vector, uniform, perturb = DESIGN.as_dict, DESIGN.as_vector, DESIGN.uniform, DESIGN.perturb
__all__ = ["CONFIRM", "KEEP", "NAMES", "RANGES", "STEP", "Shapes", "as_dict", "as_vector", "compile_all",
           "load_results", "main", "perturb", "score", "toml_text", "uniform"]


def main(argv: list[str] | None = None) -> None:
    run_design(DESIGN, argv, screen=8, doc=__doc__ or "")


if __name__ == "__main__":
    main()
