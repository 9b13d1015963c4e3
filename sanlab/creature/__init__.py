"""Creatures: the frozen spec (SI units) and the TOML file format that describes them.

Modules: ``spec`` (the dataclasses, every default and vocabulary), ``loader`` (the file format),
``files`` (built-ins, loading by name or path), ``free`` (free numbers and couplings, §6.3), ``geometry`` (mass properties, link frames),
``table1`` (the paper's Table 1); ``_checks`` and ``_toml`` are the loader's value checks and
table reader.
"""

from ._checks import printable
from .files import builtin_names, load, load_design, load_file, read_source
from .free import Design, FreeNumber
from .geometry import initial_frames, world_point
from .loader import CreatureError, loads
from .spec import (
    Actuator,
    AngleSensor,
    AngularActuator,
    Creature,
    Evaluation,
    EyeSensor,
    Follow,
    Friction,
    Ground,
    JointLimit,
    JointSpring,
    LengthSensor,
    LinearActuator,
    LinearSpring,
    Link,
    PointRef,
    SanConfig,
    Sensor,
    Shape,
    Terrain,
    TiltSensor,
    TouchSensor,
    World,
)

__all__ = [
    "Actuator", "AngleSensor", "AngularActuator", "Creature", "CreatureError", "Design", "Evaluation",
    "EyeSensor", "Follow", "FreeNumber", "Friction", "Ground", "JointLimit", "JointSpring", "LengthSensor", "LinearActuator",
    "LinearSpring", "Link", "PointRef", "SanConfig", "Sensor", "Shape", "Terrain", "TiltSensor", "TouchSensor",
    "World", "builtin_names", "initial_frames", "load", "load_design", "load_file", "loads", "printable", "read_source",
    "world_point",
]  # fmt: skip
