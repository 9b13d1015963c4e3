"""Generated test bodies for the engine's growth table and first calls: chains of N segments.

A chain of ``n`` segments (0.1 m, 0.1 kg each, or drawn from a seed) lying on flat ground in the
vertical plane, as a user would describe a snake or a centipede: a contact point at each
segment's far end (and at the first segment's start), a touch sensor per contact, an angle
sensor and an angular PD servo per joint (n - 1 joints).

    from chains import chain_creature, random_chain
    spec = chain_creature(16)
    spec = random_chain(9, seed)  # a chain no process has seen: its own lengths and masses
"""

from __future__ import annotations


def chain_toml(n: int, seg: float | list[float] = 0.1, mass: float | list[float] = 0.1, name: str = "") -> str:
    """The creature file (TOML text) of an ``n``-segment chain; ``seg`` (m) and ``mass`` (kg) one
    number for every segment or a list of one per segment."""
    if n < 1:
        raise ValueError(f"a chain needs at least one segment, got {n}")
    segs = [float(seg)] * n if isinstance(seg, (int, float)) else [float(x) for x in seg]
    masses = [float(mass)] * n if isinstance(mass, (int, float)) else [float(x) for x in mass]
    if len(segs) != n or len(masses) != n:
        raise ValueError(f"expected {n} segment lengths and masses, got {len(segs)} and {len(masses)}")
    equal = "equal " if len(set(segs)) == 1 and len(set(masses)) == 1 else ""
    out = [f'name = "{name or f"chain{n}"}"', f'description = "a generated chain of {equal}segments"', "dt = 0.001",
           "[world]", 'plane = "vertical"', "gravity = 9.81",
           "[evaluation]", 'metric = "distance"', "seconds = 2.0"]
    for i, (seg_i, mass_i) in enumerate(zip(segs, masses)):
        out += ["[[links]]", f'name = "s{i}"', f"mass = {mass_i!r}", 'shape = "segment"',
                f"points = [[0.0, 0.0], [{seg_i!r}, 0.0]]"]
        if i == 0:
            out += [f"contacts = [[0.0, 0.0], [{seg_i!r}, 0.0]]", "position = [0.0, 0.0]", "angle_deg = 0"]
        else:
            out += [f"contacts = [[{seg_i!r}, 0.0]]", f'parent = "s{i - 1}"', f"anchor = [{segs[i - 1]!r}, 0.0]",
                    "angle_deg = 0"]
    for i in range(n):
        for c in range(2 if i == 0 else 1):
            out += ["[[sensors]]", f'name = "t{i}_{c}"', 'type = "touch"', f'link = "s{i}"', f"contact = {c}"]
    for i in range(1, n):
        out += ["[[sensors]]", f'name = "a{i}"', 'type = "angle"', f'link = "s{i}"', "min_deg = 20", "max_deg = 180"]
        out += ["[[actuators]]", f'name = "m{i}"', 'type = "angular"', f'joint = "s{i}"', "min_deg = -45",
                "max_deg = 45", f"ks = {0.02 * masses[i] / 0.1!r}", f"kd = {0.002 * masses[i] / 0.1!r}"]
    return "\n".join(out) + "\n"


def random_chain_toml(n: int, seed: int) -> str:
    """The file of an ``n``-segment chain with its own segment lengths (0.07-0.13 m) and masses
    (0.07-0.13 kg) drawn from ``seed``: a creature no process has met before (its numbers, and so
    any per-creature compile, differ from every other seed's)."""
    import random

    rng = random.Random(seed)
    segs = [round(rng.uniform(0.07, 0.13), 4) for _ in range(n)]
    masses = [round(rng.uniform(0.07, 0.13), 4) for _ in range(n)]
    return chain_toml(n, segs, masses, name=f"chain{n}_{seed}")


def random_chain(n: int, seed: int):
    """The parsed creature of :func:`random_chain_toml`."""
    from sanlab import creature

    return creature.loads(random_chain_toml(n, seed), source=f"<chain{n}_{seed}>")


def chain_creature(n: int):
    """The parsed creature (``sanlab.creature.Creature``) of an ``n``-segment chain."""
    from sanlab import creature

    return creature.loads(chain_toml(n), source=f"<chain{n}>")
