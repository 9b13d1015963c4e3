"""All drawing of creatures and worlds: one place, on any :class:`~sanlab.render.canvas.Canvas`.

A frame (:func:`draw_frame`) is, back to front: the ground (terrain line with distance ticks, or a
light grid for the horizontal plane), the follow point's path, the centre-of-mass trail so far,
the creature (links by shape: segments as thick lines, polygons filled, point masses as discs;
linear actuators and springs as thin lines; joints as small rings; contact points orange while
they touch the ground, grey otherwise; the head, see below; the centre of mass as a small quartered
disc), the follow point, then the overlays: time (top left), title (top right), a distance scale bar (bottom left),
and optionally a panel of the SAN's outputs over time under the picture.

Colours: each subtree hanging from a root gets its own hue (the root is the darkest), so legs
can be told apart; a faded copy (strobe pictures) mixes every colour towards the background.

The head: a magenta dot in a white ring on the root of the first free tree (``Scene.head``: a
body's centroid, a segment's free end), so that a long creature's front can be told from its back
and, in a strobe picture, every pose's head stands out of the overlapping bodies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sanlab.render.canvas import Canvas, Color, View, mix

BACKGROUND: Color = (251, 250, 246)
GROUND_FILL: Color = (230, 224, 210)
GROUND_LINE: Color = (96, 86, 70)
TICK: Color = (160, 150, 132)
GRID: Color = (226, 226, 222)
GRID_AXIS: Color = (200, 200, 194)
TEXT: Color = (40, 40, 40)
MUTED: Color = (110, 110, 110)
ROOT: Color = (30, 58, 110)  # navy: the root link(s)
LIMBS: tuple[Color, ...] = (
    (46, 117, 204),  # blue
    (0, 146, 130),  # teal
    (140, 86, 190),  # purple
    (200, 90, 80),  # brick
    (90, 140, 40),  # olive
)
JOINT_RING: Color = (25, 25, 25)
JOINT_FILL: Color = (255, 255, 255)
CONTACT_ON: Color = (245, 128, 20)
CONTACT_OFF: Color = (165, 165, 165)
MUSCLE: Color = (200, 60, 60)
SPRING: Color = (120, 120, 120)
COM_DARK: Color = (25, 25, 25)
TRAIL: Color = (185, 185, 200)
FOLLOW: Color = (214, 39, 40)
FOLLOW_PATH: Color = (240, 180, 180)
PANEL_BG: Color = (255, 255, 255)
NODE_OFF: Color = (236, 236, 232)
NODE_SENSOR: Color = (110, 110, 110)
NODE_HIDDEN: Color = (46, 117, 204)
NODE_ACTUATOR: Color = (245, 128, 20)
CURSOR: Color = (214, 39, 40)
HEAD: Color = (222, 24, 140)  # magenta: a hue no link, contact or actuator uses


def link_colors(spec) -> list[Color]:
    """A colour per link: roots navy, each subtree hanging from a root in its own hue."""
    names = {l.name: i for i, l in enumerate(spec.links)}
    out: list[Color] = []
    branch: dict[int, int] = {}
    nxt = 0
    for i, l in enumerate(spec.links):
        if l.parent is None:
            out.append(ROOT if l.shape.kind != "point" else LIMBS[0])
            continue
        p = names[l.parent]
        if spec.links[p].parent is None:
            branch[i] = nxt
            nxt += 1
        else:
            branch[i] = branch[p]
        out.append(LIMBS[branch[i] % len(LIMBS)])
    return out


def nice(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above ``x``."""
    if not x > 0:
        return 1.0
    e = math.floor(math.log10(x))
    for m in (5, 2, 1):
        if m * 10**e <= x * (1 + 1e-9):
            return m * 10**e
    return 10**e


def fmt_length(m: float) -> str:
    if m >= 1:
        return f"{m:g} m"
    if m >= 0.01:
        return f"{m * 100:g} cm"
    return f"{m * 1000:g} mm"


