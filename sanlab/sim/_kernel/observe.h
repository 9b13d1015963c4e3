// What is read off a state: the centre of mass, the mechanical energy, the momenta of a velocity,
// and the observers a rollout accumulates (paper §5.1's metric, the behaviour descriptors).
#pragma once
#include "sensors.h"
#include "solve.h"
#include "terrain.h"

namespace sanlab {

// What a rollout accumulates besides the state (sanlab.metrics.Metric and
// sanlab.descriptors.Descriptors): the metric's ingredients and the
// behaviour descriptors, per lane, updated before each step from its prepared tile. The host turns
// them into scores with the same functions as before (metrics.scores, descriptors.values).
//
// Config oi (layout.OBSERVE): kind (layout.METRIC_KINDS), fell_com (0/1), fell_link (0/1), depth
// (0/1: track the deepest contact), root (descriptors' rotating root, -1 none), sensors
// (descriptors' word: 0 = no word), n_fell, n_joints, n_touch, then the fell links, the joints'
// dofs and the touch sensors' indices; of (layout.OBSERVE_F): fell angle (rad), fell COM height,
// fell link height (m). Accumulators (layout.ACC), one V each: the metric's, then the descriptors'
// (duty [n_touch], words and times [EVENTS] at the end); tracking's gap: the sum over steps of the
// distance from the centre of mass to the follow point, and that distance at the first step.
constexpr double DEBOUNCE_S = 0.02;

inline int obs_values(const int32_t *oi) { return A_FIXED + oi[O_N_TOUCH] + 2 * EVENTS; }

// Whole-creature centre of mass (and, with a velocity-prepared tile, its velocity); links welded
// to the world do not count
template <class V> static inline void centre_of_mass(const Model &m, const Tile<V> &t, V &cx, V &cy, V *vx, V *vy) {
  V mx{}, my{}, total{}, sx{}, sy{};
  for (int i = 0; i < m.nlink; ++i) {
    if (m.link(i).welded) continue;
    V mass = t.link(i).mass;
    mx = mx + mass * t.com[i][0];
    my = my + mass * t.com[i][1];
    if (vx) {
      V ux, uy;
      point_vel(t, i, t.com[i][0], t.com[i][1], ux, uy);
      sx = sx + mass * ux;
      sy = sy + mass * uy;
    }
    total = total + mass;
  }
  V inv = 1.0f / total;
  cx = mx * inv;
  cy = my * inv;
  if (vx) {
    *vx = sx * inv;
    *vy = sy * inv;
  }
}

// Mechanical energy of a prepared tile (J): kinetic (of the velocity M^-1 p),
// gravitational (m g y of each centre of mass, vertical plane) and elastic (passive joint and
// linear springs; actuators, stops and the ground excluded). Links welded to the world do not count.
template <class V> static inline void energy(const Model &m, const Tile<V> &t, V &kin, V &grav, V &elastic) {
  kin = V{};
  grav = V{};
  elastic = V{};
  const bool vertical = m.world().plane == PLANE_VERTICAL;
  for (int i = 0; i < m.nlink; ++i) {
    if (m.link(i).welded) continue;
    const LinkNumbers<V> &f = t.link(i);
    V vx, vy;
    point_vel(t, i, t.com[i][0], t.com[i][1], vx, vy);
    // (0.5 m) |v|^2 and ((0.5 I) w) w, associated as the stored gaits were scored
    kin = kin + (0.5f * f.mass) * (vx * vx + vy * vy) + ((0.5f * f.inertia) * t.w[i]) * t.w[i];
    if (vertical) grav = grav + (f.mass * t.world().gravity) * t.com[i][1];
  }
  for (int i = 0; i < m.nlink; ++i) {
    const LinkInts &l = m.link(i);
    if (!l.spring) continue;
    const LinkNumbers<V> &f = t.link(i);
    V d = (t.th[i] - t.th[l.parent]) - f.jspring_rest;
    elastic = elastic + (0.5f * f.jspring_k) * (d * d);
  }
  for (int n = 0; n < m.nspring; ++n) {
    const SpringNumbers<V> &f = t.spring(n);
    V pax, pay, pbx, pby;
    point_at(t, m.spring(n).link_a, f.point_a_x, f.point_a_y, pax, pay);
    point_at(t, m.spring(n).link_b, f.point_b_x, f.point_b_y, pbx, pby);
    V dx = pbx - pax, dy = pby - pay;
    V d = Lanes<V>::sqrt(dx * dx + dy * dy) - f.rest;
    elastic = elastic + (0.5f * f.ks) * (d * d);
  }
}

// The momenta p = M(q) qd of a tile whose positions are computed, for
// velocities qd in state coordinates: turned into tree coordinates, multiplied by the mass matrix
// (formed, or composite bodies on the articulated route), turned back as a force.
template <class V> static inline void momenta(const Model &m, Tile<V> &t, Ptr<const V> qd, Ptr<V> p) {
  const int D = m.ndof;
  for (int d = 0; d < D; ++d) t.x[d] = qd[d];
  turn(m, t, t.x, 1, 0);
  if (m.world().articulated) {
    bodies(m, t);
    art_matvec(m, t, t.x, p);
  } else {
    mass_matrix(m, t);
    for (int a = 0; a < D; ++a) {
      V acc{};
      for (int b = 0; b < D; ++b) acc += t.M[a * D + b] * t.x[b];
      p[a] = acc;
    }
  }
  turn(m, t, p, 1, 1);
}

// the accumulators at the start (positions of the tile already computed)
template <class V> static inline void observe_init(const Model &m, const Tile<V> &t, const int32_t *oi, Ptr<V> acc) {
  for (int k = 0; k < obs_values(oi); ++k) acc[k] = V{};
  V cx, cy;
  centre_of_mass(m, t, cx, cy, (V *)nullptr, (V *)nullptr);
  acc[A_P0X] = acc[A_PX] = cx;
  acc[A_P0Y] = acc[A_PY] = acc[A_Y0] = cy;
  acc[A_WORD] = acc[A_CANDIDATE] = V{} - 1.0f;
}

// one step's update, from a prepared tile at time `time` (paper §5.1's metric: sanlab.metrics;
// the behaviour descriptors: sanlab.descriptors)
template <class V> static inline void observe(const Model &m, const Tile<V> &t, const int32_t *oi, const double *of,
                                              V time, Ptr<V> acc) {
  using Ls = Lanes<V>;
  using R = real<V>;
  const bool vertical = m.world().plane == PLANE_VERTICAL;
  const int32_t *fell = oi + O_LISTS, *joints = fell + oi[O_N_FELL], *touch = joints + oi[O_N_JOINTS];
  const V dt = t.world().dt;
  // the metric
  V f = acc[A_FELL];
  for (int k = 0; k < oi[O_N_FELL]; ++k) {
    int i = fell[k];
    V a = wrap_angle(t.th[i]);
    f = Ls::sel(Ls::abs(a) > R(of[OF_FELL_ANGLE]), V{} + 1.0f, f);
    if (oi[O_FELL_LINK] && vertical)
      f = Ls::sel(t.com[i][1] - ground_height(m, t, t.com[i][0]) < R(of[OF_FELL_LINK_HEIGHT]), V{} + 1.0f, f);
  }
  V px, py, vx, vy;
  centre_of_mass(m, t, px, py, &vx, &vy);
  if (oi[O_FELL_COM] && vertical) f = Ls::sel(py - ground_height(m, t, px) < R(of[OF_FELL_COM_HEIGHT]), V{} + 1.0f, f);
  acc[A_FELL] = f;
  if (oi[O_KIND] == M_HOPPING) {
    V up = Ls::max(py - acc[A_Y0], V{});
    acc[A_HOP] = acc[A_HOP] + up * up * dt;
  } else if (oi[O_KIND] == M_PURSUIT) {
    V fx, fy;
    follow_point(m, t, time, fx, fy);
    V dx = fx - px, dy = fy - py;
    V inv = 1.0f / Ls::max(Ls::sqrt(dx * dx + dy * dy), V{} + R(1e-9));
    acc[A_PURSUIT] = acc[A_PURSUIT] + (vx * dx + vy * dy) * inv * dt;
  } else if (oi[O_KIND] == M_TRACKING) {
    V fx, fy;
    follow_point(m, t, time, fx, fy);
    V dx = fx - px, dy = fy - py;
    V gap = Ls::sqrt(dx * dx + dy * dy);
    acc[A_GAP0] = Ls::sel(acc[A_STEPS] > 0.0f, acc[A_GAP0], gap);
    acc[A_GAP] = acc[A_GAP] + gap;
  }
  if (oi[O_DEPTH] && m.ncontact) {
    V d = t.depth[0];
    for (int c = 1; c < m.ncontact; ++c) d = Ls::max(d, t.depth[c]);
    acc[A_DEEPEST] = Ls::max(acc[A_DEEPEST], d);
  }
  // the descriptors
  V y{}, air{};
  if (vertical) {
    y = py - ground_height(m, t, px);
    auto any = V{} < 0.0f;  // all false
    for (int c = 0; c < m.ncontact; ++c) any = any | (t.depth[c] > 0.0f);
    air = Ls::sel(any, V{}, V{} + 1.0f);
  }
  const int root = oi[O_ROOT];
  if (root >= 0) {
    V th = t.th[root], d = th - acc[A_ANGLE];
    d = wrap_angle(d);
    acc[A_TURN] = acc[A_TURN] + Ls::sel(acc[A_STEPS] > 0.0f, d, V{});
    acc[A_ANGLE] = th;
  }
  if (oi[O_N_JOINTS]) {
    V js{};
    for (int k = 0; k < oi[O_N_JOINTS]; ++k) js = js + Ls::abs(t.qd[joints[k]]);
    acc[A_JOINT_SPEED] = acc[A_JOINT_SPEED] + js / R(oi[O_N_JOINTS]);
  }
  Ptr<V> duty = acc + A_FIXED, words = duty + oi[O_N_TOUCH], times = words + EVENTS;
  for (int k = 0; k < oi[O_N_TOUCH]; ++k) duty[k] = duty[k] + t.bits[touch[k]];
  if (oi[O_SENSORS]) {
    V w{};
    for (int s = 0; s < oi[O_SENSORS]; ++s) w = w + Ls::sel(t.bits[s] > 0.5f, V{} + R(1 << s), V{});
    V since = Ls::sel(w == acc[A_CANDIDATE], acc[A_SINCE], time);
    acc[A_SINCE] = since;
    acc[A_CANDIDATE] = w;
    auto fresh = (w != acc[A_WORD]) & (time - since + dt >= R(DEBOUNCE_S));
    for (int l = 0; l < Ls::W; ++l) {
      if (!Ls::on(fresh, l)) continue;
      int slot = (int)Ls::lane(acc[A_CHANGES], l) % EVENTS;
      Ls::set(words[slot], l, Ls::lane(w, l));
      Ls::set(times[slot], l, Ls::lane(since, l));
    }
    acc[A_CHANGES] = acc[A_CHANGES] + Ls::sel(fresh, V{} + 1.0f, V{});
    acc[A_WORD] = Ls::sel(fresh, w, acc[A_WORD]);
  }
  acc[A_STEPS] = acc[A_STEPS] + 1.0f;
  acc[A_HEIGHT] = acc[A_HEIGHT] + y;
  acc[A_HEIGHT2] = acc[A_HEIGHT2] + y * y;
  acc[A_AIRBORNE] = acc[A_AIRBORNE] + air;
}

}  // namespace sanlab
