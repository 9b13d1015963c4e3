"""Read creature files (TOML, see ``FORMAT.md``) into the frozen dataclasses of ``spec.py``.

Files use degrees and the paper's N·m/deg; everything returned is SI (radians, N·m/rad). Every
problem raises :class:`CreatureError` with a one-line message ``file: field: expected X, got Y``.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable, Iterable
from importlib import resources
from pathlib import Path
from typing import Any

from .spec import (
    AngleSensor,
    AngularActuator,
    Creature,
    Evaluation,
    EyeSensor,
    Follow,
    Friction,
    Ground,
    JointSpring,
    LengthSensor,
    LinearActuator,
    LinearSpring,
    Link,
    PointRef,
    SanConfig,
    Shape,
    Terrain,
    TouchSensor,
    Vec2,
    World,
)

__all__ = [
    "CreatureError",
    "builtin_names",
    "initial_frames",
    "load",
    "load_file",
    "loads",
    "read_source",
    "world_point",
]

PER_DEG = 180.0 / math.pi  # (N m/deg) * PER_DEG = N m/rad


class CreatureError(ValueError):
    """A bad creature file; ``str()`` is one line: ``file: field: expected X, got Y``."""


# ---------------------------------------------------------------------------------------------
# Checks: each takes a raw TOML value and returns the converted value or raises _Bad.

_REQUIRED = object()  # no default: the field must be present
_MISSING = object()  # the value of an absent field; every check rejects it
_SAME = object()


class _Bad(Exception):
    """``what`` was expected; ``sub`` (e.g. "[1]") locates the culprit inside the checked value."""

    def __init__(self, what: str, sub: str = "", got: Any = _SAME):
        self.what, self.sub, self.got = what, sub, got


Check = Callable[[Any], Any]


def _show(v: Any) -> str:
    if v is _MISSING:
        return "nothing"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, dict):
        return "a table"
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _num(what: str, ok: Callable[[float], bool] = lambda x: True) -> Check:
    def check(v: Any) -> float:
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float))
            or not math.isfinite(v)
            or not ok(v)
        ):
            raise _Bad(what)
        return float(v)

    return check


def number(unit: str = "") -> Check:
    return _num("a number" + _unit(unit))


def positive(unit: str = "") -> Check:
    return _num("a positive number" + _unit(unit), lambda x: x > 0)


def nonneg(unit: str = "") -> Check:
    return _num("a non-negative number" + _unit(unit), lambda x: x >= 0)


def within(lo: float, hi: float, unit: str = "", open_lo: bool = False) -> Check:
    what = f"a number in {'(' if open_lo else '['}{lo:g}, {hi:g}]" + _unit(unit)
    return _num(what, lambda x: (lo < x if open_lo else lo <= x) and x <= hi)


def integer(lo: int = 0) -> Check:
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise _Bad(f"an integer >= {lo}")
        return v

    return check


def string(v: Any) -> str:
    if not isinstance(v, str):
        raise _Bad("a string")
    return v


def nonempty(v: Any) -> str:
    if not isinstance(v, str) or not v.strip():
        raise _Bad("a non-empty string")
    return v


def boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise _Bad("true or false")
    return v


def one_of(options: Iterable[str], what: str = "one of") -> Check:
    options = list(options)

    def check(v: Any) -> str:
        if not isinstance(v, str) or v not in options:
            raise _Bad(f"{what} {options}")
        return v

    return check


def list_of(item: Check, what: str, lo: int = 0, hi: int | None = None) -> Check:
    def check(v: Any) -> tuple:
        if not isinstance(v, list) or len(v) < lo or (hi is not None and len(v) > hi):
            raise _Bad(what)
        out = []
        for i, x in enumerate(v):
            try:
                out.append(item(x))
            except _Bad as e:
                raise _Bad(e.what, f"[{i}]{e.sub}", x if e.got is _SAME else e.got) from None
        return tuple(out)

    return check


def vec2(unit: str = "m") -> Check:
    coord = number()

    def check(v: Any) -> Vec2:
        if not isinstance(v, list) or len(v) != 2:
            raise _Bad("a pair of numbers [x, y]" + _unit(unit))
        try:
            return (coord(v[0]), coord(v[1]))
        except _Bad:
            raise _Bad("a pair of numbers [x, y]" + _unit(unit)) from None

    return check


def points(what: str, lo: int = 0, hi: int | None = None) -> Check:
    return list_of(vec2(), what, lo, hi)


def link_pair(names: list[str]) -> Check:
    inner = list_of(one_of(names, "one of the link names"), "a pair of link names [from, to]", 2, 2)

    def check(v: Any) -> tuple[str, str]:
        a, b = inner(v)
        if a == b:
            raise _Bad("two different link names [from, to]")
        return (a, b)

    return check


# ---------------------------------------------------------------------------------------------
# Tables


class _Table:
    """One TOML table being read. ``path`` (e.g. "links[2]") locates it in messages."""

    def __init__(self, src: str, path: str, data: Any, fields: Iterable[str] | None):
        self.src, self.path = src, path
        if not isinstance(data, dict):
            raise self.error("", "a table", data)
        self.data = data
        if fields is not None:  # None: the caller restricts once it knows the table's type
            self.restrict(fields)

    def at(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path and key else (key or self.path)

    def error(self, key: str, what: str, got: Any) -> CreatureError:
        return CreatureError(
            f"{self.src}: {self.at(key) or '(top level)'}: expected {what}, got {_show(got)}"
        )

    def restrict(self, fields: Iterable[str], context: str = "") -> None:
        """Reject keys outside ``fields`` (catches typos before they become confusing errors)."""
        fields = sorted(fields)
        for key in self.data:
            if key not in fields:
                raise CreatureError(
                    f"{self.src}: {self.at(key)}: unknown field{context}; expected one of {fields}"
                )

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, check: Check, default: Any = _REQUIRED) -> Any:
        v = self.data.get(key, _MISSING)
        if v is _MISSING and default is not _REQUIRED:
            return default
        try:
            return check(v)
        except _Bad as e:
            raise self.error(key + e.sub, e.what, v if e.got is _SAME else e.got) from None

    def forbid(self, key: str, why: str) -> None:
        if key in self.data:
            raise self.error(key, f"no {key} {why}", self.data[key])

    def table(self, key: str, fields: Iterable[str]) -> _Table | None:
        return _Table(self.src, self.at(key), self.data[key], fields) if key in self.data else None

    def tables(self, key: str, fields: Iterable[str] | None, lo: int = 0) -> list[_Table]:
        """An array of tables ``[[key]]``."""
        v = self.data.get(key, [])
        if not isinstance(v, list) or len(v) < lo:
            what = f"at least one [[{key}]] table" if lo else f"an array of [[{key}]] tables"
            raise self.error(key, what, v if key in self.data else _MISSING)
        return [_Table(self.src, f"{self.at(key)}[{i}]", x, fields) for i, x in enumerate(v)]


# ---------------------------------------------------------------------------------------------
# Geometry


def _mass_props(kind: str, pts: tuple[Vec2, ...], mass: float) -> tuple[Vec2, float]:
    """Default centre of mass (m) and inertia about it (kg m^2) of a uniform shape."""
    if kind == "segment":
        (x0, y0), (x1, y1) = pts
        return ((x0 + x1) / 2, (y0 + y1) / 2), mass * ((x1 - x0) ** 2 + (y1 - y0) ** 2) / 12
    if kind == "polygon":
        a, (cx, cy), j = _polygon(pts)
        return (cx, cy), mass * (j / a - cx * cx - cy * cy)
    return (0.0, 0.0), 0.0


def _polygon(pts: tuple[Vec2, ...]) -> tuple[float, Vec2, float]:
    """Shoelace: signed area, area centroid, polar second moment about the origin (sign of area)."""
    a = cx = cy = j = 0.0
    for (x0, y0), (x1, y1) in zip(pts, pts[1:] + pts[:1], strict=True):
        c = x0 * y1 - x1 * y0
        a += c
        cx += (x0 + x1) * c
        cy += (y0 + y1) * c
        j += c * (x0 * x0 + x0 * x1 + x1 * x1 + y0 * y0 + y0 * y1 + y1 * y1)
    a /= 2
    if abs(a) < 1e-12:
        return 0.0, (0.0, 0.0), 0.0
    return a, (cx / (6 * a), cy / (6 * a)), j / 12


def _frames(links: Iterable[Link]) -> dict[str, tuple[float, float, float]]:
    frames: dict[str, tuple[float, float, float]] = {}
    for link in links:  # parents come first, so one pass suffices
        if link.parent is None:
            frames[link.name] = (*link.position, link.angle)
        else:
            px, py, pa = frames[link.parent]
            x, y = _apply((px, py, pa), link.anchor)
            frames[link.name] = (x, y, pa + link.angle)
    return frames


def _apply(frame: tuple[float, float, float], p: Vec2) -> Vec2:
    x, y, a = frame
    c, s = math.cos(a), math.sin(a)
    return (x + c * p[0] - s * p[1], y + s * p[0] + c * p[1])


def initial_frames(creature: Creature) -> dict[str, tuple[float, float, float]]:
    """World pose (x m, y m, angle rad) of every link's frame in the initial configuration."""
    return _frames(creature.links)


