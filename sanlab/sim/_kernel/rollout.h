// The controllers and a tile's rollout: what the CPU's entry points (kernel.cpp) and the GPU's
// (gpu.cu, one creature per thread) share, over step.h.
#pragma once
#ifndef __CUDACC_RTC__
#include <cstring>
#endif
#include "step.h"

namespace sanlab {

// The creature's counts and tables (the caller's arrays, in the order of layout.ORDER) as a Model;
// its derived tables (dense_idx, kid_start, kids) are the caller's to set
static inline void model_of(Model &m, const int32_t *dims, const void *const *tables) {
  m.nlink = dims[DIM_LINKS]; m.ncontact = dims[DIM_CONTACTS]; m.ntree = dims[DIM_TREES]; m.ndof = dims[DIM_DOFS];
  m.nsensor = dims[DIM_SENSORS]; m.nact = dims[DIM_ACTUATORS]; m.nchain = dims[DIM_CHAIN];
  m.nrough = dims[DIM_ROUGH]; m.nnode = dims[DIM_NODES]; m.ninput = dims[DIM_INPUTS];
  m.nspring = dims[DIM_SPRINGS]; m.nedge = dims[DIM_EDGES]; m.nfollow = dims[DIM_FOLLOW];
  const int32_t **ints[] = {&m.li, &m.ri, &m.rl, &m.rn, &m.ti, &m.ci, &m.si, &m.ai, &m.pi, &m.ei, &m.wi};
  const double **reals[] = {&m.lf, &m.cf, &m.sf, &m.af, &m.pf, &m.ef, &m.wf, &m.rough, &m.follow};
  int k = 0;
  for (auto p : ints) *p = (const int32_t *)tables[k++];
  for (auto p : reals) *p = (const double *)tables[k++];
}

// The values of each float table a row may carry its own of (layout.ROW_TABLES: lf, cf, sf, af,
// pf, ef, wf, rough), one row's
static inline void row_table_sizes(const Model &m, size_t n[8]) {
  n[0] = (size_t)m.nlink * LF_WIDTH; n[1] = (size_t)m.ncontact * CF_WIDTH; n[2] = (size_t)m.nsensor * SF_WIDTH;
  n[3] = (size_t)m.nact * AF_WIDTH; n[4] = (size_t)m.nspring * PF_WIDTH; n[5] = (size_t)m.nedge * EF_WIDTH;
  n[6] = (size_t)WF_WIDTH; n[7] = (size_t)m.nrough * ROUGH_WIDTH;
}

// A tile's numbers: each lane's row's own (per_row[k]: [T * W, n] tables), or the shared ones on
// every lane
template <class V>
static void fill_numbers(const Model &m, Tile<V> &tile, const void *const *tables, const int32_t *per_row, int64_t b) {
  using Ls = Lanes<V>;
  const int W = Ls::W;
  size_t counts[8];
  row_table_sizes(m, counts);
  V *dst[] = {tile.lf, tile.cf, tile.sf, tile.af, tile.pf, tile.ef, tile.wf, tile.rough};
  for (int k = 0; k < 8; ++k) {
    const double *src = (const double *)tables[11 + k];
    const size_t n = counts[k];
    for (size_t v = 0; v < n; ++v)
      for (int l = 0; l < W; ++l)
        Ls::set(dst[k][v], l, real<V>(per_row[k] ? src[((size_t)b * W + l) * n + v] : src[v]));
  }
}

// ---------------------------------------------------------------- controllers
//
// What a rollout asks of its controller, one tile at a time: at(b) the controller of tile b (a
// SAN's weights are the creatures' own), and act(m, t, par, st, time): the activations t.act in
// [0, 1] from the tile's sensor values t.bits at time `time` (s), its parameters `par` [n_param]
// and its state `st` [n_state] (updated in place), both values of V in the tile's scratch.
// One rollout template serves them all, so every kind steps, observes and records alike.
// (their kinds: layout.h, K_SAN ... K_PATTERN)

// the SAN (san.h): k1, k2 [N] (1/s); state istate, out [N]; weights [W][I][NP] int16 per tile;
// wv: the float tiles' weights side by side (san.h: san_weights), where kernel.cpp made them
template <class V> struct SanControl {
  const short *weights;
  int NP;
  size_t per_tile;
  const V *wv = nullptr;
  static size_t n_param(const Model &m) { return 2 * (size_t)m.nnode; }
  static size_t n_state(const Model &m) { return 2 * (size_t)m.nnode; }
  SanControl at(int64_t b) const { return {weights + (size_t)b * per_tile, NP, per_tile}; }
  void act(const Model &m, Tile<V> &t, Ptr<const V> par, Ptr<V> st, V) const {
#ifndef __CUDACC_RTC__
    if (wv) return san_lanes(m, t, wv, par, par + m.nnode, st, st + m.nnode);
#endif
    san(m, t, weights, NP, par, par + m.nnode, st, st + m.nnode);
  }
};

// external activations u [A], held for every step of the call (sim.ConstantController)
template <class V> struct HoldControl {
  static size_t n_param(const Model &m) { return m.nact; }
  static size_t n_state(const Model &) { return 0; }
  HoldControl at(int64_t) const { return *this; }
  void act(const Model &m, Tile<V> &t, Ptr<const V> par, Ptr<V>, V) const {
    for (int a = 0; a < m.nact; ++a) t.act[a] = par[a];
  }
};

// u_a = 0.5 + 0.5 sin(2 pi f t + phase_a): phases [A] (rad), then f (Hz) (sim.SineController,
// whose clock is the rollout's time here)
template <class V> struct SineControl {
  static size_t n_param(const Model &m) { return m.nact + 1; }
  static size_t n_state(const Model &) { return 0; }
  SineControl at(int64_t) const { return *this; }
  void act(const Model &m, Tile<V> &t, Ptr<const V> par, Ptr<V>, V time) const {
    const V w = real<V>(2 * M_PI) * par[m.nact] * time;  // ((2 pi) f) t, the order the stored gaits ran in
    for (int a = 0; a < m.nact; ++a) {
      V s, c;
      sincos(w + par[a], s, c);
      t.act[a] = 0.5f + 0.5f * s;
    }
  }
};

// An open-loop square wave per actuator (sim.PatternController): u_a = high_a while the phase of
// the cycle, frac(t / period - phase_a), lies below duty_a, else low_a. par: (phase_a, duty_a,
// low_a, high_a) for each actuator (phase and duty as fractions of the period, levels as
// activations in [0, 1]), then the period (s); t is the rollout's time before the step.
template <class V> struct PatternControl {
  static size_t n_param(const Model &m) { return 4 * (size_t)m.nact + 1; }
  static size_t n_state(const Model &) { return 0; }
  PatternControl at(int64_t) const { return *this; }
  void act(const Model &m, Tile<V> &t, Ptr<const V> par, Ptr<V>, V time) const {
    using Ls = Lanes<V>;
    const V cycles = time / par[4 * m.nact];
    for (int a = 0; a < m.nact; ++a) {
      Ptr<const V> pa = par + 4 * a;
      const V x = cycles - pa[0];
      t.act[a] = Ls::sel(x - Ls::floor(x) < pa[1], pa[3], pa[2]);
    }
  }
};

// u = clip(W bits + b, 0, 1): W [A][S], then b [A] (sim.ReflexController)
template <class V> struct ReflexControl {
  static size_t n_param(const Model &m) { return (size_t)m.nact * m.nsensor + m.nact; }
  static size_t n_state(const Model &) { return 0; }
  ReflexControl at(int64_t) const { return *this; }
  void act(const Model &m, Tile<V> &t, Ptr<const V> par, Ptr<V>, V) const {
    using Ls = Lanes<V>;
    for (int a = 0; a < m.nact; ++a) {
      V x{};
      for (int s = 0; s < m.nsensor; ++s) x = x + par[a * m.nsensor + s] * t.bits[s];
      t.act[a] = Ls::min(Ls::max(x + par[m.nact * m.nsensor + a], V{}), V{} + 1.0f);
    }
  }
};

// ---------------------------------------------------------------- rollouts

// Frames to record: every `every` steps from the first, the first `n` of them; each frame holds
// q, qd [D] (the velocity of that state), bits [S], u [A], then the controller's state before
// that step [n_state] (a SAN's istate, out), `values` values of V in all
struct Record {
  int64_t every, n, values;
};

// A tile's state, copied in and out of the caller's arrays: q, p [D], anchor [C][2], t, dmax
inline size_t state_values(const Model &m) { return 2 * (size_t)m.ndof + 2 * (size_t)m.ncontact + 2; }

// `steps` steps of a tile (step.h: step), recording the frames asked for; then the final state's
// velocity and, for the metric, its centre of mass. frames: the tile's [n, values, W] float64
// (the caller's: a float tile's values widened exactly)
template <class V, class Ctl>
static SANLAB_INLINE void run_tile(const Model &m, Tile<V> &t, const Ctl &ctl, Ptr<V> state, Ptr<const V> par, Ptr<V> cst,
                     int64_t steps, const Observers &o, Ptr<V> acc, Ptr<V> qd_out, const Record &rec, double *frames) {
  using Ls = Lanes<V>;
  Ptr<V> q = state, p = q + m.ndof;
  RowPtr<V, 2> anchor = rows<2>(p + m.ndof);
  Ptr<V> time = flat(anchor + m.ncontact);
  StepState<V> s{q, p, anchor, time, time + 1};
  const int ns = (int)Ctl::n_state(m), at_u = 2 * m.ndof + m.nsensor, at_state = at_u + m.nact;
  if (o.oi && o.init) {
    positions(m, q, t);
    observe_init(m, t, o.oi, acc);
  }
  for (int64_t n = 0; n < steps; ++n) {
    const bool keep = frames && n % rec.every == 0 && n / rec.every < rec.n;
    double *f = keep ? frames + (n / rec.every) * rec.values * Ls::W : nullptr;
    // lane by lane: the caller's buffer need not be aligned for V, and is float64 for either V
    auto put = [&](int at, const V &v) {
      for (int l = 0; l < Ls::W; ++l) f[at * Ls::W + l] = (double)Ls::lane(v, l);
    };
    auto seen = [&] {  // the state before this step, and the controller's state before its update
      if (!keep) return;
      for (int d = 0; d < m.ndof; ++d) { put(d, q[d]); put(m.ndof + d, t.qd[d]); }
      for (int k = 0; k < m.nsensor; ++k) put(2 * m.ndof + k, t.bits[k]);
      for (int k = 0; k < ns; ++k) put(at_state + k, cst[k]);
    };
    auto acted = [&] {
      if (keep)
        for (int k = 0; k < m.nact; ++k) put(at_u + k, t.act[k]);
    };
    step(m, t, s, ctl, par, cst, o, acc, seen, acted);
  }
  prepare(m, q, p, t);
  for (int d = 0; d < m.ndof; ++d) qd_out[d] = t.qd[d];
  if (o.oi) centre_of_mass(m, t, acc[A_PX], acc[A_PY], (V *)nullptr, (V *)nullptr);
}

}  // namespace sanlab
