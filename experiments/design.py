"""A creature's free numbers searched by their robust phase-1 result (issue 30; paper §6, §6.3).

The paper tuned its creatures by hand ("the angle ranges of the sensors and actuators ... were
varied in several experiments") and, for the cart, by a search over shapes (§6.3). A *design* is a
creature file with some numbers left free: ``RANGES`` (name, low, high) and ``toml_text(values)``,
the file for one vector of them. Every candidate must have the same structure (links, contacts,
sensors, actuators), so that all of them run in one compiled program: a candidate is one row of a
batched model (:class:`Designs`), as tuning batches link lengths (``sanlab.search.space``).

A candidate's score is what phase 1 would give it, made robust: the same ``--controllers``
random SANs for every candidate (``San.random_weights``: the SANs of a ``sanlab search`` of the
same seed), each scored by an ensemble of ``--screen`` members (8: the search's default ensemble;
1: single samples, eight times cheaper); the top ``CONFIRM`` SANs of each candidate are scored
again on a held-out default ensemble (8 perturbed starts, the lower of the medians at dt and
dt/2), and the best held-out speed is the candidate's. Round 1 draws ``--candidates`` designs
uniformly; each later round perturbs the best ``KEEP`` found so far (10 % of each range,
clipped). Results go to a JSON-lines file, one line a candidate, so a killed run resumes where
it stopped (a candidate is never scored twice).

A design's score is the best of a few SANs, and the search keeps the best of many designs: the
winner's score is biased up (a design with one lucky SAN can win). ``--validate K --seeds S,S``
scores the best K designs again on the random SANs of other seeds (rows of round -1), and
``--write`` then takes the design with the best mean held-out speed over those seeds.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

CONFIRM = 3  # SANs per candidate re-scored on a held-out ensemble
KEEP = 8  # candidates a later round perturbs
STEP = 0.1  # a later round's perturbation, as a fraction of each range


@dataclass(frozen=True)
class Design:
    """The free numbers of a creature file: ``ranges`` (name, low, high) and ``toml_text``, the
    file of a dict over their names (with an optional comment block ``note`` on top);
    ``reference``, if given, the values of today's creature: round 0's candidate 0, scored by the
    same rules as the rest, so that every result can be read against it."""

    name: str
    ranges: tuple[tuple[str, float, float], ...]
    toml_text: Callable[..., str]
    reference: dict[str, float] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(r[0] for r in self.ranges)

    def as_dict(self, v: np.ndarray) -> dict[str, float]:
        return {n: float(x) for n, x in zip(self.names, v)}

    def as_vector(self, g: dict[str, float]) -> np.ndarray:
        return np.array([g[n] for n in self.names], float)

    def uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        lo, hi = np.array([r[1] for r in self.ranges]), np.array([r[2] for r in self.ranges])
        return lo + (hi - lo) * rng.random((n, len(self.ranges)))

    def perturb(self, rng: np.random.Generator, parents: np.ndarray, n: int) -> np.ndarray:
        lo, hi = np.array([r[1] for r in self.ranges]), np.array([r[2] for r in self.ranges])
        pick = parents[rng.integers(0, len(parents), n)]
        return np.clip(pick + STEP * (hi - lo) * rng.standard_normal(pick.shape), lo, hi)


class Designs:
    """A parameter space over candidate creatures of one structure
    (``sanlab.evaluate.evaluator.ParamSpace``): a vector is one number, the candidate's index;
    ``batch`` gives each row every number of that candidate's compiled model (masses, contact
    points, sensor and actuator ranges, start pose, ...) and its SAN's node delays."""

    def __init__(self, models: list):
        self.models = models

    def batch(self, thetas: np.ndarray, model):
        import dataclasses

        from sanlab.san import San

        rows = [self.models[int(t[0])] for t in thetas]
        stacked = {f.name: np.stack([np.asarray(getattr(r.params, f.name), model.dtype) for r in rows])
                   for f in dataclasses.fields(model.params)}
        nodes = San.for_creature(model.spec).n_nodes
        on = np.array([[r.spec.san.delay_on] * nodes for r in rows])
        off = np.array([[r.spec.san.delay_off] * nodes for r in rows])
        return 1 / on, -1 / off, model.with_params(**stacked)


