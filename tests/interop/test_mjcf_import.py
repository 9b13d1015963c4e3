"""MJCF into creature files (``sanlab.interop.mjcf_import``), and back out (``sanlab.interop.mjcf``),
against MuJoCo's own compiled values: Gymnasium's hopper and walker2d (read from the installed
gymnasium package), and small models that exercise the conventions (the sign of a hinge about +y,
``<default>`` classes, ``fromto`` capsules, rotated bodies, welded bodies, a free joint).

No JAX here: importing and exporting never simulate (the searches are in tests/cli)."""

from __future__ import annotations

import math
import os
import tomllib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

mujoco = pytest.importorskip("mujoco")
gymnasium_mujoco = pytest.importorskip("gymnasium.envs.mujoco")

from sanlab.creature import loads  # noqa: E402
from sanlab.interop import mjcf  # noqa: E402
from sanlab.interop.mjcf_import import SNAP_GAP, MjcfError, fold, mjcf_to_toml  # noqa: E402
from tests.fuzz import odd_names  # noqa: E402

ASSETS = os.path.join(os.path.dirname(gymnasium_mujoco.__file__), "assets")
GYM = {"hopper": os.path.join(ASSETS, "hopper.xml"), "walker2d": os.path.join(ASSETS, "walker2d_v5.xml")}


def _compiled(path_or_xml: str, from_string: bool = False):
    m = mujoco.MjModel.from_xml_string(path_or_xml) if from_string else mujoco.MjModel.from_xml_path(path_or_xml)
    d = mujoco.MjData(m)
    return m, d


def _at(m, d, qpos, armature: bool = True) -> np.ndarray:
    """Kinematics (and the mass matrix, returned, without armature unless asked) at ``qpos``."""
    if not armature:
        m.dof_armature[:] = 0.0
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    for i in range(m.nv):
        e, out = np.zeros(m.nv), np.zeros(m.nv)
        e[i] = 1.0
        mujoco.mj_mulM(m, d, out, e)
        M[:, i] = out
    return M


def _planar_inertia(m, d, b: int) -> float:
    R = d.ximat[b].reshape(3, 3)
    return float((R @ np.diag(m.body_inertia[b]) @ R.T)[1, 1])


def _import(tmp_path, xml: str, name: str = "model.xml"):
    path = tmp_path / name
    path.write_text(xml)
    text, warnings = mjcf_to_toml(path)
    return loads(text, name), text, warnings


@pytest.fixture(scope="module", params=sorted(GYM))
def gym_model(request):
    """(name, original MjModel, MjData, imported spec, TOML text, warnings) of a Gymnasium model."""
    text, warnings = mjcf_to_toml(GYM[request.param])
    m, d = _compiled(GYM[request.param])
    return request.param, m, d, loads(text, request.param + ".toml"), text, warnings


# -- what the import says, against MuJoCo's compiled model --------------------------------------------


def test_links_masses_and_inertias_are_what_mujoco_compiled(gym_model):
    name, m, d, spec, _, _ = gym_model
    _at(m, d, m.qpos0)
    bodies = {m.body(b).name: b for b in range(1, m.nbody)}
    assert [link.name for link in spec.links] == list(bodies)  # one link per body, parents first
    for link in spec.links:
        b = bodies[link.name]
        assert link.mass == pytest.approx(m.body_mass[b], rel=1e-9)
        assert link.inertia == pytest.approx(_planar_inertia(m, d, b), rel=1e-9)
        parent = m.body(int(m.body_parentid[b])).name
        assert link.parent == (None if parent == "world" else parent)


def test_the_start_pose_is_qpos0_set_onto_the_floor(gym_model):
    """Every joint anchor and centre of mass where MuJoCo puts it at qpos0, all moved by one
    vertical offset: the lowest contact point onto the floor."""
    name, m, d, spec, _, warnings = gym_model
    _at(m, d, m.qpos0)
    X, _ = mjcf.link_poses(spec, mjcf.initial_q(spec))
    com = mjcf.com_positions(spec, mjcf.initial_q(spec))
    offsets = []
    for i, link in enumerate(spec.links):
        b = m.body(link.name).id
        j = int(m.body_jntadr[b]) + int(m.body_jntnum[b]) - 1  # a root's hinge comes last
        offsets.append(X[i] - d.xanchor[j][[0, 2]])
        offsets.append(com[i] - d.xipos[b][[0, 2]])
    offsets = np.array(offsets)
    np.testing.assert_allclose(offsets, offsets[:1].repeat(len(offsets), 0), atol=1e-9)
    dx, dy = offsets[0]
    assert dx == pytest.approx(0, abs=1e-12) and 0 < -dy <= SNAP_GAP
    lows = [p[1] for i, link in enumerate(spec.links) for p in _world(spec, i, link.contacts)]
    assert min(lows) == pytest.approx(0, abs=1e-9)
    assert any(w.startswith("start pose:") and f"{-dy * 100:.3g} cm" in w for w in warnings)


