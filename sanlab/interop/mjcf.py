"""Export a sanlab ``Creature`` as an MJCF model, so that MuJoCo can check the simulator.

The one copy of the converter: the MuJoCo tests (``tests/sim/test_mujoco.py``),
``benchmarks/mujoco_route.py`` and ``sanlab export-mjcf`` use it. It needs only NumPy (and mujoco
to *load* the result, :func:`load`); it never loads the simulator. The other way, MJCF into a creature
file, is ``sanlab.interop.mjcf_import``.

Conventions (vertical plane only):

* sanlab's plane (x, y) is MuJoCo's x-z plane: a point (x, y) becomes (x, 0, y), gravity -y
  becomes -z.
* A positive sanlab angle turns +x toward +y (counter-clockwise). In MuJoCo's x-z plane that is a
  turn of +x toward +z, i.e. a right-handed rotation about **-y**: every hinge has axis (0, -1, 0),
  so a hinge's qpos *is* the sanlab angle with the same sign (checked in the tests).
* A free root gets three joints, in sanlab's dof order: slide x, slide z (sanlab y), hinge (the
  root's absolute angle). Its body frame sits at the world origin at qpos = 0, so the slide
  qpos are the root origin's world x and y, exactly sanlab's root dofs.
* A fixed root is a body without joints, placed at ``position`` and turned by ``angle``.
* A jointed link is a child body at ``anchor`` (parent frame) with one hinge at its origin; its
  qpos is sanlab's relative joint angle. Bodies are built with zero angles, so qpos = 0 is the
  straight pose and the spec's initial angles go in through :func:`initial_qpos`.
* Mass, COM and the planar inertia about the COM go into ``<inertial>``: ``diaginertia`` y is the
  planar inertia; x and z get the same value, which satisfies MuJoCo's triangle inequality and
  cannot matter (the motion has no dof that turns about x or z, so no gyroscopic term either).
  ``inertiafromgeom="false"``: geoms carry no mass.
* Joint springs become joint ``stiffness`` / ``springref`` / ``damping``; angular actuators
  become ``motor`` actuators (gear 1 on the joint) when asked for, so a PD law computed outside
  writes its torque into ``data.ctrl``, or ``position`` actuators (``servos``: kp = ks, kv = kd,
  ctrlrange the target range, so ``data.ctrl`` is the target angle and MuJoCo runs sanlab's PD law
  T = ks (ctrl - q) - kd q').
* ``limits``: a joint limit becomes the hinge's ``range`` (MuJoCo's own soft limit, not sanlab's
  stop stiffness and damping).
* ``sensors``: the SAN's binary sensors as MuJoCo's, named as in the spec: a ``touch`` sensor on a
  ``site`` at the contact point (a site sits at every contact point), a ``jointpos`` for an angle
  sensor (and for a tilt sensor on a root, whose absolute angle is its hinge), each with its
  on-range in a comment; eye and length sensors and tilt sensors on jointed links have no MuJoCo
  counterpart and are only named in a comment (:func:`unexported`).
* ``outline``: each link's outline as visual geoms (capsules along its edges; no mass, no
  collisions), so that the model can be looked at in MuJoCo's viewer.
* Ground (optional): a plane and one small sphere per sanlab contact point, centred on the point.
  The plane sits at z = -radius, so a sphere touches it exactly when its centre, the sanlab
  contact point, reaches z = 0 (sanlab's ground), whatever the link's orientation. Spheres collide
  only with the plane (contype 1 / conaffinity 0 against the plane's 0 / 1), as sanlab has no
  self-collision.

Sanlab's dof order and MuJoCo's qpos order differ when links are not listed depth first; use
:func:`qpos_index` (sanlab dof -> MuJoCo qpos address; every joint has one dof, so it is also the
qvel address).
"""

from __future__ import annotations

import math
from typing import Any
from xml.sax.saxutils import quoteattr
from xml.sax.saxutils import unescape as xml_unescape

import numpy as np

from sanlab.creature.geometry import link_frames
from sanlab.creature.spec import AngleSensor, AngularActuator, Creature, TiltSensor, TouchSensor

