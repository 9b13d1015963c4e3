"""Creature file format: built-ins, unit conversion, defaults, validation messages (the check
and creatures commands: ``tests/cli/test_creatures.py``)."""

import math

import pytest

from sanlab.creature import (
    CreatureError,
    builtin_names,
    initial_frames,
    load,
    load_file,
    loads,
    read_source,
    world_point,
)
from tests.helpers import BASE, DATA

PER_DEG = 180 / math.pi


@pytest.mark.parametrize(
    "name, links, sensors, actuators, hidden, dofs",
    [("cart", 2, 6, 1, 5, 4), ("bounder", 5, 8, 4, 8, 7)],
)
def test_builtin_counts(name, links, sensors, actuators, hidden, dofs):
    c = load(name)
    assert (len(c.links), len(c.sensors), len(c.actuators), c.san.hidden, c.dofs) == (
        links, sensors, actuators, hidden, dofs,
    )  # fmt: skip
    assert c.name == name and 0.07 <= c.san.delay_on == c.san.delay_off <= 0.15  # the paper's range
    assert c.evaluation.seconds == 6.0


def test_builtin_names_and_source():
    assert builtin_names() == sorted(builtin_names())
    assert {"cart", "bounder"} <= set(builtin_names())
    text, where = read_source("cart")
    assert where == "builtin:cart" and 'name = "cart"' in text
    assert loads(text) == load("cart")


def test_cart_matches_figure_11():
    c = load("cart")
    assert [(k.name, k.mass) for k in c.links] == [("L1", 0.10), ("L2", 0.10)]
    assert c.links[1].parent == "L1"
    touch = [(s.name, s.kind, s.link, s.contact) for s in c.sensors[:4]]
    assert touch == [
        ("S1", "touch", "L1", 0),
        ("S2", "touch", "L1", 2),
        ("S3", "touch", "L2", 0),
        ("S4", "touch", "L2", 2),
    ]
    s5, s6 = c.sensors[4:]
    assert (s5.kind, s5.link, s6.kind, s6.link) == ("angle", "L2", "angle", "L2")
    assert s5.min == pytest.approx(-math.pi) and s5.max == pytest.approx(math.radians(-120))
    assert s6.min == pytest.approx(math.radians(120)) and s6.max == pytest.approx(math.pi)
    (a1,) = c.actuators
    assert (a1.name, a1.kind, a1.joint) == ("A1", "angular", "L2")
    assert (a1.min, a1.max) == pytest.approx((math.radians(-140), math.radians(140)))
    assert a1.ks == pytest.approx(0.002 * PER_DEG)  # N m/rad
    assert a1.kd == pytest.approx(0.0001 * PER_DEG)  # N m s/rad
    assert c.evaluation.metric == "distance"
    # standing on the blade's keel: one contact on the ground, none below it
    ys = [world_point(c, link.name, p)[1] for link in c.links for p in link.contacts]
    assert min(ys) == pytest.approx(0.0, abs=1e-4) and sorted(ys)[1] > 0.005
    # S2 and S3 sit at the joint's ends of the two links, S1 and S4 at the free ends
    joint = world_point(c, "L2", (0.0, 0.0))
    at = lambda s: world_point(c, s.link, c.links[0 if s.link == "L1" else 1].contacts[s.contact])
    near = [math.dist(at(s), joint) for s in c.sensors[:4]]
    assert near[1] < 0.02 and near[2] < 0.02 and near[0] > 0.1 and near[3] > 0.1