def world_point(creature: Creature, link: str, at: Vec2 = (0.0, 0.0)) -> Vec2:
    """Initial world position (m) of point ``at`` (link frame, m) of ``link``."""
    return _apply(_frames(creature.links)[link], at)


# ---------------------------------------------------------------------------------------------
# The format

TOP = {
    "name", "description", "dt", "world", "san", "evaluation", "links", "sensors", "actuators",
    "springs",
}  # fmt: skip
WORLD = {"plane", "gravity", "water_drag", "ground", "terrain", "follow"}
GROUND = {"stiffness", "damping", "friction", "slip_speed"}
TERRAIN = {
    "flat": {"kind"},
    "slope": {"kind", "angle_deg"},
    "hill": {"kind", "height", "width", "center"},
    "rough": {"kind", "height", "wavelength", "seed"},
}
FOLLOW = {"points", "speed", "loop"}
SAN = {"hidden", "delay_on", "delay_off"}
EVALUATION = {"metric", "seconds", "fell_link", "fell_angle_deg", "hop_k"}
METRICS = ["distance", "distance_upright", "hopping", "pursuit"]
LINK = {
    "name", "mass", "shape", "points", "inertia", "com", "contacts", "position", "angle_deg",
    "parent", "anchor", "spring", "friction", "drag", "fixed",
}  # fmt: skip
SHAPES = ["segment", "polygon", "point"]
SPRING = {"stiffness", "damping", "rest_deg"}
FRICTION = {"forward", "backward", "lateral", "axis"}
POINT = {"link", "at"}
SENSOR = {
    "touch": {"link", "contact"},
    "angle": {"link", "min_deg", "max_deg"},
    "eye": {"link", "at", "min_deg", "max_deg", "axis"},
    "length": {"a", "b", "min", "max"},
}
ACTUATOR = {
    "angular": {"joint", "min_deg", "max_deg", "ks", "kd"},
    "linear": {"a", "b", "min", "max", "ks", "kd"},
}
SPRINGS = {"name", "a", "b", "stiffness", "damping", "rest"}
ANGLE = within(-180, 180, "deg")
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
    return Creature(
        name=t.get("name", nonempty, default_name),
        description=t.get("description", string, ""),
        dt=t.get("dt", positive("s"), 1.0e-3),
        links=links,
        sensors=sensors,
        actuators=actuators,
        springs=springs,
        world=world,
        san=_san(t.table("san", SAN)),
        evaluation=evaluation,
    )