def _world(spec, i, points):
    X, th = mjcf.link_poses(spec, mjcf.initial_q(spec))
    c, s = math.cos(th[i]), math.sin(th[i])
    return [(X[i][0] + c * x - s * y, X[i][1] + s * x + c * y) for x, y in points]


def test_joint_ranges_springs_and_servos_follow_the_model(gym_model):
    name, m, d, spec, text, _ = gym_model
    by_joint = {a.joint: a for a in spec.actuators}
    assert len(spec.actuators) == m.nu
    for link in spec.links[1:]:
        j = m.joint(m.body(link.name).jntadr[0])
        assert link.limit is not None  # the gymnasium hinges are about -y: the same sign
        assert (link.limit.min, link.limit.max) == pytest.approx(tuple(j.range), abs=1e-12)
        assert link.spring is not None and link.spring.damping == pytest.approx(m.dof_damping[j.dofadr[0]])
        a = by_joint[link.name]
        motor = next(k for k in range(m.nu) if m.actuator_trnid[k][0] == j.id)
        peak = abs(m.actuator_gear[motor][0]) * max(abs(m.actuator_ctrlrange[motor]))
        assert a.ks * math.radians(10) == pytest.approx(peak)  # the motor's peak torque at 10 degrees
        assert a.kd == pytest.approx(0.1 * a.ks)
        assert j.range[0] <= a.min < a.max <= j.range[1]  # targets inside the joint's range
    doc = tomllib.loads(text)
    assert doc["world"]["ground"]["friction"] == pytest.approx(m.geom("floor").friction[0])
    foot = next(link for link in spec.links if link.name == "foot")
    assert foot.friction is not None and foot.friction.forward == pytest.approx(m.geom("foot_geom").friction[0])


def test_gymnasiums_fall_test_is_carried_over(gym_model):
    name, m, d, spec, _, warnings = gym_model
    healthy = {"hopper": (0.7, 0.2), "walker2d": (0.8, 1.0)}[name]  # Hopper-v5, Walker2d-v5 defaults
    ev = spec.evaluation
    assert ev.metric == "distance_upright" and ev.direction == "forward"
    assert ev.fell_links == ("torso",)
    assert ev.fell_link_height == pytest.approx(healthy[0])  # the torso's COM is its frame's origin
    assert ev.fell_angle == pytest.approx(healthy[1])
    assert any("upper bound" in w for w in warnings) == (name == "walker2d")  # walker2d's z < 2 m


def test_sensors_are_on_the_feet_and_the_joint_ends(gym_model):
    name, m, d, spec, _, _ = gym_model
    feet = [link.name for link in spec.links if link.name.startswith("foot")]
    touch = [s for s in spec.sensors if s.kind == "touch"]
    assert sorted({s.link for s in touch}) == sorted(feet)
    assert len(touch) == 2 * len(feet)  # heel and toe of each flat foot
    for s in touch:  # both on the bottom of the foot, at qpos0
        i = [link.name for link in spec.links].index(s.link)
        (_, y), = _world(spec, i, [spec.links[i].contacts[s.contact]])
        assert y == pytest.approx(0, abs=1e-9)
    angles = [s for s in spec.sensors if s.kind == "angle"]
    servos = {a.joint: a for a in spec.actuators}
    for joint, a in servos.items():  # each servo's two ends: on near one end, off at the other
        lo, hi = sorted((s for s in angles if s.link == joint), key=lambda s: s.min)
        assert lo.min == -math.pi and a.min < lo.max < hi.min < a.max and hi.max == math.pi
    assert {s.link for s in angles} == set(servos) | {"torso"}  # and the torso's balance