def test_bounder_design():
    c = load("bounder")
    assert sum(k.mass for k in c.links) == pytest.approx(2.4 + 2 * (0.511434 + 0.445068))
    assert [s.kind for s in c.sensors] == ["touch"] * 2 + ["angle"] * 6
    for a in c.actuators:
        assert a.kind == "angular" and a.ks == pytest.approx(0.4 * PER_DEG)
        assert a.kd / a.ks == pytest.approx(0.10)
    assert {a.joint for a in c.actuators} == {k.name for k in c.links if k.parent}
    assert c.evaluation.metric == "distance_upright" and c.evaluation.fell_link == "body"
    # standing: feet just touch the ground, everything else is above it
    feet = [world_point(c, s.link, c.link(s.link).contacts[s.contact]) for s in c.sensors[:2]]
    assert [y for _, y in feet] == pytest.approx([0.0, 0.0], abs=1e-4)
    for link in c.links:
        for p in link.contacts:
            assert world_point(c, link.name, p)[1] > -1e-4
    assert initial_frames(c)["body"][2] == 0.0


def test_kitchen_sink_loads():
    c = load_file(DATA / "kitchen_sink.toml")
    w = c.world
    assert (w.plane, w.water_drag, w.follow.loop, len(w.follow.points)) == (
        "horizontal",
        2,
        True,
        3,
    )
    assert {s.kind for s in c.sensors} == {"eye", "length", "touch", "angle"}
    assert {a.kind for a in c.actuators} == {"angular", "linear"}
    assert [s.name for s in c.sensors] == ["S1", "front_eye", "S3", "S4", "S5"]
    assert c.san.hidden is None
    rear = c.link("rear")
    assert rear.is_point and rear.parent is None and rear.inertia == 0
    assert rear.contacts == ((0.0, 0.0),)
    assert rear.friction.axis == ("rear", "front")
    assert rear.friction.lateral == 0.8  # defaults to backward
    assert c.link("post").fixed and not rear.fixed
    assert c.dofs == 3 + 1 + 2 + 2  # the fixed post adds none
    spring, tether = c.springs
    assert spring.name == "K1" and spring.rest == pytest.approx(0.2)  # initial distance
    assert tether.rest == 0.5
    tail = c.link("tail")
    assert tail.spring.stiffness == pytest.approx(0.01 * PER_DEG)
    assert tail.spring.damping == pytest.approx(0.001 * PER_DEG)
    assert tail.spring.rest == pytest.approx(math.radians(5))
    assert tail.contacts == () and tail.inertia == 0.0005 and tail.com == (-0.05, 0.0)
    assert c.evaluation.fell_angle == pytest.approx(math.pi / 4)


def test_degrees_become_radians():
    extra = '[world.terrain]\nkind = "slope"\nangle_deg = 30\n[evaluation]\nfell_angle_deg = 60\n'
    c = loads(BASE + extra)
    assert c.links[0].angle == pytest.approx(math.pi / 2)  # angle_deg = 90
    assert c.links[1].angle == pytest.approx(math.radians(-45))
    assert c.world.terrain.angle == pytest.approx(math.pi / 6)
    assert c.evaluation.fell_angle == pytest.approx(math.pi / 3)
    s = c.sensors[1]
    assert (s.min, s.max) == pytest.approx((math.radians(-90), math.radians(45)))


def _one(link: str) -> str:
    return f'[[links]]\nname = "X"\nmass = 2.0\n{link}\n'


def test_default_inertia_of_rod():
    k = loads(_one('shape = "segment"\npoints = [[0, 0], [0.3, 0.4]]')).links[0]
    assert k.inertia == pytest.approx(2.0 * 0.5**2 / 12)
    assert k.com == pytest.approx((0.15, 0.2))
    assert k.contacts == ((0.0, 0.0), (0.3, 0.4))


@pytest.mark.parametrize(
    "pts", [[[1, 1], [1.4, 1], [1.4, 1.2], [1, 1.2]], [[1, 1], [1, 1.2], [1.4, 1.2], [1.4, 1]]]
)
def test_default_inertia_of_rectangle(pts):
    k = loads(_one(f'shape = "polygon"\npoints = {pts}')).links[0]  # either winding
    assert k.inertia == pytest.approx(2.0 * (0.4**2 + 0.2**2) / 12)
    assert k.com == pytest.approx((1.2, 1.1))
    assert len(k.contacts) == 4


