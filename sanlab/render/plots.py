"""Plots of runs (matplotlib, Agg backend, PNG), from data: a run's description and its scores or
tuning trace, as read from a gait library by the caller (this module reads no library).

- :func:`plot_scores`: a run's scores sorted best first against rank (log rank axis: the paper's
  long tail, a few good controllers among many that go nowhere), with a histogram beside it.
- :func:`plot_trace`: a tuning run's score against trial, accepted trials highlighted and joined
  (the best-so-far staircase), rejected ones as small grey dots.
- :func:`plot_archive`: a repertoire as a heat map, the best score of each cell of a grid over
  two behaviour descriptors (MAP-Elites' archive, or any run's evaluations binned into it).

PNG files are deterministic (no software/date metadata).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

_METADATA = {"Software": None}


class RunInfo(Protocol):
    """What a plot says about its run (``sanlab.library.Run`` is one)."""

    @property
    def run_id(self) -> str: ...
    @property
    def kind(self) -> str: ...
    @property
    def creature(self) -> str: ...
    @property
    def metric(self) -> str | None: ...  # the score's metric
    @property
    def parent_gait(self) -> str | None: ...


class TrialInfo(Protocol):
    """One tuning trial (``sanlab.library.TracePoint`` is one)."""

    @property
    def trial(self) -> int: ...
    @property
    def score(self) -> float: ...
    @property
    def accepted(self) -> bool: ...


def _figure(w: float, h: float, ncols: int = 1, **kw: Any) -> tuple[Any, Any]:
    """(figure, axes) of ``w`` x ``h`` inches at 100 dpi: one Axes, or an array of ``ncols``."""
    from matplotlib.figure import Figure  # no pyplot: rendered by Agg, no global backend change

    fig = Figure(figsize=(w, h), dpi=100, layout="constrained")
    axes = fig.subplots(1, ncols, **kw)
    return fig, axes


def _style(ax) -> None:
    ax.grid(True, which="major", color="#dddddd", linewidth=0.8)
    ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)


def plot_scores(run: RunInfo, scores: Sequence[float], path: str, top: int = 10) -> dict:
    """The sorted phase-1 ``scores`` of ``run`` (NaN: not a number, left out) -> PNG at ``path``,
    the ``top`` best marked. Returns {"path", "points": finite scores plotted, "best"}; raises
    ValueError if no score is finite."""
    every = np.asarray(scores, float)
    finite = every[np.isfinite(every)]
    if finite.size == 0:
        raise ValueError(f"run {run.run_id} has no finite scores to plot")
    s = np.sort(finite)[::-1]
    rank = np.arange(1, s.size + 1)
    fig, (ax, hx) = _figure(9.0, 3.8, 2, width_ratios=[2.2, 1])
    ax.plot(rank, s, color="#2e75cc", linewidth=1.6)
    k = min(top, s.size)
    ax.scatter(rank[:k], s[:k], s=18, color="#f58014", zorder=3, label=f"top {k}")
    ax.set_xscale("log")
    ax.set_xlabel("rank (best first)")
    metric = run.metric or "score"
    ax.set_ylabel(f"score ({metric})")
    ax.set_title(f"run {run.run_id}: {run.creature}, {every.size} controllers", loc="left", fontsize=11)
    for q in (1, 10, 50):
        if s.size >= 10:
            v = float(np.percentile(finite, 100 - q))
            ax.axhline(v, color="#999999", linewidth=0.8, linestyle=":")
            ax.annotate(f"top {q}%", (rank[-1], v), xytext=(-2, 2), textcoords="offset points",
                        ha="right", va="bottom", fontsize=8, color="#666666")
    ax.legend(loc="upper right", frameon=False, fontsize=9)
    _style(ax)
    hx.hist(finite, bins=min(40, max(5, int(np.sqrt(finite.size)))), color="#2e75cc", alpha=0.85)
    hx.set_yscale("log")
    hx.set_xlabel(f"score ({metric})")
    hx.set_ylabel("controllers")
    nonfinite = every.size - finite.size
    hx.set_title(f"{nonfinite} non-finite left out" if nonfinite else "distribution", loc="left", fontsize=10)
    _style(hx)
    fig.savefig(path, format="png", metadata=_METADATA)
    return {"path": path, "points": int(finite.size), "best": float(s[0])}


def plot_trace(run: RunInfo, trace: Sequence[TrialInfo], path: str) -> dict:
    """A tuning ``run``'s score against trial (``trace`` in trial order) -> PNG at ``path``.
    Returns {"path", "points": trials, "accepted"}; raises ValueError for an empty trace."""
    if not trace:
        raise ValueError(f"run {run.run_id} ({run.kind}) has no tuning trace to plot")
    trial = np.array([p.trial for p in trace], float)
    score = np.array([p.score for p in trace], float)
    acc = np.array([p.accepted for p in trace], bool)
    fig, ax = _figure(8.0, 4.0)
    ok = np.isfinite(score)
    ax.scatter(trial[ok & ~acc], score[ok & ~acc], s=8, color="#b5b5b5", label="rejected", zorder=2)
    if acc.any():
        ax.step(trial[acc & ok], score[acc & ok], where="post", color="#2e75cc", linewidth=1.4, zorder=3)
        ax.scatter(trial[acc & ok], score[acc & ok], s=26, color="#f58014", edgecolor="#7a3d00", linewidth=0.5,
                   label="accepted", zorder=4)
    ax.set_xlabel("trial")
    ax.set_ylabel(f"score ({run.metric or 'score'})")
    parent = f" from {run.parent_gait}" if run.parent_gait else ""
    ax.set_title(f"run {run.run_id}: tuning {run.creature}{parent}: {int(acc.sum())} of {len(trace)} accepted",
                 loc="left", fontsize=11)
    ax.legend(loc="lower right", frameon=False, fontsize=9)
    _style(ax)
    fig.savefig(path, format="png", metadata=_METADATA)
    return {"path": path, "points": len(trace), "accepted": int(acc.sum())}


def plot_archive(run: RunInfo, names: Sequence[str], ranges: Sequence[tuple[float, float]], best: np.ndarray,
                 path: str, units: dict[str, str] | None = None) -> dict:
    """A heat map of ``best`` [bins_x, bins_y] (each cell's best score, NaN: empty) over the grid
    of descriptors ``names`` with ``ranges`` -> PNG at ``path``. Returns {"path", "cells",
    "filled", "coverage", "qd_score"}; raises ValueError for a grid that is not two-dimensional."""
    best = np.asarray(best, float)
    if best.ndim != 2 or len(names) != 2 or len(ranges) != 2:
        raise ValueError("an archive plot needs a grid of two descriptors")
    filled = np.isfinite(best)
    units = units or {}
    fig, ax = _figure(6.4, 5.0)
    (x0, x1), (y0, y1) = ranges
    img = ax.imshow(np.where(filled, best, np.nan).T, origin="lower", extent=(x0, x1, y0, y1), aspect="auto",
                    cmap="viridis", interpolation="nearest")
    fig.colorbar(img, ax=ax, label=f"best score ({run.metric or 'score'})")
    label = lambda n: f"{n} ({units[n]})" if n in units else n
    ax.set_xlabel(label(names[0]))
    ax.set_ylabel(label(names[1]))
    coverage = float(filled.mean())
    qd = float(best[filled].sum())
    ax.set_title(f"run {run.run_id}: {run.creature}, {int(filled.sum())} of {best.size} cells "
                 f"({coverage:.0%}), QD-score {qd:.3g}", loc="left", fontsize=10)
    fig.savefig(path, format="png", metadata=_METADATA)
    return {"path": path, "cells": int(best.size), "filled": int(filled.sum()), "coverage": coverage, "qd_score": qd}