@pytest.mark.parametrize("name", sorted(GYM))
def test_a_round_trip_keeps_masses_inertias_and_kinematics(tmp_path, name):
    """MJCF -> TOML -> MJCF: the exported model, at its start key, has the original's body masses,
    planar inertias about the COM, joint anchors and COMs (one vertical offset: the start pose set
    onto the floor) and the same mass matrix in sanlab's coordinates (armature left out)."""
    text, _ = mjcf_to_toml(GYM[name])
    spec = loads(text, name)
    m0, d0 = _compiled(GYM[name])
    M0 = _at(m0, d0, m0.qpos0, armature=False)
    m1, d1 = _compiled(mjcf.to_mjcf(spec, ground=True, servos=True, sensors=True, limits=True, outline=True,
                                    keyframe=True), from_string=True)
    mujoco.mj_resetDataKeyframe(m1, d1, 0)
    M1 = _at(m1, d1, d1.qpos.copy())
    shift = None
    for link in spec.links:
        b0, b1 = m0.body(link.name).id, m1.body(link.name).id
        assert m1.body_mass[b1] == pytest.approx(m0.body_mass[b0], rel=1e-9)
        assert _planar_inertia(m1, d1, b1) == pytest.approx(_planar_inertia(m0, d0, b0), rel=1e-8)
        j0 = int(m0.body_jntadr[b0]) + int(m0.body_jntnum[b0]) - 1
        j1 = int(m1.body_jntadr[b1]) + int(m1.body_jntnum[b1]) - 1
        for p0, p1 in ((d0.xanchor[j0], d1.xanchor[j1]), (d0.xipos[b0], d1.xipos[b1])):
            delta = (p1 - p0)[[0, 2]]
            shift = delta if shift is None else shift
            np.testing.assert_allclose(delta, shift, atol=1e-9)
    assert shift is not None and abs(shift[0]) < 1e-12 and 0 <= -shift[1] <= SNAP_GAP
    # qpos orders agree (rootx, rootz, rooty, then the hinges depth first); rooty turns about +y,
    # the exported root hinge about -y, so its row and column change sign.
    idx = mjcf.qpos_index(spec, m1)
    sign = np.ones(m0.nv)
    sign[2] = -1.0
    np.testing.assert_allclose(M1[np.ix_(idx, idx)], sign[:, None] * M0 * sign[None, :], rtol=1e-8, atol=1e-10)


