// The sensor-actuator network (paper §4): the controller a search looks for.
#pragma once
#include "tables.h"

namespace sanlab {

// The SAN's node update (paper §4, Figures 6 and 7; sanlab.san.San.step in NumPy), after the node
// sums t.total: each node's internal state integrates at rate k1 (sum > 0) or k2 and is clipped to
// [0, 1]; its output flips to 0 or 1 where the state reaches that end; an actuator node's
// activation is its sum clipped to [-2, 2] and mapped to [0, 1].
template <class V> static inline void san_update(const Model &m, Tile<V> &t, Ptr<const V> k1, Ptr<const V> k2,
                                                 Ptr<V> istate, Ptr<V> out) {
  using Ls = Lanes<V>;
  const int N = m.nnode, H = m.world().hidden;
  const V dt = t.world().dt;
  for (int n = 0; n < N; ++n) {
    V rate = Ls::sel(t.total[n] > 0.0f, k1[n], k2[n]);
    V s = Ls::min(Ls::max(istate[n] + rate * dt, V{}), V{} + 1.0f);
    istate[n] = s;
    V o = out[n];
    out[n] = Ls::sel((o == 1.0f) & (s == 0.0f), V{}, Ls::sel((o == 0.0f) & (s == 1.0f), V{} + 1.0f, o));
    if (n >= H) t.act[n - H] = (Ls::min(Ls::max(t.total[n], V{} - 2.0f), V{} + 2.0f) + 2.0f) * 0.25f;
  }
}

// The weights are small integers and every input is 0 or 1, so a node's sum is the integer sum of
// its weights from the inputs that are on. weights: the creature's [I][NP] int16, one row of nodes
// per input (NP = N rounded up to a multiple of NS). The scalar form, one creature per thread (the
// GPU's, and the CPU's reference): node by node, in int. Exact, as the tiles' int16 vectors are
// (|a sum| <= 2 I, far inside int16), so both forms give the same bits.
template <class R>
static inline void san_scalar(const Model &m, Tile<R> &t, const short *weights, int NP, Ptr<const R> k1,
                              Ptr<const R> k2, Ptr<R> istate, Ptr<R> out) {
  const int N = m.nnode, S = m.nsensor, I = m.ninput;
  for (int n = 0; n < N; ++n) {
    int acc = 0;
    for (int i = 0; i < I; ++i) {
      R x = i < S ? t.bits[i] : out[i - S];
      if (x != 0.0f) acc += weights[i * NP + n];
    }
    t.total[n] = (R)acc;
  }
  san_update(m, t, k1, k2, istate, out);
}
static inline void san(const Model &m, Tile<double> &t, const short *weights, int NP, Ptr<const double> k1,
                       Ptr<const double> k2, Ptr<double> istate, Ptr<double> out) {
  san_scalar(m, t, weights, NP, k1, k2, istate, out);
}
static inline void san(const Model &m, Tile<float> &t, const short *weights, int NP, Ptr<const float> k1,
                       Ptr<const float> k2, Ptr<float> istate, Ptr<float> out) {
  san_scalar(m, t, weights, NP, k1, k2, istate, out);
}

#ifndef __CUDACC_RTC__
// The tiles' form: per creature, the rows of its weights W[i][:] of the inputs that are on, added
// with a mask, 32 nodes per instruction. weights: the tile's creatures' [W][I][NP].
typedef short vs __attribute__((vector_size(64)));
typedef short vs_u __attribute__((vector_size(64), aligned(2)));  // the caller's rows: any alignment
constexpr int NS = 32;

template <class V> static inline void san(const Model &m, Tile<V> &t, const short *weights, int NP, const V *k1,
                                          const V *k2, V *istate, V *out) {
  using Ls = Lanes<V>;
  const int N = m.nnode, S = m.nsensor, I = m.ninput, chunks = NP / NS;
  for (int l = 0; l < Ls::W; ++l) {
    vs acc[8];  // up to 256 nodes
    for (int c = 0; c < chunks; ++c) acc[c] = vs{};
    const vs_u *rows = (const vs_u *)(weights + (size_t)l * I * NP);
    for (int i = 0; i < I; ++i) {
      real<V> x = i < S ? Ls::lane(t.bits[i], l) : Ls::lane(out[i - S], l);
      short on = x != 0.0f ? (short)-1 : (short)0;
      for (int c = 0; c < chunks; ++c) acc[c] += rows[i * chunks + c] & on;
    }
    for (int n = 0; n < N; ++n) Ls::set(t.total[n], l, (real<V>)acc[n / NS][n % NS]);
  }
  san_update(m, t, k1, k2, istate, out);
}

// The float tiles' form: the tile's creatures side by side, one select and add per input and node
// for all 16 of them, where the form above pays each creature's inputs one by one (measured: the
// bounder's float32 SAN took as long as its float64 one). wv [I][N]: the weight from input i to
// node n of each lane's creature, as floats (san_weights, once per call); the sums are of small
// integers, exact in any order, so the same bits as the integer sums.
template <class V> static inline void san_weights(const Model &m, const short *weights, int NP, V *wv) {
  using Ls = Lanes<V>;
  const int N = m.nnode, I = m.ninput;
  for (int l = 0; l < Ls::W; ++l)
    for (int i = 0; i < I; ++i)
      for (int n = 0; n < N; ++n) Ls::set(wv[i * N + n], l, (real<V>)weights[((size_t)l * I + i) * NP + n]);
}

template <class V> static inline void san_lanes(const Model &m, Tile<V> &t, const V *wv, const V *k1, const V *k2,
                                                V *istate, V *out) {
  using Ls = Lanes<V>;
  const int N = m.nnode, S = m.nsensor, I = m.ninput;
  for (int n = 0; n < N; ++n) t.total[n] = V{};
  for (int i = 0; i < I; ++i) {
    auto on = (i < S ? t.bits[i] : out[i - S]) != 0.0f;
    if (!Ls::any(on)) continue;
    const V *w = wv + (size_t)i * N;
    for (int n = 0; n < N; ++n) t.total[n] = t.total[n] + Ls::sel(on, w[n], V{});
  }
  san_update(m, t, k1, k2, istate, out);
}
#endif

}  // namespace sanlab
