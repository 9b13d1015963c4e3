"""Strobe pictures (multi-exposure, like the paper's Figures 10-15) and contact sheets.

A strobe picture shows the whole trajectory in one fixed view, fitted to what moves: the
creature drawn every Δt, older poses fainter (their colours mixed towards the background; a
legend says pale is early), the newest one in full with its centre of mass; every pose's head
(the root link's marker, see :mod:`~sanlab.render.draw`) over all the bodies, so that no later
body hides an earlier head; the centre of mass's path as a thin line; the ground with distance
ticks; a scale bar; which way and how far the creature moved along x (an arrow).

Δt is chosen so that successive poses are about 0.4 creature widths apart along the path, and
at most 0.4 s apart (8 to 24 exposures over the run), rounded to whole recorded frames. Poses
that would overlap are then left out: an exposure whose pose is closer than MIN_SPACING (a
twentieth) of the creature's size, rounded down to two digits, to any exposure kept already
(``Scene.pose_distance``: the mean distance between the same outline points), so that a slow or
long creature (a 1.2 m snake moving 4 cm/s) shows a few poses apart rather than a dozen in one
blob. The first and the last exposure always stay, and the title then says what was done:
"Δt = 0.40 s, thinned to poses ≥ 6 cm apart (4 exposures over 4.0 s)".

A contact sheet puts one strobe tile per gait on a grid (:func:`sheet_layout`), each labelled
with its rank, gait id, speed and an arrow for its direction along x. Tiles share one scale (so that distances compare at a
glance) unless a trajectory does not fit at it, or the common scale would shrink most tiles more
than twofold: then that tile is fitted on its own; every tile has its scale bar.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sanlab.render import draw
from sanlab.render.canvas import PillowCanvas, View, mix
from sanlab.render.film import GROUND_BAND, content_box, even, fixed_view

MIN_EXPOSURES, MAX_EXPOSURES = 8, 24
MAX_DT = 0.4  # s: at least this often (within MAX_EXPOSURES), to catch fast cycles
MIN_SPACING = 0.05  # creature sizes: a pose closer than this to a kept one is left out
FADE_OLDEST = 0.78  # the first exposure's colours are this far towards the background


@dataclass(frozen=True)
class Exposures:
    """The exposures of a strobe picture: ``frames`` (frame indices, first and last included),
    ``step`` (s) the Δt of the even grid they were taken from, and ``gap`` (m) the least distance
    between two poses (``Scene.pose_distance``) when poses that close were left out, else 0."""

    frames: list[int]
    step: float
    gap: float = 0.0

    @property
    def thinned(self) -> bool:
        return self.gap > 0


def plan_exposures(scene, n: int | None = None, most: int | None = None) -> Exposures:
    """The exposures of ``scene``: every k-th frame, first and last included; ``n`` of them
    (default: see the module docstring), at most ``most``. Without ``n``, a pose closer than
    MIN_SPACING creature sizes to one kept already is left out (the first and last never are)."""
    F = scene.n_frames
    if F <= 1:
        return Exposures([0], 0.0)
    auto = n is None
    if n is None:
        cw, _ = scene.extent()
        d = scene.com[-1] - scene.com[0]
        travel = float(np.hypot(*d)) if scene.plane != "vertical" else abs(float(d[0]))
        span = float(scene.t[-1] - scene.t[0])
        n = max(math.ceil(travel / (0.4 * cw)), math.ceil(span / MAX_DT)) + 1
        n = int(np.clip(n, MIN_EXPOSURES, MAX_EXPOSURES))
    if most is not None:
        n = min(n, most)
    k = max(1, int(round((F - 1) / max(n - 1, 1))))
    idx = list(range(0, F, k))
    if idx[-1] != F - 1:
        if F - 1 - idx[-1] < 0.5 * k:
            idx[-1] = F - 1
        else:
            idx.append(F - 1)
    step = float(scene.t[idx[1]] - scene.t[idx[0]])
    if not auto or len(idx) <= 2:
        return Exposures(idx, step)
    gap = _floor2(MIN_SPACING * scene.size())  # a round length, which the title states exactly
    # Against every pose kept so far, not just the one before: a creature rocking back and forth
    # comes back over its old poses, and those overlap as much as two successive ones.
    kept = [idx[0], idx[-1]]
    for f in idx[1:-1]:
        if min(scene.pose_distance(f, g) for g in kept) >= gap:
            kept.append(f)
    if len(kept) == len(idx):
        return Exposures(idx, step)
    return Exposures(sorted(kept), step, gap)


def _floor2(x: float) -> float:
    """``x`` > 0 rounded down to two significant digits (0.1237 -> 0.12)."""
    e = math.floor(math.log10(x)) - 1
    return round(math.floor(x / 10**e * (1 + 1e-12)) * 10**e, 12)  # 0.059, which prints as 5.9 cm


def exposures(scene, n: int | None = None, most: int | None = None) -> list[int]:
    """Frame indices of the exposures (:func:`plan_exposures`)."""
    return plan_exposures(scene, n, most).frames


def strobe_height(scene, width: int) -> int:
    """The picture height at ``width`` that fits what moves (:func:`film.content_box`, and the
    ground band on the vertical plane) exactly, within 20% to 80% of the width."""
    x0, y0, x1, y1 = content_box(scene)
    bh = (y1 - y0) / (1 - GROUND_BAND) if scene.plane == "vertical" else y1 - y0
    return even(int(np.clip(width * bh / (x1 - x0), 0.2 * width, 0.8 * width)))


def motion(scene) -> tuple[str, str]:
    """(arrow, words) for the direction the centre of mass moved along x over the scene, e.g.
    ("→", "+x 14 cm"); ("", "") if it did not move."""
    dx = scene.dx
    if not np.isfinite(dx) or abs(dx) < 1e-4:
        return "", ""
    d = abs(dx)
    size = f"{d:.3g} m" if d >= 1 else f"{d * 100:.3g} cm" if d >= 0.01 else f"{d * 1000:.3g} mm"
    return ("→" if dx > 0 else "←"), f"{'+' if dx > 0 else '-'}x {size}"


def draw_legend(canvas, view: View, at: tuple[float, float], size: float = 11) -> None:
    """"early ▪▪▪ late": three swatches from pale to full, right-aligned at pixel ``at``."""
    saved = canvas.view
    canvas.view = View.screen(view.width, view.height)
    x, y = at
    canvas.text((x, y), "late", draw.TEXT, size, anchor="rm")
    x -= 32
    for k in range(3):
        fade = FADE_OLDEST * (1 - k / 2)
        colour = mix(draw.ROOT, draw.BACKGROUND, fade)
        canvas.rect((x - 12 * (3 - k), y - 4, x - 12 * (3 - k) + 9, y + 4), colour, True)
    canvas.text((x - 42, y), "early", draw.TEXT, size, anchor="rm")
    canvas.view = saved


def draw_strobe(canvas, scene, view: View, shots: Exposures, labels: bool = True, overlays: bool = True) -> None:
    """Multi-exposure of ``scene`` at ``shots.frames`` on ``canvas`` through ``view``; ``labels``:
    distance labels on the ground; ``overlays``: Δt (and the thinning), title and scale bar."""
    canvas.view = view
    sizes = draw.Sizes.for_view(view, scene.size())
    draw.draw_ground(canvas, scene, view, labels=labels)
    draw.draw_follow_path(canvas, scene)
    draw.draw_trail(canvas, scene, scene.n_frames - 1)
    idx = shots.frames
    n = len(idx)
    fades = [0.0 if j == n - 1 else FADE_OLDEST * (1.0 - j / max(n - 1, 1)) ** 0.8 for j in range(n)]
    for j, f in enumerate(idx):
        draw.draw_follow_point(canvas, scene, f, sizes, fades[j])
        draw.draw_pose(canvas, scene, f, sizes, fade=fades[j], detail=True, com=False, head=False)
    # every pose's head over all the bodies (a later body would hide an earlier head: a creature
    # moving along itself crawls over where its head was), then the newest centre of mass
    for f, fade in zip(idx, fades):
        draw.draw_head(canvas, scene, f, sizes, fade)
    draw.draw_com(canvas, scene, idx[-1], sizes)
    if overlays:
        what = f"t = {scene.t[idx[0]]:.2f} s"
        if n > 1:
            thin = f", thinned to poses ≥ {draw.fmt_length(shots.gap)} apart" if shots.thinned else ""
            what = f"Δt = {shots.step:.2f} s{thin}  ({n} exposures over {scene.duration:.1f} s)"
        arrow, words = motion(scene)
        if arrow:
            what += f"   moved {arrow} {words}"
        draw.draw_label(canvas, view, what, "tl", 13)
        draw.draw_label(canvas, view, scene.title, "tr", 12, draw.MUTED)
        draw.draw_scale_bar(canvas, view)
        if n > 1:
            draw_legend(canvas, view, (view.width - 12, view.height - 16))


def strobe(scene, width: int = 1000, n: int | None = None, nodes: bool = False):
    """The strobe picture of ``scene`` (a PIL image)."""
    w = even(width)
    h = strobe_height(scene, w)
    view = fixed_view(scene, w, h)
    shots = plan_exposures(scene, n)
    total = h + (even(draw.panel_height(scene, w)) if nodes else 0)
    canvas = PillowCanvas(w, total, draw.BACKGROUND, view)
    draw_strobe(canvas, scene, view, shots)
    if nodes:
        draw.draw_panel(canvas, scene, (0, h, w, total), shots.frames)
    return canvas.image()


def write_strobe(scene, path: str, width: int = 1000, n: int | None = None, nodes: bool = False) -> dict:
    """Write the strobe picture of ``scene`` as PNG; returns its path, size (px), the number of
    exposures and their spacing: ``step_s`` (s) and ``gap_m`` (m, 0 unless thinned)."""
    im = strobe(scene, width, n, nodes)
    im.save(path, format="PNG", optimize=False)
    shots = plan_exposures(scene, n)
    return {"path": path, "size": im.size, "exposures": len(shots.frames), "step_s": shots.step, "gap_m": shots.gap}


# ------------------------------------------------------------------------------ contact sheet

HEADER = 34
TILE_EXPOSURES = 12
LABEL = 22
GAP = 2


def sheet_layout(n: int, width: int = 1200) -> dict:
    """Grid of a contact sheet of ``n`` tiles: cols, rows, tile size (label strip included),
    the header's height, and each tile's pixel box (x0, y0, x1, y1)."""
    cols = 1 if n <= 1 else 2 if n <= 8 else 3
    rows = max(1, math.ceil(n / cols))
    tw = (width - GAP * (cols + 1)) // cols
    th = LABEL + even(int(0.42 * tw))
    boxes = []
    for k in range(n):
        r, c = divmod(k, cols)
        x0 = GAP + c * (tw + GAP)
        y0 = HEADER + GAP + r * (th + GAP)
        boxes.append((x0, y0, x0 + tw, y0 + th))
    height = HEADER + GAP + rows * (th + GAP)
    return {"cols": cols, "rows": rows, "tile": (tw, th), "header": HEADER, "label": LABEL, "size": (width, height), "boxes": boxes}


def contact_sheet(tiles: list[tuple[str, object]], title: str = "", width: int = 1200):
    """One strobe tile per (label, scene), in order, on a grid; returns a PIL image."""
    from PIL import Image

    lay = sheet_layout(len(tiles), width)
    W, H = lay["size"]
    sheet = Image.new("RGB", (W, H), draw.GRID)
    head = PillowCanvas(W, HEADER, draw.BACKGROUND)
    head.text((10, HEADER / 2), title, draw.TEXT, 15, anchor="lm")
    draw_legend(head, View.screen(W, HEADER), (W - 12, HEADER / 2))
    sheet.paste(head.image(), (0, 0))
    tw, th = lay["tile"]
    fits = [fixed_view(sc, tw, th - LABEL).scale for _, sc in tiles]
    common = max(min(fits), 0.5 * float(np.median(fits))) if fits else 1.0
    for (label, sc), (x0, y0, _, _) in zip(tiles, lay["boxes"]):
        pic = fixed_view(sc, tw, th - LABEL, scale=common)
        # the tile's view: the picture's, extended up over the label strip
        inner = View(pic.x0, pic.y0, pic.x1, pic.y1 + LABEL / pic.scale, tw, th)
        canvas = PillowCanvas(tw, th, draw.BACKGROUND, inner)
        draw_strobe(canvas, sc, inner, plan_exposures(sc, most=TILE_EXPOSURES), labels=False, overlays=False)
        canvas.view = View.screen(tw, th)
        canvas.rect((0, 0, tw, LABEL), draw.BACKGROUND, True)
        canvas.segment((0, LABEL - 0.5), (tw, LABEL - 0.5), 1.0, draw.GRID)
        arrow, _ = motion(sc)
        canvas.text((8, LABEL / 2 + 1), f"{label} {arrow}".rstrip(), draw.TEXT, 12, anchor="lm")
        draw.draw_scale_bar(canvas, inner, (tw - 10, LABEL / 2 + 1), 11)  # in the label strip
        sheet.paste(canvas.image(), (x0, y0))
    return sheet