CONTACT_RADIUS = 1.0e-3  # m, radius of the spheres standing in for contact points


def _f(x: float) -> str:
    return repr(float(x))


def _vec(*xs: float) -> str:
    return " ".join(_f(x) for x in xs)


def joint_names(spec: Creature) -> list[str]:
    """MuJoCo joint name of each sanlab dof, in sanlab's dof order."""
    names = []
    for link in spec.links:
        if link.is_point:
            raise NotImplementedError(f"point mass {link.name!r}: not supported by the converter")
        if link.parent is None:
            if link.fixed:
                continue
            names += [f"{link.name}:x", f"{link.name}:y", f"{link.name}:angle"]
        else:
            names.append(f"{link.name}:joint")
    return names


def to_mjcf(
    spec: Creature,
    *,
    dt: float | None = None,
    integrator: str = "Euler",
    ground: bool = False,
    contact_radius: float = CONTACT_RADIUS,
    friction: float | None = None,
    solref: tuple[float, float] | None = None,
    solimp: tuple[float, ...] | None = None,
    motors: bool = False,
    cone: str = "pyramidal",
    servos: bool = False,
    sensors: bool = False,
    limits: bool = False,
    outline: bool = False,
    keyframe: bool = False,
    comment: str | None = None,
) -> str:
    """MJCF text of ``spec`` (see the module docstring for the conventions).

    dt: time step (default: the spec's). integrator: MuJoCo's integrator ("Euler" is semi-implicit
    Euler, the same scheme as sanlab's for smooth forces). ground: add the plane and contact
    spheres (otherwise no geom collides). friction: Coulomb coefficient of the contacts (default:
    the spec's ground friction, and a link's own where it has one). solref / solimp: MuJoCo's
    soft-contact parameters of the ground contacts (default: MuJoCo's). motors: one ``motor`` actuator per angular actuator, in spec
    order, named after it. servos: one ``position`` actuator per angular actuator instead (kp = ks
    N m/rad, kv = kd N m s/rad, ctrlrange = its target range in rad). sensors: the spec's sensors
    as MuJoCo sensors, a site at every contact point. limits: joint limits as hinge ranges.
    outline: the links' outlines as visual geoms. keyframe: a ``<key name="start">`` holding the
    spec's start pose (qpos = 0 is the straight pose at the origin; ``mj_resetDataKeyframe`` or the
    viewer's "Load key" starts from the creature's own). comment: a line for an XML comment under
    the root element. Raises NotImplementedError for what has no counterpart (see the checks below)
    and ValueError for motors and servos together.
    """
    if motors and servos:
        raise ValueError("motors and servos: expected one kind of actuator, got both")
    if spec.world.plane != "vertical":
        raise NotImplementedError("only the vertical plane maps onto MuJoCo's x-z plane")
    if spec.springs or any(a.kind != "angular" for a in spec.actuators):
        raise NotImplementedError("linear springs and linear actuators are not converted")
    if spec.world.water_drag:
        raise NotImplementedError("water drag is not converted")
    if spec.world.terrain.kind != "flat" and ground:
        raise NotImplementedError("only flat ground is converted")
    joint_names(spec)  # validates: no point masses
    dt = spec.dt if dt is None else dt
    mu = spec.world.ground.friction if friction is None else friction
    children: dict[str | None, list] = {}
    for link in spec.links:
        children.setdefault(link.parent, []).append(link)

    # A link's own friction (its forward coefficient; MuJoCo's is isotropic) goes on its spheres,
    # and the plane gets the smallest of all, since MuJoCo takes the larger of the two geoms'.
    own = {link.name: link.friction.forward for link in spec.links if link.friction is not None and friction is None}
    mu_plane = min([mu, *own.values()])
    geom_attr = f'type="sphere" size="{_f(contact_radius)}" contype="1" conaffinity="0"'
    if ground:
        geom_attr += ' condim="3" friction="{mu}"'
        if solref is not None:
            geom_attr += f' solref="{_vec(*solref)}"'
        if solimp is not None:
            geom_attr += f' solimp="{_vec(*solimp)}"'

    lines: list[str] = []
    hinge = 'type="hinge" axis="0 -1 0"'  # +angle turns +x toward +z, as sanlab's x toward y

    def joint(ind: str, name: str, kind: str, extra: str = "") -> None:
        lines.append(f"{ind}  <joint name={quoteattr(name)} {kind}{extra}/>")

    def body(link, depth: int) -> None:
        ind = "  " * depth
        name = quoteattr(link.name)
        if link.parent is None and link.fixed:
            a = link.angle
            pos = _vec(link.position[0], 0, link.position[1])
            quat = _vec(math.cos(a / 2), 0.0, -math.sin(a / 2), 0.0)  # turn by a about -y
            lines.append(f'{ind}<body name={name} pos="{pos}" quat="{quat}">')
        elif link.parent is None:
            lines.append(f"{ind}<body name={name}>")
            joint(ind, link.name + ":x", 'type="slide" axis="1 0 0"')
            joint(ind, link.name + ":y", 'type="slide" axis="0 0 1"')
            joint(ind, link.name + ":angle", hinge)
        else:
            lines.append(f'{ind}<body name={name} pos="{_vec(link.anchor[0], 0, link.anchor[1])}">')
            extra = ""
            if link.spring is not None:
                sp = link.spring
                extra = (
                    f' stiffness="{_f(sp.stiffness)}" springref="{_f(sp.rest)}"'
                    f' damping="{_f(sp.damping)}"'
                )
            if limits and link.limit is not None:
                extra += f' limited="true" range="{_vec(link.limit.min, link.limit.max)}"'
            joint(ind, link.name + ":joint", hinge, extra)
        inertia = max(float(link.inertia), 1e-12)
        lines.append(
            f'{ind}  <inertial pos="{_vec(link.com[0], 0, link.com[1])}" mass="{_f(link.mass)}" '
            f'diaginertia="{_vec(inertia, inertia, inertia)}"/>'
        )
        if ground:
            for k, c in enumerate(link.contacts):
                gname = quoteattr(f"{link.name}:c{k}")
                attr = geom_attr.replace("{mu}", _vec(own.get(link.name, mu), 0.005, 0.0001))
                lines.append(f'{ind}  <geom name={gname} pos="{_vec(c[0], 0, c[1])}" {attr}/>')
        if sensors:
            for k, c in enumerate(link.contacts):  # a touch sensor counts contacts inside its site
                sname = quoteattr(f"{link.name}:c{k}")
                lines.append(f'{ind}  <site name={sname} pos="{_vec(c[0], 0, c[1])}" size="{_f(2 * contact_radius)}"/>')
        if outline:
            for a, b in _edges(link):
                lines.append(f'{ind}  <geom type="capsule" fromto="{_vec(a[0], 0, a[1], b[0], 0, b[1])}" '
                             f'size="{_f(edge_radius)}" contype="0" conaffinity="0" group="1" rgba="0.8 0.6 0.4 1"/>')
        for child in children.get(link.name, []):
            body(child, depth + 1)
        lines.append(f"{ind}</body>")

    edge_radius = _edge_radius(spec)
    for root in children.get(None, []):
        body(root, 2)

    out = [f"<mujoco model={quoteattr(spec.name)}>"]
    if comment:
        out.append(f"  <!-- {_comment(comment)} -->")
    out += [
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option timestep="{_f(dt)}" integrator="{integrator}" '
        f'gravity="0 0 {_f(-spec.world.gravity)}" cone="{cone}"/>',
        "  <worldbody>",
    ]
    if ground:
        out.append(
            f'    <geom name="ground" type="plane" size="0 0 1" pos="0 0 {_f(-contact_radius)}" '
            f'contype="0" conaffinity="1" condim="3" friction="{_vec(mu_plane, 0.005, 0.0001)}"/>'
        )
    out += lines
    out.append("  </worldbody>")
    if (motors or servos) and spec.actuators:
        out.append("  <actuator>")
        for a in spec.actuators:
            assert isinstance(a, AngularActuator)  # checked above: linear ones are refused
            jname = quoteattr(a.joint + ":joint")
            if motors:
                out.append(f'    <motor name={quoteattr(a.name)} joint={jname} gear="1"/>')
            else:
                out.append(f'    <position name={quoteattr(a.name)} joint={jname} kp="{_f(a.ks)}" kv="{_f(a.kd)}" '
                           f'ctrlrange="{_vec(a.min, a.max)}"/>')
        out.append("  </actuator>")
    if sensors and spec.sensors:
        out += ["  <sensor>", *_sensor_lines(spec), "  </sensor>"]
    if keyframe:
        start = dict(zip(joint_names(spec), initial_q(spec)))
        written = [n for line in lines if (n := _joint_name(line)) is not None]  # MuJoCo's qpos order
        out += ["  <keyframe>", f'    <key name="start" qpos="{_vec(*(start[n] for n in written))}"/>', "  </keyframe>"]
    out.append("</mujoco>")
    return "\n".join(out) + "\n"


