"""Rendering gaits: animations, strobe pictures and the canvas, from scenes (data).

The scene is one gait of a tiny seeded search on the cart (the ``lib_run`` and ``scene1``
fixtures in ``tests/conftest.py``); every replay uses the same duration and frame rate so that
the rollout compiles once. The ``sanlab render`` command, contact sheets of a run and plots are
tested in ``tests/cli/test_render.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from sanlab.render import draw, film, strobe
from sanlab.render.canvas import PillowCanvas, View
from tests.helpers import FPS


def _close(pixel, color, tol=40) -> bool:
    return float(np.abs(np.asarray(pixel[:3], float) - np.asarray(color, float)).max()) <= tol


def _near(img: np.ndarray, u: float, v: float, color, r: int = 1, tol: int = 40) -> bool:
    """Some pixel within r of (u, v) has ``color``."""
    i, j = int(v), int(u)
    patch = img[max(0, i - r) : i + r + 1, max(0, j - r) : j + r + 1].reshape(-1, 3)
    return any(_close(p, color, tol) for p in patch)


def _axis(scene) -> tuple[np.ndarray, np.ndarray]:
    """The ends of the root link's long axis (link frame): a segment's two points, or the cart's
    outline's A and B (vertices 0 and 2 of A, D, B, C: cart.toml), inside the filled outline."""
    p = scene.shape_points(0)
    return p[0], p[len(p) // 2]


def _root_samples(scene, frame: int, view: View):
    """Pixels on the root link (L1) at 30 %, 50 % and 70 % of its long axis."""
    a, b = _axis(scene)
    pts = scene.to_world(frame, 0, [a + t * (b - a) for t in (0.3, 0.5, 0.7)])
    return list(zip(*view.px(pts[:, 0], pts[:, 1])))


def _far_pixel(scene, frame: int, view: View):
    """A pixel of the sky at least 40 px from every point of the creature and off the labels."""
    pts = scene.outline_points()[frame]
    u, v = view.px(pts[:, 0], pts[:, 1])
    ground_v = view.px(0.0, float(scene.terrain(np.array([view.x0]))[0]))[1]
    for vv in range(40, int(ground_v) - 20, 10):
        for uu in range(20, view.width - 20, 10):
            if np.min(np.hypot(u - uu, v - vv)) > 40:
                return uu, vv
    raise AssertionError("no free sky in the picture")


# --------------------------------------------------------------------------- animations


def test_gif_has_every_frame_at_the_requested_rate(scene1, tmp_path):
    path = tmp_path / "a.gif"
    info = film.animate(scene1, str(path), width=320)
    assert scene1.n_frames == 30  # 1 s at 30 fps (a frame every 33 steps of 1 ms)
    with Image.open(path) as im:
        assert im.n_frames == scene1.n_frames == info["frames"]
        assert im.size == (320, 180)
        durations = []
        for k in range(im.n_frames):
            im.seek(k)
            durations.append(im.info["duration"])
    assert set(durations) <= {30, 40}  # GIF counts hundredths: 1/30 s alternates 30 and 40 ms
    for k in range(1, len(durations) + 1):  # and the running total keeps to k / fps
        assert abs(sum(durations[:k]) - k * 1000 / FPS) <= 5
    assert film.gif_durations(5, 25.0) == [40] * 5
    assert film.gif_durations(4, 100.0) == [10] * 4


# Reading the film back with imageio-ffmpeg forks with a Python pre-exec hook, which JAX warns
# about; writing it (sanlab's own) does not (test_mp4_export_gives_no_fork_warning).
@pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")
def test_mp4_has_every_frame(scene1, tmp_path):
    import imageio_ffmpeg

    path = tmp_path / "a.mp4"
    film.animate(scene1, str(path), width=320)
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(meta["size"][1], meta["size"][0], 3) for f in reader]
    assert len(frames) == scene1.n_frames
    assert tuple(meta["size"]) == (320, 180) and meta["codec"] == "h264"
    assert meta["fps"] == pytest.approx(FPS)
    # the first picture survives the encoding: the background colour in the sky corner
    assert _close(frames[0][40, 160], draw.BACKGROUND, 8)


def test_the_creature_is_drawn_where_the_trajectory_says(scene1, tmp_path):
    path = tmp_path / "a.gif"
    film.animate(scene1, str(path), width=480)
    w, h = film.frame_size(480)
    views = film.camera(scene1, w, h)
    last = scene1.n_frames - 1
    assert not np.allclose(scene1.links[0, 0], scene1.links[last, 0])  # it did move
    with Image.open(path) as im:
        for f in (0, last):
            im.seek(f)
            img = np.asarray(im.convert("RGB"))
            hits = [_near(img, u, v, draw.ROOT) for u, v in _root_samples(scene1, f, views[f])]
            assert sum(hits) >= 2, (f, hits)
            u, v = _far_pixel(scene1, f, views[f])
            assert _close(img[v, u], draw.BACKGROUND, 6), (f, img[v, u])
            assert not _near(img, u, v, draw.ROOT, r=3)


