"""The creature's parts in the file format: ``[[links]]``, ``[[sensors]]``, ``[[actuators]]`` and
``[[springs]]`` (degrees and N·m/deg in the file, SI out; see ``FORMAT.md``)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ._checks import (
    _MISSING,
    Check,
    boolean,
    integer,
    link_pair,
    nonempty,
    nonneg,
    number,
    one_of,
    points,
    positive,
    vec2,
    within,
)
from ._toml import (
    ACTUATOR,
    FRICTION,
    LIMIT,
    LINK,
    POINT,
    SENSOR,
    SPRING,
    _Table,
    radians_field,
    spec_default,
)
from .geometry import link_frames, mass_properties, polygon_moments, transform
from .spec import (
    MAX_LINKS,
    MAX_POINTS,
    SHAPE_KINDS,
    AngleSensor,
    AngularActuator,
    EyeSensor,
    Friction,
    JointLimit,
    JointSpring,
    LengthSensor,
    LinearActuator,
    LinearSpring,
    Link,
    PointRef,
    Shape,
    TiltSensor,
    TouchSensor,
    Vec2,
)

PER_DEG = 180.0 / math.pi  # (N m/deg) * PER_DEG = N m/rad
ANGLE = within(-180, 180, "deg")


def _links(t: _Table) -> tuple[Link, ...]:
    tables = t.tables("links", LINK, lo=1, hi=MAX_LINKS)
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
    kind = t.get("shape", one_of(SHAPE_KINDS))
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
        pts = t.get("points", points(f"3 to {MAX_POINTS} points [[x, y], ...] (m)", 3))
        if polygon_moments(pts)[0] == 0.0:
            raise t.error("points", "a polygon of non-zero area", t.data["points"])
    com, inertia = mass_properties(kind, pts, mass)
    default_contacts = ((0.0, 0.0),) if kind == "point" else pts  # a point mass touches at its origin

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
        t.forbid("limit", "on a root link (it has no joint)")

    spring = None
    s = t.table("spring", SPRING)
    if s:
        spring = JointSpring(
            stiffness=s.get("stiffness", nonneg("N m/deg")) * PER_DEG,
            damping=s.get("damping", nonneg("N m s/deg"), spec_default(JointSpring, "damping")) * PER_DEG,
            rest=radians_field(s, "rest_deg", number("deg"), spec_default(JointSpring, "rest")),
        )
    limit = None
    lt = t.table("limit", LIMIT)
    if lt:
        lo, hi = _range(lt, "min_deg", "max_deg", within(-360, 360, "deg"))
        limit = JointLimit(
            min=math.radians(lo),
            max=math.radians(hi),
            stiffness=lt.get("stiffness", positive("N m/deg"), spec_default(JointLimit, "stiffness") / PER_DEG) * PER_DEG,
            damping=lt.get("damping", nonneg("N m s/deg"), spec_default(JointLimit, "damping") / PER_DEG) * PER_DEG,
        )
    friction = None
    f = t.table("friction", FRICTION)
    if f:
        backward = f.get("backward", nonneg())
        friction = Friction(
            forward=f.get("forward", nonneg()),
            backward=backward,
            lateral=f.get("lateral", nonneg(), backward),
            axis=f.get("axis", link_pair(all_names), spec_default(Friction, "axis")),
        )
    return Link(
        name=t.get("name", nonempty),
        mass=mass,
        inertia=t.get("inertia", nonneg("kg m^2"), inertia),
        com=t.get("com", vec2(), com),
        shape=Shape(kind, pts),
        contacts=t.get("contacts", points(f"a list of at most {MAX_POINTS} points [[x, y], ...] (m)"), default_contacts),
        parent=parent,
        anchor=t.get("anchor", vec2(), spec_default(Link, "anchor")),
        position=t.get("position", vec2(), spec_default(Link, "position")),
        angle=radians_field(t, "angle_deg", number("deg"), spec_default(Link, "angle")),
        spring=spring,
        limit=limit,
        friction=friction,
        drag=t.get("drag", boolean, spec_default(Link, "drag")),
        fixed=t.get("fixed", boolean, spec_default(Link, "fixed")),
    )


def _named(
    t: _Table, key: str, fields: set[str] | None, prefix: str, parse: Callable[[_Table, str], Any], most: int
) -> tuple:
    """Parse ``[[key]]`` items (at most ``most``), naming unnamed ones prefix1, prefix2, ... by
    position."""
    out, seen = [], set()
    for i, it in enumerate(t.tables(key, fields, hi=most)):
        nm = it.get("name", nonempty, f"{prefix}{i + 1}")
        if nm in seen:
            raise it.error("name", f"a name not used by another item of [[{key}]]", nm)
        seen.add(nm)
        if "name" in it:  # messages name the item as the file does
            it.label = f"{key[:-1]} {nm!r}"
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
    kind = t.data.get("type")
    if not isinstance(kind, str) or kind not in kinds:
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
    p = _Table(t.src, t.at(key), raw, POINT, t.label)
    return PointRef(_link_ref(p, "link", links).name, p.get("at", vec2(), spec_default(PointRef, "at")))


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
    if kind == "tilt":
        link = _link_ref(t, "link", links, not_point="point masses have no angle")
        return TiltSensor(nm, link.name, *_deg_range(t))
    if kind == "eye":
        link = _link_ref(t, "link", links)
        at = PointRef(link.name, t.get("at", vec2(), spec_default(PointRef, "at")))
        lo, hi = _deg_range(t)
        axis = t.get("axis", link_pair([k.name for k in links]), spec_default(EyeSensor, "axis"))
        return EyeSensor(nm, at, lo, hi, axis)
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
    frames = link_frames(links)
    (xa, ya), (xb, yb) = transform(frames[a.link], a.at), transform(frames[b.link], b.at)
    return LinearSpring(
        nm,
        a,
        b,
        stiffness=t.get("stiffness", nonneg("N/m")),
        damping=t.get("damping", nonneg("N s/m"), 0.0),  # undamped, as a JointSpring's default
        rest=t.get("rest", nonneg("m"), math.hypot(xb - xa, yb - ya)),  # at rest in the initial pose
    )


def _fields(kinds: dict[str, set[str]]) -> set[str]:
    return {"name", "type"}.union(*kinds.values())
