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

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

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
CONFIRM = 3  # SANs per candidate re-scored on a held-out ensemble
KEEP = 8  # candidates a later round perturbs
STEP = 0.1  # a later round's perturbation, as a fraction of each range


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


def as_dict(v: np.ndarray) -> dict[str, float]:
    return {n: float(x) for n, x in zip(NAMES, v)}


def as_vector(g: dict[str, float]) -> np.ndarray:
    return np.array([g[n] for n in NAMES], float)


def uniform(rng: np.random.Generator, n: int) -> np.ndarray:
    lo, hi = np.array([r[1] for r in RANGES]), np.array([r[2] for r in RANGES])
    return lo + (hi - lo) * rng.random((n, len(RANGES)))


def perturb(rng: np.random.Generator, parents: np.ndarray, n: int) -> np.ndarray:
    lo, hi = np.array([r[1] for r in RANGES]), np.array([r[2] for r in RANGES])
    pick = parents[rng.integers(0, len(parents), n)]
    return np.clip(pick + STEP * (hi - lo) * rng.standard_normal(pick.shape), lo, hi)


class Shapes:
    """A parameter space over candidate geometries (``sanlab.evaluate.evaluator.ParamSpace``): a
    vector is one number, the candidate's index; ``batch`` gives each row that candidate's
    masses, inertias, centres of mass, joint anchors, contact points and seated start."""

    def __init__(self, models: list):
        self.models = models

    def batch(self, thetas: np.ndarray, model):
        import jax
        import jax.numpy as jnp

        from sanlab.san import San

        rows = [self.models[int(t[0])] for t in thetas]
        names = ("mass", "inertia", "com", "anchor", "contact", "q0")
        over = {k: jnp.asarray(np.stack([np.asarray(getattr(r.params, k)) for r in rows]), model.dtype) for k in names}
        B = len(rows)
        base = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (B,) + x.shape), model)
        on, off = model.spec.san.delay_on, model.spec.san.delay_off
        nodes = San.for_creature(model.spec).n_nodes
        return np.full((B, nodes), 1 / on), np.full((B, nodes), -1 / off), base.with_params(**over)


def compile_all(texts: list[str], template):
    """Each text's model, seated on the ground, in the template's program (the same structure)."""
    from sanlab.creature.loader import loads
    from sanlab.sim.compiler import compile_creature

    out = []
    for text in texts:
        m = compile_creature(loads(text, "<candidate>"), template.dtype)
        if m.structure != template.structure:
            raise ValueError("a candidate's structure differs from the template's")
        out.append(m)
    return out


def score(texts: list[str], controllers: int, seed: int, batch: int) -> list[dict]:
    """Each candidate's robust phase-1 result (see the module docstring)."""
    from sanlab.creature.loader import loads
    from sanlab.evaluate.ensemble import audit_key, default_ensemble, search_key
    from sanlab.evaluate.evaluator import Evaluator

    template = loads(texts[0], "<template>")
    ev = Evaluator(template, ensemble=default_ensemble(8), batch=batch, space=None)
    models = compile_all(texts, ev.model)
    ev.space = Shapes(models)
    W1 = np.stack([ev.san.random_weights(seed, i) for i in range(controllers)])
    G = len(texts)
    W = np.tile(W1, (G, 1, 1))
    thetas = np.repeat(np.arange(G, dtype=float), controllers)[:, None]
    keys = [search_key(seed, i) for i in range(controllers)] * G
    s = ev(W, thetas, keys)
    sc = np.asarray(s.score).reshape(G, controllers)
    best = np.argsort(-sc, axis=1)[:, :CONFIRM]
    Wc = np.stack([W1[j] for row in best for j in row])
    tc = np.repeat(np.arange(G, dtype=float), CONFIRM)[:, None]
    kc = [audit_key(search_key(seed, int(j))) for row in best for j in row]
    h = ev(Wc, tc, kc)
    hs = np.asarray(h.score).reshape(G, CONFIRM)
    hv = np.asarray(h.speed_cm_s).reshape(G, CONFIRM)
    turns = np.asarray(h.descriptors["turns_per_s"]).reshape(G, CONFIRM) if h.descriptors else np.zeros((G, CONFIRM))
    out = []
    for g in range(G):
        k = int(np.argmax(hs[g]))
        out.append({"score_m": float(hs[g, k]), "speed_cm_s": float(hv[g, k]), "san": int(best[g, k]),
                    "turns_per_s": float(turns[g, k]), "phase1_best_m": float(sc[g].max()),
                    "phase1_median_m": float(np.median(sc[g]))})
    return out


def load_results(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="JSON-lines results (resumes from it)")
    ap.add_argument("--candidates", type=int, default=64, help="shapes a round scores")
    ap.add_argument("--rounds", type=int, default=1, help="rounds: the first uniform, later ones around the best")
    ap.add_argument("--controllers", type=int, default=200, help="random SANs per shape (phase 1)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk", type=int, default=16, help="shapes per evaluation call (a resumable piece)")
    ap.add_argument("--batch", type=int, default=256, help="controllers per rollout")
    ap.add_argument("--write", type=Path, help="write the best candidate so far as a creature file and stop")
    a = ap.parse_args(argv)
    from sanlab import configure

    configure()
    done = load_results(a.out)
    if a.write:
        best = max(done, key=lambda r: r["score_m"])
        note = (f"Geometry found by experiments/cart_geometry.py (round {best['round']}, candidate "
                f"{best['index']}, seed {best.get('seed', a.seed)}):\nheld-out robust phase-1 speed {best['speed_cm_s']:.1f} cm/s.")
        a.write.write_text(toml_text(best["geometry"], note))
        print(f"wrote {a.write}: {best['speed_cm_s']:.1f} cm/s (round {best['round']}, candidate {best['index']})")
        return
    for rnd in range(a.rounds):
        rng = np.random.default_rng([a.seed, rnd])
        if rnd == 0:
            vecs = uniform(rng, a.candidates)
        else:
            prior = [r for r in done if r["round"] < rnd]
            if not prior:
                break
            top = sorted(prior, key=lambda r: -r["score_m"])[:KEEP]
            vecs = perturb(rng, np.stack([as_vector(r["geometry"]) for r in top]), a.candidates)
        have = {r["index"] for r in done if r["round"] == rnd}
        todo = [i for i in range(a.candidates) if i not in have]
        for c in range(0, len(todo), a.chunk):
            idx = todo[c:c + a.chunk]
            t0 = time.perf_counter()
            res = score([toml_text(as_dict(vecs[i])) for i in idx], a.controllers, a.seed, a.batch)
            with a.out.open("a") as f:
                for i, r in zip(idx, res):
                    row = {"round": rnd, "index": i, "seed": a.seed, "geometry": as_dict(vecs[i]), **r}
                    done.append(row)
                    f.write(json.dumps(row) + "\n")
            best = max(done, key=lambda r: r["score_m"])
            print(f"round {rnd}: {len(idx)} shapes in {time.perf_counter() - t0:.0f} s; best so far "
                  f"{best['speed_cm_s']:.1f} cm/s (round {best['round']}, candidate {best['index']}, "
                  f"{best['turns_per_s'] * 6:.1f} turns in 6 s)", flush=True)


if __name__ == "__main__":
    main()