@pytest.mark.parametrize("mode", ["auto", "follow", "fixed"])
def test_the_camera_keeps_the_creature_in_the_picture(scene1, mode):
    w, h = film.frame_size(320)
    views = film.camera(scene1, w, h, mode)
    assert len(views) == scene1.n_frames
    pts = scene1.outline_points()
    for f, view in enumerate(views):
        assert view.width == w and view.height == h
        assert view.scale == pytest.approx(views[0].scale)  # one scale for the whole film
        u, v = view.px(pts[f, :, 0], pts[f, :, 1])
        assert u.min() >= 0 and u.max() <= w and v.min() >= 0 and v.max() <= h


def test_nodes_panel_adds_a_raster_under_the_picture(scene1):
    pic = next(film.frames(scene1, 320, nodes=True))
    w, h = film.frame_size(320)
    assert pic.size[0] == w and pic.size[1] == h + film.even(draw.panel_height(scene1, w))
    panel = np.asarray(pic)[h:]
    on = scene1.nodes[:, scene1.n_hidden :].any()
    assert on == any(_close(p, draw.NODE_ACTUATOR, 30) for p in panel.reshape(-1, 3)[::3])


def test_canvas_maps_world_to_pixels_with_y_up():
    v = View.fit((0.0, 0.0, 2.0, 1.0), 200, 100)
    assert v.scale == pytest.approx(100.0)
    assert v.px(0.0, 0.0) == (pytest.approx(0.0), pytest.approx(100.0))
    assert v.px(2.0, 1.0) == (pytest.approx(200.0), pytest.approx(0.0))
    c = PillowCanvas(200, 100, (255, 255, 255), v)
    c.segment((0.5, 0.25), (1.5, 0.25), 6, (255, 0, 0))
    c.circle((1.0, 0.75), 5, (0, 0, 255))
    img = np.asarray(c.image())
    assert tuple(img[75, 100]) == (255, 0, 0) and tuple(img[25, 100]) == (0, 0, 255)
    assert tuple(img[50, 100]) == (255, 255, 255)


# --------------------------------------------------------------------------- strobe and sheet


def test_strobe_draws_the_newest_pose_in_full(scene1, tmp_path):
    path = tmp_path / "s.png"
    info = strobe.write_strobe(scene1, str(path), width=800)
    idx = strobe.exposures(scene1)
    assert idx[0] == 0 and idx[-1] == scene1.n_frames - 1 and len(idx) == info["exposures"]
    assert strobe.MIN_EXPOSURES <= len(idx) <= strobe.MAX_EXPOSURES
    with Image.open(path) as im:
        assert im.size == (800, strobe.strobe_height(scene1, 800))
        img = np.asarray(im.convert("RGB"))
    view = film.fixed_view(scene1, *img.shape[1::-1])
    hits = [_near(img, u, v, draw.ROOT, tol=12) for u, v in _root_samples(scene1, idx[-1], view)]
    assert sum(hits) >= 2, hits
    oldest = draw.mix(draw.ROOT, draw.BACKGROUND, strobe.FADE_OLDEST)  # the first pose, faded
    assert any(_near(img, u, v, oldest, tol=12) for u, v in _root_samples(scene1, 0, view))


def test_too_short_to_record_a_frame_is_an_error():
    from types import SimpleNamespace

    from sanlab.render.scene import from_result

    with pytest.raises(ValueError, match="too short to record a frame at 30 frames per second"):
        from_result(None, None, SimpleNamespace(frames=None), 30.0)


def test_link_outlines_follow_tuned_length_scales(scene1):
    import dataclasses

    big = dataclasses.replace(scene1, scale=np.array([2.0, 1.0]), _cache={})
    assert np.allclose(big.shape_points(0), 2 * scene1.shape_points(0))
    assert np.allclose(big.shape_points(1), scene1.shape_points(1))
    ends = big.to_world(0, 0, np.stack(_axis(big)))
    assert np.hypot(*(ends[1] - ends[0])) == pytest.approx(2 * 0.136, rel=1e-5)  # L1's axis is 13.6 cm long
    assert big.outline_points().shape == scene1.outline_points().shape


def test_mp4_export_gives_no_fork_warning(scene1, tmp_path):
    import warnings

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        film.animate(scene1, str(tmp_path / "a.mp4"), width=160)
    assert not [w for w in seen if "fork" in str(w.message)], [str(w.message) for w in seen]


