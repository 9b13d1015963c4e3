// sanlab's simulator on a GPU: the kernel's scalar forms (Lanes<double> and Lanes<float>, one
// creature per thread), compiled at run time by NVRTC (sanlab/sim/gpu.py: -default-device,
// --fmad=false: every multiply and add a separate IEEE operation, as -ffp-contract=off makes them
// on the CPU). The same headers and the same run_tile as kernel.cpp's sanlab_rollout with
// scalar = 1, so a thread steps its creature as the CPU's scalar form does, in float64 or float32
// (docs/gpu.md says where the bits may part: atan2).
//
// Arguments as sanlab_rollout's (kernel.cpp) with W = 1, all in device memory: dims, tables (an
// array of device pointers, layout.ORDER), numbers (8 device pointers: the float tables a row may
// carry its own of, layout.ROW_TABLES, in the arithmetic's type R: float64's are tables' own,
// float32's rounded copies), per_row, state (5 device pointers: q, p [B, D], anchor [B, C, 2], t,
// dmax [B]), par [B, n_param], cst [B, n_state], weights [B, I, NP] (a SAN's; null for the
// others), oi, of, acc [B, obs_values] (null: no observers), qd [B, D], frames [B, n_frames,
// values] or null, all float64 whatever R (a float thread rounds what it reads and widens what it
// writes, as the CPU's float tiles); then derived [D + L + 1 + max(1, kids)] int32: dense_idx,
// kid_start, kids (kernel.cpp's Tables builds the same on the CPU), and scratch
// [ceil(B / SANLAB_WARP), per_thread, SANLAB_WARP] of R, per_thread as gpu.py's scratch_values
// counts it: the tile's (tables.h: tile_layout, which kernel.cpp's sanlab_tile_values answers) and
// the state's.
//
// The scratch is lane-innermost in blocks of a warp: value k of thread b lies at
// (b / SANLAB_WARP) * SANLAB_WARP * per_thread + k * SANLAB_WARP + b % SANLAB_WARP, reached
// through tables.h's Strided, so that the 32 threads of a warp reading their value k read 32
// neighbouring addresses (docs/gpu.md: why blocks of a warp rather than one stride of B).
#include "rollout.h"

using namespace sanlab;

template <class R, class Ctl>
static SANLAB_INLINE void gpu_rollout(const Ctl &ctl, const int32_t *dims, const void *const *tables,
                               const void *const *numbers, const int32_t *per_row, double *const *state,
                               const double *par, double *cst, const int32_t *oi, const double *of, int32_t init,
                               double *acc, double *qd, double *frames, int64_t every, int64_t n_frames,
                               const int32_t *derived, void *scratch, int64_t per_thread, int64_t B, int64_t steps) {
  const int64_t b = (int64_t)blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= B) return;
  Model m;
  model_of(m, dims, tables);
  m.dense_idx = derived;
  m.kid_start = derived + m.ndof;
  m.kids = derived + m.ndof + m.nlink + 1;
  const Observers o{oi, of, init};
  const size_t na = oi ? (size_t)obs_values(oi) : 0, npar = Ctl::n_param(m), nst = Ctl::n_state(m);
  const size_t sizes[] = {(size_t)m.ndof, (size_t)m.ndof, (size_t)(2 * m.ncontact), 1, 1};
  const Record rec{every > 0 ? every : 1, n_frames, 2 * m.ndof + m.nsensor + m.nact + (int64_t)nst};
  Ptr<R> mem{(R *)scratch + (b / SANLAB_WARP) * SANLAB_WARP * per_thread + b % SANLAB_WARP};
  Tile<R> tile = tile_at<R>(m, mem);
  // the creature's numbers read where they are, not copied as fill_numbers does for the CPU's
  // lanes: a shared table is one address every thread reads (a broadcast), a per-row one [B, n]
  // is the thread's row (the tile keeps the room for them unused)
  size_t counts[8];
  row_table_sizes(m, counts);
  R **nums[] = {&tile.lf, &tile.cf, &tile.sf, &tile.af, &tile.pf, &tile.ef, &tile.wf, &tile.rough};
  for (int k = 0; k < 8; ++k)  // never written: a step reads them through the tile's const accessors
    *nums[k] = (R *)numbers[k] + (per_row[k] ? b * counts[k] : 0);
  Ptr<R> s = mem + tile_values<R>(m), at = s;
  for (int k = 0; k < 5; ++k) {
    for (size_t v = 0; v < sizes[k]; ++v) at[v] = (R)state[k][b * sizes[k] + v];
    at = at + sizes[k];
  }
  Ptr<R> p = at, c = p + npar, a = c + nst, v = a + na;
  for (size_t k = 0; k < npar; ++k) p[k] = (R)par[b * npar + k];
  for (size_t k = 0; k < nst; ++k) c[k] = (R)cst[b * nst + k];
  if (na && !init)
    for (size_t k = 0; k < na; ++k) a[k] = (R)acc[b * na + k];
  double *fr = frames ? frames + b * n_frames * rec.values : nullptr;
  run_tile(m, tile, ctl.at(b), s, p, c, steps, o, a, v, rec, fr);
  at = s;
  for (int k = 0; k < 5; ++k) {
    for (size_t v = 0; v < sizes[k]; ++v) state[k][b * sizes[k] + v] = (double)at[v];
    at = at + sizes[k];
  }
  for (size_t k = 0; k < nst; ++k) cst[b * nst + k] = (double)c[k];
  for (size_t k = 0; k < na; ++k) acc[b * na + k] = (double)a[k];
  for (int d = 0; d < m.ndof; ++d) qd[b * m.ndof + d] = (double)v[d];
}