@dataclass(frozen=True)
class Sizes:
    """Stroke sizes (output pixels) for a view: links get thinner as the view zooms out."""

    link: float
    joint: float
    contact: float
    point_mass: float
    thin: float

    @classmethod
    def for_view(cls, view: View, creature_size: float | None = None) -> "Sizes":
        ref = creature_size * view.scale if creature_size else 0.25 * view.width
        lw = float(np.clip(0.045 * ref, 2.0, 9.0))
        return cls(lw, max(1.6, 0.62 * lw), max(1.4, 0.5 * lw), max(3.0, 1.5 * lw), max(1.0, 0.3 * lw))


# ------------------------------------------------------------------------------ the world


def draw_ground(canvas: Canvas, scene, view: View, labels: bool = True) -> None:
    """Terrain (vertical plane) with distance ticks, or a grid (horizontal plane)."""
    if scene.plane != "vertical":
        _grid(canvas, view)
        return
    n = max(2, view.width // 2)
    x = np.linspace(view.x0, view.x1, n)
    h = scene.terrain(x)
    below = view.y0 - 0.1 * (view.y1 - view.y0)
    pts = list(zip(x, h)) + [(view.x1, below), (view.x0, below)]
    canvas.polygon(pts, GROUND_FILL, True)
    step = nice((view.x1 - view.x0) / 12)
    major = 5 * step if nice(5 * step) == 5 * step else 2 * step
    tick = 6.0 / view.scale
    k0, k1 = math.ceil(view.x0 / step), math.floor(view.x1 / step)
    for k in range(k0, k1 + 1):
        xx = k * step
        hh = float(scene.terrain(np.array([xx]))[0])
        is_major = abs(xx / major - round(xx / major)) < 1e-6
        canvas.segment((xx, hh), (xx, hh - (1.8 if is_major else 1.0) * tick), 1.2 if is_major else 1.0, TICK)
        if labels and is_major:
            canvas.text((xx, hh - 2.4 * tick), f"{xx:g}", TICK, 10, anchor="ma")
    canvas.polyline(list(zip(x, h)), 2.0, GROUND_LINE)


def _grid(canvas: Canvas, view: View) -> None:
    step = nice((view.x1 - view.x0) / 10)
    for k in range(math.ceil(view.x0 / step), math.floor(view.x1 / step) + 1):
        canvas.segment((k * step, view.y0), (k * step, view.y1), 1.0, GRID_AXIS if k == 0 else GRID)
    for k in range(math.ceil(view.y0 / step), math.floor(view.y1 / step) + 1):
        canvas.segment((view.x0, k * step), (view.x1, k * step), 1.0, GRID_AXIS if k == 0 else GRID)


def draw_follow_path(canvas: Canvas, scene, fade: float = 0.0) -> None:
    if scene.follow_path is None:
        return
    pts = scene.follow_path
    # dashed: every other run of 8 samples
    for a in range(0, len(pts) - 1, 16):
        canvas.polyline([tuple(p) for p in pts[a : a + 9]], 1.6, mix(FOLLOW_PATH, BACKGROUND, fade))


def draw_follow_point(canvas: Canvas, scene, frame: int, sizes: Sizes, fade: float = 0.0) -> None:
    if scene.follow is None:
        return
    c = tuple(scene.follow[frame])
    col = mix(FOLLOW, BACKGROUND, fade)
    r = max(4.0, 1.6 * sizes.point_mass)
    canvas.circle(c, r, col, fill=False, width=2.0)
    canvas.circle(c, 0.35 * r, col, fill=True)


def draw_trail(canvas: Canvas, scene, frame: int, color: Color = TRAIL) -> None:
    """The centre of mass's path up to ``frame``."""
    if frame > 0:
        canvas.polyline([tuple(p) for p in scene.com[: frame + 1]], 1.5, color)


# ------------------------------------------------------------------------------ the creature


def draw_pose(canvas: Canvas, scene, frame: int, sizes: Sizes, fade: float = 0.0, detail: bool = True, com: bool = True,
              head: bool = True) -> None:
    """The creature at ``frame``. ``fade`` in [0, 1] mixes colours towards the background;
    ``detail`` adds joints, contact points and actuators/springs; ``head`` the head marker
    (:func:`draw_head`); ``com`` the centre of mass."""
    spec = scene.spec
    f = lambda c: mix(c, BACKGROUND, fade) if fade else c
    colors = link_colors(spec)
    world = [scene.to_world(frame, i, scene.shape_points(i)) for i in range(len(spec.links))]

    if detail:
        for s in spec.springs:
            a, b = scene.attachment(frame, s.a), scene.attachment(frame, s.b)
            canvas.segment(a, b, sizes.thin, f(SPRING))
    order = sorted(range(len(spec.links)), key=lambda i: spec.links[i].shape.kind != "polygon")
    for i in order:  # polygons (bodies) first, limbs over them
        link, pts = spec.links[i], world[i]
        col = f(colors[i])
        if link.shape.kind == "polygon":
            canvas.polygon([tuple(p) for p in pts], col, True)
            canvas.polygon([tuple(p) for p in pts], f(mix(colors[i], (0, 0, 0), 0.35)), False, max(1.0, 0.35 * sizes.link))
        elif link.shape.kind == "segment":
            canvas.segment(tuple(pts[0]), tuple(pts[1]), sizes.link, col)
        else:
            canvas.circle(tuple(pts[0]), sizes.point_mass, col, True)
    if detail:
        for a_i, a in enumerate(spec.actuators):
            if a.kind != "linear":
                continue
            pa, pb = scene.attachment(frame, a.a), scene.attachment(frame, a.b)
            u = float(scene.u[frame, a_i]) if scene.u.size else 0.5
            canvas.segment(pa, pb, max(1.5, sizes.thin * (1.0 + 1.5 * u)), f(mix(MUSCLE, BACKGROUND, 0.55 * (1 - u))))
        joints = [i for i, link in enumerate(spec.links) if link.parent is not None]
        jxy = scene.links[frame, joints, :2] if joints else np.zeros((0, 2))
        halo = 1.5 * sizes.joint / canvas.view.scale
        for c in range(scene.contacts.shape[1]):
            on = scene.depth[frame, c] > 0
            p = scene.contacts[frame, c]
            at_joint = len(jxy) and np.min(np.hypot(*(jxy - p).T)) < 0.5 * halo
            # a contact on a joint shows as a ring around the joint's symbol
            r = 1.45 * sizes.joint if at_joint else sizes.contact
            canvas.circle(tuple(p), r, f(CONTACT_ON if on else CONTACT_OFF), True)
        for i in joints:
            j = tuple(scene.links[frame, i, :2])
            canvas.circle(j, sizes.joint, f(JOINT_RING), True)
            canvas.circle(j, 0.55 * sizes.joint, f(JOINT_FILL), True)
    if head:  # over joints and contacts, which may sit on it (a snake's snout is a contact point)
        draw_head(canvas, scene, frame, sizes, fade)
    if com:
        draw_com(canvas, scene, frame, sizes, fade)


def draw_head(canvas: Canvas, scene, frame: int, sizes: Sizes, fade: float = 0.0) -> None:
    """The head marker at ``frame``: a HEAD disc (radius 0.8 link widths, at least 3.5 px) in a
    white ring 1.5 px wide, wider than the link it sits on."""
    c = tuple(scene.head()[frame])
    r = max(3.5, 0.8 * sizes.link)
    canvas.circle(c, r + 1.5, mix(JOINT_FILL, BACKGROUND, fade), True)
    canvas.circle(c, r, mix(HEAD, BACKGROUND, fade), True)


def draw_com(canvas: Canvas, scene, frame: int, sizes: Sizes, fade: float = 0.0) -> None:
    """The centre of mass at ``frame`` (:func:`_com_marker`, radius 0.8 link widths, at least 3 px)."""
    _com_marker(canvas, tuple(scene.com[frame]), max(3.0, 0.8 * sizes.link), fade)


def _com_marker(canvas: Canvas, c, r: float, fade: float) -> None:
    """The classic centre-of-mass symbol: a disc with two dark quarters."""
    dark, light = mix(COM_DARK, BACKGROUND, fade), mix((255, 255, 255), BACKGROUND, fade)
    canvas.circle(c, r, dark, True)
    canvas.circle(c, 0.72 * r, light, True)
    x, y = c
    s = 0.72 * r / canvas.view.scale
    n = 6
    for q0 in (0.0, math.pi):  # first and third quadrants dark
        arc = [(x + s * math.cos(q0 + k * math.pi / 2 / n), y + s * math.sin(q0 + k * math.pi / 2 / n)) for k in range(n + 1)]
        canvas.polygon([c] + arc, dark, True)


# ------------------------------------------------------------------------------ overlays


def draw_scale_bar(canvas: Canvas, view: View, at: tuple[float, float] | None = None, size: float = 12) -> None:
    """A bar of a round length (about a fifth of the view). ``at``: the pixel where the bar's
    right end sits, label to its left (default: bottom-left corner, label above the bar)."""
    length = nice(0.22 * (view.x1 - view.x0))
    px = length * view.scale
    saved = canvas.view
    canvas.view = View.screen(view.width, view.height)
    if at is None:
        x0, y = 14.0, view.height - 14.0
        canvas.text((x0 + px / 2, y - 5), fmt_length(length), TEXT, size, anchor="md")
    else:
        x0, y = at[0] - px, at[1]
        canvas.text((x0 - 6, y), fmt_length(length), TEXT, size, anchor="rm")
    canvas.segment((x0, y), (x0 + px, y), 2.0 if at else 3.0, TEXT)
    canvas.segment((x0, y - 4), (x0, y + 4), 1.5, TEXT)
    canvas.segment((x0 + px, y - 4), (x0 + px, y + 4), 1.5, TEXT)
    canvas.view = saved


def draw_label(canvas: Canvas, view: View, string: str, where: str = "tl", size: float = 13, color: Color = TEXT) -> None:
    """Text in a corner of the picture (tl, tr, bl, br), in screen space."""
    if not string:
        return
    saved = canvas.view
    canvas.view = View.screen(view.width, view.height)
    x = 10 if where[1] == "l" else view.width - 10
    y = 8 if where[0] == "t" else view.height - 8
    anchor = ("l" if where[1] == "l" else "r") + ("a" if where[0] == "t" else "d")
    canvas.text((x, y), string, color, size, anchor=anchor)
    canvas.view = saved


# ------------------------------------------------------------------------------ SAN panel


def panel_rows(scene) -> list[tuple[str, np.ndarray, Color, list[str]]]:
    """(group, values [F, k], colour, names [k]) of the panel: sensors, hidden nodes, actuator
    nodes, each row named as the creature file names it (hidden nodes H1, H2, ...)."""
    spec = scene.spec
    groups = [
        ("sensors", scene.bits, NODE_SENSOR, [s.name for s in spec.sensors]),
        ("hidden", scene.nodes[:, : scene.n_hidden], NODE_HIDDEN, [f"H{i + 1}" for i in range(scene.n_hidden)]),
        ("actuators", scene.nodes[:, scene.n_hidden :], NODE_ACTUATOR, [a.name for a in spec.actuators]),
    ]
    return [g for g in groups if g[1].shape[1]]


NAMED_ROWS = 40  # up to this many rows each is named (and tall enough to read its name)
NAME_H = 10  # px per named row


def panel_height(scene, width: int) -> int:
    """Height (px) of the SAN panel for a picture ``width`` wide."""
    rows = sum(g[1].shape[1] for g in panel_rows(scene))
    gaps = len(panel_rows(scene)) - 1
    return int(16 + rows * _row_h(rows) + gaps * 4 + 14)


def _row_h(rows: int) -> int:
    if rows <= NAMED_ROWS:
        return NAME_H
    return int(np.clip(round(100 / max(rows, 1)), 3, 8))


def _panel_image(scene, name: str, vals: np.ndarray, color: Color, rh: int) -> np.ndarray:
    key = ("panel", name, rh)
    cache = getattr(scene, "_cache", {})
    if key not in cache:
        on = (vals.T > 0.5)[:, :, None]
        rgb = np.where(on, np.array(color, np.uint8), np.array(NODE_OFF, np.uint8)).astype(np.uint8)
        img = np.repeat(rgb, rh, axis=0)  # rh pixel rows per node, the last one a white gap
        img[rh - 1 :: rh] = PANEL_BG
        cache[key] = img
    return cache[key]


def draw_panel(canvas: Canvas, scene, box, frames=None) -> None:
    """A raster of the SAN's outputs over the whole run in the pixel box (x0, y0, x1, y1):
    rows = sensors (grey), hidden nodes (blue), actuator nodes (orange), each named as in the
    creature file (up to NAMED_ROWS rows; beyond, by group), columns = time; a red cursor at each
    frame of ``frames`` (an int or a list)."""
    x0, y0, x1, y1 = box
    saved = canvas.view
    canvas.view = View.screen(canvas.width, canvas.height)
    canvas.rect((x0, y0, x1, y1), PANEL_BG, True)
    canvas.segment((x0, y0 + 0.5), (x1, y0 + 0.5), 1.0, GRID_AXIS)
    groups = panel_rows(scene)
    rows = sum(g[1].shape[1] for g in groups)
    rh = _row_h(rows)
    named = rows <= NAMED_ROWS
    label_w = 96 if named else 64
    gx0, gx1 = x0 + label_w, x1 - 10
    y = y0 + 8
    F = scene.n_frames
    for name, vals, color, names in groups:
        k = vals.shape[1]
        canvas.raster(_panel_image(scene, name, vals, color, rh), (gx0, y, gx1, y + k * rh))
        text = color if name != "sensors" else MUTED
        if named:
            for r, row in enumerate(names):
                shown = row if len(row) <= 14 else row[:13] + "…"
                canvas.text((gx0 - 6, y + (r + 0.45) * rh), shown, text, 8, anchor="rm")
        else:
            canvas.text((gx0 - 6, y + k * rh / 2), f"{name}", text, 10, anchor="rm")
        y += k * rh + 4
    canvas.text((gx0, y + 1), f"{scene.t[0]:g} s", MUTED, 9, anchor="la")
    canvas.text((gx1, y + 1), f"{scene.t[0] + scene.duration:.3g} s", MUTED, 9, anchor="ra")
    if frames is not None:
        for fi in np.atleast_1d(frames):
            cx = gx0 + (fi + 0.5) * (gx1 - gx0) / F
            canvas.segment((cx, y0 + 4), (cx, y - 2), 1.5, CURSOR)
    canvas.view = saved


# ------------------------------------------------------------------------------ a whole frame


def draw_frame(canvas: Canvas, scene, frame: int, view: View, nodes: bool = False, trail: bool = True) -> None:
    """One animation frame: world, creature, overlays (and the SAN panel under the picture when
    ``nodes``; the canvas must then be ``panel_height`` taller than the view)."""
    canvas.view = view
    sizes = Sizes.for_view(view, scene.size())
    draw_ground(canvas, scene, view)
    draw_follow_path(canvas, scene)
    if trail:
        draw_trail(canvas, scene, frame)
    draw_pose(canvas, scene, frame, sizes)
    draw_follow_point(canvas, scene, frame, sizes)
    draw_label(canvas, view, f"t = {scene.t[frame]:.2f} s", "tl", 14)
    draw_label(canvas, view, scene.title, "tr", 12, MUTED)
    draw_scale_bar(canvas, view)
    if nodes:
        draw_panel(canvas, scene, (0, view.height, view.width, canvas.height), frame)
    canvas.view = view
