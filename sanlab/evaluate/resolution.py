"""Does the step resolve a creature's servos, springs and stops? (issue 28: a gait the integrator
powers must not rank; issue 48: nor one a spring powers)

The step integrates every stiff term implicitly (``docs/simulator.md``, "The step"), so a servo of any
stiffness stays stable at dt = 1 ms. Stable is not resolved: an underdamped PD servo
(damping ratio zeta < 1) oscillates at omega = sqrt(ks / I), and once omega dt > 1 the step
cannot follow that oscillation (fewer than about six steps a period); the implicit step then
damps what the equations say rings, and the numbers it gives are the integrator's, not the
creature's. Measured: the built-in bounder with every link at 1 g, ks = 1e6 N m/deg and kd = 0
(omega dt of several hundred) scored 250 m/s under ``--metric distance``, and dt/4 sped its
gaits up further (energy from nowhere). An overdamped servo (zeta >= 1) is different: it
settles within a step at any stiffness, and the implicit step settles it too, so it is not
flagged however stiff.

A joint spring, a joint stop (a one-sided spring while engaged) and a linear spring are the same
oscillator with the file's stiffness and damping (issue 48: the twolink with a 1e6 N m/deg joint
spring at a 90 degree rest angle topped a search table at 67 cm/s, 4x the built-in, unflagged),
and a linear actuator the same as an angular servo: each is checked the same way, a line against
the effective mass it moves (``creature.geometry.line_masses``).

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
from sanlab.creature.spec import AngularActuator, Creature, LinearActuator

OMEGA_DT = 1.0  # omega dt beyond which an underdamped servo, spring or stop is not resolved by the step


@dataclass(frozen=True)
class Passive:
    """A spring the file gives (a joint spring, a joint stop while engaged, a linear spring):
    what it is, its stiffness k and damping c (SI: N m/rad and N m s/rad, or N/m and N s/m)
    and the inertia it moves (kg m^2, or kg along a line)."""

    what: str
    stiffness: float
    damping: float
    inertia: float

    @property
    def omega(self) -> float:
        return math.sqrt(max(self.stiffness, 0.0) / self.inertia)

    @property
    def zeta(self) -> float:
        return self.damping / max(2.0 * math.sqrt(max(self.stiffness, 0.0) * self.inertia), 1e-300)

    def unresolved(self, dt: float) -> bool:
        return self.zeta < 1.0 and self.omega * dt > OMEGA_DT


@dataclass(frozen=True)
class Servos:
    """What the step must resolve in a creature: its servos that move an inertia (their indices
    among its actuators [A'] and the inertias they move [A']: kg m^2 at a joint, kg along a
    linear actuator's line) and the springs and stops of its file (:class:`Passive`)."""

    index: np.ndarray
    inertia: np.ndarray
    passive: tuple[Passive, ...] = ()

    @classmethod
    def of(cls, spec: Creature) -> Servos:
        inertia = geometry.joint_inertias(spec)
        lines = [(k, a) for k, a in enumerate(spec.actuators) if isinstance(a, LinearActuator)]
        masses = dict(zip([k for k, _ in lines], geometry.line_masses(spec, [(a.a, a.b) for _, a in lines])))
        idx, I = [], []
        for k, a in enumerate(spec.actuators):
            moved = inertia.get(a.joint, math.inf) if isinstance(a, AngularActuator) else masses[k]
            if math.isfinite(moved):
                idx.append(k)
                I.append(moved)
        passive = []
        for link in spec.links:
            moved = inertia.get(link.name, math.inf)
            if not math.isfinite(moved):
                continue
            if link.spring is not None:
                passive.append(Passive(f"link {link.name} spring", link.spring.stiffness, link.spring.damping, moved))
            if link.limit is not None:
                passive.append(Passive(f"link {link.name} limit", link.limit.stiffness, link.limit.damping, moved))
        for sp, m in zip(spec.springs, geometry.line_masses(spec, [(sp.a, sp.b) for sp in spec.springs])):
            if math.isfinite(m):
                passive.append(Passive(f"spring {sp.name}", sp.stiffness, sp.damping, m))
        return cls(np.asarray(idx, int), np.asarray(I, float), tuple(passive))

    def modes(self, ks, kd) -> tuple[np.ndarray, np.ndarray]:
        """(omega [..., A'] rad/s, zeta [..., A']) for servo gains ks, kd [..., A] (SI)."""
        ks = np.asarray(ks, float)[..., self.index]
        kd = np.asarray(kd, float)[..., self.index]
        omega = np.sqrt(np.maximum(ks, 0.0) / self.inertia)
        zeta = kd / np.maximum(2.0 * np.sqrt(np.maximum(ks, 0.0) * self.inertia), 1e-300)
        return omega, zeta

    def unresolved(self, ks, kd, dt: float) -> np.ndarray:
        """Whether any servo (for gains [..., A]), spring or stop is underdamped and faster than
        the step resolves: bool [...]."""
        shape = np.shape(ks)[:-1]
        if any(p.unresolved(dt) for p in self.passive):
            return np.ones(shape, bool)
        if not len(self.index):
            return np.zeros(shape, bool)
        omega, zeta = self.modes(ks, kd)
        return np.any((zeta < 1.0) & (omega * dt > OMEGA_DT), axis=-1)
