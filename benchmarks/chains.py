"""Generated test bodies for the engine's growth table: a chain of N equal segments.

A chain of ``n`` segments (0.1 m, 0.1 kg each) lying on flat ground in the vertical plane, as a
user would describe a snake or a centipede: a contact point at each segment's far end (and at
the first segment's start), a touch sensor per contact, an angle sensor and an angular PD servo
per joint (n - 1 joints).

    from chains import chain_creature
    spec = chain_creature(16)
"""

from __future__ import annotations


def chain_toml(n: int, seg: float = 0.1, mass: float = 0.1) -> str:
    """The creature file (TOML text) of an ``n``-segment chain."""
    if n < 1:
        raise ValueError(f"a chain needs at least one segment, got {n}")
    out = [f'name = "chain{n}"', 'description = "a generated chain of equal segments"', "dt = 0.001",
           "[world]", 'plane = "vertical"', "gravity = 9.81",
           "[evaluation]", 'metric = "distance"', "seconds = 2.0"]
    for i in range(n):
        out += ["[[links]]", f'name = "s{i}"', f"mass = {mass}", 'shape = "segment"',
                f"points = [[0.0, 0.0], [{seg}, 0.0]]"]
        if i == 0:
            out += [f"contacts = [[0.0, 0.0], [{seg}, 0.0]]", "position = [0.0, 0.0]", "angle_deg = 0"]
        else:
            out += [f"contacts = [[{seg}, 0.0]]", f'parent = "s{i - 1}"', f"anchor = [{seg}, 0.0]", "angle_deg = 0"]
    for i in range(n):
        for c in range(2 if i == 0 else 1):
            out += ["[[sensors]]", f'name = "t{i}_{c}"', 'type = "touch"', f'link = "s{i}"', f"contact = {c}"]
    for i in range(1, n):
        out += ["[[sensors]]", f'name = "a{i}"', 'type = "angle"', f'link = "s{i}"', "min_deg = 20", "max_deg = 180"]
        out += ["[[actuators]]", f'name = "m{i}"', 'type = "angular"', f'joint = "s{i}"', "min_deg = -45",
                "max_deg = 45", f"ks = {0.02 * mass / 0.1}", f"kd = {0.002 * mass / 0.1}"]
    return "\n".join(out) + "\n"


def chain_creature(n: int):
    """The parsed creature (``sanlab.creature.Creature``) of an ``n``-segment chain."""
    from sanlab import creature

    return creature.loads(chain_toml(n), source=f"<chain{n}>")