def test_default_inertia_of_triangle_ignores_explicit_com():
    shape = 'shape = "polygon"\npoints = [[0, 0], [0.3, 0], [0, 0.6]]\ncom = [0, 0]'
    k = loads(_one(shape)).links[0]
    assert k.inertia == pytest.approx(2.0 * (0.3**2 + 0.6**2) / 18)  # about its own centroid
    assert k.com == (0.0, 0.0)


def test_hidden_nodes_default_to_one_per_sensor_and_zero_means_none():
    assert loads(BASE).n_hidden == 2  # two sensors, no [san] table
    assert loads(BASE + "[san]\nhidden = 5\n").n_hidden == 5
    assert loads(BASE + "[san]\nhidden = 0\n").n_hidden == 0


def test_the_format_and_the_spec_share_defaults_and_vocabularies():
    from sanlab.creature import _toml, spec

    assert tuple(_toml.TERRAIN) == spec.TERRAIN_KINDS
    c = loads(BASE)  # no [world], [san], [evaluation], dt: all defaults
    assert (c.world, c.san, c.evaluation, c.dt) == (spec.World(), spec.SanConfig(), spec.Evaluation(), 1e-3)
    c = loads(BASE + "[world]\n[san]\n[evaluation]\n")  # empty tables: the same defaults
    assert (c.world, c.san, c.evaluation) == (spec.World(), spec.SanConfig(), spec.Evaluation())
    assert c.links[0].drag and not c.links[0].fixed and c.links[0].position == (0.0, 0.0)


def test_point_mass_defaults():
    k = loads(_one('shape = "point"\nposition = [1, 2]')).links[0]
    assert (k.inertia, k.com, k.position) == (0.0, (0.0, 0.0), (1.0, 2.0))
    assert k.contacts == ((0.0, 0.0),)




def sub(old: str, new: str, n: int = 0) -> str:
    """BASE with the n-th occurrence (from 0) of ``old`` replaced."""
    parts = BASE.split(old)
    assert len(parts) > n + 1, old
    return old.join(parts[: n + 1]) + new + old.join(parts[n + 1 :])


POINT = '[[links]]\nname = "P"\nmass = 1\nshape = "point"\n'

