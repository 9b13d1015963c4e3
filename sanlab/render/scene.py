"""A replayed gait as plain arrays: everything the drawing code needs, computed once.

:func:`scene` replays a gait on the same kernel as the search (``Gait.replay``) and turns each
recorded frame into world placements through ``sim.poses`` (one call of the kernel for all of
them), so what is drawn is exactly what was simulated.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from sanlab.creature.spec import Creature
    from sanlab.sim.model import Model


@dataclass
class Scene:
    """One recorded rollout of one creature. F frames, L links, C contacts."""

    spec: Creature
    model: Model  # the gait's, with its parameter overrides
    t: np.ndarray  # [F] s
    links: np.ndarray  # [F, L, 3] origin x, y and absolute angle of each link frame
    contacts: np.ndarray  # [F, C, 2]
    depth: np.ndarray  # [F, C] > 0: touching
    com: np.ndarray  # [F, 2]
    u: np.ndarray  # [F, A] actuator activations
    bits: np.ndarray  # [F, S] sensor values
    nodes: np.ndarray  # [F, H + A] SAN node outputs (hidden first, then actuator nodes); a pattern's: its activations [F, A]
    n_hidden: int
    fps: float  # requested frame rate
    title: str = ""  # e.g. "3fa1c2d0/1  cart  7.3 cm/s"
    follow: np.ndarray | None = None  # [F, 2] the follow point at each frame
    follow_path: np.ndarray | None = None  # [P, 2] the whole follow spline
    scale: np.ndarray | None = None  # [L] link length scales of a gait tuned with --morphology
    com_end: np.ndarray | None = None  # [2] the centre of mass at the run's end (None: the last frame's)
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def dx(self) -> float:
        """How far the centre of mass moved along x over the whole run (m): to the run's end, not
        to the last recorded frame, so that it does not depend on the frame rate."""
        end = self.com[-1] if self.com_end is None else self.com_end
        return float(end[0] - self.com[0, 0])

    @property
    def n_frames(self) -> int:
        return int(self.t.shape[0])

    @property
    def frame_dt(self) -> float:
        """Simulated time between recorded frames (s)."""
        return float(self.t[1] - self.t[0]) if self.n_frames > 1 else 1.0 / self.fps

    @property
    def duration(self) -> float:
        """Simulated time the frames cover (s)."""
        return self.n_frames * self.frame_dt

    @property
    def plane(self) -> str:
        return self.spec.world.plane

    # -- geometry ------------------------------------------------------------------------------

    def to_world(self, frame: int, link: int, pts) -> np.ndarray:
        """Points [K, 2] in ``link``'s frame -> world, at ``frame``."""
        x, y, a = self.links[frame, link]
        c, s = np.cos(a), np.sin(a)
        p = np.asarray(pts, float).reshape(-1, 2)
        return np.stack([x + c * p[:, 0] - s * p[:, 1], y + s * p[:, 0] + c * p[:, 1]], 1)

    def shape_points(self, link: int) -> np.ndarray:
        """Outline of ``link`` in its frame [K, 2] (a point mass: its origin), scaled as tuned."""
        l = self.spec.links[link]
        pts = np.asarray(l.shape.points if l.shape.kind != "point" else [(0.0, 0.0)], float).reshape(-1, 2)
        return pts * (1.0 if self.scale is None else float(self.scale[link]))

    def attachment(self, frame: int, ref) -> tuple[float, float]:
        """World position of a PointRef (link name, point in its frame) at ``frame``."""
        i = [l.name for l in self.spec.links].index(ref.link)
        k = 1.0 if self.scale is None else float(self.scale[i])
        return tuple(self.to_world(frame, i, [np.asarray(ref.at, float) * k])[0])

    @property
    def head_link(self) -> int:
        """Index of the creature's head: the root of the first free tree (the first link with no
        parent that is not welded to the world); the first root if every root is fixed."""
        roots = [i for i, l in enumerate(self.spec.links) if l.parent is None]
        free = [i for i in roots if not self.spec.links[i].fixed]
        return (free or roots or [0])[0]

    def head_point(self) -> np.ndarray:
        """Where the head marker sits on the head link, in its frame (m) [2]: a polygon's centroid
        (of area), a point mass's origin, and on a segment the end away from the joints of the
        links hanging from it (the free end: a snake's snout, a walker's head), its first point
        when both ends are as far (or nothing hangs from it)."""
        i = self.head_link
        link = self.spec.links[i]
        pts = self.shape_points(i)
        if link.shape.kind == "polygon":
            return _centroid(pts)
        if link.shape.kind != "segment":
            return pts[0]
        k = 1.0 if self.scale is None else float(self.scale[i])
        anchors = [np.asarray(c.anchor, float) * k for c in self.spec.links if c.parent == link.name]
        if not anchors:
            return pts[0]
        mid = np.mean(anchors, 0)
        d0, d1 = (float(np.hypot(*(p - mid))) for p in pts[:2])
        return pts[1] if d1 > d0 + 1e-9 else pts[0]

    def head(self) -> np.ndarray:
        """The head marker's world position (m) in every frame: [F, 2]."""
        if "head" not in self._cache:
            i, p = self.head_link, self.head_point()
            x, y, a = (self.links[:, i, k] for k in range(3))
            c, s = np.cos(a), np.sin(a)
            self._cache["head"] = np.stack([x + c * p[0] - s * p[1], y + s * p[0] + c * p[1]], 1)
        return self._cache["head"]

    def pose_distance(self, f: int, g: int) -> float:
        """How far apart the poses of frames ``f`` and ``g`` are (m): the mean distance between the
        same outline point (every shape and contact point) in the two frames. A shift by d gives
        d; a change of shape in place counts too."""
        p = self.outline_points()
        return float(np.mean(np.hypot(*(p[g] - p[f]).T)))

    def outline_points(self) -> np.ndarray:
        """Every shape point of every link, in world coordinates, per frame: [F, K, 2]."""
        if "outline" not in self._cache:
            self._cache["outline"] = self._outline_points()
        return self._cache["outline"]

    def _outline_points(self) -> np.ndarray:
        parts = []
        for i in range(len(self.spec.links)):
            pts = self.shape_points(i)
            x, y, a = (self.links[:, i, k][:, None] for k in range(3))
            c, s = np.cos(a), np.sin(a)
            parts.append(np.stack([x + c * pts[:, 0] - s * pts[:, 1], y + s * pts[:, 0] + c * pts[:, 1]], -1))
        if self.contacts.shape[1]:
            parts.append(self.contacts)
        return np.concatenate(parts, 1)

    def bounds(self, frames=None) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of the creature over ``frames`` (default: all)."""
        p = self.outline_points()
        if frames is not None:
            p = p[frames]
        return float(p[..., 0].min()), float(p[..., 1].min()), float(p[..., 0].max()), float(p[..., 1].max())

    def size(self) -> float:
        """The creature's size (m): the largest width or height of its outline in any frame."""
        if "size" not in self._cache:
            p = self.outline_points()
            ext = p.max(1) - p.min(1)
            self._cache["size"] = float(max(ext.max(), 0.05))
        return self._cache["size"]

    def extent(self) -> tuple[float, float]:
        """The creature's largest width and largest height (m) over all frames."""
        if "extent" not in self._cache:
            p = self.outline_points()
            ext = np.maximum(p.max(1) - p.min(1), 0.02)
            self._cache["extent"] = (float(ext[:, 0].max()), float(ext[:, 1].max()))
        return self._cache["extent"]

    def terrain(self, x: np.ndarray) -> np.ndarray:
        """Ground height at ``x`` (vertical plane)."""
        from sanlab.sim import terrain_height

        h, _ = terrain_height(self.model, np.asarray(x, np.float64))
        return np.broadcast_to(np.asarray(h, float), np.shape(x)).copy()


