"""Rows: copies of one creature that the caller steps a few steps at a time, each row with its own
state and its observer's accumulators carried from call to call (what a Gymnasium environment
steps, ``sanlab.gym``).

    rows = Rows(model, 4, observe=Metric.for_creature(spec).observe())
    rows.restart(np.ones(4, bool), q, seat=np.ones(4, bool))   # at rest, accumulators started
    rows.step(u, steps=2)                                       # activations u [4, A] held
    rows.bits(), rows.columns()["px"]                           # sensors, accumulators by name

The kernel steps a row bit for bit the same alone or in any batch, and continuing a run over
several calls is the run in one call, so a row reproduces ``sim.rollout`` of the same controller.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sanlab.sim import kernel
from sanlab.sim.model import Model
from sanlab.sim.state import packed


class Rows:
    """``n`` copies of ``model`` stepped together under held activations (see the module
    docstring). ``observe``: what to accumulate along the way (``sanlab.metrics.Metric.observe()``,
    or None). State (each [n, ...] float64, read-only between calls): ``q``, ``p``, ``qd`` (the
    velocity M(q)^-1 p) [n, D], ``anchor`` [n, C, 2], ``t`` [n] (s), ``acc`` [n, observe.size]."""

    def __init__(self, model: Model, n: int, observe: kernel.Observe | None = None):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"n: expected a number of rows >= 1, got {n!r}")
        self.model = model
        self._pk = packed(model)
        self.observe = observe
        if observe is not None:
            observe.check(self._pk)
        D, C, n = self._pk.ndof, self._pk.ci.shape[0], int(n)
        self.n = n
        self.q, self.p, self.qd = np.zeros((n, D)), np.zeros((n, D)), np.zeros((n, D))
        self.anchor, self.t = np.zeros((n, C, 2)), np.zeros(n)
        self.acc = np.zeros((n, observe.size if observe is not None else 0))

    def restart(self, mask: Any, q: Any, seat: Any) -> None:
        """Start the rows where ``mask`` [n] from coordinates q [n, D] (those rows' only), at rest
        at time 0, re-seated on the ground where ``seat`` [n] (vertical plane: every free tree
        lifted just clear of it), their accumulators started from the new state."""
        m = np.flatnonzero(np.asarray(mask, bool))
        if not len(m):
            return
        qs, anchor = kernel.start(self._pk, np.asarray(q, np.float64)[m], seat=np.asarray(seat, bool)[m])
        # zero steps from the start: the velocity, and the accumulators as a run starts them
        r = kernel.run_open(self._pk, "hold", np.zeros((len(m), self._pk.ai.shape[0])), qs, np.zeros_like(qs), anchor,
                            0, observe=self.observe)
        self.q[m], self.p[m], self.anchor[m], self.t[m], self.qd[m] = qs, 0.0, anchor, 0.0, r["qd"]
        if self.observe is not None:
            self.acc[m] = r["acc"]

    def step(self, u: Any, steps: int = 1) -> None:
        """Every row ``steps`` steps on under activations u [n, A] in [0, 1], held."""
        ob = self.observe
        r = kernel.run_open(self._pk, "hold", np.asarray(u, np.float64), self.q, self.p, self.anchor, steps, t0=self.t,
                            observe=ob, acc=self.acc if ob is not None else None)
        self.q, self.p, self.anchor, self.t, self.qd = r["q"], r["p"], r["anchor"], r["t"], r["qd"]
        if ob is not None:
            self.acc = r["acc"]

    def bits(self) -> np.ndarray:
        """The sensor values [n, S] (0.0 / 1.0) of every row's state at its time."""
        return kernel.sense(self._pk, self.q, self.t)

    def finite(self) -> np.ndarray:
        """[n] bool: each row's state finite and not blown up, as a rollout's end judges it."""
        from sanlab.sim.rollout import stayed_finite

        return stayed_finite(self.q, self.qd, self.p, self.t)

    def columns(self) -> dict[str, np.ndarray]:
        """The accumulators by name (``sim.rollout``'s observers' columns: ``sim.ACC`` [n] each,
        "duty" [n, touch sensors], "words", "times" [n, EVENTS]). Raises ValueError without an
        observer."""
        if self.observe is None:
            raise ValueError("columns: these rows accumulate nothing (Rows(..., observe=None))")
        from sanlab.sim.rollout import columns

        return columns(self.acc, self.observe)