# (id, file text, field path in the message, the message's "got" part)
# fmt: off
BAD = [
    ("unknown key", sub("mass = 0.1", "mas = 0.1"), "links[0].mas: unknown field", "'mass'"),
    ("negative mass", sub("mass = 0.1", "mass = -1", 1), "links[1].mass", "got -1"),
    ("missing parent", sub('parent = "L1"', 'parent = "L9"'), "links[1].parent", "got 'L9'"),
    ("child before parent", sub('name = "L1"', 'name = "L0"\nparent = "L2"'), "links[0].parent", "got 'L2'"),
    ("own parent", sub('parent = "L1"', 'parent = "L2"'), "links[1].parent", "got 'L2'"),
    ("bad sensor link", sub('link = "L1"', 'link = "L3"'), "sensors[0].link", "['L1', 'L2'], got 'L3'"),
    ("min >= max", sub("min_deg = -90\nmax_deg = 45", "min_deg = 45\nmax_deg = 45"), "sensors[1].max_deg", "got 45"),
    ("angle out of range", sub("min_deg = -90\nmax_deg = 45", "min_deg = -200\nmax_deg = 45"), "sensors[1].min_deg", "got -200"),
    ("wrong type", 'dt = "fast"\n' + BASE, "dt: expected a number in [1e-05, 0.01] (s)", "got 'fast'"),
    ("bool is not a number", sub("mass = 0.1", "mass = true"), "links[0].mass", "got true"),
    ("nan", sub("mass = 0.1", "mass = nan"), "links[0].mass", "got nan"),
    ("toml syntax", sub("mass = 0.1", "mass = "), "line 3, column", "got a syntax error"),
    ("duplicate toml key", sub("mass = 0.1", "mass = 0.1\nmass = 0.2"), "line", "got a syntax error"),
    ("no links", 'name = "empty"\n', "links: expected at least one [[links]] table", "got nothing"),
    ("duplicate link name", sub('name = "L2"', 'name = "L1"'), "links[1].name", "got 'L1'"),
    ("position on joint", sub("anchor = [0.2, 0]", "anchor = [0.2, 0]\nposition = [0, 1]"), "links[1].position", "got [0, 1]"),
    ("fixed joint", sub("anchor = [0.2, 0]", "anchor = [0.2, 0]\nfixed = true"), "links[1].fixed", "got true"),
    ("anchor on root", sub("angle_deg = 90", "angle_deg = 90\nanchor = [1, 0]"), "links[0].anchor", "got [1, 0]"),
    ("spring on root", sub("angle_deg = 90", "angle_deg = 90\nspring = { stiffness = 1 }"), "links[0].spring", "got a table"),
    ("point parent", POINT + sub('name = "L1"', 'name = "L1"\nparent = "P"'), "links[1].parent", "got 'P'"),
    ("point with parent", BASE + POINT + 'parent = "L1"\n', "links[2].parent", "got 'L1'"),
    ("point with points", BASE + POINT + "points = [[0, 0]]\n", "links[2].points", "got [[0, 0]]"),
    ("segment of 3 points", sub("[0.2, 0]]", "[0.2, 0], [1, 1]]"), "links[0].points", "exactly 2 points"),
    ("zero-length segment", sub("[0.2, 0]]", "[0, 0]]"), "links[0].points", "got [[0, 0], [0, 0]]"),
    ("bad point", sub("[0.2, 0]]", '[0.2, "x"]]'), "links[0].points[1]", "got [0.2, 'x']"),
    ("flat polygon", sub('"segment"\npoints = [[0, 0], [0.2, 0]]', '"polygon"\npoints = [[0, 0], [1, 0], [2, 0]]'),
     "links[0].points", "non-zero area"),
    ("contact index", sub("contact = 0", "contact = 2"), "sensors[0].contact", "in [0, 1], got 2"),
    ("field of other sensor type", sub("contact = 0", "contact = 0\nmin_deg = 3"),
     "sensors[0].min_deg: unknown field for a touch sensor", "'link'"),
    ("bad sensor type", sub('type = "touch"', 'type = "smell"'), "sensors[0].type", "got 'smell'"),
    ("duplicate sensor name", sub('type = "angle"', 'name = "S1"\ntype = "angle"'), "sensors[1].name", "got 'S1'"),
    ("actuator on root", sub('joint = "L2"', 'joint = "L1"'), "actuators[0].joint", "jointed link"),
    ("negative ks", sub("ks = 0.002", "ks = -0.002"), "actuators[0].ks", "(N m/deg), got -0.002"),
    ("missing required", sub("ks = 0.002\n", ""), "actuators[0].ks", "got nothing"),
    ("same joint twice", BASE + BASE[BASE.index("[[actuators]]"):], "actuators[1].joint", "got 'L2'"),
    ("eye without follow", BASE + '[[sensors]]\ntype = "eye"\nlink = "L1"\nmin_deg = -10\nmax_deg = 10\n',
     "world.follow", "got nothing"),
    ("pursuit without follow", BASE + '[evaluation]\nmetric = "pursuit"\n', "world.follow", "got nothing"),
    ("terrain in horizontal plane", BASE + '[world]\nplane = "horizontal"\n[world.terrain]\nkind = "hill"\n',
     "world.terrain.kind", "got 'hill'"),
    ("field of other terrain", BASE + '[world.terrain]\nkind = "slope"\nseed = 3\n',
     "world.terrain.seed: unknown field for terrain kind 'slope'", "'angle_deg'"),
    ("zero dt", "dt = 0\n" + BASE, "dt", "got 0"),
    ("negative ground stiffness", BASE + "[world.ground]\nstiffness = -5\n", "world.ground.stiffness", "got -5"),
    ("hidden not integer", BASE + "[san]\nhidden = 2.5\n", "san.hidden", "got 2.5"),
    ("upright needs fell_link", BASE + '[evaluation]\nmetric = "distance_upright"\n', "evaluation.fell_link", "got nothing"),
    ("unknown fell_link", BASE + '[evaluation]\nfell_link = "torso"\n', "evaluation.fell_link", "got 'torso'"),
    ("points on one link", BASE + '[[springs]]\na = { link = "L1" }\nb = { link = "L1", at = [1, 0] }\nstiffness = 1\n',
     "springs[0].b.link", "got 'L1'"),
    ("bad point ref", BASE + '[[springs]]\na = { link = "L1", att = [0, 0] }\nb = { link = "L2" }\nstiffness = 1\n',
     "springs[0].a.att: unknown field", "'at'"),
    ("axis of one link", sub("angle_deg = 90", 'angle_deg = 90\nfriction = { forward = 0.1, backward = 0.5, axis = ["L1", "L1"] }'),
     "links[0].friction.axis", "got ['L1', 'L1']"),
    ("follow of one point", BASE + "[world.follow]\npoints = [[0, 0]]\nspeed = 1\n", "world.follow.points", "2 to 64 points"),
    ("limit on a root", sub("angle_deg = 90", "angle_deg = 90\nlimit = { min_deg = -10, max_deg = 10 }"),
     "links[0].limit", "no limit on a root link"),
    ("limit min above max", sub('parent = "L1"', 'parent = "L1"\nlimit = { min_deg = 30, max_deg = 10 }'),
     "links[1].limit.max_deg", "got 10"),
    ("limit typo", sub('parent = "L1"', 'parent = "L1"\nlimit = { min_deg = -30, max = 10 }'),
     "links[1].limit.max: unknown field", "'max_deg'"),
    ("negative skin drag", BASE + "[world]\nwater_tangential = -0.1\n", "world.water_tangential", "got -0.1"),
    ("tilt on a point mass", BASE + '[[links]]\nname = "P"\nmass = 1\nshape = "point"\n'
     '[[sensors]]\ntype = "tilt"\nlink = "P"\nmin_deg = -10\nmax_deg = 10\n', "sensors[2].link", "got 'P'"),
    ("unknown fell link in a list", BASE + '[evaluation]\nfell_link = ["L1", "torso"]\n', "evaluation.fell_link[1]",
     "got 'torso'"),
    ("link height without fell link", BASE + "[evaluation]\nfell_link_height = 0.1\n", "evaluation.fell_link",
     "got nothing"),
    ("height in the horizontal plane", BASE + '[world]\nplane = "horizontal"\n[evaluation]\nfell_com_height = 0.1\n',
     "evaluation.fell_com_height", "got 0.1"),
    ("unknown direction", BASE + '[evaluation]\ndirection = "up"\n', "evaluation.direction", "got 'up'"),
    ("joint without inertia", sub('parent = "L1"', 'parent = "L1"\ninertia = 0\ncom = [0, 0]'), "links[1].inertia",
     "got 0.0"),
    ("history not an array", 'history = "2026-12-04: longer legs"\n' + BASE,
     'history: expected an array of at most 1000 strings, oldest first, each "YYYY-MM-DD: what changed; why"',
     "got '2026-12-04: longer legs'"),
    ("history without a date", 'history = ["2026-12-04: ok", "longer legs"]\n' + BASE,
     'history[1]: expected one line "YYYY-MM-DD: what changed; why" (a date, then printable text; at most 500 '
     "characters)", "got 'longer legs'"),
    ("history of no date", 'history = ["2026-02-30: longer legs"]\n' + BASE, "history[0]", "got '2026-02-30: longer legs'"),
    ("history saying nothing", 'history = ["2026-12-04:  "]\n' + BASE, "history[0]", "got '2026-12-04:  '"),
    ("history of two lines", 'history = ["2026-12-04: a\\nb"]\n' + BASE, "history[0]", "got '2026-12-04: a\\nb'"),
    ("history too long", 'history = ["2026-12-04: ' + "x" * 490 + '"]\n' + BASE, "history[0]", "at most 500 characters"),
    ("history entry not a string", "history = [20261204]\n" + BASE, "history[0]", "got 20261204"),
]
# fmt: on