def poses(model, q):
    """``sim.poses`` of frames q [F, D] -> dict of numpy arrays (the kernel; nothing compiled)."""
    from sanlab import sim

    return sim.poses(model, np.asarray(q, np.float64))


def follow_samples(model, t: np.ndarray) -> np.ndarray:
    """The follow point at times ``t`` [F] -> [F, 2]."""
    from sanlab import sim

    return sim.follow_point(model, np.asarray(t, np.float64).reshape(-1))


def from_result(gait, model, result, fps: float, title: str = "") -> Scene:
    """A scene from a recorded ``sim.Result`` (batch 1) of ``gait``."""
    fr = result.frames
    if fr is None or np.asarray(fr.t).shape[0] == 0:
        raise ValueError(f"too short to record a frame at {fps:g} frames per second")
    q = np.asarray(fr.q[0])
    ok = np.all(np.isfinite(q), axis=1)
    n = len(q) if ok.all() else max(1, int(np.argmin(ok)))  # keep the frames before it blew up
    if n < len(q):
        fr = cut_frames(fr, n)
        q = q[:n]
        title = (title + "  " if title else "") + f"(non-finite after t = {float(fr.t[-1]):.2f} s)"
    # the run's final state rides along in the same call (one compiled program, not two), when
    # the run stayed finite: it is where the run ended, after the last recorded frame
    q_end = np.asarray(result.state.q, q.dtype)[:1]
    with_end = bool(ok.all() and np.all(np.isfinite(q_end)))
    P = poses(model, np.concatenate([q, q_end]) if with_end else q)
    com_end = np.asarray(P["com"][-1], float) if with_end else None
    if with_end:
        P = {k: v[:-1] for k, v in P.items()}
    spec = gait.spec
    if gait.params.free is not None and spec.design is not None:  # tuned free numbers: draw that body
        spec = spec.design.creature(gait.params.free)
    follow = path = None
    if model.structure.follow:
        follow = follow_samples(model, np.asarray(fr.t))
        path = np.asarray(model.params.follow, float)
    san = gait.san
    return Scene(
        spec=spec,
        model=model,
        t=np.asarray(fr.t, float),
        links=np.asarray(P["links"], float),
        contacts=np.asarray(P["contacts"], float),
        depth=np.asarray(P["depth"], float),
        com=np.asarray(P["com"], float),
        u=np.asarray(fr.u[0], float),
        bits=np.asarray(fr.bits[0], float),
        # a pattern has no nodes: its panel shows the actuators' activations
        nodes=np.asarray(fr.u[0] if gait.kind == "pattern" else fr.cstate.out[0], float),
        n_hidden=0 if gait.kind == "pattern" else san.n_hidden,
        fps=float(fps),
        title=title,
        follow=follow,
        follow_path=path,
        scale=np.asarray(gait.params.scale, float) if gait.params.scale else None,
        com_end=com_end,
    )