#define SANLAB_GPU_ARGS                                                                                             \
  const int32_t *dims, const void *const *tables, const void *const *numbers, const int32_t *per_row,            \
      double *const *state, const double *par, double *cst, const int16_t *weights, int32_t NP, const int32_t *oi, \
      const double *of, int32_t init, double *acc, double *qd, double *frames, int64_t every, int64_t n_frames,    \
      const int32_t *derived, void *scratch, int64_t per_thread, int64_t B, int64_t steps
#define SANLAB_GPU_PASS                                                                                              \
  dims, tables, numbers, per_row, state, par, cst, oi, of, init, acc, qd, frames, every, n_frames, derived, scratch, \
      per_thread, B, steps

// one entry per controller (layout.h's K_SAN ... K_PATTERN) and arithmetic (float64:
// sanlab_gpu_san ..., float32: sanlab_gpu_san_f32 ...), each built where gpu.py defines its
// SANLAB_GPU_<KIND> and SANLAB_GPU_F64 or SANLAB_GPU_F32 (a search's first call waits for the
// SAN's entry in its arithmetic alone), and reporting its registers alone
#define SANLAB_GPU_SAN_CONTROL(R) SanControl<R>{(const short *)weights, NP, (size_t)dims[DIM_INPUTS] * NP}
#ifdef SANLAB_GPU_F64
#ifdef SANLAB_GPU_SAN
extern "C" __global__ void sanlab_gpu_san(SANLAB_GPU_ARGS) {
  gpu_rollout<double>(SANLAB_GPU_SAN_CONTROL(double), SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_HOLD
extern "C" __global__ void sanlab_gpu_hold(SANLAB_GPU_ARGS) {
  gpu_rollout<double>(HoldControl<double>{}, SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_SINE
extern "C" __global__ void sanlab_gpu_sine(SANLAB_GPU_ARGS) {
  gpu_rollout<double>(SineControl<double>{}, SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_REFLEX
extern "C" __global__ void sanlab_gpu_reflex(SANLAB_GPU_ARGS) {
  gpu_rollout<double>(ReflexControl<double>{}, SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_PATTERN
extern "C" __global__ void sanlab_gpu_pattern(SANLAB_GPU_ARGS) {
  gpu_rollout<double>(PatternControl<double>{}, SANLAB_GPU_PASS);
}
#endif
#endif  // SANLAB_GPU_F64

#ifdef SANLAB_GPU_F32
#ifdef SANLAB_GPU_SAN
extern "C" __global__ void sanlab_gpu_san_f32(SANLAB_GPU_ARGS) {
  gpu_rollout<float>(SANLAB_GPU_SAN_CONTROL(float), SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_HOLD
extern "C" __global__ void sanlab_gpu_hold_f32(SANLAB_GPU_ARGS) {
  gpu_rollout<float>(HoldControl<float>{}, SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_SINE
extern "C" __global__ void sanlab_gpu_sine_f32(SANLAB_GPU_ARGS) {
  gpu_rollout<float>(SineControl<float>{}, SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_REFLEX
extern "C" __global__ void sanlab_gpu_reflex_f32(SANLAB_GPU_ARGS) {
  gpu_rollout<float>(ReflexControl<float>{}, SANLAB_GPU_PASS);
}
#endif
#ifdef SANLAB_GPU_PATTERN
extern "C" __global__ void sanlab_gpu_pattern_f32(SANLAB_GPU_ARGS) {
  gpu_rollout<float>(PatternControl<float>{}, SANLAB_GPU_PASS);
}
#endif
#endif  // SANLAB_GPU_F32