def compile_all(texts: Sequence[str], template) -> list:
    """Each text's model in the template's program (the same structure), or ValueError."""
    from sanlab.creature.loader import loads
    from sanlab.sim.compiler import compile_creature

    out = []
    for text in texts:
        m = compile_creature(loads(text, "<candidate>"), template.dtype)
        if m.structure != template.structure:
            raise ValueError("a candidate's structure differs from the template's")
        out.append(m)
    return out


def score(texts: Sequence[str], controllers: int, seed: int, batch: int, screen: int = 8, confirm: int = CONFIRM,
          pick: str = "best") -> list[dict]:
    """Each candidate's robust phase-1 result (see the module docstring): its ``confirm`` best
    SANs re-scored on the held-out ensemble, and the best of them (``pick="best"``) or their mean
    (``"mean"``: less of a lottery, as a design then wins by many good SANs, not one)."""
    from sanlab.creature.loader import loads
    from sanlab.evaluate.ensemble import audit_key, default_ensemble, search_key
    from sanlab.evaluate.evaluator import Evaluator

    template = loads(texts[0], "<template>")
    first = Evaluator(template, ensemble=default_ensemble(screen), batch=batch, space=None)
    models = compile_all(texts, first.model)
    first.space = Designs(models)
    W1 = np.stack([first.san.random_weights(seed, i) for i in range(controllers)])
    G = len(texts)
    W = np.tile(W1, (G, 1, 1))
    thetas = np.repeat(np.arange(G, dtype=float), controllers)[:, None]
    keys = [search_key(seed, i) for i in range(controllers)] * G
    s = first(W, thetas, keys)
    confirm = min(confirm, controllers)
    sc = np.asarray(s.score).reshape(G, controllers)
    best = np.argsort(-sc, axis=1)[:, :confirm]
    held = first if screen == 8 else Evaluator(template, ensemble=default_ensemble(8), batch=batch, space=first.space)
    Wc = np.stack([W1[j] for row in best for j in row])
    tc = np.repeat(np.arange(G, dtype=float), confirm)[:, None]
    kc = [audit_key(search_key(seed, int(j))) for row in best for j in row]
    h = held(Wc, tc, kc)
    hs = np.asarray(h.score).reshape(G, confirm)
    hv = np.asarray(h.speed_cm_s).reshape(G, confirm)
    turns = np.asarray(h.descriptors["turns_per_s"]).reshape(G, confirm) if h.descriptors else np.zeros((G, confirm))
    out = []
    for g in range(G):
        k = int(np.argmax(hs[g]))
        head = ({"score_m": float(hs[g, k]), "speed_cm_s": float(hv[g, k])} if pick == "best" else
                {"score_m": float(hs[g].mean()), "speed_cm_s": float(hv[g].mean()), "best_speed_cm_s": float(hv[g, k])})
        out.append({**head, "san": int(best[g, k]),
                    "turns_per_s": float(turns[g, k]), "phase1_best_m": float(sc[g].max()),
                    "phase1_median_m": float(np.median(sc[g]))})
    return out


