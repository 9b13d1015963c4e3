// Lanes: the value type the kernel is written over. A GCC vector of W doubles or W floats on the
// CPU (one SIMD register per value: every operation of a step is one vector instruction for a
// whole tile of W creatures), or plain double or float (one creature per thread: the GPU's form,
// and the tests' reference). R is the arithmetic's scalar type: float64 (double) or float32
// (float), the model's dtype; every constant of a step is written as an R (or as a float literal,
// exact in both) so that a float step computes in float and a double one as it always did.
// sin and cos are one polynomial per R on every lane and target, so a trajectory does not depend
// on which lane computed it.
//
// The same headers compile for a GPU at run time through NVRTC (sanlab/sim/gpu.py, gpu.cu), which
// defines __CUDACC_RTC__ and has no C++ standard library, no GCC vector types and no __builtin_*:
// there only the scalar forms exist, over CUDA's sqrt, floor, fabs and atan2 (sqrt, floor and fabs
// are exact in IEEE arithmetic, as GCC's builtins are, so they give the same bits).
#pragma once
#ifdef __CUDACC_RTC__  // <cstdint> and <cstddef> are gpu.py's (HEADERS): their few typedefs
#define SANLAB_MATH(f) ::f
// a rollout inlined whole into each entry point (gpu.cu's gpu_rollout, run_tile, step): left to
// itself NVRTC's inliner calls one of them as a function once the scratch is Strided, and the
// tile it is handed by reference then lives on the stack (about 800 bytes), each of its pointers
// loaded from there (and with run_tile inlined alone, spills)
#define SANLAB_INLINE __forceinline__
#else
#define SANLAB_INLINE inline
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#if defined(__AVX__)
#include <immintrin.h>
#endif
#define SANLAB_MATH(f) __builtin_##f
#endif
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

