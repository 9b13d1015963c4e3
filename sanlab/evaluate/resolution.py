"""Does the step resolve a creature's servos? (issue 28: a gait the integrator powers must not rank)

The step integrates every stiff term implicitly (``sanlab.sim.dynamics``), so a servo of any
stiffness stays stable at dt = 1 ms. Stable is not resolved: an underdamped PD servo
(damping ratio zeta < 1) oscillates at omega = sqrt(ks / I), and once omega dt > 1 the step
cannot follow that oscillation (fewer than about six steps a period); the implicit step then
damps what the equations say rings, and the numbers it gives are the integrator's, not the
creature's. Measured: the built-in bounder with every link at 1 g, ks = 1e6 N m/deg and kd = 0
(omega dt of several hundred) scored 250 m/s under ``--metric distance``, and dt/4 sped its
gaits up further (energy from nowhere). An overdamped servo (zeta >= 1) is different: it
settles within a step at any stiffness, and the implicit step settles it too, so it is not
flagged however stiff.

I is the joint's effective inertia at the start pose (``creature.geometry.joint_inertias``);
a tuned or reshaped creature's servo gains are taken per evaluation, its inertias from the file
(the check is of the servo, not the pose). The built-ins are far inside the bound (the largest
omega dt is the fish's 0.32, overdamped; the bounder's 0.10, zeta 1.9).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sanlab.creature import geometry
from sanlab.creature.spec import AngularActuator, Creature

OMEGA_DT = 1.0  # omega dt beyond which an underdamped servo is not resolved by the step


@dataclass(frozen=True)
class Servos:
    """The angular servos of a creature that move an inertia: their indices among its
    actuators [A'] and their joints' effective inertias [A'] (kg m^2)."""

    index: np.ndarray
    inertia: np.ndarray

    @classmethod
    def of(cls, spec: Creature) -> Servos:
        inertia = geometry.joint_inertias(spec)
        idx, I = [], []
        for k, a in enumerate(spec.actuators):
            if isinstance(a, AngularActuator) and math.isfinite(inertia.get(a.joint, math.inf)):
                idx.append(k)
                I.append(inertia[a.joint])
        return cls(np.asarray(idx, int), np.asarray(I, float))

    def modes(self, ks, kd) -> tuple[np.ndarray, np.ndarray]:
        """(omega [..., A'] rad/s, zeta [..., A']) for servo gains ks, kd [..., A] (SI, rad)."""
        ks = np.asarray(ks, float)[..., self.index]
        kd = np.asarray(kd, float)[..., self.index]
        omega = np.sqrt(np.maximum(ks, 0.0) / self.inertia)
        zeta = kd / np.maximum(2.0 * np.sqrt(np.maximum(ks, 0.0) * self.inertia), 1e-300)
        return omega, zeta

    def unresolved(self, ks, kd, dt: float) -> np.ndarray:
        """Whether any servo is underdamped and faster than the step resolves: bool [...] for
        gains [..., A]."""
        if not len(self.index):
            return np.zeros(np.shape(ks)[:-1], bool)
        omega, zeta = self.modes(ks, kd)
        return np.any((zeta < 1.0) & (omega * dt > OMEGA_DT), axis=-1)
