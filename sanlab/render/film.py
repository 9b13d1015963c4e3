"""Animations of a gait: GIF (Pillow) and MP4 (H.264 through imageio-ffmpeg's bundled ffmpeg).

One output frame per recorded frame. The picture is 16:9 (``width`` x ``width * 9 / 16``), plus
the SAN panel under it when ``nodes``.

Camera (``camera="auto"``, the default): the scale is fixed for the whole film, so that the
creature's largest width spans about 1/2.8 of the picture and its largest height at most 0.6 of
it: the creature is always drawn large. On each axis the camera stays put if the whole
trajectory fits at that scale, and otherwise follows the centre of mass, smoothed with a
Gaussian of 0.4 s (a centred filter: the whole trajectory is known), then nudged where needed so
that the creature never leaves the picture. On the vertical plane the ground keeps a band at the
bottom of the picture, and its distance ticks (labelled in metres) show the motion when the
camera follows. ``camera="fixed"`` fits the whole trajectory in one view (like the strobe
pictures); ``"follow"`` always follows along x (and along y too on the horizontal plane).

Timing: the rollout records a frame every round(1 / (fps dt)) simulation steps (at 30 fps and
dt = 1 ms, every 33 ms), and the film plays them at ``fps``. GIF counts time in hundredths of a
second, so 1/fps is rounded per frame such that the running total stays within 5 ms of k/fps
(at 30 fps: 30, 40, 30, 30, 40, ... ms); 25 or 50 fps are exact.

Files are deterministic: one GIF palette from a fixed sample of frames, no dithering; the MP4 is
encoded by one x264 thread with bit-exact flags and no metadata, which makes it byte-identical
from run to run with the same ffmpeg build (imageio-ffmpeg's wheel pins one).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np

from sanlab.render import draw
from sanlab.render.canvas import PillowCanvas, View

ASPECT = 9 / 16
WIDTH_RANGE = (64, 4096)  # px: a picture's width (`sanlab render --width`, the Gymnasium envs' width=)
WIDTHS_ACROSS = 2.8  # the view is this many creature widths wide ...
HEIGHT_FILL = 0.6  # ... or more, so that the creature's height fills at most this much of it
SMOOTH_S = 0.4
GROUND_BAND = 0.2  # fraction of the picture's height kept for the ground (vertical plane)


def frame_size(width: int) -> tuple[int, int]:
    """(width, height) of the picture (even numbers: H.264 wants them)."""
    w = max(64, int(width) // 2 * 2)
    return w, max(36, int(round(w * ASPECT / 2)) * 2)


def _smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    if sigma <= 0 or len(x) < 3:
        return x.copy()
    r = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    pad = np.pad(x, r, mode="edge")
    return np.convolve(pad, k, mode="valid")


def _track(centre: np.ndarray, lo: np.ndarray, hi: np.ndarray, span: float, sigma: float, follow: bool) -> np.ndarray:
    """Camera centres [F] on one axis for a view ``span`` wide that must show [lo[f], hi[f]]."""
    a, b = float(lo.min()), float(hi.max())
    if not follow and b - a <= span:
        return np.full(len(centre), 0.5 * (a + b))
    c = _smooth(centre, sigma)
    if b - a > span:
        c = np.clip(c, a + span / 2, b - span / 2)  # stay over the trajectory at both ends
    for _ in range(2):  # keep the creature in the picture, then soften the corrections
        need_lo, need_hi = hi - span / 2, lo + span / 2
        c = np.where(need_lo <= need_hi, np.clip(c, need_lo, need_hi), 0.5 * (lo + hi))
        c = _smooth(c, 0.25 * sigma)
    need_lo, need_hi = hi - span / 2, lo + span / 2
    return np.where(need_lo <= need_hi, np.clip(c, need_lo, need_hi), 0.5 * (lo + hi))


def _extents(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per frame: x and y ranges [F] of the creature (and the follow point)."""
    p = scene.outline_points()
    if scene.follow is not None:
        p = np.concatenate([p, scene.follow[:, None, :]], 1)
    return p[..., 0].min(1), p[..., 0].max(1), p[..., 1].min(1), p[..., 1].max(1)


