// The step of sanlab's simulator over a tile of W creatures, reading the creature as data: step()
// below names its stages in order, each a function in a header of its own that cites what it
// implements (docs/simulator.md walks them). V is the lane type (lanes.h): a GCC vector of W
// doubles, one SIMD register per value, or plain double, one creature per thread (the GPU's form
// and the tests' reference), bit for bit the same.
#pragma once
#include "contacts.h"     // the ground's normal force and stick-slip friction
#include "forces.h"       // inertial force, gravity, joint springs and stops, actuators, linear springs, water
#include "kinematics.h"   // link frames, points, Jacobian rows, link velocities
#include "lanes.h"        // the lane type, sin and cos
#include "observe.h"      // centre of mass, energy, momenta, the observers
#include "san.h"          // the sensor-actuator network
#include "sensors.h"      // the sensors, the follow point
#include "solve.h"        // the step's matrix, its solve, the integrator
#include "tables.h"       // the creature's tables and a tile's scratch
#include "terrain.h"      // the ground's height and slope

namespace sanlab {

// Where the creature is: link frames, contact points and their depth below the ground
template <class V> static inline void positions(const Model &m, Ptr<const V> q, Tile<V> &t) {
  link_frames(m, q, t);
  contact_geometry(m, t);
}

// Where the creature is and how fast it moves: positions, then the velocity M^-1 p of the state
template <class V> static inline void prepare(const Model &m, Ptr<const V> q, Ptr<const V> p, Tile<V> &t) {
  positions(m, q, t);
  velocities(m, p, t);
}

// What one step needs besides the tile: the state (updated in place), the controller and where
// the observers keep their sums
template <class V> struct StepState {
  Ptr<V> q, p;          // [ndof] coordinates and momenta
  RowPtr<V, 2> anchor;  // [ncontact] where each contact's friction holds it
  Ptr<V> time, dmax;    // s; the deepest penetration so far (m)
};
struct Observers {
  const int32_t *oi;  // null: none (observe.h: the config)
  const double *of;
  int init;           // 1: start the accumulators from a rollout's first state
};

// One step of a tile (semi-implicit Euler in momentum form; docs/simulator.md, "The step"):
// ctl.act(m, t, par, cst, time) sets the activations t.act from the sensor values t.bits; `seen`
// is called once the sensors are read and `acted` once the controller has acted (recording).
template <class V, class Ctl, class Seen, class Acted>
static SANLAB_INLINE void step(const Model &m, Tile<V> &t, StepState<V> &s, const Ctl &ctl, Ptr<const V> par, Ptr<V> cst,
                        const Observers &o, Ptr<V> acc, Seen seen, Acted acted) {
  positions(m, s.q, t);               // kinematics, terrain and contacts (kinematics.h, contacts.h)
  velocities(m, s.p, t);              // qd = M^-1 p (solve.h)
  sense(m, t, *s.time);               // the sensors (sensors.h)
  seen();
  ctl.act(m, t, par, cst, *s.time);   // the controller: a SAN (san.h) or open loop (kernel.cpp)
  acted();
  if (o.oi) observe(m, t, o.oi, o.of, *s.time, acc);  // the observers (observe.h)
  start_step(m, t);                   // A = M, Q = 0 (solve.h)
  inertial_forces(m, t);              // forces (forces.h)
  gravity(m, t);                      // vertical plane only
  joint_springs(m, t);
  joint_stops(m, t);
  actuators(m, t);
  linear_springs(m, t);
  contacts(m, t, s.anchor, *s.dmax);  // the ground or the floor (contacts.h)
  if (m.nedge) water(m, t);
  solve_step(m, t);                   // A du = h Q (solve.h)
  integrate(m, t, s.q, s.p);          // p += M du, q += h v* (solve.h)
  *s.time = *s.time + t.world().dt;
}

// ---------------------------------------------------------------- start states

// Lifts every free tree just enough that none of its contact points is below the ground (the
// vertical plane), in place on q; then the tile holds q's positions.
template <class V> static inline void seat(const Model &m, Tile<V> &t, Ptr<V> q) {
  using Ls = Lanes<V>;
  positions(m, q, t);
  for (int tr = 0; tr < m.ntree; ++tr) {
    const TreeInts &T = m.tree(tr);
    if (!T.free) continue;
    V lift{};
    for (int c = 0; c < m.ncontact; ++c)
      if (m.link(m.ci[c]).tree == tr) lift = Ls::max(lift, ground_height(m, t, t.cp[c][0]) - t.cp[c][1]);
    int dy = m.link(T.root).dof_y;
    q[dy] = q[dy] + lift;
  }
  positions(m, q, t);
}

}  // namespace sanlab
