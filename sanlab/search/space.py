"""The parameters phase 2 tunes (paper §5.3, Figure 8), as one flat vector per controller.

For a creature with H hidden nodes, A actuators and R range sensors (angle, eye, length; touch
sensors have no range) the vector holds, in this order:

    k1, k2 of each hidden node               2 H   (stored as the delays T_on = 1/k1, T_off = -1/k2)
    Amin, Amax, ks, kd of each actuator       4 A
    Smin, Smax of each range sensor           2 R

(the bounder: 2x8 + 4x4 + 2x6 = 44, the paper's count). With ``morphology``, a creature file
with free numbers (``sanlab.creature.free``) adds its free numbers that shape the body (§6.3;
``sanlab design`` searches the same numbers globally, this is the local case): each within its
range, perturbed by 5 % of it, the couplings of its ``[design]`` table applied, the body
compiled again for each vector. Free numbers that only set what the vector above already holds
(a range end, a gain, a delay) are left to it, and so are those that set numbers a gait cannot
store (:data:`BODY_FIELDS`: the ground, the gravity, a joint's spring ...): those stay at their
defaults. A file without free numbers gets, with ``morphology``, one
length scale per link (§6.3): the link's outline, contact points, centre of mass and the points
attached to it (children's joints, actuator, spring and sensor attachments) scale with it; its
mass scales with its length and with the square root of the strength (ks) of the actuator
driving its joint (a stronger muscle is heavier), and its inertia with mass x length^2.

Perturbation sizes (delta, the paper's "+delta or -delta"):

- node delays: 0.01 s (about 10 % of the paper's 0.07-0.15 s);
- actuator and sensor range ends: 5 % of the nominal range width (max - min);
- ks and kd: 10 % of the nominal value;
- link length scale: 0.05 (5 %).

Validity is kept by projection after every perturbation: delays stay within [0.01, 1] s,
ks, kd >= 0, every range keeps min < max (by at least 1 % of its nominal width), angle ranges (actuator targets and sensor
ranges) stay within [-180, 180] deg, length ranges >= 0, length scales within [0.5, 1.5].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sanlab.creature.spec import Creature
from sanlab.evaluate.records import GaitParams
from sanlab.san import San
from sanlab.sim.model import drag_edges

# The compiled numbers a free number may move for tuning to move it: what a gait's model
# overrides can hold (``sanlab.gait``), besides the controller's own (CONTROLLER_FIELDS).
BODY_FIELDS = ("mass", "inertia", "com", "anchor", "contact", "act_pts", "sens_pts", "spr_pts", "edge", "q0",
               "root_pose", "contact_load")
CONTROLLER_FIELDS = ("act_min", "act_max", "act_ks", "act_kd", "sens_min", "sens_max")


@dataclass(frozen=True)
class Param:
    name: str  # e.g. "H3.T_on", "A1.min", "S4.max", "L2.scale", a free number's name
    kind: str  # t_on, t_off, amin, amax, ks, kd, smin, smax, scale, free
    index: int  # node, actuator, sensor, link or free number index
    delta: float
    lo: float
    hi: float
    partner: int = -1  # index in the vector of the other end of a range (min < max)
    gap: float = 0.0  # smallest allowed max - min


class Space:
    """Tunable parameters of one creature; maps vectors to controller and model parameters."""

    def __init__(self, spec: Creature, morphology: bool = False):
        self.spec = spec
        self.san = San.for_creature(spec)
        self.morphology = morphology
        params: list[Param] = []
        for h in range(self.san.n_hidden):
            params.append(Param(f"H{h + 1}.T_on", "t_on", h, 0.01, 0.01, 1.0))
            params.append(Param(f"H{h + 1}.T_off", "t_off", h, 0.01, 0.01, 1.0))
        for a, act in enumerate(spec.actuators):
            width = act.max - act.min
            lo, hi = (-math.pi, math.pi) if act.kind == "angular" else (0.0, math.inf)
            n = len(params)
            params.append(Param(f"{act.name}.min", "amin", a, 0.05 * width, lo, hi, n + 1, 0.01 * width))
            params.append(Param(f"{act.name}.max", "amax", a, 0.05 * width, lo, hi, n, 0.01 * width))
            params.append(Param(f"{act.name}.ks", "ks", a, 0.1 * act.ks, 0.0, math.inf))
            params.append(Param(f"{act.name}.kd", "kd", a, 0.1 * act.kd, 0.0, math.inf))
        for s, sen in enumerate(spec.sensors):
            if sen.kind == "touch":
                continue
            width = sen.max - sen.min
            lo, hi = (0.0, math.inf) if sen.kind == "length" else (-math.pi, math.pi)
            n = len(params)
            params.append(Param(f"{sen.name}.min", "smin", s, 0.05 * width, lo, hi, n + 1, 0.01 * width))
            params.append(Param(f"{sen.name}.max", "smax", s, 0.05 * width, lo, hi, n, 0.01 * width))
        self.design = spec.design if morphology and spec.design is not None else None
        self._bodies: dict[tuple[float, ...], dict] = {}
        if self.design is not None:
            for j in body_numbers(spec):
                f = self.design.free[j]
                params.append(Param(f.name, "free", j, 0.05 * (f.max - f.min), f.min, f.max))
        elif morphology:
            for i, link in enumerate(spec.links):
                params.append(Param(f"{link.name}.scale", "scale", i, 0.05, 0.5, 1.5))
        self.params = tuple(params)

    def __len__(self) -> int:
        return len(self.params)

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]

    def nominal(self, gait_params: GaitParams | None = None) -> np.ndarray:
        """The starting vector: the creature file's values, or a gait's own values."""
        gp = gait_params or GaitParams()
        model = gp.model
        s = self.spec
        H = self.san.n_hidden
        k1, k2 = gp.rates(self.san.n_nodes, s.san.delay_on, s.san.delay_off)
        arr = {
            "amin": np.asarray(model.get("act_min", [a.min for a in s.actuators]), float),
            "amax": np.asarray(model.get("act_max", [a.max for a in s.actuators]), float),
            "ks": np.asarray(model.get("act_ks", [a.ks for a in s.actuators]), float),
            "kd": np.asarray(model.get("act_kd", [a.kd for a in s.actuators]), float),
            "smin": np.asarray(model.get("sens_min", [getattr(x, "min", 0.0) for x in s.sensors]), float),
            "smax": np.asarray(model.get("sens_max", [getattr(x, "max", 0.0) for x in s.sensors]), float),
            "scale": np.asarray(gp.scale if gp.scale is not None else [1.0] * len(s.links), float),
            "free": np.asarray(gp.free if gp.free is not None else
                               (self.design.defaults if self.design is not None else []), float),
            "t_on": 1.0 / k1[:H],
            "t_off": -1.0 / k2[:H],
        }
        return np.array([arr[p.kind][p.index] for p in self.params], float)

    def perturb(self, theta: np.ndarray, which: int, sign: float) -> np.ndarray:
        """theta with parameter ``which`` moved by sign x delta, projected back to validity."""
        out = np.array(theta, float)
        p = self.params[which]
        v = out[which] + sign * p.delta
        lo, hi = p.lo, p.hi
        if p.partner >= 0:  # keep min < max
            if p.kind in ("amin", "smin"):
                hi = min(hi, out[p.partner] - p.gap)
            else:
                lo = max(lo, out[p.partner] + p.gap)
        out[which] = min(max(v, lo), hi)
        return out

    def valid(self, theta: np.ndarray) -> bool:
        for i, p in enumerate(self.params):
            if not (p.lo <= theta[i] <= p.hi):
                return False
            if p.partner >= 0 and p.kind in ("amin", "smin") and not theta[i] < theta[p.partner]:
                return False
        return True

    def gait_params(self, theta: np.ndarray, model) -> GaitParams:
        """What a tuned gait stores: per-node k1, k2 and model overrides (``model`` is the
        nominal compiled creature, needed to re-seat a reshaped one)."""
        k1, k2, over = self._arrays(theta)
        overrides = {k: np.asarray(v).tolist() for k, v in over.items()}
        scale = None
        if self.design is not None:
            overrides["q0"] = np.asarray(self.batch(theta[None], model)[2].params.q0[0]).tolist()
            return GaitParams(k1=tuple(k1.tolist()), k2=tuple(k2.tolist()), model=overrides,
                              free=tuple(float(x) for x in self.free_values(theta)))
        if self.morphology:
            scale = tuple(float(theta[i]) for i, p in enumerate(self.params) if p.kind == "scale")
            overrides["q0"] = np.asarray(self.batch(theta[None], model)[2].params.q0[0]).tolist()
        return GaitParams(k1=tuple(k1.tolist()), k2=tuple(k2.tolist()), model=overrides, scale=scale)

    def _arrays(self, theta: np.ndarray):
        s = self.spec
        k1 = np.full(self.san.n_nodes, 1 / s.san.delay_on)
        k2 = np.full(self.san.n_nodes, -1 / s.san.delay_off)
        over = {
            "act_min": np.array([a.min for a in s.actuators], float),
            "act_max": np.array([a.max for a in s.actuators], float),
            "act_ks": np.array([a.ks for a in s.actuators], float),
            "act_kd": np.array([a.kd for a in s.actuators], float),
            "sens_min": np.array([getattr(x, "min", 0.0) for x in s.sensors], float),
            "sens_max": np.array([getattr(x, "max", 0.0) for x in s.sensors], float),
        }
        key = {"amin": "act_min", "amax": "act_max", "ks": "act_ks", "kd": "act_kd", "smin": "sens_min", "smax": "sens_max"}
        scale = np.ones(len(s.links))
        for v, p in zip(theta, self.params):
            if p.kind == "t_on":
                k1[p.index] = 1.0 / v
            elif p.kind == "t_off":
                k2[p.index] = -1.0 / v
            elif p.kind == "scale":
                scale[p.index] = v
            elif p.kind != "free":
                over[key[p.kind]][p.index] = v
        if self.design is not None:
            over.update(self._body(self.free_values(theta)))
        elif self.morphology:
            over.update(self._morphology(scale, over["act_ks"]))
        return k1, k2, over

    def free_values(self, theta: np.ndarray) -> np.ndarray:
        """Every free number of the file [F] (its own units) at ``theta``: the tuned ones from
        it, the rest at their defaults; totals held (``Design.project``)."""
        assert self.design is not None
        v = self.design.defaults.copy()
        for x, p in zip(theta, self.params):
            if p.kind == "free":
                v[p.index] = x
        return self.design.project(v)

    def _body(self, v: np.ndarray) -> dict:
        """The body arrays (:data:`BODY_FIELDS`) of the file's creature at free values ``v``,
        compiled once per distinct vector."""
        from sanlab.sim.compiler import compile_creature

        key = tuple(float(x) for x in v)
        if key not in self._bodies:
            assert self.design is not None
            m = compile_creature(self.design.creature(v), "float64")
            arrays = {f: np.asarray(getattr(m.params, f), float) for f in BODY_FIELDS}
            self._bodies[key] = {f: a for f, a in arrays.items() if a.size}  # none for no springs, no edges
            if len(self._bodies) > 4096:  # a long tuning visits many: keep memory bounded
                self._bodies.pop(next(iter(self._bodies)))
        return self._bodies[key]

    def _morphology(self, scale: np.ndarray, ks: np.ndarray) -> dict:
        """Model arrays for link length scales (see the module docstring)."""
        s = self.spec
        names = {l.name: i for i, l in enumerate(s.links)}
        strength = np.ones(len(s.links))
        for a, act in enumerate(s.actuators):
            if act.kind == "angular" and act.ks > 0:
                strength[names[act.joint]] = math.sqrt(max(ks[a], 0.0) / act.ks)
        mass = np.array([l.mass for l in s.links]) * scale * strength
        inertia = np.array([l.inertia for l in s.links]) * (mass / np.array([l.mass for l in s.links])) * scale**2
        com = np.array([l.com for l in s.links]) * scale[:, None]
        anchor = np.array([(l.anchor if l.parent else (0.0, 0.0)) for l in s.links], float)
        for i, l in enumerate(s.links):
            if l.parent:
                anchor[i] *= scale[names[l.parent]]
        contact = np.array([c for l in s.links for c in l.contacts], float).reshape(-1, 2)
        owners = [i for i, l in enumerate(s.links) for _ in l.contacts]
        contact *= scale[owners][:, None] if owners else 1.0

        def pts(refs):
            out = np.array([[r.at for r in pair] for pair in refs], float).reshape(-1, 2, 2)
            for n, pair in enumerate(refs):
                for e, r in enumerate(pair):
                    out[n, e] *= scale[names[r.link]]
            return out

        lin = [(a.a, a.b) if a.kind == "linear" else None for a in s.actuators]
        act_pts = np.zeros((len(lin), 2, 2))
        for n, pair in enumerate(lin):
            if pair:
                act_pts[n] = pts([pair])[0]
        sens_pts = np.zeros((len(s.sensors), 2, 2))
        for n, x in enumerate(s.sensors):
            if x.kind == "eye":
                sens_pts[n, 0] = np.array(x.at.at) * scale[names[x.at.link]]
            elif x.kind == "length":
                sens_pts[n] = pts([(x.a, x.b)])[0]
        out = {"mass": mass, "inertia": inertia, "com": com, "anchor": anchor, "contact": contact,
               "act_pts": act_pts, "sens_pts": sens_pts}
        if s.springs:
            out["spr_pts"] = pts([(x.a, x.b) for x in s.springs])
        edges = drag_edges(s)
        if edges:
            out["edge"] = np.array([(np.multiply(a, scale[i]), np.multiply(b, scale[i])) for i, a, b in edges], float)
        return out

    def batch(self, thetas: np.ndarray, model):
        """Controller rates and a model whose parameters carry a leading batch axis, one row per
        vector: (k1 [B, N], k2 [B, N], model)."""
        import dataclasses

        rows = [self._arrays(t) for t in thetas]
        k1 = np.stack([r[0] for r in rows])
        k2 = np.stack([r[1] for r in rows])
        B = len(rows)
        p = model.params
        base = model.with_params(**{f.name: np.broadcast_to(np.asarray(getattr(p, f.name)), (B, *np.shape(getattr(p, f.name))))
                                    for f in dataclasses.fields(p)})
        over = {k: np.asarray(np.stack([r[2][k] for r in rows]), model.dtype) for k in rows[0][2]}
        m = base.with_params(**over)
        if self.morphology and self.spec.world.plane == "vertical" and model.structure.contacts:
            m = m.with_params(q0=_rest_on_ground(m, model))
        return k1, k2, m


def _rest_on_ground(batched, nominal):
    """q0 [B, D] with the roots shifted vertically so that the lowest contact starts where it did
    nominally (a longer leg must not start inside the ground)."""
    from sanlab.sim import poses

    q0 = np.array(batched.params.q0, np.float64)
    low = poses(batched, q0, params_batched=True)["contacts"][:, :, 1].min(1)
    shift = poses(nominal, nominal.params.q0)["contacts"][:, 1].min() - low
    for ls in batched.structure.links:
        if ls.parent < 0 and ls.dof_y >= 0:
            q0[:, ls.dof_y] += shift
    return q0


def body_numbers(spec: Creature) -> list[int]:
    """Indices of the file's free numbers (``spec.design``) that tuning with ``morphology``
    moves (see the module docstring): those that, between a quarter and three quarters of their
    range, change some of :data:`BODY_FIELDS` in the compiled creature and nothing outside them
    and the controller's arrays, and none of the controller's arrays (which the vector holds)."""
    from sanlab.creature import CreatureError
    from sanlab.sim.compiler import compile_creature

    design = spec.design
    if design is None:
        return []
    out = []
    for j, f in enumerate(design.free):
        ends = []
        for t in (0.25, 0.75):
            v = design.defaults.copy()
            v[j] = f.min + t * (f.max - f.min)
            try:
                ends.append(compile_creature(design.creature(v), "float64"))
            except CreatureError:
                break
        if len(ends) < 2 or ends[0].structure != ends[1].structure:
            continue
        a, b = ends[0].params, ends[1].params
        moved = {k for k in a.__dataclass_fields__
                 if np.asarray(getattr(a, k)).shape != np.asarray(getattr(b, k)).shape
                 or not np.array_equal(np.asarray(getattr(a, k)), np.asarray(getattr(b, k)))}
        if moved and moved <= set(BODY_FIELDS):
            out.append(j)
    return out
