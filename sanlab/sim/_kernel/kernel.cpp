// sanlab's simulator kernel: C entry points over step.h, called through ctypes (sanlab/sim/kernel.py).
//
// rollout runs `steps` steps of a batch of creatures under one kind of controller, tile by tile:
// each tile of W creatures is one OpenMP task, its state copied into an aligned scratch, stepped,
// and copied back. inspect computes what the host asks of single configurations (poses, energy,
// momenta, velocities, sensor values) over the same tiles.
#include <cstring>
#include <cstdlib>
#include <type_traits>
#include <vector>
// No SLP vectorisation of the scalar code: GCC 12 recognises step.h's rotations (c x - s y,
// s x + c y) as complex multiplications and emits a fused vfmaddsub despite -ffp-contract=off,
// so the plain-double form (the GPU's reference) parted from the tiles in the last bit wherever a
// point sits off a link's axis (the kitchen sink's head). The tiles are explicit vectors already:
// measured no slower without it (bounder, 135 ns per creature-step either way).
#pragma GCC optimize("no-tree-slp-vectorize")
#include "rollout.h"

using namespace sanlab;

// The creature's tables as a Model, with the two tables derived from them (dense_idx, children)
struct Tables {
  Model m;
  std::vector<int32_t> dense, kid_start, kids;
  Tables(const int32_t *dims, const void *const *tables) {
    model_of(m, dims, tables);
    dense.resize(m.ndof);
    for (int d = 0; d < m.ndof; ++d) dense[d] = d;
    m.dense_idx = dense.data();
    kid_start.assign(m.nlink + 1, 0);
    for (int i = 0; i < m.nlink; ++i) {
      for (int j = 0; j < m.nlink; ++j)
        if (m.link(j).parent == i) kids.push_back(j);
      kid_start[i + 1] = (int32_t)kids.size();
    }
    kids.push_back(0);  // never read: keeps data() valid for a creature of one link
    m.kid_start = kid_start.data();
    m.kids = kids.data();
  }
};

// f(tile, x, b) for each of T tiles, spread over the threads: each thread's tile scratch and an
// aligned block x of `extra` values of V, the tile's numbers filled in. The two are blocks of
// their own: a scratch that overran its layout would corrupt the state silently (it did once),
// and a sanitizer sees only writes past a block.
template <class V, class F>
static void over_tiles(const Model &m, const void *const *tables, const int32_t *per_row, int64_t T, size_t extra,
                       F f) {
  // at least one value: aligned_alloc of nothing may return null
  auto block = [](size_t n) { return (V *)std::aligned_alloc(64, ((n ? n : 1) * sizeof(V) + 63) / 64 * 64); };
  const size_t nt = tile_values<V>(m);
  // one tile runs on the calling thread: waking the pool for it cost more than the work (a
  // Gymnasium env's step, one creature for one step: 0.48 ms in the kernel call on 2 busy cores)
#pragma omp parallel if (T > 1)
  {
    V *mem = block(nt), *x = block(extra);
    Tile<V> tile = tile_at<V>(m, mem);
#pragma omp for schedule(dynamic, 1)
    for (int64_t b = 0; b < T; ++b) {
      fill_numbers(m, tile, tables, per_row, b);
      f(tile, x, b);
    }
    std::free(mem);
    std::free(x);
  }
}

// copies n values of V between a caller's float64 [T, n, W] array (tile b) and a scratch: a float
// tile rounds what it reads to float and widens what it writes (exactly)
template <class V> static inline void load(V *dst, const double *src, int64_t b, size_t n) {
  using Ls = Lanes<V>;
  src += (size_t)b * n * Ls::W;
  if constexpr (sizeof(real<V>) == sizeof(double)) {
    std::memcpy(dst, src, n * sizeof(V));
  } else {
    for (size_t v = 0; v < n; ++v)
      for (int l = 0; l < Ls::W; ++l) Ls::set(dst[v], l, (real<V>)src[v * Ls::W + l]);
  }
}
template <class V> static inline void store(double *dst, const V *src, int64_t b, size_t n) {
  using Ls = Lanes<V>;
  dst += (size_t)b * n * Ls::W;
  if constexpr (sizeof(real<V>) == sizeof(double)) {
    std::memcpy(dst, src, n * sizeof(V));
  } else {
    for (size_t v = 0; v < n; ++v)
      for (int l = 0; l < Ls::W; ++l) dst[v * Ls::W + l] = (double)Ls::lane(src[v], l);
  }
}

