"""Seeing the gaits: animations (GIF, MP4), strobe pictures and contact sheets (PNG), plots.

    from sanlab.render import animate, write_strobe
    from sanlab.render.scene import scene
    sc = scene(Gait.from_library(lib, "3fa1c2d0/1"))      # replay once, keep the poses
    animate(sc, "gait.gif"); write_strobe(sc, "gait.png")

Modules: ``canvas`` (view, the Canvas protocol and the Pillow canvas), ``draw`` (all drawing),
``scene`` (a replayed gait as arrays), ``film`` (camera and animations), ``strobe`` (strobe
pictures, contact sheets), ``plots`` (matplotlib). Everything here takes data (a gait, a scene,
scores, a trace) and reads no gait library; the ``sanlab render`` command, which does, is
``sanlab.cli.render``. Nothing heavy is imported until used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # for type checkers; at run time __getattr__ imports each on first use
    from sanlab.render.film import animate
    from sanlab.render.plots import plot_scores, plot_trace
    from sanlab.render.strobe import contact_sheet, write_strobe

__all__ = ["animate", "contact_sheet", "plot_scores", "plot_trace", "write_strobe"]


def __getattr__(name: str):
    if name == "animate":
        from sanlab.render.film import animate

        return animate
    if name in ("contact_sheet", "write_strobe"):
        from sanlab.render import strobe

        return getattr(strobe, name)
    if name in ("plot_scores", "plot_trace"):
        from sanlab.render import plots

        return getattr(plots, name)
    raise AttributeError(f"module 'sanlab.render' has no attribute {name!r}")
