"""Vary the four-link chain's free sizes, gains and ranges, scored robustly (issue 30; paper §6).

Its robust tuned speed falls short of Table 1 (median 35 of 55 cm/s over five seeds,
docs/table1.md). The paper gives its counts only (4 links, 11 sensors, 3 actuators, 8 hidden
nodes); its drawing, sizes and gains are lost, and its creatures' "angle ranges of the sensors
and actuators ... were varied in several experiments". Free here, as in ``RANGES``: each bar's
length, the end joints' and the middle joint's gains (N m/deg, kd = 0.1 ks as the paper
suggests) and ranges (+-), where the joint sensors turn on (a fraction of their actuator's
range: a sensor past its actuator's reach never turns on) and the node delay (the paper's
0.07-0.15 s). The bars' masses (0.1 kg), the ground and the start (flat on the ground) stay the
built-in's.

    python experiments/fourlink_design.py --out fourlink_design.jsonl --candidates 64 --rounds 4
    python experiments/fourlink_design.py --out fourlink_design.jsonl --validate 6 --seeds 1,2,3
    python experiments/fourlink_design.py --out fourlink_design.jsonl --write best_fourlink.toml

``fourlink_design.jsonl`` beside this script holds the run behind the built-in chain (those
three commands, seed 0, 2026-12-03): 256 designs, then the best six and the first version on
seeds 1-3. The first version scored 14.5 · 14.2 · 12.9 cm/s there, the chosen design (round 2,
candidate 41) 40.7 · 32.5 · 23.7; the built-in's file says what changed.

The search itself is ``experiments/design.py``'s; by default it screens the random SANs with
single samples (``--screen 1``) and scores a design by the mean held-out speed of its ten best
SANs (``--confirm 10 --pick mean``), as the bounder's search does (its docstring says why).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from design import Design, angle_sensors, angular_actuators, header, touch_sensors
from design import main as run_design

# name, low, high (metres, N m/deg, degrees, seconds; fractions of a range)
RANGES: tuple[tuple[str, float, float], ...] = (
    ("len1", 0.10, 0.30),          # tail bar
    ("len2", 0.10, 0.30),
    ("len3", 0.10, 0.30),
    ("len4", 0.10, 0.30),          # head bar
    ("ks_end", 0.005, 0.08),       # first and last joints
    ("ks_mid", 0.01, 0.16),        # middle joint
    ("range_end", 60.0, 160.0),    # end joints' targets in [-range, +range] deg
    ("range_mid", 60.0, 160.0),
    ("sense", 0.3, 1.0),           # joint sensors on past this fraction of their actuator's range
    ("delay", 0.07, 0.15),         # s, the SAN's node delay (on and off)
)


def toml_text(g: dict[str, float], note: str = "") -> str:
    """The four-link chain's file of design ``g`` (a dict over the names of ``RANGES``)."""
    head = "".join(f"# {line}\n" for line in note.splitlines()) if note else ""
    L = [g["len1"], g["len2"], g["len3"], g["len4"]]
    links = f'''
[[links]]
name = "L1"
mass = 0.1
shape = "segment"
points = [[0.0, 0.0], [{L[0]:.6f}, 0.0]]
position = [0.0, 0.0]
'''
    for i in (1, 2, 3):  # drawn along +x, lying flat: not the legs' segment() along -y
        links += f'''
[[links]]
name = "L{i + 1}"
mass = 0.1
shape = "segment"
points = [[0.0, 0.0], [{L[i]:.6f}, 0.0]]
contacts = [[{L[i]:.6f}, 0.0]]
parent = "L{i}"
anchor = [{L[i - 1]:.6f}, 0.0]
'''
    joints = (("L2", g["ks_end"], g["range_end"]), ("L3", g["ks_mid"], g["range_mid"]), ("L4", g["ks_end"], g["range_end"]))
    folds = [(link, lo, hi) for link, _, r in joints
             for lo, hi in ((round(g["sense"] * r, 3), 180), (-180, -round(g["sense"] * r, 3)))]
    ground = "[world.ground]\nstiffness = 10000.0\ndamping = 20.0\nfriction = 0.6\n"
    return (head + header("fourlink", "Table 1 of van de Panne & Fiume 1993: a chain of four links and three motors.", 8,
                          g["delay"], 'metric = "distance"\nseconds = 6.0', ground)
            + links + touch_sensors([("L1", 0), ("L1", 1), ("L2", 0), ("L3", 0), ("L4", 0)])
            + angle_sensors(folds, 6) + angular_actuators([(link, -r, r, ks) for link, ks, r in joints]))


# the four-link chain before this search, as a design (its file at 29a0af5, to the last digit):
# round 0's candidate 0; and the design the built-in now is (round 2, candidate 41 of
# fourlink_design.jsonl beside this script; tests/test_design.py)
FIRST = {"len1": 0.2, "len2": 0.2, "len3": 0.2, "len4": 0.2, "ks_end": 0.03, "ks_mid": 0.06, "range_end": 120.0,
         "range_mid": 120.0, "sense": 0.5, "delay": 0.07}
CHOSEN = {"len1": 0.23789372498589942, "len2": 0.26417287540114154, "len3": 0.18408804968604756,
          "len4": 0.13759407578773747, "ks_end": 0.05326076224231952, "ks_mid": 0.1350231348172635,
          "range_end": 160.0, "range_mid": 160.0, "sense": 0.8845725894287837, "delay": 0.12510543126156817}
DESIGN = Design("fourlink_design", RANGES, toml_text, reference=FIRST)


def main(argv: list[str] | None = None) -> None:
    run_design(DESIGN, argv, screen=1, confirm=10, pick="mean", doc=__doc__ or "")


if __name__ == "__main__":
    main()
