// sanlab's simulator kernel: C entry points over step.h, called through ctypes (sanlab/sim/kernel.py).
//
// rollout_san runs `steps` steps of a batch of creatures under SANs, tile by tile: each tile of W
// creatures is one OpenMP task, its state copied into an aligned scratch, stepped, and copied back.
#include <cstring>
#include <cstdlib>
#include <vector>
#include "step.h"

using namespace sanlab;

// A tile's state, copied in and out of the caller's arrays: q, p [D], anchor [C][2], istate,
// out [N], t, dmax, then the SAN's WT [I][N], k1, k2 [N]
// A tile's state, copied in and out of the caller's arrays: q, p [D], anchor [C][2], istate,
// out [N], t, dmax, then the SAN's k1, k2 [N]
template <class V> static size_t state_values(const Model &m) { return 2 * m.D + 2 * m.C + 2 * m.N + 2 + 2 * m.N; }

// The observers' config (see step.h, "observers"), or none
struct Observe {
  const int32_t *oi;
  const double *of;
  int init;  // 1: start the accumulators from this call's first state
};

// Frames to record: every `every` steps from the first, the first `n` of them; each frame holds
// q, qd [D] (the velocity of that state), bits [S], u [A], istate, out [N] (the SAN's state
// before that step), FV values of V in all
struct Record {
  int64_t every, n;
};

inline int64_t frame_values(const Model &m) { return 2 * m.D + m.S + m.A + 2 * m.N; }

template <class V>
static void run_tile(const Model &m, Tile<V> &t, V *s, const short *weights, int NP, int64_t steps, const Observe &o,
                     V *acc, V *qd_out, const Record &rec, V *frames) {
  V *q = s, *p = q + m.D, (*anchor)[2] = (V(*)[2])(p + m.D), *istate = (V *)(anchor + m.C), *out = istate + m.N;
  V *time = out + m.N, *dmax = time + 1, *k1 = dmax + 1, *k2 = k1 + m.N;
  if (o.oi && o.init) {
    positions(m, q, t);
    observe_init(m, t, o.oi, acc);
  }
  for (int64_t n = 0; n < steps; ++n) {
    prepare(m, q, p, t);
    sense(m, t, *time);
    const bool keep = frames && n % rec.every == 0 && n / rec.every < rec.n;
    V *f = keep ? frames + (n / rec.every) * frame_values(m) : nullptr;
    // the caller's frame buffer need not be aligned for V: stored value by value, unaligned
    auto put = [&](int at, const V &v) { std::memcpy((void *)(f + at), &v, sizeof(V)); };
    if (keep) {  // the state before this step, and the SAN's state before its update
      for (int d = 0; d < m.D; ++d) { put(d, q[d]); put(m.D + d, t.qd[d]); }
      for (int k = 0; k < m.S; ++k) put(2 * m.D + k, t.bits[k]);
      for (int k = 0; k < m.N; ++k) { put(2 * m.D + m.S + m.A + k, istate[k]); put(2 * m.D + m.S + m.A + m.N + k, out[k]); }
    }
    san(m, t, weights, NP, k1, k2, istate, out);
    if (keep)
      for (int k = 0; k < m.A; ++k) put(2 * m.D + m.S + k, t.act[k]);
    if (o.oi) observe(m, t, o.oi, o.of, *time, acc);
    advance(m, t, q, p, anchor, *dmax);
    *time = *time + t.wf[W_DT];
  }
  // the final state's velocity M^-1 p (state coordinates) and, for the metric, its centre of mass
  prepare(m, q, p, t);
  for (int d = 0; d < m.D; ++d) qd_out[d] = t.qd[d];
  if (o.oi) centre_of_mass(m, t, acc[A_PX], acc[A_PY], (V *)nullptr, (V *)nullptr);
}

