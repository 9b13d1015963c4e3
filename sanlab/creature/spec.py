"""Frozen, validated description of a creature: the contract between files and the simulator.

Everything here is in SI units (metres, kilograms, seconds, radians, newtons). Degrees and the
paper's N·m/deg exist only in the TOML files (see ``sanlab/creature/FORMAT.md``); the loader
converts them. Instances are immutable and hashable, so a spec can key a compilation cache.

Coordinates: every link has its own frame. For a jointed link the frame's origin is the joint,
and its x axis is the link's "axis" (the zero of angle sensors, eyes and anisotropic friction).
A point on a link is written in that link's frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal, get_args

Vec2 = tuple[float, float]

# The closed vocabularies of the format, each written once; the loader and the metrics read them.
ShapeKind = Literal["segment", "polygon", "point"]
TerrainKind = Literal["flat", "slope", "hill", "rough"]
Plane = Literal["vertical", "horizontal"]
MetricName = Literal["distance", "distance_upright", "hopping", "pursuit", "tracking"]
Direction = Literal["either", "forward", "backward"]
SHAPE_KINDS: tuple[ShapeKind, ...] = get_args(ShapeKind)
TERRAIN_KINDS: tuple[TerrainKind, ...] = get_args(TerrainKind)
PLANES: tuple[Plane, ...] = get_args(Plane)
METRICS: tuple[MetricName, ...] = get_args(MetricName)  # paper §5.1; see sanlab.metrics
DIRECTIONS: tuple[Direction, ...] = get_args(Direction)
FOLLOW_METRICS = ("pursuit", "tracking")  # the metrics that score following the point ([world.follow])
# The unit of each metric's score (hopping adds k times a height integral in m^2 s to metres).
SCORE_UNITS: dict[str, str] = {"distance": "m", "distance_upright": "m", "hopping": "m + k m^2 s", "pursuit": "m",
                               "tracking": "ratio"}

# Limits of the format (FORMAT.md, "Limits"): sizes that keep `sanlab check` within a second and a
# network within memory, and numbers that keep a run meaningful in float32. Written once here;
# the loader enforces them with its usual one-line errors.
MAX_FILE_BYTES = 1 << 20  # a creature file
# Keys, checked before the TOML is parsed (Python's reader spends about 1 KB per key part, and
# time quadratic in the parts of one dotted key): parts of one dotted key or table header (the
# format's deepest is 3, world.ground.stiffness), and in the whole file (walker.toml: 197).
MAX_KEY_PARTS = 16
MAX_KEY_PARTS_TOTAL = 20_000
MAX_NAME = 64  # characters in a name (links, sensors, actuators, springs, the creature)
MAX_DESCRIPTION = 500  # characters in the description
MAX_HISTORY = 1000  # entries in the history (a design writes one per run: far more than a file meets)
MAX_HISTORY_ENTRY = 500  # characters in one history entry, as in the description
MAX_LINKS = 32
MAX_POINTS = 64  # in one outline, one contact list or the follow path
MAX_CONTACTS = 128  # contact points, all links together
MAX_SENSORS = 64
MAX_ACTUATORS = 32
MAX_HIDDEN = 64
MAX_SPRINGS = 32
MAX_MAGNITUDE = 1e6  # any number, in the file's unit (1e39 would overflow float32)
MAX_COORDINATE = 1e3  # m: any point, position or length (float32 keeps mm at 1 km)
MIN_POSITIVE = 1e-9  # the smallest value a "> 0" field takes
DT_RANGE = (1e-5, 1e-2)  # s: the time step (beyond 10 ms a falling body enters the ground cm deep per step)
MAX_STEPS = 1_000_000  # evaluation seconds / dt: steps of one trial
DELAY_RANGE = (1e-3, 100.0)  # s: a node's delays T_on, T_off
# The ground spring must be resolvable in float32: k dt^2 / m <= this for every link with contact
# points (m its mass per contact point). Measured on the bounder: 1e9 N/m (3e3) still runs as at
# 5e4 N/m; 1e12 N/m (3e6) throws it at 9 m/s.
MAX_GROUND_STIFFNESS_RATIO = 1e4
# A run is flagged (like a non-finite one) once a contact goes deeper than this fraction of the
# creature's size, or MAX_PENETRATION, whichever is smaller: the ground no longer holds it.
PENETRATION_FRACTION = 0.25
MAX_PENETRATION = 0.1  # m


@dataclass(frozen=True)
class Shape:
    """Outline of a link in its own frame, used for drawing and water drag.

    kind: "segment" (2 points), "polygon" (>= 3 points, closed), or "point" (a point mass; no
    points, the link frame's origin is the mass).
    """

    kind: ShapeKind
    points: tuple[Vec2, ...] = ()


@dataclass(frozen=True)
class JointSpring:
    """Passive torsional spring + damper in a joint: T = -k (phi - rest) - c phi_dot."""

    stiffness: float  # N m / rad
    damping: float = 0.0  # N m s / rad
    rest: float = 0.0  # rad


@dataclass(frozen=True)
class JointLimit:
    """A range the joint angle cannot leave (a mechanical stop, not the servo's target range).

    Outside [min, max] a one-sided spring-damper pushes the joint back, T = k (limit - phi) -
    c phi_dot, and only ever pushes (it never pulls the joint into the stop), like the ground.
    """

    min: float  # rad
    max: float  # rad
    stiffness: float = 57.29577951308232  # N m / rad (1 N m/deg)
    damping: float = 0.5729577951308232  # N m s / rad (0.01 N m s/deg)


@dataclass(frozen=True)
class Friction:
    """Per-link friction override, possibly anisotropic.

    Sliding along +axis ("forward") uses ``forward``, along -axis ``backward``; any sliding
    across the axis uses ``lateral``. The axis is the link's x axis, or, if ``axis`` is given,
    the direction from the origin of link ``axis[0]`` to the origin of link ``axis[1]`` (this is
    how point masses, which have no orientation, get a forward direction).
    """

    forward: float
    backward: float
    lateral: float
    axis: tuple[str, str] | None = None


@dataclass(frozen=True)
class Link:
    """One rigid link (or point mass).

    A link with ``parent is None`` is a root: a free body with dofs (x, y, angle), or (x, y) for a
    point mass. Otherwise it hangs from ``parent`` by a revolute joint whose dof is the angle of
    this link's frame relative to the parent's frame; the joint sits at ``anchor`` (parent frame)
    and is this link's origin.
    """

    name: str
    mass: float  # kg
    inertia: float  # kg m^2 about the centre of mass (0 for a point mass)
    com: Vec2  # centre of mass, link frame (m)
    shape: Shape
    contacts: tuple[Vec2, ...] = ()  # points that can touch the ground, link frame (m)
    parent: str | None = None
    anchor: Vec2 = (0.0, 0.0)  # joint position in the parent's frame (m); unused for roots
    position: Vec2 = (0.0, 0.0)  # initial origin, world (m); roots only
    angle: float = 0.0  # initial angle (rad): absolute for roots, relative to parent for joints
    spring: JointSpring | None = None  # passive joint spring; joints only
    limit: JointLimit | None = None  # mechanical stop of the joint; joints only
    friction: Friction | None = None  # overrides the world's isotropic friction
    drag: bool = True  # feels water drag (only if the world has water)
    fixed: bool = False  # roots only: welded to the world at position/angle (no dofs); for rigs and tests

    @property
    def is_point(self) -> bool:
        return self.shape.kind == "point"

    @property
    def dofs(self) -> int:
        """Generalised coordinates this link adds, in this order: a free root's x, y (m) and, unless
        it is a point mass, its absolute angle (rad); a jointed link's joint angle (rad); a fixed
        root none."""
        if self.fixed:
            return 0
        if self.parent is not None:
            return 1
        return 2 if self.is_point else 3


@dataclass(frozen=True)
class PointRef:
    """A point fixed on a link: ``at`` in the link's frame (m)."""

    link: str
    at: Vec2 = (0.0, 0.0)


@dataclass(frozen=True)
class TouchSensor:
    """On (1) while contact point ``contact`` of ``link`` touches the ground."""

    name: str
    link: str
    contact: int
    kind: Literal["touch"] = "touch"


@dataclass(frozen=True)
class AngleSensor:
    """On while an angle lies in [min, max] (rad, wrapped to [-pi, pi)).

    For a jointed link the angle is its joint angle (relative to its parent); for a root link it
    is the link's absolute angle.
    """

    name: str
    link: str
    min: float
    max: float
    kind: Literal["angle"] = "angle"


@dataclass(frozen=True)
class TiltSensor:
    """On while the link's absolute (world) angle lies in [min, max] (rad, wrapped to [-pi, pi)):
    a balance organ, the counterpart of the joint-angle sensor."""

    name: str
    link: str
    min: float
    max: float
    kind: Literal["tilt"] = "tilt"


@dataclass(frozen=True)
class EyeSensor:
    """On while the follow point lies in the cone [min, max] (rad, wrapped to [-pi, pi)).

    The direction to the follow point is taken from ``at`` and measured relative to the link's
    x axis, or, if ``axis`` is given, to the direction from link ``axis[0]``'s origin to link
    ``axis[1]``'s origin.
    """

    name: str
    at: PointRef
    min: float
    max: float
    axis: tuple[str, str] | None = None
    kind: Literal["eye"] = "eye"


@dataclass(frozen=True)
class LengthSensor:
    """On while the distance between two points lies in [min, max] (m)."""

    name: str
    a: PointRef
    b: PointRef
    min: float
    max: float
    kind: Literal["length"] = "length"


Sensor = TouchSensor | AngleSensor | TiltSensor | EyeSensor | LengthSensor


@dataclass(frozen=True)
class AngularActuator:
    """PD servo in the joint of ``joint`` (a link name): T = ks (theta_d - theta) - kd theta_dot.

    The controller's output u in [0, 1] maps to theta_d = min + u (max - min).
    """

    name: str
    joint: str
    min: float  # rad
    max: float  # rad
    ks: float  # N m / rad
    kd: float  # N m s / rad
    kind: Literal["angular"] = "angular"


@dataclass(frozen=True)
class LinearActuator:
    """PD servo between two points: F = ks (L_d - L) - kd L_dot, pushing the points apart when > 0."""

    name: str
    a: PointRef
    b: PointRef
    min: float  # m
    max: float  # m
    ks: float  # N / m
    kd: float  # N s / m
    kind: Literal["linear"] = "linear"


Actuator = AngularActuator | LinearActuator


@dataclass(frozen=True)
class LinearSpring:
    """Passive spring + damper between two points: F = k (rest - L) - c L_dot."""

    name: str
    a: PointRef
    b: PointRef
    stiffness: float  # N / m
    damping: float  # N s / m
    rest: float  # m


@dataclass(frozen=True)
class Ground:
    """Penalty ground: per contact point N = max(0, k d - c v_n) for penetration d > 0.

    Friction is Coulomb with coefficient ``friction``, and it sticks. Each touching contact keeps
    an anchor on the ground; while the contact slips slower than ``slip_speed`` and a spring
    (stiffness k, the ground's) with a damper mu N / slip_speed to its anchor needs no more than
    mu N, the contact is held, with no creep however long a load inside the friction cone lasts.
    Otherwise it slides with Coulomb friction mu N against the slip (an implicit damper that can
    stop a slip within a step but never reverse it) and its anchor restarts where it stops.
    """

    stiffness: float = 5.0e4  # N / m (stiff: penetration stays ~1 cm under a 4 kg landing)
    damping: float = 300.0  # N s / m
    friction: float = 0.6
    slip_speed: float = 1.0e-4  # m/s (as Drake's default stiction tolerance)


@dataclass(frozen=True)
class Terrain:
    """Ground height y = h(x) (vertical plane only).

    flat: h = 0. slope: h = tan(angle) x. hill: h = height * (1 + cos(pi (x - center) / half
    width)) / 2 inside |x - center| < half width (a smooth bump). rough: a sum of sinusoids whose
    phases and amplitudes come from ``seed``, with RMS height ``height`` and shortest wavelength
    ``wavelength``.
    """

    kind: TerrainKind = "flat"
    angle: float = 0.0  # rad, slope
    height: float = 0.0  # m, hill peak / rough RMS
    width: float = 1.0  # m, hill full width
    center: float = 1.0  # m, hill centre
    wavelength: float = 0.5  # m, rough
    seed: int = 0


@dataclass(frozen=True)
class Follow:
    """A follow point moving at ``speed`` (m/s) along a Catmull-Rom spline through ``points``."""

    points: tuple[Vec2, ...]
    speed: float
    loop: bool = False


@dataclass(frozen=True)
class World:
    """Where the creature lives.

    plane "vertical": gravity pulls along -y and the ground is the terrain. plane "horizontal":
    seen from above, no gravity in the plane; every contact point always rests on the floor and
    carries an equal share of its link's weight (m g / contacts) as normal load for friction.
    water_drag k (N s / m^2): each link with ``drag`` feels F = -k ∫ (v·N) N ds along each edge of
    its outline (paper §3.4), plus a tangential (skin) part -k_t ∫ (v·T) T ds with k_t =
    ``water_tangential`` x k, so that a slender body coasting along its axis slows down too
    (``water_tangential = 0`` is the paper's normal-only model).
    """

    plane: Plane = "vertical"
    gravity: float = 9.81  # m/s^2
    ground: Ground = field(default_factory=Ground)
    terrain: Terrain = field(default_factory=Terrain)
    water_drag: float = 0.0  # N s / m^2
    water_tangential: float = 0.1  # skin drag coefficient as a fraction of water_drag
    follow: Follow | None = None


@dataclass(frozen=True)
class SanConfig:
    """Defaults for this creature's sensor-actuator networks (paper §4)."""

    hidden: int | None = None  # None: as many hidden nodes as sensors (see Creature.n_hidden)
    delay_on: float = 0.1  # s, T_on = 1 / k1
    delay_off: float = 0.1  # s, T_off = -1 / k2


@dataclass(frozen=True)
class Evaluation:
    """How this creature's gaits are scored (paper §5.1).

    metric: one of :data:`METRICS`. ``direction``: the way a gait must move along x to count,
    "forward" (+x), "backward" (-x) or "either" (the paper's |x(T) - x(0)|).

    Falling (any of these, at any time, means the creature fell): one of the ``fell_links``
    turned so that its absolute angle left [-fell_angle, fell_angle]; the creature's centre of
    mass came closer to the ground than ``fell_com_height``; the centre of mass of one of the
    ``fell_links`` came closer to the ground than ``fell_link_height``. ``hop_k`` is the k of the
    hopping metric.
    """

    metric: MetricName = "distance"
    seconds: float = 6.0  # s of simulated time per evaluation
    fell_links: tuple[str, ...] = ()
    fell_angle: float = math.pi / 2  # rad
    fell_com_height: float | None = None  # m above the ground
    fell_link_height: float | None = None  # m above the ground
    hop_k: float = 1.0  # 1/(m s): weight of the height integral (m^2 s) in the hopping score
    direction: Direction = "either"

    @property
    def fell_link(self) -> str | None:
        """The first fell link, if any (most creatures have one)."""
        return self.fell_links[0] if self.fell_links else None

    @property
    def can_fall(self) -> bool:
        return bool(self.fell_links) or self.fell_com_height is not None


@dataclass(frozen=True)
class Creature:
    """A whole creature: its links (parents before children), sensors, actuators and passive
    springs, the world it lives in, its SANs' defaults, how its gaits are scored, and the time
    step ``dt`` (s) it is simulated with."""

    name: str
    links: tuple[Link, ...]
    sensors: tuple[Sensor, ...] = ()
    actuators: tuple[Actuator, ...] = ()
    springs: tuple[LinearSpring, ...] = ()
    world: World = field(default_factory=World)
    san: SanConfig = field(default_factory=SanConfig)
    evaluation: Evaluation = field(default_factory=Evaluation)
    dt: float = 1.0e-3  # s
    description: str = ""
    # the file's changes, oldest first, each one line "YYYY-MM-DD: what changed; why" (what a report
    # says of a changed file; docs/creature-format.md, "History"): the file's record, not part of the
    # creature's identity, so a body `sanlab design` writes loads equal to ``design.creature(values)``
    history: tuple[str, ...] = field(default=(), compare=False)
    # the file's free numbers (``free.Design``) when it has any, else None: what tuning with
    # --morphology moves (``sanlab.search.space``); not part of the creature's identity
    design: Any = field(default=None, compare=False, repr=False)

    def link(self, name: str) -> Link:
        for link in self.links:
            if link.name == name:
                return link
        raise KeyError(name)

    @property
    def dofs(self) -> int:
        """Number of generalised coordinates: each link's :attr:`Link.dofs`, in link order."""
        return sum(link.dofs for link in self.links)

    @property
    def n_hidden(self) -> int:
        """Hidden nodes of this creature's SANs: ``san.hidden`` when the file gives it (0 is
        allowed), else one per sensor (Table 1's usual choice)."""
        return self.san.hidden if self.san.hidden is not None else len(self.sensors)