template <class V, class Ctl>
static void rollout(const Ctl &ctl, const int32_t *dims, const void *const *tables, const int32_t *per_row,
                    double *const *state, const double *par, double *cst, const int32_t *oi, const double *of,
                    int32_t init, double *acc, double *qd, double *frames, int64_t every, int64_t n_frames, int64_t T,
                    int64_t steps) {
  Tables tb(dims, tables);
  const Model &m = tb.m;
  const Observers o{oi, of, init};
  const size_t na = oi ? (size_t)obs_values(oi) : 0, npar = Ctl::n_param(m), nst = Ctl::n_state(m);
  const size_t sizes[] = {(size_t)m.ndof, (size_t)m.ndof, (size_t)(2 * m.ncontact), 1, 1};
  const Record rec{every > 0 ? every : 1, n_frames, 2 * m.ndof + m.nsensor + m.nact + (int64_t)nst};
  // a SAN on float tiles sums its inputs lane by lane from its weights as floats (san.h: san_lanes)
  constexpr bool lane_san = std::is_same<Ctl, SanControl<vf>>::value;
  const size_t nw = lane_san ? (size_t)m.ninput * m.nnode : 0;
  const size_t extra = state_values(m) + npar + nst + na + m.ndof + nw;
  over_tiles<V>(m, tables, per_row, T, extra, [&](Tile<V> &tile, V *s, int64_t b) {
    V *at = s;
    for (int k = 0; k < 5; ++k) { load(at, state[k], b, sizes[k]); at += sizes[k]; }
    V *p = at, *c = p + npar, *a = c + nst, *v = a + na;
    load(p, par, b, npar);
    load(c, cst, b, nst);
    if (na && !init) load(a, acc, b, na);
    double *fr = frames ? frames + (size_t)b * n_frames * rec.values * Lanes<V>::W : nullptr;
    auto ctl_b = ctl.at(b);
    if constexpr (lane_san) {
      san_weights(m, ctl_b.weights, ctl_b.NP, v + m.ndof);
      ctl_b.wv = v + m.ndof;
    }
    run_tile(m, tile, ctl_b, s, p, c, steps, o, a, v, rec, fr);
    at = s;
    for (int k = 0; k < 5; ++k) { store(state[k], at, b, sizes[k]); at += sizes[k]; }
    store(cst, c, b, nst);
    if (na) store(acc, a, b, na);
    store(qd, v, b, m.ndof);
  });
}

template <class V>
static void rollout_kind(int32_t kind, const int32_t *dims, const void *const *tables, const int32_t *per_row,
                         double *const *state, const double *par, double *cst, const int16_t *weights, int32_t NP,
                         const int32_t *oi, const double *of, int32_t init, double *acc, double *qd, double *frames,
                         int64_t every, int64_t n_frames, int64_t T, int64_t steps) {
  auto run = [&](const auto &ctl) {
    rollout<V>(ctl, dims, tables, per_row, state, par, cst, oi, of, init, acc, qd, frames, every, n_frames, T, steps);
  };
  if (kind == K_SAN) run(SanControl<V>{(const short *)weights, NP, (size_t)Lanes<V>::W * dims[DIM_INPUTS] * NP});
  else if (kind == K_HOLD) run(HoldControl<V>{});
  else if (kind == K_SINE) run(SineControl<V>{});
  else if (kind == K_PATTERN) run(PatternControl<V>{});
  else run(ReflexControl<V>{});
}

// ---------------------------------------------------------------- inspectors
//
// What the host asks of single configurations, per row: each reads in [n_in] and writes
// out [n_out] (values of V, one per row of the tile; see inspect_sizes).
// (their kinds: layout.h, I_POSES ... I_CENTRE_OF_MASS)

