"""Read creature files (TOML, see ``FORMAT.md``) into the frozen dataclasses of ``spec.py``.

Files use degrees and the paper's N·m/deg; everything returned is SI (radians, N·m/rad). Every
problem raises :class:`CreatureError` with a one-line message ``file: field: expected X, got Y``.
Every default is the spec dataclass's own (``_toml.spec_default``), so the file format and the spec
cannot disagree about one. Built-in creatures and files by path: ``files.py``.
"""

from __future__ import annotations

import re
import sys
import tomllib
from dataclasses import replace
from functools import partial
from pathlib import Path

from . import geometry
from ._checks import (
    _MISSING,
    CreatureError,
    _Bad,
    _num,
    boolean,
    dated,
    integer,
    list_of,
    nonempty,
    nonneg,
    number,
    one_of,
    points,
    positive,
    printable,
    text,
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
    key_fault,
    radians_field,
    spec_default,
)
from .free import Design, read_design
from .spec import (
    DELAY_RANGE,
    DIRECTIONS,
    DT_RANGE,
    FOLLOW_METRICS,
    MAX_ACTUATORS,
    MAX_CONTACTS,
    MAX_DESCRIPTION,
    MAX_FILE_BYTES,
    MAX_GROUND_STIFFNESS_RATIO,
    MAX_HIDDEN,
    MAX_HISTORY,
    MAX_HISTORY_ENTRY,
    MAX_POINTS,
    MAX_SENSORS,
    MAX_SPRINGS,
    MAX_STEPS,
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

__all__ = ["CreatureError", "build", "loads", "loads_design"]

SLOPE = _num("a number in (-90, 90) (deg)", lambda x: -90 < x < 90)


def _stem(source: str) -> str:
    if source.startswith("builtin:"):
        return source[len("builtin:") :]
    stem = "unnamed" if source.startswith("<") else Path(source).stem
    try:  # the file's stem names the creature unless the file does: it must make a valid name
        return nonempty(stem)
    except _Bad:
        return "unnamed"


def loads(text: str, source: str = "<string>") -> Creature:
    """Parse and validate creature TOML ``text``; ``source`` names the file in error messages.
    A file with free numbers (``free``) gives its creature at their defaults, couplings applied.

    Raises :class:`CreatureError` (one printable line) for anything that is not a valid creature
    within the format's limits (``spec.MAX_*``; FORMAT.md, "Limits"), and for nothing else."""
    return loads_design(text, source)[1]


def loads_design(text: str, source: str = "<string>") -> tuple[Design, Creature]:
    """The free numbers and couplings of creature TOML ``text`` (``free.Design``: none for a file
    without ranges) and its creature at their defaults (what :func:`loads` returns), checked.
    Raises :class:`CreatureError` as :func:`loads` does."""
    shown = printable(source)  # messages stay one printable line whatever the file is called
    if not isinstance(text, str):
        raise CreatureError(f"{shown}: expected TOML text, got {type(text).__name__}")
    if len(text) > MAX_FILE_BYTES:
        raise CreatureError(f"{shown}: expected a creature file of at most {MAX_FILE_BYTES >> 20} MiB, "
                            f"got {len(text)} characters")
    fault = key_fault(text)
    if fault is not None:
        pos, what, got = fault
        line = text.count("\n", 0, pos) + 1
        column = pos - text.rfind("\n", 0, pos)
        raise CreatureError(f"{shown}: line {line}, column {column}: expected {what}, got {got}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e)
        m = re.search(r"\s*\(at (.*)\)$", msg)
        where, why = (m.group(1), msg[: m.start()]) if m else ("TOML", msg)
        raise CreatureError(
            f"{shown}: {where}: expected valid TOML, got a syntax error ({printable(why)})"
        ) from None
    except RecursionError:  # tomllib recurses once per level of nested arrays and inline tables
        raise CreatureError(f"{shown}: expected valid TOML, got arrays or tables nested too deep to read") from None
    except ValueError:  # not a TOMLDecodeError: int() refuses a decimal integer of more than 4300 digits
        raise CreatureError(f"{shown}: {_long_integer(text)}: expected valid TOML, got an integer of more than "
                            f"{sys.get_int_max_str_digits()} digits") from None
    try:
        # partials of module functions, not lambdas: a creature with its design is pickled to Ray workers
        design = read_design(data, shown, partial(expand_repeats, shown=shown), partial(build, shown=shown,
                                                                                         stem=_stem(source)))
        creature = design.creature()
        return design, (replace(creature, design=design) if design.free else creature)
    except RecursionError:  # a deeply nested value that parsed, met where a number was expected
        raise CreatureError(f"{shown}: expected a creature file, got values nested too deep to check") from None


def build(data: dict, shown: str, stem: str) -> Creature:
    """The creature of parsed, written-out TOML ``data`` (no free numbers, no ``[[repeat]]``).
    Raises :class:`CreatureError` naming ``shown``."""
    try:
        return _creature(_Table(shown, "", data, TOP), stem)
    except RecursionError:
        raise CreatureError(f"{shown}: expected a creature file, got values nested too deep to check") from None


REPEATED = ("links", "sensors", "actuators", "springs")  # what a [[repeat]] may hold
MAX_REPEAT = 64  # copies of one [[repeat]]: no part list holds more (spec.MAX_SENSORS)
_PLACEHOLDER = re.compile(r"\{i([+-][0-9]{1,4})?\}")


def expand_repeats(data: dict, shown: str = "<string>") -> dict:
    """The parsed file with its ``[[repeat]]`` tables written out (FORMAT.md, "Repeating parts").

    Each ``[[repeat]]`` has ``count`` (1 to :data:`MAX_REPEAT`), an optional ``start`` (the first
    ``i``, default 1) and arrays of tables named as the file's own (``[[repeat.links]]``,
    ``[[repeat.sensors]]``, ``[[repeat.actuators]]``, ``[[repeat.springs]]``). Its tables are
    copied ``count`` times, with ``{i}``, ``{i-1}``, ``{i+1}`` (any ``{i+K}``, ``{i-K}``) in every
    string replaced by the copy's number, and appended, in order, after the file's own tables of
    that name (so a repeated link's parent may be a link written above, or an earlier copy).
    A file without ``[[repeat]]`` is returned as it is. Raises CreatureError (one line, naming
    ``repeat[k]``) for a malformed ``[[repeat]]``; what it expands to is checked as if written out
    (messages then count the written-out tables: links[5] is the sixth link after expansion)."""
    if "repeat" not in data:
        return data
    top = _Table(shown, "", {"repeat": data["repeat"]}, ("repeat",))
    out = {k: (list(v) if k in REPEATED and isinstance(v, list) else v) for k, v in data.items() if k != "repeat"}
    for block in top.tables("repeat", ("count", "start", *REPEATED), lo=1, hi=MAX_REPEAT):
        count = block.get("count", integer(1, MAX_REPEAT))
        start = block.get("start", integer(-1000, 1000), 1)
        if not any(k in block for k in REPEATED):
            raise block.error("", f"a table of parts to repeat ({', '.join(f'[[repeat.{k}]]' for k in REPEATED)})",
                              block.data)
        for key in REPEATED:
            if key not in block:
                continue
            parts = block.data[key]
            if not isinstance(parts, list) or not all(isinstance(p, dict) for p in parts):
                raise block.error(key, f"an array of [[repeat.{key}]] tables", parts)
            if key in out and not isinstance(out[key], list):
                continue  # the file's own [[key]] is malformed: the checks that follow say so
            copies = [_numbered(p, i) for i in range(start, start + count) for p in parts]
            out[key] = [*out.get(key, []), *copies]
    return out


def _numbered(value, i: int):
    """``value`` with ``{i}`` and ``{i+K}`` in its strings replaced by the numbers (recursively)."""
    if isinstance(value, str):
        return _PLACEHOLDER.sub(lambda m: str(i + int(m.group(1) or 0)), value)
    if isinstance(value, dict):
        return {k: _numbered(v, i) for k, v in value.items()}
    if isinstance(value, list):
        return [_numbered(v, i) for v in value]
    return value


def _long_integer(text: str) -> str:
    """Where (``line N``) the first decimal integer too long for Python's int() is, or "TOML"."""
    limit = sys.get_int_max_str_digits()
    for m in re.finditer(r"[0-9][0-9_]*", text):  # linear: each run of digits is looked at once
        if limit and len(m.group()) - m.group().count("_") > limit:
            return f"line {text.count(chr(10), 0, m.start()) + 1}"
    return "TOML"


def _creature(t: _Table, default_name: str) -> Creature:
    links = _links(t)
    if not any(link.dofs for link in links):  # only fixed roots: nothing a SAN could move, nothing to simulate
        raise t.error("links[0].fixed", "at least one degree of freedom (a root link without fixed = true, or a "
                      "jointed link): with every link fixed nothing can move", True)
    n_contacts = sum(len(k.contacts) for k in links)
    if n_contacts > MAX_CONTACTS:
        i = max(range(len(links)), key=lambda i: len(links[i].contacts))
        raise t.error(f"links[{i}].contacts", f"at most {MAX_CONTACTS} contact points in all links together",
                      f"{n_contacts} in all")
    world = _world(t.table("world", WORLD))
    sensors = _named(t, "sensors", None, "S", lambda s, nm: _sensor(s, nm, links), MAX_SENSORS)
    actuators = _named(t, "actuators", None, "A", lambda s, nm: _actuator(s, nm, links), MAX_ACTUATORS)
    springs = _named(t, "springs", SPRINGS, "K", lambda s, nm: _spring(s, nm, links), MAX_SPRINGS)
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
    if evaluation.metric in FOLLOW_METRICS and world.follow is None:
        raise t.error("world.follow", f"a follow path (evaluation.metric is {evaluation.metric!r})", _MISSING)
    driven: dict[str, int] = {}
    for i, a in enumerate(actuators):
        if a.kind == "angular" and driven.setdefault(a.joint, i) != i:
            raise t.error(
                f"actuators[{i}].joint",
                f"a joint not driven by actuators[{driven[a.joint]}]",
                a.joint,
            )
    dt = t.get("dt", within(*DT_RANGE, "s"), spec_default(Creature, "dt"))
    if evaluation.seconds < dt:  # a run of no steps, scored 0 with no flag (issue 57)
        raise t.error("evaluation.seconds", f"at least one step of dt = {dt:g} s", evaluation.seconds)
    if evaluation.seconds / dt > MAX_STEPS:
        raise t.error("evaluation.seconds", f"at most {MAX_STEPS * dt:g} s ({MAX_STEPS:,} steps of dt = {dt:g} s)",
                      evaluation.seconds)
    creature = Creature(
        name=t.get("name", nonempty, default_name),
        description=t.get("description", text(MAX_DESCRIPTION), spec_default(Creature, "description")),
        history=t.get("history", list_of(dated(MAX_HISTORY_ENTRY), f'an array of at most {MAX_HISTORY} strings, '
                                         'oldest first, each "YYYY-MM-DD: what changed; why"', 0, MAX_HISTORY),
                      spec_default(Creature, "history")),
        dt=dt,
        links=links,
        sensors=sensors,
        actuators=actuators,
        springs=springs,
        world=world,
        san=_san(t.table("san", SAN)),
        evaluation=evaluation,
    )
    _check_inertia(t, creature)
    _check_ground(t, creature)
    return creature


def _check_ground(t: _Table, creature: Creature) -> None:
    """The ground's spring must be resolvable by the step in float32 (spec.MAX_GROUND_STIFFNESS_
    RATIO): k dt^2 / m bounded for the lightest mass per contact point. The step treats the spring
    implicitly, so it never explodes; past the bound it returns nonsense (bodies thrown at m/s)."""
    k, dt = creature.world.ground.stiffness, creature.dt
    carried = [(link.mass / len(link.contacts), i) for i, link in enumerate(creature.links) if link.contacts]
    if not carried:
        return
    m, i = min(carried)
    if k * dt * dt / m <= MAX_GROUND_STIFFNESS_RATIO:
        return
    most = MAX_GROUND_STIFFNESS_RATIO * m / (dt * dt)
    why = (f"(k dt^2 / m <= {MAX_GROUND_STIFFNESS_RATIO:g} with dt = {dt:g} s and link {creature.links[i].name!r} "
           f"carrying {m:g} kg per contact point: a stiffer ground is not resolved by the step)")
    ground = t.data.get("world", {}).get("ground", {})
    if isinstance(ground, dict) and "stiffness" in ground:
        raise t.error("world.ground.stiffness", f"at most {most:.3g} N/m {why}", k)
    raise t.error(f"links[{i}].mass", f"at least {k * dt * dt / MAX_GROUND_STIFFNESS_RATIO * len(creature.links[i].contacts):.3g} kg "
                  f"for the ground's stiffness {k:g} N/m {why}", creature.links[i].mass)


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
    raise t.error(f"links[{i}].inertia", "an inertia about the link's own degree of freedom that is not "
                  "negligible beside the rest of the creature (the mass matrix's smallest eigenvalue above "
                  f"{DEGENERATE:g} x its largest), or its centre of mass away from the joint", link.inertia)


def _san(t: _Table | None) -> SanConfig:
    if t is None:
        return SanConfig()
    d = SanConfig()
    delay = within(*DELAY_RANGE, "s")
    return SanConfig(
        hidden=t.get("hidden", integer(0, MAX_HIDDEN), d.hidden),
        delay_on=t.get("delay_on", delay, d.delay_on),
        delay_off=t.get("delay_off", delay, d.delay_off),
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
            points=f.get("points", points(f"a list of 2 to {MAX_POINTS} points [[x, y], ...] (m)", 2)),
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