def test_mp4_errors_are_oserrors_with_ffmpegs_reason(scene1, tmp_path):
    with pytest.raises(OSError, match="ffmpeg could not write"):
        film.animate(scene1, str(tmp_path / "missing" / "a.mp4"), width=160)


def test_the_raster_names_every_row_as_the_creature_file_does(scene1):
    groups = draw.panel_rows(scene1)
    names = [n for g in groups for n in g[3]]
    spec = scene1.spec
    assert names == [s.name for s in spec.sensors] + [f"H{i + 1}" for i in range(spec.n_hidden)] + [a.name for a in spec.actuators]
    assert draw._row_h(len(names)) == draw.NAME_H  # tall enough to read each name


def test_a_strobe_fits_what_moves(scene1):
    w = 1000
    h = strobe.strobe_height(scene1, w)
    x0, y0, x1, y1 = film.content_box(scene1)
    want = w * (y1 - y0) / (1 - film.GROUND_BAND) / (x1 - x0)
    assert h == film.even(int(np.clip(want, 0.2 * w, 0.8 * w)))
    view = film.fixed_view(scene1, w, h)
    assert view.y1 - y1 <= 0.02 * (view.y1 - view.y0) + 1e-9  # no band of empty sky above it
    tall = film.fixed_view(scene1, w, w)  # a taller picture than it needs: the room is shared
    used = (y1 - y0) / (1 - film.GROUND_BAND)
    above, below = tall.y1 - y1, (y0 - film.GROUND_BAND * used) - tall.y0
    assert above == pytest.approx(below) and above > 0


def test_strobes_say_which_way_it_moved_and_that_pale_is_early(scene1):
    import dataclasses

    from sanlab.render.canvas import mix

    assert scene1.com_end is not None  # the run's own end, after the last recorded frame
    for shift, arrow, words in ((0.2, "→", "+x 20 cm"), (-0.05, "←", "-x 5 cm"), (0.0, "", "")):
        end = scene1.com[0] + np.array([shift, 0.0])
        assert strobe.motion(dataclasses.replace(scene1, com_end=end, _cache={})) == (arrow, words)
        com = scene1.com.copy()  # without a final state, the last frame stands for the end
        com[-1, 0] = com[0, 0] + shift
        assert strobe.motion(dataclasses.replace(scene1, com=com, com_end=None, _cache={})) == (arrow, words)
    img = np.asarray(strobe.strobe(scene1, 800).convert("RGB"))
    corner = img[-30:, -140:].reshape(-1, 3)
    assert any(_close(p, draw.ROOT, 12) for p in corner)  # the legend's darkest swatch ...
    assert any(_close(p, mix(draw.ROOT, draw.BACKGROUND, strobe.FADE_OLDEST), 12) for p in corner)  # ... its palest


# --------------------------------------------------------------------------- head and thinning

# A top-view snake (docs/top-view-snake.md) of twelve 10 cm segments, the head s0 drawn backwards
# so that its first point is the snout; its scenes below are made by hand (no simulation).
SNAKE = """\
name = "snake12"
[world]
plane = "horizontal"
[[links]]
name = "s0"
mass = 0.05
shape = "segment"
points = [[0, 0], [-0.1, 0]]
[[repeat]]
count = 11
[[repeat.links]]
name = "s{i}"
parent = "s{i-1}"
mass = 0.05
shape = "segment"
points = [[0, 0], [-0.1, 0]]
anchor = [-0.1, 0]
[[repeat.sensors]]
name = "straight{i}"
type = "angle"
link = "s{i}"
min_deg = -10
max_deg = 10
[[repeat.actuators]]
name = "m{i}"
type = "angular"
joint = "s{i}"
min_deg = -40
max_deg = 40
ks = 0.01
kd = 0.001
"""


def _snake_scene(head_x, seconds: float = 4.0, wave: float = 0.05):
    """The 12-link snake, its head at (head_x(t), 0) heading along +x, a bending wave of
    ``wave`` rad running down its joints; every frame at ``FPS``."""
    from sanlab.creature import loads
    from sanlab.render.scene import Scene

    spec = loads(SNAKE)
    t = np.arange(int(seconds * FPS) + 1) / FPS
    F, L = len(t), len(spec.links)
    links = np.zeros((F, L, 3))
    links[:, 0, 0] = head_x(t)
    for i in range(1, L):  # each joint at the tail of the one before, bent by the wave
        x, y, a = links[:, i - 1].T
        links[:, i] = np.stack([x - 0.1 * np.cos(a), y - 0.1 * np.sin(a), a + wave * np.sin(2 * np.pi * (t - i / 6))], 1)
    com = links[:, :, :2].mean(1) - 0.05 * np.stack([np.cos(links[:, :, 2]), np.sin(links[:, :, 2])], -1).mean(1)  # mid-segments
    contacts = np.zeros((F, 0, 2))
    S, A = len(spec.sensors), len(spec.actuators)
    return Scene(spec=spec, model=None, t=t, links=links, contacts=contacts, depth=np.zeros((F, 0)), com=com,  # type: ignore[arg-type]
                 u=np.zeros((F, A)), bits=np.zeros((F, S)), nodes=np.zeros((F, A)), n_hidden=0, fps=FPS, title="snake12")