static void inspect_sizes(const Model &m, int kind, size_t &n_in, size_t &n_out) {
  const size_t D = m.ndof;
  switch (kind) {
    case I_POSES: n_in = D; n_out = 3 * (size_t)m.nlink + 3 * (size_t)m.ncontact + 2; break;  // links, contacts, depth, com
    case I_ENERGY: n_in = 2 * D; n_out = 3; break;                                  // q, p -> kinetic, gravity, elastic
    case I_MOMENTA: n_in = 2 * D; n_out = D; break;                                 // q, qd -> p
    case I_VELOCITY: n_in = 2 * D; n_out = D; break;                                // q, p -> qd
    case I_SENSE: n_in = D + 1; n_out = m.nsensor; break;                                 // q, t -> bits
    case I_FOLLOW_POINT: n_in = 1; n_out = 2; break;                                      // t -> follow point
    default: n_in = 2 * D; n_out = 4; break;                                        // q, p -> com, its velocity
  }
}

template <class V> static void inspect(const Model &m, Tile<V> &t, int kind, const V *in, V *out) {
  const V *q = in;
  switch (kind) {
    case I_POSES: {
      positions(m, q, t);
      V *o = out;
      for (int i = 0; i < m.nlink; ++i) { *o++ = t.X[i][0]; *o++ = t.X[i][1]; *o++ = t.th[i]; }
      for (int c = 0; c < m.ncontact; ++c) { *o++ = t.cp[c][0]; *o++ = t.cp[c][1]; }
      for (int c = 0; c < m.ncontact; ++c) *o++ = t.depth[c];
      centre_of_mass(m, t, o[0], o[1], (V *)nullptr, (V *)nullptr);
      break;
    }
    case I_ENERGY:
      prepare(m, q, in + m.ndof, t);
      energy(m, t, out[0], out[1], out[2]);
      break;
    case I_MOMENTA:
      positions(m, q, t);
      momenta(m, t, in + m.ndof, out);
      break;
    case I_VELOCITY:
      prepare(m, q, in + m.ndof, t);
      for (int d = 0; d < m.ndof; ++d) out[d] = t.qd[d];
      break;
    case I_SENSE:
      positions(m, q, t);
      sense(m, t, in[m.ndof]);
      for (int s = 0; s < m.nsensor; ++s) out[s] = t.bits[s];
      break;
    case I_FOLLOW_POINT:
      follow_point(m, t, in[0], out[0], out[1]);
      break;
    default:
      prepare(m, q, in + m.ndof, t);
      centre_of_mass(m, t, out[0], out[1], &out[2], &out[3]);
  }
}

// the hash of the sources this library was built from (setup.py); kernel.py checks it
#ifndef SANLAB_KERNEL_SOURCE
#define SANLAB_KERNEL_SOURCE "unknown"
#endif