def cut_frames(fr, n: int):
    """Frames (batch 1) cut to the first ``n``."""
    cut = lambda x: x if x is None or np.ndim(x) < 2 else np.asarray(x)[:, :n]
    from sanlab.sim import SanState

    cs: Any = fr.cstate
    cs = SanState(cut(cs.istate), cut(cs.out)) if isinstance(cs, SanState) else cut(cs)
    return fr._replace(t=np.asarray(fr.t)[:n], q=cut(fr.q), qd=cut(fr.qd), bits=cut(fr.bits), u=cut(fr.u), cstate=cs)


def gait_title(gait, rank: int | None = None) -> str:
    """E.g. "3fa1c2d0#17 (rank 1)  cart  7.3 cm/s (median of 8)": the stored speed, the
    ensemble's median when it has several members (the picture is one replay of them)."""
    K = gait.ensemble.members
    speed = "" if not np.isfinite(gait.speed_cm_s) else \
        f"  {gait.speed_cm_s:.1f} cm/s" + (f" (median of {K})" if K > 1 else "")
    ranked = f" (rank {rank})" if rank else ""
    kind = "  pattern" if gait.kind == "pattern" else ""  # never mistaken for a SAN
    return f"{gait.gait_id}{ranked}  {gait.spec.name}{kind}{speed}"


def scene(gait, seconds: float | None = None, fps: float = 30.0, title: str | None = None) -> Scene:
    """Replay ``gait`` for ``seconds`` (default: its run's), recording ``fps`` frames per second."""
    model = gait.model()
    result = gait.replay(seconds, fps=fps, model=model)
    return from_result(gait, model, result, fps, gait_title(gait) if title is None else title)


def _centroid(pts: np.ndarray) -> np.ndarray:
    """Centre of area of the polygon ``pts`` [K, 2] (m); the mean of its points if it has none."""
    x, y = pts[:, 0], pts[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    area = 0.5 * float(cross.sum())
    if abs(area) < 1e-12:
        return pts.mean(0)
    cx = float(((x + np.roll(x, -1)) * cross).sum()) / (6 * area)
    cy = float(((y + np.roll(y, -1)) * cross).sum()) / (6 * area)
    return np.array([cx, cy])