def _y_needs(scene, ylo, yhi, h, margin):
    if scene.plane != "vertical":
        return ylo - margin, yhi + margin
    ground = scene.terrain(scene.com[:, 0])
    return np.minimum(ylo, ground) - GROUND_BAND * h, yhi + margin


def camera(scene, width: int, height: int, mode: str = "auto") -> list[View]:
    """One view per frame (see the module docstring). ``height``: the picture's, panel excluded."""
    if mode not in ("auto", "follow", "fixed"):
        raise ValueError(f"camera: expected auto, follow or fixed, got {mode!r}")
    s = scene.size()
    margin = 0.15 * s
    xlo, xhi, ylo, yhi = _extents(scene)
    F = scene.n_frames
    if mode == "fixed":
        return [fixed_view(scene, width, height)] * F
    cw, ch = scene.extent()
    w = max(WIDTHS_ACROSS * cw, ch / HEIGHT_FILL * width / height)
    h = w * height / width
    step = scene.t[1] - scene.t[0] if F > 1 else 1.0
    sigma = SMOOTH_S / step
    follow = mode == "follow"
    cx = _track(scene.com[:, 0], xlo - margin, xhi + margin, w, sigma, follow)
    lo, hi = _y_needs(scene, ylo, yhi, h, margin)
    if scene.plane == "vertical" and hi.max() - lo.min() <= h:
        cy = np.full(F, lo.min() + h / 2)  # ground band at the bottom, sky above
    else:  # the vertical plane follows in y only where it must (slopes, high jumps)
        cy = _track(scene.com[:, 1], lo, hi, h, sigma, follow and scene.plane != "vertical")
    return [View.centred(float(x), float(y), w, width, height) for x, y in zip(cx, cy)]


def content_box(scene, frames=None) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) (m) that a fixed view of ``scene`` over ``frames`` (default: all) must
    show: the creature (and follow point) with a margin, down to the ground on the vertical
    plane."""
    s = scene.size()
    margin = 0.15 * s
    xlo, xhi, ylo, yhi = _extents(scene)
    if frames is not None:
        xlo, xhi, ylo, yhi = xlo[frames], xhi[frames], ylo[frames], yhi[frames]
    x0, x1 = float(xlo.min()) - margin, float(xhi.max()) + margin
    y0, y1 = float(ylo.min()) - margin, float(yhi.max()) + margin
    if scene.plane == "vertical":
        y0 = min(float(ylo.min()), float(np.min(scene.terrain(np.linspace(x0, x1, 64)))))
    return x0, y0, x1, y1


def fixed_view(scene, width: int, height: int, frames=None, scale: float | None = None) -> View:
    """One view containing the creature over ``frames`` (default: all), with the ground band
    on the vertical plane. ``scale`` (px/m): use it where the trajectory fits, else fit. Room
    the content does not fill is shared equally above and below it (on the vertical plane: half
    to the sky, half to the ground), so the drawing sits in the middle of the picture rather
    than under a band of empty sky."""
    x0, y0, x1, y1 = content_box(scene, frames)
    band = GROUND_BAND if scene.plane == "vertical" else 0.0
    fit = min(width / (x1 - x0), height * (1 - band) / (y1 - y0))
    k = fit if scale is None else min(scale, fit)
    w, h = width / k, height / k
    cx = 0.5 * (x0 + x1)
    used = (y1 - y0) / (1 - band)  # the content and its ground band
    spare = max(0.0, h - used)
    bottom = y0 - band * used - 0.5 * spare
    return View(cx - w / 2, bottom, cx + w / 2, bottom + h, width, height)


def frames(scene, width: int = 640, nodes: bool = False, camera_mode: str = "auto") -> Iterator:
    """The film's pictures (PIL images), one per recorded frame."""
    w, h = frame_size(width)
    views = camera(scene, w, h, camera_mode)
    total = h + (even(draw.panel_height(scene, w)) if nodes else 0)
    for f, view in enumerate(views):
        canvas = PillowCanvas(w, total, draw.BACKGROUND, view)
        draw.draw_frame(canvas, scene, f, view, nodes=nodes)
        yield canvas.image()