extern "C" {

const char *sanlab_kernel_source() { return SANLAB_KERNEL_SOURCE; }

// creatures per tile: float64's (f32 = 0) or float32's (1)
int sanlab_kernel_lanes(int32_t f32) { return f32 ? Lanes<vf>::W : Lanes<vd>::W; }

// The float64 values of one creature's scratch in the scalar form (tables.h: tile_layout): what a
// GPU thread needs besides its state (sanlab/sim/gpu.py); dims as sanlab_rollout's
int64_t sanlab_tile_values(const int32_t *dims) {
  Model m{};
  m.nlink = dims[DIM_LINKS]; m.ncontact = dims[DIM_CONTACTS]; m.ndof = dims[DIM_DOFS]; m.nsensor = dims[DIM_SENSORS];
  m.nact = dims[DIM_ACTUATORS]; m.nrough = dims[DIM_ROUGH]; m.nnode = dims[DIM_NODES]; m.nspring = dims[DIM_SPRINGS];
  m.nedge = dims[DIM_EDGES];
  return (int64_t)tile_values<double>(m);
}

// Runs `steps` steps of T tiles of W creatures under one kind of controller (kernel.py: run_san,
// run_open); scalar = 1: one creature per thread in plain double (W = 1), the form a GPU thread
// runs, here for the tests that it steps every creature bit for bit as the vector form does.
// f32 = 1: the arithmetic in float32 (Lanes<vf>, W = sanlab_kernel_lanes(1); scalar: plain float),
// the caller's arrays float64 still: read rounded to float, written back widened.
// kind: layout.h's K_SAN ... K_PATTERN (see the controllers above for their parameters).
// dims: the counts of layout.DIMS, in its order (DIM_LINKS ...; nodes 0 and inputs = sensors but for a SAN);
// tables: the creature's tables in the order of layout.ORDER; per_row: for each float table but
// the follow path (lf, cf, sf, af, pf, ef, wf, rough), 1 where it holds one copy per row
// ([T * W, ...]: mixed batches), 0 where one copy serves every row; state: q, p [T, D, W], anchor
// [T, C, 2, W], t, dmax [T, W] (updated in place); par [T, n_param, W] the controller's
// parameters, cst [T, n_state, W] its state (updated in place); float64. weights: a SAN's int16
// [T * W, I, NP], each creature's transposed (one row of NP nodes per input), NP the node count
// rounded up to a multiple of 32 (zeros past N); null for the others.
// oi, of: the observers' config (observe.h), or null for none; acc [T, obs_values, W]
// their accumulators (started here when init is 1); qd [T, D, W] receives the final velocity.
// frames: null, or [T, n_frames, 2 D + S + A + n_state, W] for a frame every `every` steps.
void sanlab_rollout(int32_t kind, int32_t scalar, const int32_t *dims, const void *const *tables,
                    const int32_t *per_row, double *const *state, const double *par, double *cst,
                    const int16_t *weights, int32_t NP, const int32_t *oi, const double *of, int32_t init, double *acc,
                    double *qd, double *frames, int64_t every, int64_t n_frames, int64_t T, int64_t steps,
                    int32_t f32) {
  auto run = [&](auto lane) {
    rollout_kind<decltype(lane)>(kind, dims, tables, per_row, state, par, cst, weights, NP, oi, of, init, acc, qd,
                                 frames, every, n_frames, T, steps);
  };
  if (f32) {
    if (scalar) run(0.0f);
    else run(vf{});
  } else {
    if (scalar) run(0.0);
    else run(vd{});
  }
}

// Inspects T tiles of W configurations (kernel.py: poses, energy, momenta, velocity, sense,
// follow_point, centre_of_mass): in [T, n_in, W] -> out [T, n_out, W] (inspect_sizes); scalar = 1:
// one configuration per thread in plain double (W = 1), as rollout's; f32 = 1: in float32, as rollout's.
void sanlab_inspect(int32_t kind, int32_t scalar, const int32_t *dims, const void *const *tables,
                    const int32_t *per_row, const double *in, double *out, int64_t T, int32_t f32) {
  Tables tb(dims, tables);
  const Model &m = tb.m;
  size_t n_in, n_out;
  inspect_sizes(m, kind, n_in, n_out);
  auto run = [&](auto lane) {
    using V = decltype(lane);
    over_tiles<V>(m, tables, per_row, T, n_in + n_out, [&](Tile<V> &tile, V *x, int64_t b) {
      load(x, in, b, n_in);
      inspect(m, tile, kind, x, x + n_in);
      store(out, x + n_in, b, n_out);
    });
  };
  if (f32) {
    if (scalar) run(0.0f);
    else run(vf{});
  } else {
    if (scalar) run(0.0);
    else run(vd{});
  }
}

// Start states at rest: q [T, D, W] seated on the ground in
// place on the lanes where seat [T, W] is nonzero (step.h: seat), and the friction
// anchors anchor [T, C, 2, W] at the contact points of the resulting pose; f32 = 1: in float32
// (W = sanlab_kernel_lanes(1)), as rollout's.
void sanlab_start(const int32_t *dims, const void *const *tables, const int32_t *per_row, double *q,
                  const double *seat_rows, double *anchor, int64_t T, int32_t f32) {
  Tables tb(dims, tables);
  const Model &m = tb.m;
  auto run = [&](auto lane) {
    using V = decltype(lane);
    over_tiles<V>(m, tables, per_row, T, 2 * m.ndof + 1 + 2 * m.ncontact, [&](Tile<V> &tile, V *qt, int64_t b) {
      V *seated = qt + m.ndof, *on = seated + m.ndof, *cp = on + 1;
      load(qt, q, b, m.ndof);
      std::memcpy(seated, qt, m.ndof * sizeof(V));
      load(on, seat_rows, b, 1);
      seat(m, tile, seated);
      for (int d = 0; d < m.ndof; ++d) qt[d] = *on != 0.0f ? seated[d] : qt[d];
      positions(m, qt, tile);
      store(q, qt, b, m.ndof);
      for (int c = 0; c < m.ncontact; ++c)
        for (int a = 0; a < 2; ++a) cp[2 * c + a] = tile.cp[c][a];
      store(anchor, cp, b, 2 * m.ncontact);
    });
  };
  if (f32) run(vf{});
  else run(vd{});
}
}
