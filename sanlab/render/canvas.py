"""Where drawing lands: a view (world box in metres -> pixels, y up) and a canvas to draw on.

Geometry is given in WORLD coordinates (metres) and mapped through the canvas's current
:class:`View`; sizes (line widths, radii, text sizes) are in OUTPUT pixels, so strokes stay
readable whatever the zoom. :class:`PillowCanvas` is the one backend: it draws on an image
``supersample`` times larger and box-filters it down, which antialiases every edge.

Everything here is deterministic: the same calls give the same pixels (no system fonts: the text
uses DejaVu Sans shipped with matplotlib, or Pillow's built-in font, with Pillow's basic layout).
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol

import numpy as np

Color = tuple[int, int, int]
Point = tuple[float, float]


@dataclass(frozen=True)
class View:
    """Maps the world box [x0, x1] x [y0, y1] (m) onto ``width`` x ``height`` pixels.

    The scale is uniform (pixels per metre, along x); with ``y_up`` the world's y axis points up
    the image. Pixel (i, j) covers [i, i + 1) x [j, j + 1): :meth:`px` returns continuous
    coordinates, and ``int()`` of them is the pixel a point lands in.
    """

    x0: float
    y0: float
    x1: float
    y1: float
    width: int
    height: int
    y_up: bool = True

    @property
    def scale(self) -> float:
        """Pixels per metre."""
        return self.width / (self.x1 - self.x0)

    @classmethod
    def fit(cls, box: Sequence[float], width: int, height: int) -> "View":
        """The smallest view of aspect width:height that contains ``box`` (x0, y0, x1, y1),
        centred on it."""
        x0, y0, x1, y1 = (float(v) for v in box)
        w, h = max(x1 - x0, 1e-9), max(y1 - y0, 1e-9)
        aspect = width / height
        if w / h < aspect:
            w = h * aspect
        else:
            h = w / aspect
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        return cls(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2, int(width), int(height))

    @classmethod
    def centred(cls, cx: float, cy: float, w: float, width: int, height: int) -> "View":
        """A view ``w`` metres wide centred on (cx, cy)."""
        h = w * height / width
        return cls(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2, int(width), int(height))

    @classmethod
    def screen(cls, width: int, height: int) -> "View":
        """Identity mapping: 'world' coordinates are pixels, y down (for overlays)."""
        return cls(0.0, 0.0, float(width), float(height), int(width), int(height), y_up=False)

    def px(self, x, y):
        """World (m) -> continuous pixel coordinates (works on scalars and arrays)."""
        s = self.scale
        u = (np.asarray(x, float) - self.x0) * s
        v = (self.y1 - np.asarray(y, float)) * s if self.y_up else (np.asarray(y, float) - self.y0) * s
        return u, v



class Canvas(Protocol):
    """Everything the drawing code (``draw``, ``strobe``) calls: a second backend (SVG,
    matplotlib) implements exactly this. Positions are in the current ``view``'s coordinates
    (world metres, or output pixels under ``View.screen``); widths, radii and text sizes are in
    output pixels; colours are RGB 0-255."""

    view: View  # may be swapped at any time (overlays draw under View.screen(width, height))
    width: int  # output picture size, pixels
    height: int

    def segment(self, p0: Point, p1: Point, width: float, color: Color) -> None:
        """A thick line with round caps."""
        ...

    def polyline(self, points: Iterable[Point], width: float, color: Color) -> None:
        """Connected segments with round joins and caps."""
        ...

    def circle(self, center: Point, radius: float, color: Color, fill: bool = True, width: float = 1.0) -> None:
        """A disc, or (``fill=False``) a ring with an outline ``width`` pixels wide."""
        ...

    def polygon(self, points: Sequence[Point], color: Color, fill: bool = True, width: float = 1.0) -> None:
        """A filled polygon, or (``fill=False``) its closed outline ``width`` pixels wide."""
        ...

    def rect(self, box: tuple[float, float, float, float], color: Color, fill: bool = True, width: float = 1.0) -> None:
        """An axis-aligned rectangle (x0, y0, x1, y1)."""
        ...

    def text(self, pos: Point, string: str, color: Color, size: float, anchor: str = "la") -> None:
        """``anchor``: Pillow's two letters (horizontal l/m/r, vertical a(scender)/m/s/d)."""
        ...

    def raster(self, rgb: np.ndarray, box: tuple[float, float, float, float]) -> None:
        """An RGB array [rows, cols, 3] (uint8) stretched over the output-pixel box (x0, y0, x1, y1)."""
        ...


def mix(color: Color, other: Color, t: float) -> Color:
    """``color`` moved a fraction ``t`` of the way towards ``other``."""
    r, g, b = (int(round(a + (b - a) * t)) for a, b in zip(color, other))
    return (r, g, b)


