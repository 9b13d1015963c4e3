// The ground: its height h(x) and slope h'(x) in the vertical plane (paper §3.4: the creatures move
// on a ground of stiff springs; sanlab adds a slope, a hill and rough ground, creature-format.md).
// One function serves the contacts, the observers and the seating of a start pose.
#pragma once
#include "tables.h"

namespace sanlab {

// h and h' at x (m, m/m): flat 0; slope tan(a) x; hill H (1 + cos(pi (x - c) / hw)) / 2 inside
// |x - c| < hw, else 0; rough sum_k a_k sin(w_k x + phase_k)
template <class V> static inline void terrain(const Model &m, const Tile<V> &t, V x, V &h, V &dh) {
  using Ls = Lanes<V>;
  using R = real<V>;
  const int kind = m.world().terrain;
  if (kind == TERRAIN_FLAT) {
    h = V{};
    dh = V{};
  } else if (kind == TERRAIN_SLOPE) {
    h = t.world().slope * x;
    dh = V{} + t.world().slope;
  } else if (kind == TERRAIN_HILL) {
    V H = t.world().hill_height, hw = t.world().hill_half_width, cx = t.world().hill_centre;
    V u = (x - cx) * (R(M_PI) / hw), su, cu;
    sincos(u, su, cu);
    auto inside = Ls::abs(x - cx) < hw;
    h = Ls::sel(inside, 0.5f * H * (1.0f + cu), V{});
    dh = Ls::sel(inside, -0.5f * H * (R(M_PI) / hw) * su, V{});
  } else {
    h = V{};
    dh = V{};
    for (int k = 0; k < m.nrough; ++k) {
      V a = t.rough_term(k).amplitude, w = t.rough_term(k).wavenumber, ph = t.rough_term(k).phase;
      V s, co;
      sincos(w * x + ph, s, co);
      h = h + a * s;
      dh = dh + a * w * co;
    }
  }
}

// the ground's height at x (m)
template <class V> static inline V ground_height(const Model &m, const Tile<V> &t, V x) {
  V h, dh;
  terrain(m, t, x, h, dh);
  return h;
}

}  // namespace sanlab
