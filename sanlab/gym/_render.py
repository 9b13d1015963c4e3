"""``render_mode="rgb_array"``: a picture of one row's current state, drawn by sanlab's own
drawing code (``sanlab.render.draw``) as an animation frame of ``sanlab render`` is.

The scale is fixed when the environment is made (the creature's largest width spans 1/2.8 of
the picture, as in ``sanlab.render.film``), the camera follows the centre of mass along x (and
along y in the horizontal plane) with the ground at the bottom of the picture, and the centre
of mass's path since the last reset is drawn behind the creature.
"""

from __future__ import annotations

import numpy as np

from sanlab.render import draw, film
from sanlab.render.canvas import PillowCanvas, View
from sanlab.render.scene import Scene, follow_samples, poses


class Renderer:
    """Pictures of ``model``'s creature, ``width`` x ``width * 9 / 16`` pixels (even sizes)."""

    def __init__(self, model, width: int = 640):
        self.model = model
        self.spec = model.spec
        self.width, self.height = film.frame_size(width)
        self.follow_path = np.asarray(model.params.follow, float) if model.structure.follow else None
        start = self.scene(np.asarray(model.params.q0)[None], 0.0)
        cw, ch = start.extent()
        self.span = max(film.WIDTHS_ACROSS * cw, ch / film.HEIGHT_FILL * self.width / self.height)
        self.size = start.size()

    def scene(self, q: np.ndarray, t: float) -> Scene:
        """A one-frame scene of coordinates q [1, D] at time t (s)."""
        P = poses(self.model, q)
        S, A = len(self.spec.sensors), len(self.spec.actuators)
        follow = follow_samples(self.model, np.array([t])) if self.follow_path is not None else None
        return Scene(spec=self.spec, model=self.model, t=np.array([t]), links=np.asarray(P["links"], float),
                     contacts=np.asarray(P["contacts"], float), depth=np.asarray(P["depth"], float),
                     com=np.asarray(P["com"], float), u=np.full((1, A), 0.5), bits=np.zeros((1, S)),
                     nodes=np.zeros((1, 0)), n_hidden=0, fps=30.0, follow=follow, follow_path=self.follow_path)

    def frame(self, q: np.ndarray, t: float, u: np.ndarray | None, trail: np.ndarray) -> np.ndarray:
        """The picture [H, W, 3] uint8 of coordinates q [D] at time t (s) under activations u [A]
        (None: none yet), with the centre of mass's path ``trail`` [F, 2] (m)."""
        sc = self.scene(np.asarray(q)[None], t)
        if u is not None:
            sc.u = np.asarray(u, float)[None]
        w, h = self.span, self.span * self.height / self.width
        cx, cy = float(sc.com[0, 0]), float(sc.com[0, 1])
        if sc.plane == "vertical":
            cy = float(sc.terrain(np.array([cx]))[0]) - film.GROUND_BAND * h + h / 2 - 0.15 * self.size
        view = View.centred(cx, cy, w, self.width, self.height)
        canvas = PillowCanvas(self.width, self.height, draw.BACKGROUND, view)
        sizes = draw.Sizes.for_view(view, self.size)
        draw.draw_ground(canvas, sc, view)
        draw.draw_follow_path(canvas, sc)
        if len(trail) > 1:
            canvas.polyline([tuple(p) for p in trail[:: max(1, len(trail) // 2000)]], 1.5, draw.TRAIL)
        draw.draw_pose(canvas, sc, 0, sizes)
        draw.draw_follow_point(canvas, sc, 0, sizes)
        draw.draw_label(canvas, view, f"t = {t:.2f} s", "tl", 14)
        draw.draw_label(canvas, view, self.spec.name, "tr", 12, draw.MUTED)
        draw.draw_scale_bar(canvas, view)
        return np.asarray(canvas.image().convert("RGB"), dtype=np.uint8)