namespace sanlab {

template <class V> struct Lanes;

template <> struct Lanes<double> {
  static constexpr int W = 1;
  using M = bool;
  using R = double;
  static double sel(bool m, double a, double b) { return m ? a : b; }
  static double sqrt(double a) { return SANLAB_MATH(sqrt)(a); }
  static double floor(double a) { return SANLAB_MATH(floor)(a); }
  static double abs(double a) { return SANLAB_MATH(fabs)(a); }
  // the eye's angle: glibc's atan2 on the CPU, CUDA's (2 ulp) on a GPU: the one function whose
  // bits may differ between the two (docs/gpu.md)
  static double atan2(double y, double x) { return SANLAB_MATH(atan2)(y, x); }
  static double min(double a, double b) { return a < b ? a : b; }
  static double max(double a, double b) { return a > b ? a : b; }
  static bool any(bool m) { return m; }
  static bool on(bool m, int) { return m; }
  static double lane(double a, int) { return a; }
  static void set(double &a, int, double v) { a = v; }
};

// float32: the same in float (sqrtf, floorf, fabsf, atan2f), one creature per thread
template <> struct Lanes<float> {
  static constexpr int W = 1;
  using M = bool;
  using R = float;
  static float sel(bool m, float a, float b) { return m ? a : b; }
  static float sqrt(float a) { return SANLAB_MATH(sqrtf)(a); }
  static float floor(float a) { return SANLAB_MATH(floorf)(a); }
  static float abs(float a) { return SANLAB_MATH(fabsf)(a); }
  static float atan2(float y, float x) { return SANLAB_MATH(atan2f)(y, x); }
  static float min(float a, float b) { return a < b ? a : b; }
  static float max(float a, float b) { return a > b ? a : b; }
  static bool any(bool m) { return m; }
  static bool on(bool m, int) { return m; }
  static float lane(float a, int) { return a; }
  static void set(float &a, int, float v) { a = v; }
};

#ifndef __CUDACC_RTC__  // the CPU's SIMD tiles
// A tile is one 64-byte value per quantity whatever the machine: 8 doubles or 16 floats, one
// AVX-512 register (an AVX2 machine splits it in two, a narrower one further). The float tile
// takes twice the creatures of the double one in the same bytes.
#ifndef SANLAB_LANES
#define SANLAB_LANES 8
#endif
#define SANLAB_FLOAT_LANES (2 * SANLAB_LANES)
typedef double vd __attribute__((vector_size(8 * SANLAB_LANES)));
typedef long vm __attribute__((vector_size(8 * SANLAB_LANES)));
typedef float vf __attribute__((vector_size(4 * SANLAB_FLOAT_LANES)));
typedef int vmf __attribute__((vector_size(4 * SANLAB_FLOAT_LANES)));

template <> struct Lanes<vd> {
  static constexpr int W = SANLAB_LANES;
  using M = vm;
  using R = double;
  static vd sel(vm m, vd a, vd b) { return m ? a : b; }
  static vd sqrt(vd a) {
    vd r;
    for (int l = 0; l < W; ++l) r[l] = __builtin_sqrt(a[l]);
    return r;
  }
  static vd floor(vd a) {
    vd r;
    for (int l = 0; l < W; ++l) r[l] = __builtin_floor(a[l]);
    return r;
  }
  static vd abs(vd a) { return a < 0.0 ? -a : a; }
  // min/max as the scalar form: a < b ? a : b (NaN handling the same on every lane)
  static vd min(vd a, vd b) { return a < b ? a : b; }
  static vd max(vd a, vd b) { return a > b ? a : b; }
  static bool any(vm m) {
    long r = 0;
    for (int l = 0; l < W; ++l) r |= m[l];
    return r != 0;
  }
  static double lane(vd a, int l) { return a[l]; }
  static bool on(vm m, int l) { return m[l] != 0; }
  static void set(vd &a, int l, double v) { a[l] = v; }
};

template <> struct Lanes<vf> {
  static constexpr int W = SANLAB_FLOAT_LANES;
  using M = vmf;
  using R = float;
  static vf sel(vmf m, vf a, vf b) { return m ? a : b; }
  static vf sqrt(vf a) {
    vf r;
    for (int l = 0; l < W; ++l) r[l] = __builtin_sqrtf(a[l]);
    return r;
  }
  // floorf on every lane, one instruction a register where the machine has it (GCC leaves the
  // loop below scalar, its SLP vectoriser being off: kernel.cpp), exact as floorf is (-0 stays -0)
  static vf floor(vf a) {
    vf r;
#if defined(__AVX512F__)
    if constexpr (sizeof(vf) == 64) return (vf)_mm512_roundscale_ps((__m512)a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
#endif
#if defined(__AVX__)
    if constexpr (sizeof(vf) % 32 == 0) {
      for (size_t k = 0; k < sizeof(vf); k += 32) {
        __m256 h;
        std::memcpy(&h, (const char *)&a + k, 32);
        h = _mm256_floor_ps(h);
        std::memcpy((char *)&r + k, &h, 32);
      }
      return r;
    }
#endif
    for (int l = 0; l < W; ++l) r[l] = __builtin_floorf(a[l]);
    return r;
  }
  static vf abs(vf a) { return a < 0.0f ? -a : a; }
  static vf min(vf a, vf b) { return a < b ? a : b; }
  static vf max(vf a, vf b) { return a > b ? a : b; }
  // a test of the whole mask where the machine has one (the lane loop stays scalar, as floor's)
  static bool any(vmf m) {
#if defined(__AVX512F__)
    if constexpr (sizeof(vmf) == 64) return _mm512_test_epi32_mask((__m512i)m, (__m512i)m) != 0;
#endif
#if defined(__AVX__)
    if constexpr (sizeof(vmf) % 32 == 0) {
      for (size_t k = 0; k < sizeof(vmf); k += 32) {
        __m256i h;
        std::memcpy(&h, (const char *)&m + k, 32);
        if (!_mm256_testz_si256(h, h)) return true;
      }
      return false;
    }
#endif
    int r = 0;
    for (int l = 0; l < W; ++l) r |= m[l];
    return r != 0;
  }
  static float lane(vf a, int l) { return a[l]; }
  static bool on(vmf m, int l) { return m[l] != 0; }
  static void set(vf &a, int l, float v) { a[l] = v; }
};
#endif  // __CUDACC_RTC__

// the scalar type of lane type V: double or float
template <class V> using real = typename Lanes<V>::R;

// sin and cos on lanes: Cody-Waite reduction to [-pi/4, pi/4] and kernel polynomials, branch-free
// so that it vectorises; the same code on every target, so a creature's trajectory does not depend
// on which lane or target computed it. float64: fdlibm's polynomials (|error| about 1 ulp);
// float32: Cephes' sinf and cosf (about 1 ulp of float), reduced by pi/2 in three parts whose
// first has 8 bits, exact in k p1 for |x| below about 10^5 rad.
template <class V> static inline void sincos(V x, V &s, V &c) {
  using Ls = Lanes<V>;
  using R = real<V>;
  V k, ps, pc;
  if constexpr (sizeof(R) == sizeof(double)) {
    const double p1 = 1.57079632673412561417e+00, p2 = 6.07710050630396597660e-11, p3 = 2.02226624879595063154e-21;
    k = Ls::floor(x * 0.63661977236758134308 + 0.5);
    V r = ((x - k * p1) - k * p2) - k * p3;
    V z = r * r;
    ps = r + r * z * (-1.66666666666666324348e-01 + z * (8.33333333332248946124e-03 + z * (-1.98412698298579493134e-04 +
         z * (2.75573137070700676789e-06 + z * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10)))));
    V hz = 0.5 * z;
    V w = 1.0 - hz;
    pc = w + (((1.0 - w) - hz) + z * z * (4.16666666666666019037e-02 + z * (-1.38888888888741095749e-03 +
         z * (2.48015872894767294178e-05 + z * (-2.75573143513906633035e-07 + z * (2.08757232129817482790e-09 +
         z * -1.13596475577881948265e-11))))));
  } else {
    const R p1 = 1.5703125f, p2 = 4.837512969970703125e-4f, p3 = R(7.54978995489188216e-8);
    k = Ls::floor(x * R(0.63661977236758134308) + 0.5f);
    V r = ((x - k * p1) - k * p2) - k * p3;
    V z = r * r;
    ps = r + r * z * (R(-1.6666654611e-1) + z * (R(8.3321608736e-3) + z * R(-1.9515295891e-4)));
    pc = ((z * z) * (R(4.166664568298827e-2) + z * (R(-1.388731625493765e-3) + z * R(2.443315711809948e-5))) -
          0.5f * z) + 1.0f;
  }
  // quadrant n = k mod 4: sin = (ps, pc, -ps, -pc)[n], cos = (pc, -ps, -pc, ps)[n]
  V q = k - 4.0f * Ls::floor(k * 0.25f);
  auto swap = (q == 1.0f) | (q == 3.0f);
  V s0 = Ls::sel(swap, pc, ps), c0 = Ls::sel(swap, ps, pc);
  s = Ls::sel(q >= 2.0f, -s0, s0);
  c = Ls::sel((q == 1.0f) | (q == 2.0f), -c0, c0);
}

// a wrapped to [-pi, pi) (rad)
template <class V> static inline V wrap_angle(V a) {
  using R = real<V>;
  return a - R(2 * M_PI) * Lanes<V>::floor((a + R(M_PI)) * R(0.5 / M_PI));
}

}  // namespace sanlab
