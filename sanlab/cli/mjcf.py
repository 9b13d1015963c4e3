"""``sanlab import-mjcf`` and ``sanlab export-mjcf``: creatures to and from MuJoCo's MJCF.

    sanlab import-mjcf MODEL.xml [-o creature.toml] [--json]
    sanlab export-mjcf CREATURE|GAIT [-o model.xml] [--motors] [--db PATH]

Import compiles the model with MuJoCo (``sanlab.interop.mjcf_import``) and writes a commented
creature file; what it cannot carry over is one warning line each on stderr. Export writes the
creature (a gait's, with its tuned parameters) as MJCF with ground, outlines, servos and the SAN's
sensors, for MuJoCo's viewer (``sanlab.interop.mjcf``). Neither simulates; only reading a gait
from the library loads the simulator's modules.
"""

from __future__ import annotations

import os
from typing import Annotated

import typer

from sanlab.cli._common import (
    DbOpt,
    JsonOpt,
    check_gait,
    console,
    dump_json,
    fail,
    library_call,
    load_or_exit,
    open_library,
    output_file,
    safe,
    warn,
)
from sanlab.cli._schemas import schema_id
from sanlab.creature import CreatureError, builtin_names, loads

NEEDS_MUJOCO = "needs the mujoco package: pip install mujoco (or pip install 'sanlab[gym]')"


def import_mjcf(
    model: Annotated[str, typer.Argument(metavar="MODEL.xml", help="A planar MJCF model (e.g. Gymnasium's hopper.xml).")],
    out: Annotated[str | None, typer.Option("--out", "-o", help="Write the creature file here (whole or not at all); "
                                            "default: print it.")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Convert a planar MuJoCo model (MJCF) into a commented creature file.

    MuJoCo compiles the model; links, masses, inertias, joint ranges and springs, servos from its
    motors, touch sensors on its feet and angle sensors at its joints' ends, and its fall test (the
    healthy height and angle of Gymnasium's hopper and walker2d) come from the compiled model. Each
    thing the format cannot carry (armature, self-collision, ...) is one warning line on stderr (more
    than three alike, e.g. static bodies, are folded into one); a model that is not planar in the x-z
    plane, or a name that is not printable UTF-8, is an error naming the joint or element. See
    docs/mjcf.md."""
    from sanlab.interop.mjcf_import import MjcfError, mjcf_to_toml

    try:
        text, warnings = mjcf_to_toml(model)
    except MjcfError as e:
        raise fail(str(e)) from None
    except ImportError:  # mujoco is imported when a model is compiled
        raise fail(f"import-mjcf {NEEDS_MUJOCO}") from None
    for line in warnings:
        warn(f"warning: {line}")
    spec = loads(text, out or "<import>")
    if out:
        with output_file(out, "--out") as path, open(path, "w", encoding="utf-8") as f:
            f.write(text)
    if as_json:
        summary = {"schema": schema_id("mjcf-import"), "source": os.path.abspath(model), "out": os.path.abspath(out) if out else None, "name": spec.name,
                   "links": len(spec.links), "dofs": spec.dofs, "sensors": len(spec.sensors),
                   "actuators": len(spec.actuators), "warnings": warnings}
        if not out:
            summary["toml"] = text
        typer.echo(dump_json(summary))
    elif out:
        console.print(f"wrote {safe(out)}: {safe(spec.name)}, {len(spec.links)} links, {len(spec.sensors)} sensors, "
                      f"{len(spec.actuators)} actuators, {len(warnings)} warning{'s' * (len(warnings) != 1)}")
        console.print(f"next: sanlab check {safe(out)} --simulate    sanlab search {safe(out)}", soft_wrap=True)
    else:
        typer.echo(text, nl=False)


def _is_creature(target: str) -> bool:
    """A built-in name or an existing path (a .toml file may hold a '/'), rather than a gait id."""
    return target in builtin_names() or os.path.exists(target) or target.endswith(".toml")


def export_mjcf(
    target: Annotated[str, typer.Argument(metavar="CREATURE|GAIT", help=(
        "A built-in creature, a .toml file, or a gait (RUN/RANK, e.g. 3fa1c2d0/1, or RUN#IDX) whose creature, with "
        "its tuned parameters, is exported."))],
    out: Annotated[str | None, typer.Option("--out", "-o", help="Write the model here (whole or not at all); "
                                            "default: print it.")] = None,
    motors: Annotated[bool, typer.Option("--motors", help=(
        "Torque motors (gear 1, ctrl in N m) instead of position servos (ctrl = the target angle in rad, "
        "kp = ks, kv = kd: sanlab's PD law)."))] = False,
    db: DbOpt = "sanlab.db",
) -> None:
    """Write a creature (or a gait's) as a MuJoCo model (MJCF), to load in MuJoCo's viewer.

    The model has the ground, the links' outlines, a servo per actuator, the SAN's sensors as
    MuJoCo sensors (touch on a site at each contact point, jointpos for angle sensors) and the
    start pose as keyframe "start"; the network itself is not in it (sanlab export GAIT --c writes
    it in C). Angles in radians, sanlab's plane (x, y) as MuJoCo's x-z plane (see docs/mjcf.md)."""
    from sanlab.interop import mjcf

    comment = None
    if _is_creature(target):
        spec, where = load_or_exit(target)
        comment = f"Written by `sanlab export-mjcf` from creature {spec.name} ({where})"
    else:
        from sanlab.gait import Gait
        from sanlab.tuned import apply_to_file

        check_gait(target, "CREATURE|GAIT")
        lib = open_library(db, readonly=True)
        ev = library_call(lib.gait, target)
        gait = library_call(Gait.from_library, lib, ev.gait_id)
        try:
            spec = loads(apply_to_file(gait), f"gait {ev.gait_id}")
        except (ValueError, CreatureError) as e:
            raise fail(f"{lib.path}: gait {ev.gait_id} cannot be written as a creature ({e})") from None
        comment = (f"Written by `sanlab export-mjcf {target}`: the creature of gait {ev.gait_id} in {lib.path} "
                   f"({spec.name}, with the gait's parameters applied); its network is not in the model")
    try:
        # implicitfast: MuJoCo's Euler takes a servo's kv explicitly, which a stiff servo on a light
        # link makes unstable at the creature's own step
        text = mjcf.to_mjcf(spec, ground=True, servos=not motors, motors=motors, sensors=True, limits=True,
                            outline=True, keyframe=True, comment=comment, integrator="implicitfast")
    except NotImplementedError as e:
        raise fail(f"{target}: cannot be exported as MJCF ({e})") from None
    for line in mjcf.unexported(spec):
        warn(f"warning: {line}")
    if out:
        with output_file(out, "--out") as path, open(path, "w", encoding="utf-8") as f:
            f.write(text)
        console.print(f"wrote {safe(out)}: {safe(spec.name)} as MJCF (python -m mujoco.viewer --mjcf={safe(out)})",
                      soft_wrap=True)
    else:
        typer.echo(text, nl=False)
