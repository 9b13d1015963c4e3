// Contacts (paper §3.4: "the external forces applied by the ground are calculated using stiff spring
// and dampers"; docs/simulator.md, "Forces"): each contact point's place against the ground, the
// normal spring-damper N = max(0, k d - c v), and friction that holds: one stick-slip law
// (stick_slip) against an anchor on the ground, in the vertical plane along the ground's tangent,
// seen from above along a link's axes (anisotropic) or within a disc (isotropic).
#pragma once
#include "forces.h"
#include "terrain.h"

namespace sanlab {

// Each contact's world point cp, its depth below the ground (> 0: touching; horizontal plane:
// always on the floor, 1) and the ground's normal and tangent gn there (nx, ny, tx, ty)
template <class V> static inline void contact_geometry(const Model &m, Tile<V> &t) {
  using Ls = Lanes<V>;
  const int kind = m.world().terrain;
  for (int c = 0; c < m.ncontact; ++c) {
    int i = m.ci[c];
    V rx = t.contact(c).point_x, ry = t.contact(c).point_y;
    V cc = t.cs[i][0], ss = t.cs[i][1];
    V px = t.X[i][0] + (cc * rx - ss * ry), py = t.X[i][1] + (ss * rx + cc * ry);
    t.cp[c][0] = px;
    t.cp[c][1] = py;
    if (m.world().plane == PLANE_HORIZONTAL) {  // seen from above: every contact always rests on the floor
      t.depth[c] = V{} + 1.0f;
      continue;
    }
    if (kind == TERRAIN_FLAT) {
      t.gn[c][0] = V{};
      t.gn[c][1] = V{} + 1.0f;
      t.gn[c][2] = V{} + 1.0f;
      t.gn[c][3] = V{};
      t.depth[c] = (0.0f - py) * 1.0f;
      continue;
    }
    V h, dh;
    terrain(m, t, px, h, dh);
    V inv = 1.0f / Ls::sqrt(1.0f + dh * dh);
    t.gn[c][0] = -dh * inv;
    t.gn[c][1] = inv;
    t.gn[c][2] = inv;
    t.gn[c][3] = dh * inv;
    t.depth[c] = (h - py) * inv;
  }
}

// The stick-slip law along one tangent, the one every contact's friction uses: a spring gk to the
// anchor and a damper limit / slip stick while their force needs no more than the limit mu N;
// beyond it Coulomb sliding, limit against the velocity. The element's matrix coefficient and
// force, and how far behind the contact its anchor stays (docs/simulator.md, "Forces")
template <class V> static inline void stick_slip(V stretch, V v, V limit, V gk, V slip, V h, V &coef,
                                                 V &f, V &held) {
  using Ls = Lanes<V>;
  V c = limit / slip;
  V s = Ls::min(Ls::max(stretch, -limit / gk), limit / gk);
  V trial = -gk * s - c * v;
  V slide = limit / Ls::max(Ls::abs(v), V{} + slip);
  auto stick = (limit > 0.0f) & (Ls::abs(trial) <= limit);
  coef = Ls::sel(stick, h * c + (h * h) * gk, h * slide);
  f = Ls::sel(stick, trial - (h * gk) * v, -slide * v);
  held = Ls::sel(stick, s, V{});
}

// Vertical plane: every contact's normal force and stick-slip friction against the ground, as
// elements of the step (paper §3.4: "stiff spring and dampers"); a contact no lane touches adds
// nothing
template <class V> static inline void ground_laws(const Model &m, Tile<V> &t, RowPtr<V, 2> anchor, V &dmax) {
  using Ls = Lanes<V>;
  const V h = t.world().dt;
  const V gk = t.world().ground_k, gc = t.world().ground_c, slip = t.world().slip;
  const V cn = h * gc + (h * h) * gk;
  for (int c = 0; c < m.ncontact; ++c) {
    int i = m.ci[c];
    const LinkInts &l = m.link(i);
    V nx = t.gn[c][0], ny = t.gn[c][1], tx = t.gn[c][2], ty = t.gn[c][3];
    V dep = t.depth[c];
    dmax = Ls::max(dmax, dep);
    V vx = t.cv[c][0], vy = t.cv[c][1];
    V vn = vx * nx + vy * ny, vt = vx * tx + vy * ty;
    V fn = gk * dep - gc * vn;
    auto on = (dep > 0.0f) & (fn > 0.0f);
    V N = Ls::sel(on, fn, V{});
    V stretch = (t.cp[c][0] - anchor[c][0]) * tx + (t.cp[c][1] - anchor[c][1]) * ty;
    V mu = V{} + t.link(i).mu_forward;
    if (l.aniso) {
      int frm = l.axis_from, to = l.axis_to;
      V axx = frm >= 0 ? t.X[to][0] - t.X[frm][0] : t.cs[i][0];
      V axy = frm >= 0 ? t.X[to][1] - t.X[frm][1] : t.cs[i][1];
      mu = Ls::sel((axx * tx + axy * ty) * (gk * stretch + vt) > 0.0f, mu, V{} + t.link(i).mu_backward);
    }
    V limit = mu * N;
    V coef, f, held;
    stick_slip(stretch, vt, limit, gk, slip, h, coef, f, held);
    if (Ls::any(on)) {
      row_element(m, t, i, t.cp[c][0], t.cp[c][1], nx, ny, Ls::sel(on, V{} + cn, V{}),
                  Ls::sel(on, fn - (h * gk) * vn, V{}));
    }
    if (Ls::any(limit > 0.0f)) {
      row_element(m, t, i, t.cp[c][0], t.cp[c][1], tx, ty, coef, f);
    }
    anchor[c][0] = t.cp[c][0] - held * tx;
    anchor[c][1] = t.cp[c][1] - held * ty;
  }
}

// Horizontal plane: every contact's friction against the floor under its constant load
// (paper §3.4's ground, seen from above): anisotropic along a link axis (stick_slip per axis), or
// isotropic within a disc (the same law on the tangential vector)
template <class V> static inline void plane_laws(const Model &m, Tile<V> &t, RowPtr<V, 2> anchor) {
  using Ls = Lanes<V>;
  const V h = t.world().dt, gk = t.world().ground_k, slip = t.world().slip;
  for (int c = 0; c < m.ncontact; ++c) {
    int i = m.ci[c];
    const LinkInts &l = m.link(i);
    const LinkNumbers<V> &f = t.link(i);
    V px = t.cp[c][0], py = t.cp[c][1], vx = t.cv[c][0], vy = t.cv[c][1];
    V N = t.contact(c).load;
    V dx = px - anchor[c][0], dy = py - anchor[c][1];
    if (l.aniso) {
      int frm = l.axis_from, to = l.axis_to;
      V ax = frm >= 0 ? t.X[to][0] - t.X[frm][0] : t.cs[i][0];
      V ay = frm >= 0 ? t.X[to][1] - t.X[frm][1] : t.cs[i][1];
      V inv = 1.0f / Ls::sqrt(ax * ax + ay * ay + real<V>(1e-12));
      V e1x = ax * inv, e1y = ay * inv, e2x = -e1y, e2y = e1x;
      V va = vx * e1x + vy * e1y, vl = vx * e2x + vy * e2y;
      V s1 = dx * e1x + dy * e1y, s2 = dx * e2x + dy * e2y;
      V mu = Ls::sel(gk * s1 + va > 0.0f, V{} + f.mu_forward, V{} + f.mu_backward);
      V c1, f1, h1, c2, f2, h2;
      stick_slip(s1, va, mu * N, gk, slip, h, c1, f1, h1);
      stick_slip(s2, vl, V{} + f.mu_lateral * N, gk, slip, h, c2, f2, h2);
      row_element(m, t, i, px, py, e1x, e1y, c1, f1);
      row_element(m, t, i, px, py, e2x, e2y, c2, f2);
      anchor[c][0] = px - h1 * e1x - h2 * e2x;
      anchor[c][1] = py - h1 * e1y - h2 * e2y;
    } else {
      V limit = f.mu_forward * N, cc = limit / slip;
      V r = Ls::sqrt(dx * dx + dy * dy);
      V scale = Ls::min(V{} + 1.0f, (limit / gk) / Ls::max(r, V{} + real<V>(1e-30)));
      V sx = dx * scale, sy = dy * scale;
      V tx = -gk * sx - cc * vx, ty = -gk * sy - cc * vy;
      auto stick = (V{} + limit > 0.0f) & (tx * tx + ty * ty <= limit * limit);
      V speed = Ls::sqrt(vx * vx + vy * vy);
      V slide = limit / Ls::max(speed, V{} + slip);
      V ks = Ls::sel(stick, V{} + gk, V{}), damp = Ls::sel(stick, V{} + cc, slide);
      V coef = h * damp + (h * h) * ks;
      V e0[2] = {V{} + 1.0f, V{}}, e1[2] = {V{}, V{} + 1.0f};
      V trial[2] = {tx, ty}, vel[2] = {vx, vy};
      for (int a = 0; a < 2; ++a) {
        V *e = a == 0 ? e0 : e1;
        row_element(m, t, i, px, py, e[0], e[1], coef, Ls::sel(stick, trial[a], -slide * vel[a]) - (h * ks) * vel[a]);
      }
      anchor[c][0] = px - Ls::sel(stick, sx, V{});
      anchor[c][1] = py - Ls::sel(stick, sy, V{});
    }
  }
}

// Every contact's forces: against the ground (vertical plane) or the floor (horizontal)
template <class V> static inline void contacts(const Model &m, Tile<V> &t, RowPtr<V, 2> anchor, V &dmax) {
  if (m.world().plane == PLANE_VERTICAL) ground_laws(m, t, anchor, dmax);
  else plane_laws(m, t, anchor);
}

}  // namespace sanlab
