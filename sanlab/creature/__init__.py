"""Creatures: the frozen spec (SI units) and the TOML file format that describes them."""

from .loader import (
    CreatureError,
    builtin_names,
    initial_frames,
    load,
    load_file,
    loads,
    read_source,
    world_point,
)
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
    TouchSensor,
    World,
)

__all__ = [
    "Actuator", "AngleSensor", "AngularActuator", "Creature", "CreatureError", "Evaluation",
    "EyeSensor", "Follow", "Friction", "Ground", "JointLimit", "JointSpring", "LengthSensor", "LinearActuator",
    "LinearSpring", "Link", "PointRef", "SanConfig", "Sensor", "Shape", "Terrain", "TouchSensor",
    "World", "builtin_names", "initial_frames", "load", "load_file", "loads", "read_source",
    "world_point",
]  # fmt: skip