def _fields(kinds: dict[str, set[str]]) -> set[str]:
    return {"name", "type"}.union(*kinds.values())


def _san(t: _Table | None) -> SanConfig:
    if t is None:
        return SanConfig()
    return SanConfig(
        hidden=t.get("hidden", integer(0), None),
        delay_on=t.get("delay_on", positive("s"), 0.1),
        delay_off=t.get("delay_off", positive("s"), 0.1),
    )


def _world(t: _Table | None) -> World:
    if t is None:
        return World()
    plane = t.get("plane", one_of(["vertical", "horizontal"]), "vertical")
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
        kind = tt.get("kind", one_of(TERRAIN), "flat")
        tt.restrict(TERRAIN[kind], f" for terrain kind {kind!r}")
        if plane == "horizontal" and kind != "flat":
            raise tt.error(
                "kind", "'flat' in a horizontal plane (seen from above there is no terrain)", kind
            )
        d = terrain
        terrain = Terrain(
            kind=kind,
            angle=math.radians(tt.get("angle_deg", SLOPE, 0.0)),
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
            loop=f.get("loop", boolean, False),
        )
    return World(
        plane=plane,
        gravity=t.get("gravity", nonneg("m/s^2"), 9.81),
        ground=ground,
        terrain=terrain,
        water_drag=t.get("water_drag", nonneg("N s/m^2"), 0.0),
        follow=follow,
    )