def test_the_head_is_the_free_end_of_the_first_root(scene1):
    snake = _snake_scene(lambda t: 0.05 * t)
    assert snake.head_link == 0 and np.allclose(snake.head_point(), (0.0, 0.0))  # the snout, not the neck
    assert np.allclose(snake.head()[:, 0], 0.05 * snake.t) and np.allclose(snake.head()[:, 1], 0.0)
    # the cart's root is a body: the marker sits at its centroid of area, inside its outline
    c = scene1.head_point()
    from matplotlib.path import Path

    assert scene1.head_link == 0 and Path(scene1.shape_points(0)).contains_point(c)
    assert np.allclose(scene1.head()[0], scene1.to_world(0, 0, [c])[0])


def test_films_and_strobes_mark_the_head(scene1):
    """The head marker's colour at the head's pixel: in a film frame, and in a strobe picture at
    every exposure (faded as its pose is), over the bodies of the later poses."""
    pic = np.asarray(next(film.frames(scene1, 480)).convert("RGB"))
    w, h = film.frame_size(480)
    u, v = film.camera(scene1, w, h)[0].px(*scene1.head()[0])
    assert _near(pic, float(u), float(v), draw.HEAD, tol=12)
    snake = _snake_scene(lambda t: 0.05 * t)
    img = np.asarray(strobe.strobe(snake, 1000).convert("RGB"))
    view = film.fixed_view(snake, *img.shape[1::-1])
    idx = strobe.exposures(snake)
    n = len(idx)
    for j, f in enumerate(idx):
        fade = 0.0 if j == n - 1 else strobe.FADE_OLDEST * (1.0 - j / max(n - 1, 1)) ** 0.8
        u, v = view.px(*snake.head()[f])
        assert _near(img, float(u), float(v), draw.mix(draw.HEAD, draw.BACKGROUND, fade), tol=12), (j, f)


def _pairs(frames):
    return [(a, b) for k, a in enumerate(frames) for b in frames[k + 1 :] if (a, b) != (frames[0], frames[-1])]


@pytest.mark.parametrize("head_x", [lambda t: 0.05 * t, lambda t: 0.05 * np.minimum(t, 4.0 - t)], ids=["ahead", "there-and-back"])
def test_a_slow_long_creature_is_thinned_to_poses_apart(head_x, tmp_path):
    """A 1.2 m snake moving 5 cm/s for 4 s: the even grid would pile 11 exposures 2 cm apart;
    what is left are poses at least a twentieth of its size from one another (and from an
    earlier pose it came back over), the first and the last always among them."""
    snake = _snake_scene(head_x)
    shots = strobe.plan_exposures(snake)
    frames = shots.frames
    assert frames[0] == 0 and frames[-1] == snake.n_frames - 1
    assert shots.step == pytest.approx(0.4)  # the even grid's Δt, which the title still gives
    assert shots.thinned and 0.05 <= shots.gap <= 0.06  # a twentieth of 1.2 m, rounded down to two digits
    assert shots.gap == pytest.approx(np.floor(strobe.MIN_SPACING * snake.size() * 1000) / 1000)  # whole mm
    assert 2 < len(frames) < strobe.MIN_EXPOSURES
    assert all(snake.pose_distance(a, b) >= shots.gap for a, b in _pairs(frames))
    assert set(frames) <= set(range(0, snake.n_frames - 1, round(0.4 * FPS))) | {snake.n_frames - 1}
    info = strobe.write_strobe(snake, str(tmp_path / "s.png"), 600)
    assert info["exposures"] == len(frames) and info["gap_m"] == shots.gap


def test_poses_apart_are_not_thinned(scene1):
    """The cart's built-in gait moves more than a twentieth of its size between exposures: its
    strobe keeps every exposure of the even grid, as before."""
    shots = strobe.plan_exposures(scene1)
    assert not shots.thinned and shots.gap == 0
    assert shots.frames == strobe.plan_exposures(scene1, n=len(shots.frames)).frames  # an explicit n is never thinned
    assert strobe.MIN_EXPOSURES <= len(shots.frames)
