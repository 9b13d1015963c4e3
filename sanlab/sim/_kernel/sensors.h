// The sensors (paper §3.2): binary values of a tile whose positions are computed, and the follow
// point the eyes look for.
#pragma once
#include "kinematics.h"

namespace sanlab {

// The follow point at time `time` (s): linear interpolation in the path's arc-length table
// (paper §3.2: the follow point)
template <class V> static inline void follow_point(const Model &m, const Tile<V> &t, V time, V &x, V &y) {
  using Ls = Lanes<V>;
  using R = real<V>;
  using Rs = Lanes<R>;
  const int n = m.nfollow;
  V u = t.world().follow_speed * time / t.world().follow_ds;
  for (int l = 0; l < Ls::W; ++l) {
    R ul = Ls::lane(u, l);
    if (m.world().follow_loop) ul = ul - R(n - 1) * Rs::floor(ul / R(n - 1));
    ul = ul < 0.0f ? R(0) : (ul > R(n - 1) ? R(n - 1) : ul);
    int i0 = ul >= 0.0f ? (int)Rs::floor(ul) : 0;  // NaN (a NaN time): no int of it, NaN out
    if (i0 > n - 2) i0 = n - 2;
    R f = ul - R(i0);
    const double *a = m.follow + 2 * i0, *b = a + 2;  // the path's table, float64: read as R
    Ls::set(x, l, R(a[0]) + f * (R(b[0]) - R(a[0])));
    Ls::set(y, l, R(a[1]) + f * (R(b[1]) - R(a[1])));
  }
}

// Binary sensor values (paper §3.2, Figure 3: touch, angle, eye, length; tilt: a link's absolute
// angle) of a tile whose positions are computed, at time `time`
template <class V> static inline void sense(const Model &m, Tile<V> &t, V time) {
  using Ls = Lanes<V>;
  V fx{}, fy{};
  if (m.world().follow) follow_point(m, t, time, fx, fy);
  for (int s = 0; s < m.nsensor; ++s) {
    const SensorInts &si = m.sensor(s);
    const SensorNumbers<V> &sf = t.sensor(s);
    int kind = si.kind;
    if (kind == S_TOUCH) {
      t.bits[s] = m.world().plane == PLANE_HORIZONTAL ? V{} + 1.0f : Ls::sel(t.depth[si.on] > 0.0f, V{} + 1.0f, V{});
      continue;
    }
    V a;
    if (kind == S_ANGLE || kind == S_TILT) {
      int link = si.on, par = m.link(link).parent;
      V ang = (par < 0 || kind == S_TILT) ? t.th[link] : t.th[link] - t.th[par];
      a = wrap_angle(ang);
    } else if (kind == S_EYE) {
      int li = si.on, frm = si.second, to = si.third;
      V ex, ey;
      point_at(t, li, sf.point_x, sf.point_y, ex, ey);
      V ax = frm >= 0 ? t.X[to][0] - t.X[frm][0] : t.cs[li][0];
      V ay = frm >= 0 ? t.X[to][1] - t.X[frm][1] : t.cs[li][1];
      V dx = fx - ex, dy = fy - ey;
      V num = ax * dy - ay * dx, den = ax * dx + ay * dy;
      for (int l = 0; l < Ls::W; ++l) Ls::set(a, l, Lanes<real<V>>::atan2(Ls::lane(num, l), Ls::lane(den, l)));
    } else {
      V pax, pay, pbx, pby;
      point_at(t, si.on, sf.point_x, sf.point_y, pax, pay);
      point_at(t, si.second, sf.point_b_x, sf.point_b_y, pbx, pby);
      V dx = pbx - pax, dy = pby - pay;
      a = Ls::sqrt(dx * dx + dy * dy);
    }
    t.bits[s] = Ls::sel((a >= sf.min) & (a <= sf.max), V{} + 1.0f, V{});
  }
}

}  // namespace sanlab