@pytest.mark.parametrize("text, path, got", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_malformed(text, path, got):
    with pytest.raises(CreatureError) as info:
        loads(text, "bad.toml")
    msg = str(info.value)
    assert msg.startswith("bad.toml: ")
    assert path in msg and got in msg and "expected" in msg
    assert "\n" not in msg


def test_base_is_valid():
    assert loads(BASE).name == "unnamed"


def test_a_files_history_is_kept_oldest_first_and_is_no_physics():
    import dataclasses

    lines = ["2026-12-04: shin 2 cm longer; the design search's body was faster", "2026-12-09: hip gains x 1.5; robust at dt/4"]
    c = loads("history = [\n" + "".join(f'    "{line}",\n' for line in lines) + "]\n" + BASE)
    assert c.history == tuple(lines)
    assert loads(BASE).history == () and loads("history = []\n" + BASE).history == ()
    assert c == loads(BASE) and hash(c) == hash(loads(BASE))  # the file's record, not the creature's identity
    assert dataclasses.replace(c, history=()).history == ()


def test_error_names_the_file(tmp_path):
    bad = tmp_path / "oops.toml"
    bad.write_text(BASE.replace("mass = 0.1", "mass = -1", 1))
    with pytest.raises(
        CreatureError,
        match=r"oops\.toml: links\[0\]\.mass: expected a positive number \(kg\), got -1$",
    ):
        load_file(bad)
    with pytest.raises(CreatureError, match="no such file"):
        load(tmp_path / "missing.toml")
    for empty in ("", "  "):  # not "a directory" (Path("") is the current folder)
        with pytest.raises(CreatureError, match=r"got an empty name$"):
            load(empty)
    good = tmp_path / "walker2.toml"
    good.write_text(BASE)
    assert load(str(good)).name == "walker2"  # name defaults to the file stem
    assert read_source(good)[1] == str(good.resolve())


def test_new_fields_joint_limits_skin_drag_tilt_sensors_falls_and_direction():
    text = BASE.replace('parent = "L1"', 'parent = "L1"\nlimit = { min_deg = -30, max_deg = 45, stiffness = 2 }') + (
        '[world]\nwater_tangential = 0.25\n'
        '[[sensors]]\ntype = "tilt"\nlink = "L1"\nmin_deg = -20\nmax_deg = 20\n'
        '[evaluation]\nfell_link = ["L1", "L2"]\nfell_com_height = 0.05\nfell_link_height = 0.02\ndirection = "forward"\n'
    )
    c = loads(text)
    lim = c.links[1].limit
    assert lim.min == pytest.approx(math.radians(-30)) and lim.max == pytest.approx(math.radians(45))
    assert lim.stiffness == pytest.approx(2 * PER_DEG) and lim.damping == pytest.approx(0.01 * PER_DEG)  # default
    assert c.links[0].limit is None
    assert c.world.water_tangential == 0.25 and load("cart").world.water_tangential == 0.1
    tilt = c.sensors[-1]
    assert (tilt.kind, tilt.link) == ("tilt", "L1") and tilt.max == pytest.approx(math.radians(20))
    ev = c.evaluation
    assert ev.fell_links == ("L1", "L2") and ev.fell_link == "L1"
    assert (ev.fell_com_height, ev.fell_link_height, ev.direction) == (0.05, 0.02, "forward")
    assert loads(BASE + '[evaluation]\nfell_link = "L2"\n').evaluation.fell_links == ("L2",)
    assert load("cart").evaluation.direction == "either"  # the paper's |x(T) - x(0)|