def _links(t: _Table) -> tuple[Link, ...]:
    tables = t.tables("links", LINK, lo=1)
    all_names: list[str] = []
    for lt in tables:  # all names first: friction axes may name links further down
        n = lt.get("name", nonempty)
        if n in all_names:
            raise lt.error("name", "a name not used by another link", n)
        all_names.append(n)
    links: list[Link] = []
    for lt in tables:
        links.append(_link(lt, {k.name: k for k in links}, all_names))
    return tuple(links)


def _link(t: _Table, before: dict[str, Link], all_names: list[str]) -> Link:
    kind = t.get("shape", one_of(SHAPES))
    mass = t.get("mass", positive("kg"))
    pts: tuple[Vec2, ...] = ()
    if kind == "point":
        for key in ("points", "inertia", "com", "angle_deg"):
            t.forbid(key, "on a point mass")
        t.forbid("parent", "on a point mass (point masses must be roots)")
    elif kind == "segment":
        pts = t.get("points", points("exactly 2 points [[x, y], [x, y]] (m)", 2, 2))
        if pts[0] == pts[1]:
            raise t.error(
                "points", "2 distinct points (a segment of non-zero length)", t.data["points"]
            )
    else:
        pts = t.get("points", points("at least 3 points [[x, y], ...] (m)", 3))
        if _polygon(pts)[0] == 0.0:
            raise t.error("points", "a polygon of non-zero area", t.data["points"])
    com, inertia = _mass_props(kind, pts, mass)
    default_contacts = ((0.0, 0.0),) if kind == "point" else pts

    parent = None
    if "parent" in t:
        parent = t.get("parent", one_of(all_names, "one of the link names"))
        if parent not in before:
            raise t.error(
                "parent",
                "a link defined earlier in the file (parents come before children)",
                parent,
            )
        if before[parent].is_point:
            raise t.error(
                "parent", "a link that is not a point mass (point masses cannot be parents)", parent
            )
        t.forbid("position", "on a jointed link (its joint places it)")
        t.forbid("fixed", "on a jointed link (only roots can be welded to the world)")
    else:
        t.forbid("anchor", "on a root link (it has no joint)")
        t.forbid("spring", "on a root link (it has no joint)")

    spring = None
    s = t.table("spring", SPRING)
    if s:
        spring = JointSpring(
            stiffness=s.get("stiffness", nonneg("N m/deg")) * PER_DEG,
            damping=s.get("damping", nonneg("N m s/deg"), 0.0) * PER_DEG,
            rest=math.radians(s.get("rest_deg", number("deg"), 0.0)),
        )
    friction = None
    f = t.table("friction", FRICTION)
    if f:
        backward = f.get("backward", nonneg())
        friction = Friction(
            forward=f.get("forward", nonneg()),
            backward=backward,
            lateral=f.get("lateral", nonneg(), backward),
            axis=f.get("axis", link_pair(all_names), None),
        )
    return Link(
        name=t.get("name", nonempty),
        mass=mass,
        inertia=t.get("inertia", nonneg("kg m^2"), inertia),
        com=t.get("com", vec2(), com),
        shape=Shape(kind, pts),
        contacts=t.get("contacts", points("a list of points [[x, y], ...] (m)"), default_contacts),
        parent=parent,
        anchor=t.get("anchor", vec2(), (0.0, 0.0)),
        position=t.get("position", vec2(), (0.0, 0.0)),
        angle=math.radians(t.get("angle_deg", number("deg"), 0.0)),
        spring=spring,
        friction=friction,
        drag=t.get("drag", boolean, True),
        fixed=t.get("fixed", boolean, False),
    )