def _joint_name(line: str) -> str | None:
    """The name of the joint a line of :func:`to_mjcf`'s body text declares, if it declares one."""
    line = line.strip()
    if not line.startswith("<joint name="):
        return None
    quote = line[len("<joint name=")]
    end = line.index(quote, len("<joint name=") + 1)
    return xml_unescape(line[len("<joint name=") + 1:end], {"&quot;": '"', "&apos;": "'"})


def _comment(text: str) -> str:
    """``text`` safe inside an XML comment (which cannot hold "--") on one line."""
    text = " ".join(text.split())
    while "--" in text:
        text = text.replace("--", "- -")
    return text.rstrip("-")


def _edges(link) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The edges of a link's outline (a segment's one, a polygon's closed ring; none for a point)."""
    pts = list(link.shape.points)
    if len(pts) < 2:
        return []
    if len(pts) == 2:
        return [(pts[0], pts[1])]
    return [(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]


def _edge_radius(spec: Creature) -> float:
    """Radius of the outline's capsules (m): 1% of the creature's extent, at least 1 mm."""
    pts = [p for link in spec.links for p in link.shape.points] or [(0.0, 0.0)]
    extent = float(np.ptp(np.asarray(pts, float), axis=0).max()) if len(pts) > 1 else 0.0
    return max(0.01 * extent, 1e-3)


def _joint_of(spec: Creature, name: str) -> str:
    """The MuJoCo joint holding link ``name``'s rotation (a root's hinge, else its joint)."""
    return f"{name}:angle" if spec.link(name).parent is None else f"{name}:joint"


def _sensor_lines(spec: Creature) -> list[str]:
    out = []
    for s in spec.sensors:
        name = quoteattr(s.name)
        if isinstance(s, TouchSensor):
            out.append(f"    <!-- {_comment(f'{s.name}: on while contact {s.contact} of {s.link} touches the ground')} -->")
            out.append(f"    <touch name={name} site={quoteattr(f'{s.link}:c{s.contact}')}/>")
        elif isinstance(s, AngleSensor) or (isinstance(s, TiltSensor) and spec.link(s.link).parent is None):
            what = "joint angle" if spec.link(s.link).parent is not None else "absolute angle"
            on = f"{s.name}: on while the {what} of {s.link} is in [{math.degrees(s.min):.6g}, {math.degrees(s.max):.6g}] deg"
            out.append(f"    <!-- {_comment(on)} -->")
            out.append(f"    <jointpos name={name} joint={quoteattr(_joint_of(spec, s.link))}/>")
        else:
            out.append(f"    <!-- {_comment(f'{s.name} ({s.kind}): no MuJoCo sensor; not exported')} -->")
    return out


def unexported(spec: Creature) -> list[str]:
    """What ``to_mjcf(..., ground=True, sensors=True)`` leaves out, one line each: eye and length
    sensors and tilt sensors on jointed links (no MuJoCo sensor), and anisotropic friction (MuJoCo's
    is isotropic: the forward coefficient is written)."""
    out = [f"sensor {s.name} ({s.kind}): no MuJoCo counterpart, left out (named in a comment)"
           for s in spec.sensors
           if not isinstance(s, (TouchSensor, AngleSensor)) and not (isinstance(s, TiltSensor) and spec.link(s.link).parent is None)]
    for link in spec.links:
        f = link.friction
        if f is not None and not (f.forward == f.backward == f.lateral):
            out.append(f"link {link.name}: anisotropic friction ({f.forward:g} forward, {f.backward:g} backward, "
                       f"{f.lateral:g} lateral) written as {f.forward:g} (MuJoCo's is isotropic)")
    return out


def qpos_index(spec: Creature, mjmodel) -> np.ndarray:
    """MuJoCo qpos (= qvel) address of each sanlab dof, in sanlab's dof order."""
    return np.array([mjmodel.joint(n).qposadr[0] for n in joint_names(spec)], dtype=np.int64)


def rotation_dofs(spec: Creature) -> dict[str, int]:
    """sanlab dof index of each link's rotation (a root's absolute angle, else its joint angle);
    fixed roots have none."""
    out, k = {}, 0
    for link in spec.links:
        if link.dofs in (1, 3):  # a joint angle, or a rigid root's (x, y, angle)
            out[link.name] = k + link.dofs - 1
        k += link.dofs
    return out


def initial_q(spec: Creature) -> np.ndarray:
    """sanlab's initial generalised coordinates (the spec's pose), in sanlab's dof order."""
    q: list[float] = []
    for link in spec.links:
        own = [link.position[0], link.position[1], link.angle] if link.parent is None else [link.angle]
        q += own[: link.dofs]
    return np.asarray(q, float)


def link_poses(spec: Creature, q) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics from the spec's definitions (``creature.geometry.link_frames``): each
    link's frame origin [L, 2] (m) and absolute angle [L] (rad) at sanlab coordinates q [D]."""
    frames = link_frames(spec.links, np.asarray(q, float).tolist())
    pose = np.array([frames[link.name] for link in spec.links], float).reshape(-1, 3)
    return pose[:, :2], pose[:, 2]


def com_positions(spec: Creature, q) -> np.ndarray:
    """World position of each link's centre of mass [L, 2] at sanlab coordinates q."""
    X, th = link_poses(spec, q)
    com = np.array([l.com for l in spec.links], float)
    c, s = np.cos(th), np.sin(th)
    return X + np.stack([c * com[:, 0] - s * com[:, 1], s * com[:, 0] + c * com[:, 1]], 1)


def potential_energy(spec: Creature, q) -> float:
    """Gravitational potential energy sum m g y_com (J, zero at y = 0) at sanlab coordinates q."""
    m = np.array([l.mass for l in spec.links], float)
    return float(spec.world.gravity * np.sum(m * com_positions(spec, q)[:, 1]))


def set_state(spec: Creature, mjmodel, mjdata, q, qd=None) -> None:
    """Put sanlab coordinates q (and velocities qd, default 0) into ``mjdata``."""
    idx = qpos_index(spec, mjmodel)
    mjdata.qpos[idx] = np.asarray(q, float)
    mjdata.qvel[idx] = 0.0 if qd is None else np.asarray(qd, float)


def get_q(spec: Creature, mjmodel, mjdata) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's state as sanlab (q, qd)."""
    idx = qpos_index(spec, mjmodel)
    return mjdata.qpos[idx].copy(), mjdata.qvel[idx].copy()


def load(spec: Creature, **kw: Any) -> tuple[Any, Any]:
    """(MjModel, MjData) of ``spec`` at its initial pose (``to_mjcf`` keyword arguments)."""
    import mujoco

    mj: Any = mujoco  # compiled bindings: nothing a type checker can read
    m = mj.MjModel.from_xml_string(to_mjcf(spec, **kw))
    d = mj.MjData(m)
    set_state(spec, m, d, initial_q(spec))
    mj.mj_forward(m, d)
    return m, d
