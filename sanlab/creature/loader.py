"""Read creature files (TOML, see ``FORMAT.md``) into the frozen dataclasses of ``spec.py``.

Files use degrees and the paper's N·m/deg; everything returned is SI (radians, N·m/rad). Every
problem raises :class:`CreatureError` with a one-line message ``file: field: expected X, got Y``.
Every default is the spec dataclass's own (``_toml.spec_default``), so the file format and the spec
cannot disagree about one. Built-in creatures and files by path: ``files.py``.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from . import geometry
from ._checks import (
    _MISSING,
    CreatureError,
    _num,
    boolean,
    integer,
    list_of,
    nonempty,
    nonneg,
    number,
    one_of,
    points,
    positive,
    string,
    within,
)
from ._parts import _actuator, _link_ref, _links, _named, _sensor, _spring
from ._toml import (
    EVALUATION,
    FOLLOW,
    GROUND,
    SAN,
    SPRINGS,
    TERRAIN,
    TOP,
    WORLD,
    _Table,
    radians_field,
    spec_default,
)
from .spec import (
    DIRECTIONS,
    METRICS,
    PLANES,
    Creature,
    Evaluation,
    Follow,
    Ground,
    Link,
    SanConfig,
    Terrain,
    World,
)

__all__ = ["CreatureError", "loads"]

SLOPE = _num("a number in (-90, 90) (deg)", lambda x: -90 < x < 90)


def _stem(source: str) -> str:
    if source.startswith("builtin:"):
        return source[len("builtin:") :]
    return "unnamed" if source.startswith("<") else Path(source).stem


def loads(text: str, source: str = "<string>") -> Creature:
    """Parse and validate creature TOML ``text``; ``source`` names the file in error messages."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e)
        m = re.search(r"\s*\(at (.*)\)$", msg)
        where, why = (m.group(1), msg[: m.start()]) if m else ("TOML", msg)
        raise CreatureError(
            f"{source}: {where}: expected valid TOML, got a syntax error ({why})"
        ) from None
    return _creature(_Table(source, "", data, TOP), _stem(source))


def _creature(t: _Table, default_name: str) -> Creature:
    links = _links(t)
    world = _world(t.table("world", WORLD))
    sensors = _named(t, "sensors", None, "S", lambda s, nm: _sensor(s, nm, links))
    actuators = _named(t, "actuators", None, "A", lambda s, nm: _actuator(s, nm, links))
    springs = _named(t, "springs", SPRINGS, "K", lambda s, nm: _spring(s, nm, links))
    evaluation = _evaluation(t.table("evaluation", EVALUATION), links)

    for i, s in enumerate(sensors):
        if s.kind == "eye" and world.follow is None:
            raise t.error(
                "world.follow", f"a follow path (sensors[{i}] is an eye sensor)", _MISSING
            )
    if world.plane == "horizontal":
        for key in ("fell_com_height", "fell_link_height"):
            if getattr(evaluation, key) is not None:
                raise t.error(f"evaluation.{key}", "no height in a horizontal plane (seen from above there is no up)",
                              getattr(evaluation, key))
    if evaluation.metric == "pursuit" and world.follow is None:
        raise t.error("world.follow", "a follow path (evaluation.metric is 'pursuit')", _MISSING)
    driven: dict[str, int] = {}
    for i, a in enumerate(actuators):
        if a.kind == "angular" and driven.setdefault(a.joint, i) != i:
            raise t.error(
                f"actuators[{i}].joint",
                f"a joint not driven by actuators[{driven[a.joint]}]",
                a.joint,
            )
    creature = Creature(
        name=t.get("name", nonempty, default_name),
        description=t.get("description", string, spec_default(Creature, "description")),
        dt=t.get("dt", positive("s"), spec_default(Creature, "dt")),
        links=links,
        sensors=sensors,
        actuators=actuators,
        springs=springs,
        world=world,
        san=_san(t.table("san", SAN)),
        evaluation=evaluation,
    )
    _check_inertia(t, creature)
    return creature


# Smallest over largest eigenvalue of M below which a dof has, for float32 arithmetic, no inertia.
DEGENERATE = 1e-9


def _check_inertia(t: _Table, creature: Creature) -> None:
    """Every degree of freedom must carry inertia, as MuJoCo's compiler demands: a joint whose
    link has no inertia about it (its mass at the joint, zero inertia, nothing hanging from it)
    makes M(q) singular and every simulation non-finite."""
    import numpy as np

    M, owner = geometry.mass_matrix(creature)
    if not owner:
        return
    w, v = np.linalg.eigh(np.asarray(M))
    if w[0] > DEGENERATE * max(w[-1], 1e-300):
        return
    name = owner[int(np.argmax(np.abs(v[:, 0])))]
    i = [link.name for link in creature.links].index(name)
    link = creature.links[i]
    raise t.error(f"links[{i}].inertia", "inertia about the link's own degree of freedom (inertia > 0, or the "
                  "centre of mass away from the joint; without it the mass matrix is singular)", link.inertia)