def _named(
    t: _Table, key: str, fields: set[str] | None, prefix: str, parse: Callable[[_Table, str], Any]
) -> tuple:
    """Parse ``[[key]]`` items, naming unnamed ones prefix1, prefix2, ... by position."""
    out, seen = [], set()
    for i, it in enumerate(t.tables(key, fields)):
        nm = it.get("name", nonempty, f"{prefix}{i + 1}")
        if nm in seen:
            raise it.error("name", f"a name not used by another item of [[{key}]]", nm)
        seen.add(nm)
        out.append(parse(it, nm))
    return tuple(out)


def _range(t: _Table, lo_key: str, hi_key: str, check: Check) -> tuple[float, float]:
    lo, hi = t.get(lo_key, check), t.get(hi_key, check)
    if not lo < hi:
        raise t.error(hi_key, f"a value greater than {lo_key} ({t.data[lo_key]})", t.data[hi_key])
    return lo, hi


def _deg_range(t: _Table, check: Check = ANGLE) -> tuple[float, float]:
    lo, hi = _range(t, "min_deg", "max_deg", check)
    return math.radians(lo), math.radians(hi)


def _typed(t: _Table, kinds: dict[str, set[str]], what: str) -> str:
    if t.data.get("type") not in kinds:
        t.restrict(_fields(kinds))  # a typo in "type" itself shows up here
    kind = t.get("type", one_of(kinds))
    article = "an" if kind[0] in "aeiou" else "a"
    t.restrict(kinds[kind] | {"name", "type"}, f" for {article} {kind} {what}")
    return kind


def _link_ref(t: _Table, key: str, links: tuple[Link, ...], **cond: Any) -> Link:
    """A link named by field ``key``; ``cond`` may demand ``not_point`` or ``jointed``."""
    by_name = {k.name: k for k in links}
    link = by_name[t.get(key, one_of(by_name, "one of the link names"))]
    if cond.get("not_point") and link.is_point:
        raise t.error(key, f"a link that is not a point mass ({cond['not_point']})", link.name)
    if cond.get("jointed") and link.parent is None:
        raise t.error(key, "a jointed link (one with a parent)", link.name)
    return link


def _point(t: _Table, key: str, links: tuple[Link, ...]) -> PointRef:
    raw = t.data.get(key, _MISSING)
    if not isinstance(raw, dict):
        raise t.error(key, "a point { link = NAME, at = [x, y] }", raw)
    p = _Table(t.src, t.at(key), raw, POINT)
    return PointRef(_link_ref(p, "link", links).name, p.get("at", vec2(), (0.0, 0.0)))


def _two_points(t: _Table, links: tuple[Link, ...]) -> tuple[PointRef, PointRef]:
    a, b = _point(t, "a", links), _point(t, "b", links)
    if a.link == b.link:
        raise t.error(
            "b.link", "a link other than a.link (points on one rigid link never move apart)", b.link
        )
    return a, b


def _sensor(t: _Table, nm: str, links: tuple[Link, ...]):
    kind = _typed(t, SENSOR, "sensor")
    if kind == "touch":
        link = _link_ref(t, "link", links)
        n = len(link.contacts)
        if n == 0:
            raise t.error("link", "a link with contact points", link.name)
        contact = t.get("contact", integer(0))
        if contact >= n:
            raise t.error(
                "contact", f"a contact index of link {link.name!r} in [0, {n - 1}]", contact
            )
        return TouchSensor(nm, link.name, contact)
    if kind == "angle":
        link = _link_ref(t, "link", links, not_point="point masses have no angle")
        return AngleSensor(nm, link.name, *_deg_range(t))
    if kind == "eye":
        link = _link_ref(t, "link", links)
        at = PointRef(link.name, t.get("at", vec2(), (0.0, 0.0)))
        lo, hi = _deg_range(t)
        return EyeSensor(nm, at, lo, hi, t.get("axis", link_pair([k.name for k in links]), None))
    a, b = _two_points(t, links)
    return LengthSensor(nm, a, b, *_range(t, "min", "max", nonneg("m")))