// The creature's tables as a Model, with the two tables derived from them (dense_idx, children)
struct Tables {
  Model m;
  std::vector<int32_t> dense, kid_start, kids;
  Tables(const int32_t *dims, const void *const *tables) {
    m.L = dims[0]; m.C = dims[1]; m.T = dims[2]; m.D = dims[3]; m.S = dims[4]; m.A = dims[5]; m.R = dims[6];
    m.K = dims[7]; m.N = dims[8]; m.I = dims[9]; m.P = dims[10]; m.E = dims[11]; m.F = dims[12];
    const int32_t **ints[] = {&m.li, &m.ri, &m.rl, &m.rn, &m.ti, &m.ci, &m.si, &m.ai, &m.pi, &m.ei, &m.wi};
    const double **reals[] = {&m.lf, &m.cf, &m.sf, &m.af, &m.pf, &m.ef, &m.wf, &m.rough, &m.follow};
    int k = 0;
    for (auto p : ints) *p = (const int32_t *)tables[k++];
    for (auto p : reals) *p = (const double *)tables[k++];
    dense.resize(m.D);
    for (int d = 0; d < m.D; ++d) dense[d] = d;
    m.dense_idx = dense.data();
    kid_start.assign(m.L + 1, 0);
    for (int i = 0; i < m.L; ++i) {
      for (int j = 0; j < m.L; ++j)
        if (m.li[j * LI + L_PARENT] == i) kids.push_back(j);
      kid_start[i + 1] = (int32_t)kids.size();
    }
    kids.push_back(0);  // never read: keeps data() valid for a creature of one link
    m.kid_start = kid_start.data();
    m.kids = kids.data();
  }
};

// A tile's numbers: each lane's row's own (per_row[k]: [T * W, n] tables), or the shared ones on
// every lane
template <class V>
static void fill_numbers(const Model &m, Tile<V> &tile, const void *const *tables, const int32_t *per_row, int64_t b) {
  using Ls = Lanes<V>;
  const int W = Ls::W;
  const size_t counts[] = {(size_t)(m.L * LF), (size_t)(m.C * 3), (size_t)(m.S * 6), (size_t)(m.A * 8), (size_t)(m.P * 7),
                           (size_t)(m.E * 4), (size_t)W_COUNT, (size_t)(m.K * 3)};
  V *dst[] = {tile.lf, tile.cf, tile.sf, tile.af, tile.pf, tile.ef, tile.wf, tile.rough};
  for (int k = 0; k < 8; ++k) {
    const double *src = (const double *)tables[11 + k];
    const size_t n = counts[k];
    for (size_t v = 0; v < n; ++v)
      for (int l = 0; l < W; ++l) Ls::set(dst[k][v], l, per_row[k] ? src[((size_t)b * W + l) * n + v] : src[v]);
  }
}

template <class V>
static void rollout(const int32_t *dims, const void *const *tables, const int32_t *per_row, double *const *state,
                    const int16_t *weights, int32_t NP, const int32_t *oi, const double *of, int32_t init, double *acc,
                    double *qd, double *frames, int64_t every, int64_t n_frames, int64_t T, int64_t steps) {
  Tables tb(dims, tables);
  const Model &m = tb.m;
  const int W = Lanes<V>::W;
  const Observe o{oi, of, init};
  const size_t na = oi ? (size_t)obs_values(oi) : 0;
  const size_t nt = tile_values<V>(m), ns = state_values<V>(m) + na + m.D;
  // the scratch and the state in blocks of their own: a scratch that overran its layout would
  // corrupt the state silently (it did once), and a sanitizer sees only writes past a block
  auto block = [](size_t n) { return (V *)std::aligned_alloc(64, (n * sizeof(V) + 63) / 64 * 64); };
  const size_t sizes[] = {(size_t)m.D, (size_t)m.D, (size_t)(2 * m.C), (size_t)m.N, (size_t)m.N, 1, 1,
                          (size_t)m.N, (size_t)m.N};
  const int n_out = 7;  // the state parts, copied back; the SAN's parts are inputs only
#pragma omp parallel
  {
    V *mem = block(nt), *s = block(ns);
    Tile<V> tile = tile_at<V>(m, mem);
#pragma omp for schedule(dynamic, 1)
    for (int64_t b = 0; b < T; ++b) {
      fill_numbers(m, tile, tables, per_row, b);
      V *at = s;
      for (int k = 0; k < 9; ++k) { std::memcpy(at, state[k] + b * sizes[k] * W, sizes[k] * sizeof(V)); at += sizes[k]; }
      V *a = s + state_values<V>(m), *v = a + na;
      if (na && !init) std::memcpy(a, acc + b * na * W, na * sizeof(V));
      const Record rec{every > 0 ? every : 1, n_frames};
      V *fr = frames ? (V *)frames + (size_t)b * n_frames * frame_values(m) : nullptr;
      run_tile(m, tile, s, (const short *)weights + (size_t)b * W * m.I * NP, NP, steps, o, a, v, rec, fr);
      at = s;
      for (int k = 0; k < n_out; ++k) { std::memcpy(state[k] + b * sizes[k] * W, at, sizes[k] * sizeof(V)); at += sizes[k]; }
      if (na) std::memcpy(acc + b * na * W, a, na * sizeof(V));
      std::memcpy(qd + b * m.D * W, v, m.D * sizeof(V));
    }
    std::free(mem);
    std::free(s);
  }
}