def _san(t: _Table | None) -> SanConfig:
    if t is None:
        return SanConfig()
    d = SanConfig()
    return SanConfig(
        hidden=t.get("hidden", integer(0), d.hidden),
        delay_on=t.get("delay_on", positive("s"), d.delay_on),
        delay_off=t.get("delay_off", positive("s"), d.delay_off),
    )


def _world(t: _Table | None) -> World:
    if t is None:
        return World()
    w = World()
    plane = t.get("plane", one_of(PLANES), w.plane)
    g = t.table("ground", GROUND)
    ground = Ground()
    if g:
        ground = Ground(
            stiffness=g.get("stiffness", positive("N/m"), ground.stiffness),
            damping=g.get("damping", nonneg("N s/m"), ground.damping),
            friction=g.get("friction", nonneg(), ground.friction),
            slip_speed=g.get("slip_speed", positive("m/s"), ground.slip_speed),
        )
    terrain = Terrain()
    tt = t.table("terrain", set().union(*TERRAIN.values()))
    if tt:
        kind = tt.get("kind", one_of(TERRAIN), terrain.kind)
        tt.restrict(TERRAIN[kind], f" for terrain kind {kind!r}")
        if plane == "horizontal" and kind != "flat":
            raise tt.error(
                "kind", "'flat' in a horizontal plane (seen from above there is no terrain)", kind
            )
        d = terrain
        terrain = Terrain(
            kind=kind,
            angle=radians_field(tt, "angle_deg", SLOPE, d.angle),
            height=tt.get("height", nonneg("m") if kind == "rough" else number("m"), d.height),
            width=tt.get("width", positive("m"), d.width),
            center=tt.get("center", number("m"), d.center),
            wavelength=tt.get("wavelength", positive("m"), d.wavelength),
            seed=tt.get("seed", integer(0), d.seed),
        )
    f = t.table("follow", FOLLOW)
    follow = None
    if f:
        follow = Follow(
            points=f.get("points", points("a list of at least 2 points [[x, y], ...] (m)", 2)),
            speed=f.get("speed", nonneg("m/s")),
            loop=f.get("loop", boolean, spec_default(Follow, "loop")),
        )
    return World(
        plane=plane,
        gravity=t.get("gravity", nonneg("m/s^2"), w.gravity),
        ground=ground,
        terrain=terrain,
        water_drag=t.get("water_drag", nonneg("N s/m^2"), w.water_drag),
        water_tangential=t.get("water_tangential", nonneg(), w.water_tangential),
        follow=follow,
    )


def _evaluation(t: _Table | None, links: tuple[Link, ...]) -> Evaluation:
    d = Evaluation()
    if t is None:
        return d
    metric = t.get("metric", one_of(METRICS), d.metric)
    fell: tuple[str, ...] = ()
    if "fell_link" in t:
        names = [k.name for k in links]
        raw = t.data["fell_link"]
        if isinstance(raw, str):
            fell = (_link_ref(t, "fell_link", links, not_point="a point mass has no angle").name,)
        else:
            what = "one of the link names, or a list of them"
            fell = t.get("fell_link", list_of(one_of(names, "one of the link names"), what, 1))
            for i, name in enumerate(fell):
                if next(k for k in links if k.name == name).is_point:
                    raise t.error(f"fell_link[{i}]", "a link that is not a point mass (a point mass has no angle)", name)
    com_height = t.get("fell_com_height", number("m"), d.fell_com_height)
    link_height = t.get("fell_link_height", number("m"), d.fell_link_height)
    if link_height is not None and not fell:
        raise t.error("fell_link", "a link name (fell_link_height needs one)", _MISSING)
    if metric == "distance_upright" and not fell and com_height is None:
        raise t.error("fell_link", "a link name (metric 'distance_upright' needs one, or fell_com_height)", _MISSING)
    return Evaluation(
        metric=metric,
        seconds=t.get("seconds", positive("s"), d.seconds),
        fell_links=fell,
        fell_angle=radians_field(t, "fell_angle_deg", within(0, 180, "deg", open_lo=True), d.fell_angle),
        fell_com_height=com_height,
        fell_link_height=link_height,
        hop_k=t.get("hop_k", nonneg(), d.hop_k),
        direction=t.get("direction", one_of(DIRECTIONS), d.direction),
    )