def _actuator(t: _Table, nm: str, links: tuple[Link, ...]):
    kind = _typed(t, ACTUATOR, "actuator")
    if kind == "angular":
        joint = _link_ref(t, "joint", links, jointed=True).name
        lo, hi = _deg_range(t, number("deg"))
        ks = t.get("ks", nonneg("N m/deg")) * PER_DEG
        kd = t.get("kd", nonneg("N m s/deg")) * PER_DEG
        return AngularActuator(nm, joint, lo, hi, ks, kd)
    a, b = _two_points(t, links)
    lo, hi = _range(t, "min", "max", nonneg("m"))
    return LinearActuator(
        nm, a, b, lo, hi, t.get("ks", nonneg("N/m")), t.get("kd", nonneg("N s/m"))
    )


def _spring(t: _Table, nm: str, links: tuple[Link, ...]) -> LinearSpring:
    a, b = _two_points(t, links)
    frames = _frames(links)
    (xa, ya), (xb, yb) = _apply(frames[a.link], a.at), _apply(frames[b.link], b.at)
    return LinearSpring(
        nm,
        a,
        b,
        stiffness=t.get("stiffness", nonneg("N/m")),
        damping=t.get("damping", nonneg("N s/m"), 0.0),
        rest=t.get("rest", nonneg("m"), math.hypot(xb - xa, yb - ya)),
    )


def _evaluation(t: _Table | None, links: tuple[Link, ...]) -> Evaluation:
    if t is None:
        return Evaluation()
    metric = t.get("metric", one_of(METRICS), "distance")
    fell = None
    if "fell_link" in t:
        fell = _link_ref(t, "fell_link", links, not_point="a point mass has no angle").name
    elif metric == "distance_upright":
        raise t.error("fell_link", "a link name (metric 'distance_upright' needs one)", _MISSING)
    return Evaluation(
        metric=metric,
        seconds=t.get("seconds", positive("s"), 6.0),
        fell_link=fell,
        fell_angle=math.radians(t.get("fell_angle_deg", within(0, 180, "deg", open_lo=True), 90.0)),
        hop_k=t.get("hop_k", nonneg(), 1.0),
    )


# ---------------------------------------------------------------------------------------------
# Files and built-ins


def _builtin_dir():
    return resources.files("sanlab.creature").joinpath("builtin")


def builtin_names() -> list[str]:
    """Sorted names of the built-in creatures: the stems of ``sanlab/creature/builtin/*.toml``."""
    return sorted(
        p.name[: -len(".toml")] for p in _builtin_dir().iterdir() if p.name.endswith(".toml")
    )


def read_source(name_or_path: str | Path) -> tuple[str, str]:
    """(file text, where it came from): a resolved path, or ``builtin:NAME`` for a built-in."""
    s = str(name_or_path)
    if isinstance(name_or_path, str) and s in builtin_names():
        return _builtin_dir().joinpath(f"{s}.toml").read_text(encoding="utf-8"), f"builtin:{s}"
    path = Path(name_or_path)
    try:
        return path.read_text(encoding="utf-8"), str(path.resolve())
    except FileNotFoundError:
        hint = "" if path.suffix else f" and no built-in creature of that name {builtin_names()}"
        raise CreatureError(f"{s}: no such file{hint}") from None
    except UnicodeDecodeError:
        raise CreatureError(f"{s}: expected a UTF-8 text file, got undecodable bytes") from None
    except OSError as e:
        raise CreatureError(f"{s}: cannot read ({e.strerror or e})") from None


def load_file(path: str | Path) -> Creature:
    """Load a creature from a .toml file; messages name the file as given."""
    text, _ = read_source(Path(path))
    return loads(text, str(path))


def load(name_or_path: str | Path) -> Creature:
    """Load a built-in creature by name (e.g. "cart"), or else a .toml file by path."""
    text, where = read_source(name_or_path)
    return loads(text, where if where.startswith("builtin:") else str(name_or_path))