extern "C" {

int sanlab_kernel_lanes() { return Lanes<vd>::W; }

// Runs `steps` steps of T tiles of W creatures under SANs (kernel.py: run_san).
// dims: L, C, T, D, S, A, R, K, N, I, P, E, F (kernel.py); tables: the creature's tables in the
// order of kernel.TABLES; per_row: for each float table but the follow path (lf, cf, sf, af, pf,
// ef, wf, rough), 1 where it holds one copy per row ([T * W, ...]: mixed batches), 0 where one
// copy serves every row; state: q, p [T, D, W], anchor [T, C, 2, W], istate, out [T, N, W], t,
// dmax [T, W] (updated in place), then the SAN's k1, k2 [T, N, W]; float64; weights: the SAN's
// int16 [T * W, I, NP], each creature's transposed (one row of NP nodes per input), NP the node
// count rounded up to a multiple of 32 (zeros past N).
// oi, of: the observers' config (step.h, "observers"), or null for none; acc [T, obs_values, W]
// their accumulators (started here when init is 1); qd [T, D, W] receives the final velocity.
// frames: null, or [T, n_frames, frame_values, W] for a frame every `every` steps.
void sanlab_rollout_san(const int32_t *dims, const void *const *tables, const int32_t *per_row, double *const *state,
                        const int16_t *weights, int32_t NP, const int32_t *oi, const double *of, int32_t init,
                        double *acc, double *qd, double *frames, int64_t every, int64_t n_frames, int64_t T,
                        int64_t steps) {
  rollout<vd>(dims, tables, per_row, state, weights, NP, oi, of, init, acc, qd, frames, every, n_frames, T, steps);
}

// The same with one creature per thread in plain double (W = 1): the form a GPU thread runs, here
// for the tests that it steps every creature bit for bit as the vector form does.
void sanlab_rollout_san_scalar(const int32_t *dims, const void *const *tables, const int32_t *per_row,
                               double *const *state, const int16_t *weights, int32_t NP, const int32_t *oi,
                               const double *of, int32_t init, double *acc, double *qd, double *frames, int64_t every,
                               int64_t n_frames, int64_t T, int64_t steps) {
  rollout<double>(dims, tables, per_row, state, weights, NP, oi, of, init, acc, qd, frames, every, n_frames, T, steps);
}

// Start states at rest (dynamics.make_state with no velocity): q [T, D, W] seated on the ground in
// place on the lanes where seat [T, W] is nonzero (dynamics.seat_on_ground), and the friction
// anchors anchor [T, C, 2, W] at the contact points of the resulting pose.
void sanlab_start(const int32_t *dims, const void *const *tables, const int32_t *per_row, double *q, const double *seat_rows,
                  double *anchor, int64_t T) {
  Tables tb(dims, tables);
  const Model &m = tb.m;
  const int W = Lanes<vd>::W;
  const size_t nt = tile_values<vd>(m);
#pragma omp parallel
  {
    vd *mem = (vd *)std::aligned_alloc(64, nt * sizeof(vd)), *qt = (vd *)std::aligned_alloc(64, (2 * m.D + 1) * sizeof(vd));
    Tile<vd> tile = tile_at<vd>(m, mem);
    vd *seated = qt + m.D, *on = seated + m.D;
#pragma omp for schedule(dynamic, 1)
    for (int64_t b = 0; b < T; ++b) {
      fill_numbers(m, tile, tables, per_row, b);
      std::memcpy(qt, q + b * m.D * W, m.D * sizeof(vd));
      std::memcpy(seated, qt, m.D * sizeof(vd));
      std::memcpy(on, seat_rows + b * W, sizeof(vd));
      seat(m, tile, seated);
      for (int d = 0; d < m.D; ++d) qt[d] = *on != 0.0 ? seated[d] : qt[d];
      positions(m, qt, tile);
      std::memcpy(q + b * m.D * W, qt, m.D * sizeof(vd));
      for (int c = 0; c < m.C; ++c)
        for (int a = 0; a < 2; ++a) std::memcpy(anchor + ((b * m.C + c) * 2 + a) * W, &tile.cp[c][a], sizeof(vd));
    }
    std::free(mem);
    std::free(qt);
  }
}
}
