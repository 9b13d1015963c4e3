// The sensor-actuator network (paper §4): the controller a search looks for.
#pragma once
#include "tables.h"

namespace sanlab {

// The SAN's node update (paper §4, Figures 6 and 7; sanlab.san.San.step in NumPy). The weights are small integers and every input is
// 0 or 1, so a node's sum is the integer sum of its weights from the inputs that are on: per
// creature, the rows of its weights W[i][:] (int16, nodes padded to whole vectors) of the inputs
// that are on, added with a mask, 32 nodes per instruction. Exact, as the float sums were.
// weights: the tile's creatures' [W][I][NP] (NP = N rounded up to whole vectors of NS nodes).
typedef short vs __attribute__((vector_size(64)));
typedef short vs_u __attribute__((vector_size(64), aligned(2)));  // the caller's rows: any alignment
constexpr int NS = 32;

template <class V> static inline void san(const Model &m, Tile<V> &t, const short *weights, int NP, const V *k1,
                                          const V *k2, V *istate, V *out) {
  using Ls = Lanes<V>;
  const int N = m.nnode, S = m.nsensor, H = m.world().hidden, I = m.ninput, chunks = NP / NS;
  for (int l = 0; l < Ls::W; ++l) {
    vs acc[8];  // up to 256 nodes
    for (int c = 0; c < chunks; ++c) acc[c] = vs{};
    const vs_u *rows = (const vs_u *)(weights + (size_t)l * I * NP);
    for (int i = 0; i < I; ++i) {
      double x = i < S ? Ls::lane(t.bits[i], l) : Ls::lane(out[i - S], l);
      short on = x != 0.0 ? (short)-1 : (short)0;
      for (int c = 0; c < chunks; ++c) acc[c] += rows[i * chunks + c] & on;
    }
    for (int n = 0; n < N; ++n) Ls::set(t.total[n], l, (double)acc[n / NS][n % NS]);
  }
  const V dt = t.world().dt;
  for (int n = 0; n < N; ++n) {
    V rate = Ls::sel(t.total[n] > 0.0, k1[n], k2[n]);
    V s = Ls::min(Ls::max(istate[n] + rate * dt, V{}), V{} + 1.0);
    istate[n] = s;
    V o = out[n];
    out[n] = Ls::sel((o == 1.0) & (s == 0.0), V{}, Ls::sel((o == 0.0) & (s == 1.0), V{} + 1.0, o));
    if (n >= H) t.act[n - H] = (Ls::min(Ls::max(t.total[n], V{} - 2.0), V{} + 2.0) + 2.0) * 0.25;
  }
}

}  // namespace sanlab