def test_the_exported_sensors_read_in_mujoco(tmp_path):
    """Touch sensors on the feet's sites feel the ground while the hopper stands; jointpos reads
    the joint angle with sanlab's sign; position servos hold their target."""
    spec = loads(mjcf_to_toml(GYM["hopper"])[0], "hopper")
    xml = mjcf.to_mjcf(spec, ground=True, servos=True, sensors=True, limits=True, keyframe=True, integrator="implicitfast")
    m, d = _compiled(xml, True)
    assert [m.sensor(i).name for i in range(m.nsensor)] == [s.name for s in spec.sensors]
    mujoco.mj_resetDataKeyframe(m, d, 0)
    target = {a.name: 0.5 * (a.min + a.max) for a in spec.actuators}
    for i in range(m.nu):
        d.ctrl[i] = target[m.actuator(i).name]
    d.qpos[m.joint("torso:y").qposadr[0]] += 0.01  # dropped from 1 cm
    for _ in range(int(0.3 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)  # sensors of the state reached (mj_step computes them before it moves)
    touch = [s for s in spec.sensors if s.kind == "touch"]
    assert all(d.sensor(s.name).data[0] > 0 for s in touch)
    weight = sum(link.mass for link in spec.links) * 9.81
    assert sum(d.sensor(s.name).data[0] for s in touch) < 3 * weight
    knee = next(a for a in spec.actuators if a.joint == "leg")
    assert d.sensor("leg_joint_min").data[0] == pytest.approx(d.qpos[m.joint("leg:joint").qposadr[0]])
    assert d.qpos[m.joint("leg:joint").qposadr[0]] == pytest.approx(target[knee.name], abs=math.radians(4))


# -- the conventions, on small models -----------------------------------------------------------------

CONVENTIONS = """\
<mujoco model="bent">
  <compiler angle="degree"/>
  <default>
    <joint damping="0.5" limited="true"/>
    <default class="leg"><geom type="capsule" size="0.04" density="500"/></default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <body name="body" pos="0.3 0 0.8" euler="0 20 0">
      <freejoint name="root"/>
      <geom type="box" size="0.2 0.1 0.05"/>
      <body name="leg" pos="0.1 0 -0.05" quat="0.9659258 0 0.258819 0">
        <joint name="hip" type="hinge" axis="0 1 0" pos="0 0 0.02" range="-30 60" stiffness="2" springref="10"/>
        <geom class="leg" fromto="0 0 0 0 0 -0.4"/>
        <body name="toe" pos="0 0 -0.4">
          <geom type="sphere" size="0.05" density="800"/>
        </body>
      </body>
    </body>
  </worldbody>
  <!-- ctrlrange: MuJoCo leaves it in qpos units (rad), whatever compiler angle says -->
  <actuator><position name="hip_servo" joint="hip" kp="30" kv="3" ctrlrange="-0.34906585 0.6981317"/></actuator>
</mujoco>
"""


def test_conventions_free_root_plus_y_hinge_defaults_fromto_rotations_and_welds(tmp_path):
    spec, text, warnings = _import(tmp_path, CONVENTIONS)
    m, d = _compiled(str(tmp_path / "model.xml"))
    _at(m, d, m.qpos0)
    body, leg = spec.links
    assert any("free" in w and "'root'" in w for w in warnings)
    assert [link.name for link in spec.links] == ["body", "leg"]  # the toe welded into the leg
    # the toe's mass and inertia merged into the leg by parallel axes, about their joint COM
    b_leg, b_toe = m.body("leg").id, m.body("toe").id
    assert leg.mass == pytest.approx(m.body_mass[b_leg] + m.body_mass[b_toe], rel=1e-9)
    c = (m.body_mass[b_leg] * d.xipos[b_leg] + m.body_mass[b_toe] * d.xipos[b_toe]) / leg.mass
    expected = sum(_planar_inertia(m, d, b) + m.body_mass[b] * float(np.sum((d.xipos[b] - c)[[0, 2]] ** 2))
                   for b in (b_leg, b_toe))
    assert leg.inertia == pytest.approx(expected, rel=1e-9)
    # the hinge is about +y: sanlab's angle is -qpos, so the range, spring and targets flip
    j = m.joint("hip")
    assert (leg.limit.min, leg.limit.max) == pytest.approx((-j.range[1], -j.range[0]))
    assert leg.spring.rest == pytest.approx(-math.radians(10)) and leg.spring.stiffness == pytest.approx(2.0)
    servo, = spec.actuators
    assert (servo.min, servo.max) == pytest.approx((-math.radians(40), math.radians(20)))
    assert servo.ks == pytest.approx(30) and servo.kd == pytest.approx(3)
    # kinematics at a bent pose: sanlab's joint angle a is MuJoCo's qpos -a; the root where it was
    for a in (0.4, -0.3):
        q = mjcf.initial_q(spec)
        q[mjcf.rotation_dofs(spec)["leg"]] = a
        qpos = m.qpos0.copy()
        qpos[j.qposadr[0]] = -a
        _at(m, d, qpos)
        com = mjcf.com_positions(spec, q)
        shift = com[0] - d.xipos[m.body("body").id][[0, 2]]
        np.testing.assert_allclose(com[1] - shift, c_world(m, d), atol=1e-9)


def c_world(m, d) -> np.ndarray:
    b_leg, b_toe = m.body("leg").id, m.body("toe").id
    mass = m.body_mass[b_leg] + m.body_mass[b_toe]
    return ((m.body_mass[b_leg] * d.xipos[b_leg] + m.body_mass[b_toe] * d.xipos[b_toe]) / mass)[[0, 2]]


def test_a_fromto_capsule_becomes_its_ends_and_sides(tmp_path):
    """Every outline point lies on a geom's surface seen in the plane, and the capsule's far end
    (the other is inside the toe's sphere) is one of them; every outline point is a contact."""
    spec, _, _ = _import(tmp_path, CONVENTIONS)
    m, d = _compiled(str(tmp_path / "model.xml"))
    _at(m, d, m.qpos0)
    X, _ = mjcf.link_poses(spec, mjcf.initial_q(spec))
    leg = spec.links[1]
    g = m.geom(int(m.body("leg").geomadr[0]))
    r, h = g.size[:2]
    assert h == pytest.approx(0.2)  # fromto's length, halved
    centre, u = d.geom_xpos[g.id][[0, 2]], d.geom_xmat[g.id].reshape(3, 3)[[0, 2], 2]
    a, b = centre - h * u, centre + h * u
    sphere = m.geom(int(m.body("toe").geomadr[0]))
    s_centre, s_r = d.geom_xpos[sphere.id][[0, 2]], sphere.size[0]
    lift = X[1] - d.xanchor[m.joint("hip").id][[0, 2]]  # the start pose set onto the floor
    world = np.asarray(leg.shape.points) + X[1] - lift

    def on_capsule(p):
        t = np.clip(np.dot(p - a, u), 0, 2 * h)
        return abs(np.linalg.norm(p - (a + t * u)) - r) < 1e-9

    assert all(on_capsule(p) or abs(np.linalg.norm(p - s_centre) - s_r) < 1e-9 for p in world)
    tips = [a - r * u, b + r * u]  # the capsule's ends: one inside the toe's sphere, one outside
    outside = [t for t in tips if np.linalg.norm(t - s_centre) > s_r]
    assert len(outside) == 1 and any(np.allclose(p, outside[0]) for p in world)
    assert sorted(map(tuple, leg.contacts)) == sorted(map(tuple, leg.shape.points))


def test_a_model_that_is_not_planar_is_one_line_naming_the_joint(tmp_path):
    for xml, joint in ((os.path.join(ASSETS, "ant.xml"), "hip_1"), (os.path.join(ASSETS, "swimmer.xml"), "slider2")):
        with pytest.raises(MjcfError) as e:
            mjcf_to_toml(xml)
        assert f"joint '{joint}'" in str(e.value) and "planar" in str(e.value)
        assert str(e.value).startswith(xml) and "\n" not in str(e.value)
    tilted = CONVENTIONS.replace('axis="0 1 0"', 'axis="0 0 1"')
    with pytest.raises(MjcfError, match=r"joint 'hip' \(hinge, axis \(0\.766, 0, 0\.643\) at qpos0\): expected a hinge about"):
        _import(tmp_path, tilted)


def test_malformed_and_missing_files_are_one_line_naming_the_file(tmp_path):
    with pytest.raises(MjcfError, match=r"nope\.xml: no such file$"):
        mjcf_to_toml(tmp_path / "nope.xml")
    (tmp_path / "bad.xml").write_text('<mujoco>\n<worldbody><bogus/></worldbody></mujoco>')
    with pytest.raises(MjcfError) as e:
        mjcf_to_toml(tmp_path / "bad.xml")
    assert str(e.value).startswith(str(tmp_path / "bad.xml") + ": ") and "bogus" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(MjcfError, match="directory"):
        mjcf_to_toml(tmp_path)
    empty = '<mujoco><worldbody><geom type="plane" size="1 1 1"/></worldbody></mujoco>'
    with pytest.raises(MjcfError, match="at least one moving body"):
        _import(tmp_path, empty)


def test_mujocos_own_warnings_are_warnings_and_leave_no_log_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    xml = CONVENTIONS.replace('<compiler angle="degree"/>', '<compiler angle="degree" settotalmass="3"/>')
    spec, _, warnings = _import(tmp_path, xml)
    assert sum(link.mass for link in spec.links) == pytest.approx(3.0)
    said = [w for w in warnings if w.startswith("MuJoCo: ")]
    assert len(said) == 1 and "settotalmass" in said[0]
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_what_is_not_carried_over_is_one_warning_each(tmp_path):
    xml = CONVENTIONS.replace('<joint damping="0.5" limited="true"/>',
                              '<joint damping="0.5" limited="true" armature="0.2" frictionloss="0.1"/>')
    xml = xml.replace("</worldbody>", "</worldbody><sensor><jointpos joint=\"hip\"/></sensor>")
    _, text, warnings = _import(tmp_path, xml)
    for word in ("armature 0.2", "frictionloss", "1 MuJoCo sensor"):
        assert sum(word in w for w in warnings) == 1, (word, warnings)
    assert all("\n" not in w for w in warnings)
    assert all(w.split(":")[0] in text for w in warnings)  # and listed in the file's header


# -- issue 48: names that are not UTF-8 or not printable, thousands of static bodies ----------

# (the XML attribute holding the name, the element the error names)
NAMED = [('<mujoco model="bent"', "the model's name"), ('<body name="leg"', "the name of body 2 (<body>)"),
         ('<joint name="hip"', "the name of joint 1 (<joint>)"), ('<body name="body"', "the name of body 1 (<body>)"),
         ('<position name="hip_servo"', "the name of actuator 0 (<actuator>)")]


COMPILED: list[bool] = []


@settings(database=None, deadline=None, derandomize=True, max_examples=40,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(name=odd_names(), where=st.sampled_from(NAMED))
def test_a_name_not_utf8_or_not_printable_is_one_line_naming_the_element(tmp_path, name, where):
    """MuJoCo compiles such names; the importer raised UnicodeDecodeError on one that is not
    UTF-8, and wrote a newline into a TOML string (then refused its own file's line 52)."""
    attribute, element = where
    xml = CONVENTIONS.encode().replace(attribute.encode(), attribute[: attribute.index('"') + 1].encode() + name + b'"')
    path = tmp_path / "odd.xml"
    path.write_bytes(xml)
    try:
        mujoco.MjModel.from_xml_path(str(path))
    except ValueError:  # MuJoCo's parser refuses it itself: then so does the importer, in one line
        element = "expected a MuJoCo model"
    COMPILED.append(element != "expected a MuJoCo model")
    with pytest.raises(MjcfError) as e:
        mjcf_to_toml(path)
    msg = str(e.value)
    assert msg.startswith(f"{path}: ") and msg.isprintable() and element in msg, msg


def test_most_odd_names_are_compiled_by_mujoco_and_reach_the_importer():
    if not COMPILED:
        pytest.skip("run with the test above")
    assert sum(COMPILED) >= len(COMPILED) // 2, COMPILED


def test_a_name_with_quotes_and_backslashes_is_kept_as_it_is(tmp_path):
    xml = CONVENTIONS.replace('<body name="leg"', '<body name="le&quot;g\\ \'x\'"')
    spec, text, _ = _import(tmp_path, xml)
    assert [link.name for link in spec.links] == ["body", 'le"g\\ \'x\'']


def test_thousands_of_static_bodies_import_with_their_warnings_folded(tmp_path):
    """2,000 static bodies ended in mujoco.FatalError (mj_stackAlloc: out of memory, in the
    collision detection of mj_forward, which the mass matrix does not need); 1,500 imported
    with 1,501 warning lines."""
    statics = "".join(f'<body name="s{i}" pos="{i} 0 0"><geom type="box" size="0.1 0.1 0.1"/></body>' for i in range(2000))
    xml = CONVENTIONS.replace('<geom name="floor" type="plane" size="5 5 .1"/>',
                              '<geom name="floor" type="plane" size="5 5 .1"/>' + statics)
    spec, text, warnings = _import(tmp_path, xml)
    assert [link.name for link in spec.links] == ["body", "leg"]
    scenery = [w for w in warnings if "fixed to the world" in w]
    assert scenery == ["body 's0' is fixed to the world: static scenery, not carried over (sanlab's world is its ground) "
                       "(and 1,999 more like it: 's1', 's2', 's3', 's4', ...)"]
    assert len(warnings) < 10 and len(text) < 20_000


def test_fold_keeps_a_few_alike_and_folds_more():
    assert fold(["body 'a' x", "body 'b' x", "y"]) == ["body 'a' x", "body 'b' x", "y"]
    assert fold([f"geom 'g{i}' (mesh): no outline" for i in range(5)] + ["other"]) == [
        "geom 'g0' (mesh): no outline (and 4 more like it: 'g1', 'g2', 'g3', 'g4')", "other"]


def test_check_says_the_imported_models_fall_at_rest_and_never_ok_standing(gym_model):
    """Issue 57 item 4: `check --simulate` said "ok standing" for the imported walker2d, whose
    centre of mass moves 71 cm as it falls over at mid targets. Both models fall by their own
    (Gymnasium's) fell rule with the servos at mid targets: a note naming the rule, never "ok"."""
    from sanlab.check import simulate

    name, _, _, spec, _, _ = gym_model
    (f,) = [f for f in simulate(spec) if f.check == "standing"]
    assert f.note and not f.warning and f.values["fell"], f.message
    assert f.message.startswith("standing: falls by the file's fell rule with the servos at mid targets (link torso ")
    if name == "walker2d":
        assert f.values["drift_m"] > 0.5 and "past evaluation.fell_angle_deg = 57.3" in f.message