def even(n: int) -> int:
    return int(n) + (int(n) % 2)


def gif_durations(n: int, fps: float) -> list[int]:
    """Per-frame durations (ms, multiples of 10) whose running sum tracks k * 1000 / fps."""
    ends = [int(round((k + 1) * 100.0 / fps)) * 10 for k in range(n)]
    return [max(10, e - b) for e, b in zip(ends, [0] + ends[:-1])]


def write_gif(path: str, images: list, fps: float) -> None:
    from PIL import Image

    if not images:
        raise ValueError("no frames to write")
    # one palette for the whole film, from up to 12 evenly spread frames
    pick = np.unique(np.linspace(0, len(images) - 1, min(12, len(images))).round().astype(int))
    w, h = images[0].size
    sample = Image.new("RGB", (w, h * len(pick)))
    for k, i in enumerate(pick):
        sample.paste(images[i], (0, k * h))
    pal = sample.quantize(colors=255, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    frames_p = [im.quantize(palette=pal, dither=Image.Dither.NONE) for im in images]
    frames_p[0].save(
        path, format="GIF", save_all=True, append_images=frames_p[1:], duration=gif_durations(len(images), fps),
        loop=0, optimize=False, disposal=1,
    )


MP4_PARAMS = [
    "-preset", "medium", "-tune", "animation", "-threads", "1", "-x264-params", "threads=1",
    "-fflags", "+bitexact", "-flags:v", "+bitexact", "-map_metadata", "-1", "-movflags", "+faststart",
]  # fmt: skip


def write_mp4(path: str, images, fps: float, size: tuple[int, int]) -> int:
    """H.264 (yuv420p, crf 18) at ``fps``; returns the number of frames written.

    Runs imageio-ffmpeg's bundled ffmpeg itself, with the command imageio-ffmpeg's
    ``write_frames`` would build, but started in its own process group by ``process_group=0``
    rather than by a Python ``preexec_fn``: that runs no Python in the forked child, so Ctrl-C
    still reaches only sanlab and no library's warning that ``os.fork()`` may deadlock can fire.
    Raises OSError with ffmpeg's last message if it fails (a full disk, a bad path)."""
    import subprocess
    from fractions import Fraction

    import imageio_ffmpeg

    cmd = [
        imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{size[0]}x{size[1]}",
        "-pix_fmt", "rgb24", "-r", str(Fraction(float(fps)).limit_denominator()), "-i", "-",
        "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-v", "error", "-crf", "18", *MP4_PARAMS, path,
    ]  # fmt: skip
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            process_group=0)
    assert proc.stdin is not None and proc.stderr is not None
    n = 0
    try:
        for im in images:
            proc.stdin.write(np.ascontiguousarray(np.asarray(im.convert("RGB"), np.uint8)).tobytes())
            n += 1
        proc.stdin.close()
    except BrokenPipeError:
        pass  # ffmpeg stopped reading: its message says why
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    err = proc.stderr.read().decode("utf-8", "replace").strip()
    if proc.wait() != 0:
        last = err.splitlines()[-1] if err else f"exit status {proc.returncode}"
        raise OSError(f"ffmpeg could not write {path}: {last}")
    return n


def animate(scene, path: str, width: int = 640, nodes: bool = False, camera_mode: str = "auto") -> dict:
    """Write ``scene`` as .gif or .mp4 (by extension); returns a summary dict."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".gif", ".mp4"):
        raise ValueError(f"{path}: expected a .gif or .mp4 file name")
    pics = frames(scene, width, nodes, camera_mode)
    first = next(pics)
    size = first.size

    def all_pics():
        yield first
        yield from pics

    if ext == ".gif":
        imgs = list(all_pics())
        write_gif(path, imgs, scene.fps)
        n = len(imgs)
    else:
        n = write_mp4(path, all_pics(), scene.fps, size)
    return {"path": path, "frames": n, "size": size, "fps": scene.fps, "seconds": n / scene.fps}