def load_results(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def main(design: Design, argv: list[str] | None = None, *, screen: int = 8, confirm: int = CONFIRM, pick: str = "best",
         doc: str = "") -> None:
    """The command line of a design search (``--help`` lists it); ``screen``, ``confirm`` and
    ``pick``: the defaults of the options of those names."""
    ap = argparse.ArgumentParser(description=(doc or __doc__ or "").split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="JSON-lines results (resumes from it)")
    ap.add_argument("--candidates", type=int, default=64, help="designs a round scores")
    ap.add_argument("--rounds", type=int, default=1, help="rounds: the first uniform, later ones around the best")
    ap.add_argument("--controllers", type=int, default=200, help="random SANs per design (phase 1)")
    ap.add_argument("--screen", type=int, default=screen, help="ensemble members of the first scoring (1: single samples)")
    ap.add_argument("--confirm", type=int, default=confirm, help="SANs per design re-scored on the held-out ensemble")
    ap.add_argument("--pick", choices=("best", "mean"), default=pick, help="a design's score: the best or the mean of those")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk", type=int, default=16, help="designs per evaluation call (a resumable piece)")
    ap.add_argument("--batch", type=int, default=256, help="controllers per rollout")
    ap.add_argument("--validate", type=int, default=0, help="score the best K designs again on --seeds, then stop")
    ap.add_argument("--seeds", default="1,2", help="--validate: the seeds of the fresh random SANs")
    ap.add_argument("--write", type=Path, help="write the best candidate so far as a creature file and stop")
    a = ap.parse_args(argv)
    done = load_results(a.out)
    if a.validate:
        validate(design, a, done)
        return
    if a.write:
        best, note = chosen(design, done, a.seed)
        a.write.write_text(design.toml_text(best["geometry"], note))
        print(f"wrote {a.write}: {note.splitlines()[-1]}")
        return
    for rnd in range(a.rounds):
        rng = np.random.default_rng([a.seed, rnd])
        if rnd == 0:
            vecs = design.uniform(rng, a.candidates)
            if design.reference is not None:
                vecs[0] = design.as_vector(design.reference)
        else:
            prior = [r for r in done if 0 <= r["round"] < rnd]
            if not prior:
                break
            top = sorted(prior, key=lambda r: -r["score_m"])[:KEEP]
            vecs = design.perturb(rng, np.stack([design.as_vector(r["geometry"]) for r in top]), a.candidates)
        have = {r["index"] for r in done if r["round"] == rnd}
        todo = [i for i in range(a.candidates) if i not in have]
        for c in range(0, len(todo), a.chunk):
            idx = todo[c:c + a.chunk]
            t0 = time.perf_counter()
            res = score([design.toml_text(design.as_dict(vecs[i])) for i in idx], a.controllers, a.seed, a.batch,
                        a.screen, a.confirm, a.pick)
            with a.out.open("a") as f:
                for i, r in zip(idx, res):
                    row = {"round": rnd, "index": i, "seed": a.seed, "geometry": design.as_dict(vecs[i]), **r}
                    done.append(row)
                    f.write(json.dumps(row) + "\n")
            best = max(done, key=lambda r: r["score_m"])
            print(f"round {rnd}: {len(idx)} designs in {time.perf_counter() - t0:.0f} s; best so far "
                  f"{best['speed_cm_s']:.1f} cm/s (round {best['round']}, candidate {best['index']}, "
                  f"{best['turns_per_s'] * 6:.1f} turns in 6 s)", flush=True)


def _key(row: dict) -> tuple[int, int]:
    return row["round"], row["index"]


def validate(design: Design, a, done: list[dict]) -> None:
    """Score the best ``a.validate`` designs of the search (and the reference) on each seed of
    ``a.seeds``; rows of round -1 name the design they validate (``of``) and their seed."""
    search = [r for r in done if r["round"] >= 0]
    best = sorted(search, key=lambda r: -r["score_m"])[:a.validate]
    ref = [r for r in search if _key(r) == (0, 0) and design.reference is not None]
    picks = best + [r for r in ref if r not in best]
    for seed in (int(s) for s in a.seeds.split(",")):
        have = {tuple(r["of"]) for r in done if r["round"] == -1 and r["seed"] == seed}
        todo = [r for r in picks if _key(r) not in have]
        for c in range(0, len(todo), a.chunk):
            part = todo[c:c + a.chunk]
            res = score([design.toml_text(r["geometry"]) for r in part], a.controllers, seed, a.batch, a.screen,
                        a.confirm, a.pick)
            with a.out.open("a") as f:
                for r, s in zip(part, res):
                    row = {"round": -1, "index": -1, "of": list(_key(r)), "seed": seed, "geometry": r["geometry"], **s}
                    done.append(row)
                    f.write(json.dumps(row) + "\n")
    for r in picks:
        v = [x["speed_cm_s"] for x in done if x["round"] == -1 and tuple(x["of"]) == _key(r)]
        print(f"round {r['round']} candidate {r['index']}: {r['speed_cm_s']:.1f} cm/s in the search, "
              f"{' · '.join(f'{x:.1f}' for x in v)} on seeds {a.seeds} (mean {np.mean(v):.1f})")


def chosen(design: Design, done: list[dict], seed: int) -> tuple[dict, str]:
    """The design to write and its note: the best mean over the validation seeds if any design
    was validated, else the search's best."""
    checked: dict[tuple[int, int], list[float]] = {}
    for x in done:
        if x["round"] == -1:
            checked.setdefault(tuple(x["of"]), []).append(x["speed_cm_s"])
    search = [r for r in done if r["round"] >= 0]
    if checked:
        key = max(checked, key=lambda k: float(np.mean(checked[k])))
        best = next(r for r in search if _key(r) == key)
        tail = (f"validated on fresh SANs: mean held-out robust phase-1 speed {np.mean(checked[key]):.1f} cm/s "
                f"over {len(checked[key])} seeds (the search's own: {best['speed_cm_s']:.1f} cm/s).")
    else:
        best = max(search, key=lambda r: r["score_m"])
        tail = f"held-out robust phase-1 speed {best['speed_cm_s']:.1f} cm/s."
    return best, (f"Found by experiments/{design.name}.py (round {best['round']}, candidate {best['index']}, "
                  f"seed {best.get('seed', seed)}):\n{tail}")


# --- pieces of a creature file, shared by the design scripts' templates ----------------------


def header(name: str, description: str, hidden: int, delay: float, evaluation: str, world: str = "") -> str:
    """A vertical-plane creature file's top: name, description, dt = 1 ms, gravity (``world``:
    more lines of [world], such as a [world.ground] table), the SAN (``hidden`` nodes, node delay
    ``delay`` s on and off) and the [evaluation] table's lines."""
    return (f'name = "{name}"\ndescription = "{description}"\ndt = 0.001\n\n[world]\nplane = "vertical"\n'
            f'gravity = 9.81\n{world}\n[san]\nhidden = {hidden}\ndelay_on = {delay:.4f}\ndelay_off = {delay:.4f}\n\n'
            f'[evaluation]\n{evaluation}\n')


def segment(name: str, mass: float, length: float, parent: str, anchor: tuple[float, float], angle_deg: float) -> str:
    """A [[links]] table: a segment drawn along -y from its joint, its far end the one contact."""
    return (f'\n[[links]]\nname = "{name}"\nmass = {mass}\nshape = "segment"\npoints = [[0.0, 0.0], [0.0, {-length:.6f}]]\n'
            f'contacts = [[0.0, {-length:.6f}]]\nparent = "{parent}"\nanchor = [{anchor[0]:.6f}, {anchor[1]:.6f}]\n'
            f'angle_deg = {angle_deg:.4f}\n')


def touch_sensors(rows: Sequence[tuple[str, int]], first: int = 1) -> str:
    """[[sensors]] tables S{first}...: a touch sensor at contact ``c`` of link ``l`` for each (l, c)."""
    return "".join(f'\n[[sensors]]\nname = "S{i}"\ntype = "touch"\nlink = "{link}"\ncontact = {c}\n'
                   for i, (link, c) in enumerate(rows, start=first))


def angle_sensors(rows: Sequence[tuple[str, float, float]], first: int) -> str:
    """[[sensors]] tables S{first}...: an angle sensor on link ``l`` over [lo, hi] deg for each (l, lo, hi)."""
    return "".join(f'\n[[sensors]]\nname = "S{i}"\ntype = "angle"\nlink = "{link}"\nmin_deg = {lo}\nmax_deg = {hi}\n'
                   for i, (link, lo, hi) in enumerate(rows, start=first))


def angular_actuators(rows: Sequence[tuple[str, float, float, float]]) -> str:
    """[[actuators]] tables A1...: a servo on joint ``j`` over [lo, hi] deg, gain ks N m/deg and kd
    = ks / 10 (the paper's suggestion) for each (j, lo, hi, ks)."""
    return "".join(f'\n[[actuators]]\nname = "A{i}"\ntype = "angular"\njoint = "{joint}"\nmin_deg = {lo:.3f}\n'
                   f'max_deg = {hi:.3f}\nks = {ks:.6f}\nkd = {ks / 10:.7f}\n'
                   for i, (joint, lo, hi, ks) in enumerate(rows, start=1))
