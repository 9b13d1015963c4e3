"""Export a sanlab ``Creature`` as an MJCF model, so that MuJoCo can check the simulator.

The one copy of the converter: the MuJoCo tests (``tests/sim/test_mujoco.py``) and
``benchmarks/mujoco_route.py`` both use it. It needs only NumPy (and mujoco to *load* the result,
:func:`load`); it never imports JAX. Export only: nothing reads MJCF into sanlab.

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
  writes its torque into ``data.ctrl``.
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

import numpy as np

from sanlab.creature.geometry import link_frames
from sanlab.creature.spec import AngularActuator, Creature

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
) -> str:
    """MJCF text of ``spec`` (see the module docstring for the conventions).

    dt: time step (default: the spec's). integrator: MuJoCo's integrator ("Euler" is semi-implicit
    Euler, the same scheme as sanlab's for smooth forces). ground: add the plane and contact
    spheres (otherwise no geom collides). friction: Coulomb coefficient of the contacts (default:
    the spec's ground friction). solref / solimp: MuJoCo's soft-contact parameters of the ground
    contacts (default: MuJoCo's). motors: one ``motor`` actuator per angular actuator, in spec
    order, named after it.
    """
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

    geom_attr = f'type="sphere" size="{_f(contact_radius)}" contype="1" conaffinity="0"'
    if ground:
        geom_attr += f' condim="3" friction="{_vec(mu, 0.005, 0.0001)}"'
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
            joint(ind, link.name + ":joint", hinge, extra)
        inertia = max(float(link.inertia), 1e-12)
        lines.append(
            f'{ind}  <inertial pos="{_vec(link.com[0], 0, link.com[1])}" mass="{_f(link.mass)}" '
            f'diaginertia="{_vec(inertia, inertia, inertia)}"/>'
        )
        if ground:
            for k, c in enumerate(link.contacts):
                gname = quoteattr(f"{link.name}:c{k}")
                lines.append(f'{ind}  <geom name={gname} pos="{_vec(c[0], 0, c[1])}" {geom_attr}/>')
        for child in children.get(link.name, []):
            body(child, depth + 1)
        lines.append(f"{ind}</body>")

    for root in children.get(None, []):
        body(root, 2)

    out = [
        f"<mujoco model={quoteattr(spec.name)}>",
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option timestep="{_f(dt)}" integrator="{integrator}" '
        f'gravity="0 0 {_f(-spec.world.gravity)}" cone="{cone}"/>',
        "  <worldbody>",
    ]
    if ground:
        out.append(
            f'    <geom name="ground" type="plane" size="0 0 1" pos="0 0 {_f(-contact_radius)}" '
            f'contype="0" conaffinity="1" condim="3" friction="{_vec(mu, 0.005, 0.0001)}"/>'
        )
    out += lines
    out.append("  </worldbody>")
    if motors and spec.actuators:
        out.append("  <actuator>")
        for a in spec.actuators:
            assert isinstance(a, AngularActuator)  # checked above: linear ones are refused
            jname = quoteattr(a.joint + ":joint")
            out.append(f'    <motor name={quoteattr(a.name)} joint={jname} gear="1"/>')
        out.append("  </actuator>")
    out.append("</mujoco>")
    return "\n".join(out) + "\n"


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