def _font_path() -> str | None:
    spec = importlib.util.find_spec("matplotlib")
    for root in (spec.submodule_search_locations or []) if spec else []:
        path = os.path.join(root, "mpl-data", "fonts", "ttf", "DejaVuSans.ttf")
        if os.path.exists(path):
            return path
    return None


@lru_cache(maxsize=64)
def font(size: int):
    """A TrueType font of ``size`` pixels (DejaVu Sans if matplotlib is installed)."""
    from PIL import ImageFont

    path = _font_path()
    if path is not None:
        return ImageFont.truetype(path, size, layout_engine=ImageFont.Layout.BASIC)
    return ImageFont.load_default(size)


class PillowCanvas:
    """A :class:`Canvas` on a Pillow RGB image, antialiased by supersampling.

    ``view`` may be swapped at any time (``canvas.view = View.screen(w, h)`` for overlays);
    :meth:`image` returns the finished, downscaled picture.
    """

    def __init__(self, width: int, height: int, background: Color, view: View | None = None, supersample: int = 2):
        from PIL import Image, ImageDraw

        self.width, self.height, self.ss = int(width), int(height), int(supersample)
        self.background = background
        self._img = Image.new("RGB", (self.width * self.ss, self.height * self.ss), background)
        self._draw = ImageDraw.Draw(self._img)
        self.view = view if view is not None else View.screen(width, height)

    # -- coordinates -------------------------------------------------------------------------

    def _xy(self, points) -> list[tuple[float, float]]:
        pts = np.asarray(points, float).reshape(-1, 2)
        u, v = self.view.px(pts[:, 0], pts[:, 1])
        s = self.ss
        return list(zip((u * s).tolist(), (v * s).tolist()))

    # -- primitives --------------------------------------------------------------------------

    def segment(self, p0: Point, p1: Point, width: float, color: Color) -> None:
        """A thick line with round caps."""
        self.polyline([p0, p1], width, color)

    def polyline(self, points: Iterable[Point], width: float, color: Color) -> None:
        """Connected segments with round joins and caps."""
        xy = self._xy(points)
        if not xy:
            return
        w = max(1, int(round(width * self.ss)))
        if len(xy) > 1:
            self._draw.line(xy, fill=color, width=w, joint="curve")
        if w > 2:
            r = w / 2.0
            for x, y in (xy[0], xy[-1]):
                self._draw.ellipse((x - r, y - r, x + r, y + r), fill=color)

    def circle(self, center: Point, radius: float, color: Color, fill: bool = True, width: float = 1.0) -> None:
        (x, y), r = self._xy([center])[0], radius * self.ss
        box = (x - r, y - r, x + r, y + r)
        if fill:
            self._draw.ellipse(box, fill=color)
        else:
            self._draw.ellipse(box, outline=color, width=max(1, int(round(width * self.ss))))

    def polygon(self, points: Sequence[Point], color: Color, fill: bool = True, width: float = 1.0) -> None:
        xy = self._xy(points)
        if len(xy) < 2:
            return
        if fill:
            self._draw.polygon(xy, fill=color)
        else:
            self.polyline([*points, points[0]], width, color)

    def text(self, pos: Point, string: str, color: Color, size: float, anchor: str = "la") -> None:
        """``anchor``: Pillow's two letters (horizontal l/m/r, vertical a(scender)/m/s/d)."""
        (x, y) = self._xy([pos])[0]
        self._draw.text((x, y), string, fill=color, font=font(max(4, int(round(size * self.ss)))), anchor=anchor)

    def rect(self, box: tuple[float, float, float, float], color: Color, fill: bool = True, width: float = 1.0) -> None:
        """An axis-aligned rectangle (x0, y0, x1, y1) in the current view's coordinates."""
        x0, y0, x1, y1 = box
        self.polygon([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], color, fill, width)

    def raster(self, rgb: np.ndarray, box: tuple[float, float, float, float]) -> None:
        """Paste an RGB array [rows, cols, 3] stretched (nearest) over the pixel box
        (x0, y0, x1, y1) of the output image."""
        from PIL import Image

        x0, y0, x1, y1 = (int(round(v * self.ss)) for v in box)
        if x1 <= x0 or y1 <= y0:
            return
        im = Image.fromarray(np.ascontiguousarray(rgb, dtype=np.uint8), "RGB")
        self._img.paste(im.resize((x1 - x0, y1 - y0), Image.Resampling.NEAREST), (x0, y0))

    # -- result ------------------------------------------------------------------------------

    def image(self):
        """The finished picture (output size)."""
        if self.ss == 1:
            return self._img.copy()
        return self._img.reduce(self.ss)  # box filter, ss x ss pixels -> 1
