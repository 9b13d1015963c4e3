// sanlab's simulator kernel: C entry points over step.h, called through ctypes (sanlab/sim/kernel.py).
//
// rollout_san runs `steps` steps of a batch of creatures under SANs, tile by tile: each tile of W
// creatures is one OpenMP task, its state copied into an aligned scratch, stepped, and copied back.
#include <cstring>
#include <cstdlib>
#include "step.h"

using namespace sanlab;

// A tile's state, copied in and out of the caller's arrays: q, p [D], anchor [C][2], istate,
// out [N], t, dmax, then the SAN's WT [I][N], k1, k2 [N]
template <class V> static size_t state_values(const Model &m) { return 2 * m.D + 2 * m.C + 2 * m.N + 2 + m.I * m.N + 2 * m.N; }

template <class V> static void run_tile(const Model &m, Tile<V> &t, V *s, int64_t steps) {
  const double h = m.wf[W_DT];
  V *q = s, *p = q + m.D, (*anchor)[2] = (V(*)[2])(p + m.D), *istate = (V *)(anchor + m.C), *out = istate + m.N;
  V *time = out + m.N, *dmax = time + 1, *WT = dmax + 1, *k1 = WT + m.I * m.N, *k2 = k1 + m.N;
  for (int64_t n = 0; n < steps; ++n) {
    prepare(m, q, p, t);
    sense(m, t);
    san(m, t, WT, k1, k2, istate, out);
    advance(m, t, q, p, anchor, *dmax);
    *time = *time + h;
  }
}

extern "C" {

int sanlab_kernel_lanes() { return Lanes<vd>::W; }

// Arrays (float64 unless said): tables as kernel.pack(); per tile (T tiles of W lanes, lane last):
// q, p [T, D, W], anchor [T, C, 2, W], istate, out [T, N, W], t, dmax [T, W], WT [T, I, N, W],
// k1, k2 [T, N, W]; the state updated in place. Returns 0.
int sanlab_rollout_san(const int32_t *dims, const int32_t *li, const int32_t *ri, const int32_t *rl, const int32_t *rn,
                       const int32_t *ti, const int32_t *ci, const int32_t *si, const int32_t *ai, const int32_t *wi,
                       const double *lf, const double *cf, const double *sf, const double *af, const double *wf,
                       const double *rough, double *q, double *p, double *anchor, double *istate, double *out, double *t,
                       double *dmax, const double *WT, const double *k1, const double *k2, int64_t T, int64_t steps) {
  Model m;
  m.L = dims[0]; m.C = dims[1]; m.T = dims[2]; m.D = dims[3]; m.S = dims[4]; m.A = dims[5]; m.R = dims[6];
  m.K = dims[7]; m.N = dims[8]; m.I = dims[9];
  m.li = li; m.ri = ri; m.rl = rl; m.rn = rn; m.ti = ti; m.ci = ci; m.si = si; m.ai = ai; m.wi = wi;
  m.lf = lf; m.cf = cf; m.sf = sf; m.af = af; m.wf = wf; m.rough = rough;
  const int W = Lanes<vd>::W;
  const int D = m.D, C = m.C, N = m.N, I = m.I;
  const size_t nt = tile_values<vd>(m), ns = state_values<vd>(m);
  struct Part { double *base; size_t n; };  // one caller array: its tile's share is n values of vd
  const Part parts[] = {{q, (size_t)D}, {p, (size_t)D}, {anchor, (size_t)(2 * C)}, {istate, (size_t)N}, {out, (size_t)N},
                        {t, 1}, {dmax, 1}, {(double *)WT, (size_t)(I * N)}, {(double *)k1, (size_t)N}, {(double *)k2, (size_t)N}};
  const int n_out = 7;  // the state parts, copied back; the SAN's parts are inputs only
#pragma omp parallel
  {
    vd *mem = (vd *)std::aligned_alloc(64, (nt + ns) * sizeof(vd));
    Tile<vd> tile = tile_at<vd>(m, mem);
    vd *s = mem + nt;
#pragma omp for schedule(dynamic, 1)
    for (int64_t b = 0; b < T; ++b) {
      vd *at = s;
      for (const Part &x : parts) { std::memcpy(at, x.base + b * x.n * W, x.n * sizeof(vd)); at += x.n; }
      run_tile(m, tile, s, steps);
      at = s;
      for (int k = 0; k < n_out; ++k) { std::memcpy(parts[k].base + b * parts[k].n * W, at, parts[k].n * sizeof(vd)); at += parts[k].n; }
    }
    std::free(mem);
  }
  return 0;
}
}
