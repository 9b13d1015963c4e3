// The step of sanlab's simulator over a tile of W creatures, reading the creature as data.
//
// One template serves every target: V is the lane type, a GCC vector of W doubles on the CPU (one
// SIMD register per value: every operation below is one vector instruction for the whole tile),
// or plain double (one creature per thread: the GPU's form, and a test's reference). The tables
// are those of sanlab/sim/kernel.py's pack(); the arithmetic follows sanlab/sim/dynamics.py term
// for term (see that module's docstring for the physics): the same coordinates, the same
// momentum-form semi-implicit step with implicitly linearised elements, the same stick-slip
// contact laws and the same L D L^T elimination order.
#pragma once
#include <cmath>
#include <cstdint>

namespace sanlab {

// ---------------------------------------------------------------- lanes

template <class V> struct Lanes;

template <> struct Lanes<double> {
  static constexpr int W = 1;
  using M = bool;
  static double sel(bool m, double a, double b) { return m ? a : b; }
  static double sqrt(double a) { return __builtin_sqrt(a); }
  static double floor(double a) { return __builtin_floor(a); }
  static double abs(double a) { return __builtin_fabs(a); }
  static double min(double a, double b) { return a < b ? a : b; }
  static double max(double a, double b) { return a > b ? a : b; }
  static bool any(bool m) { return m; }
  static double lane(double a, int) { return a; }
  static void set(double &a, int, double v) { a = v; }
};

#ifndef SANLAB_LANES
#define SANLAB_LANES 8
#endif
typedef double vd __attribute__((vector_size(8 * SANLAB_LANES)));
typedef long vm __attribute__((vector_size(8 * SANLAB_LANES)));

template <> struct Lanes<vd> {
  static constexpr int W = SANLAB_LANES;
  using M = vm;
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
  static void set(vd &a, int l, double v) { a[l] = v; }
};

// sin and cos on lanes: Cody-Waite reduction to [-pi/4, pi/4] and fdlibm's kernel polynomials
// (|error| about 1 ulp), branch-free so that it vectorises; the same code on every target, so a
// creature's trajectory does not depend on which lane or target computed it.
template <class V> static inline void sincos(V x, V &s, V &c) {
  using Ls = Lanes<V>;
  const double p1 = 1.57079632673412561417e+00, p2 = 6.07710050630396597660e-11, p3 = 2.02226624879595063154e-21;
  V k = Ls::floor(x * 0.63661977236758134308 + 0.5);
  V r = ((x - k * p1) - k * p2) - k * p3;
  V z = r * r;
  V ps = r + r * z * (-1.66666666666666324348e-01 + z * (8.33333333332248946124e-03 + z * (-1.98412698298579493134e-04 +
         z * (2.75573137070700676789e-06 + z * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10)))));
  V hz = 0.5 * z;
  V w = 1.0 - hz;
  V pc = w + (((1.0 - w) - hz) + z * z * (4.16666666666666019037e-02 + z * (-1.38888888888741095749e-03 +
         z * (2.48015872894767294178e-05 + z * (-2.75573143513906633035e-07 + z * (2.08757232129817482790e-09 +
         z * -1.13596475577881948265e-11))))));
  // quadrant n = k mod 4: sin = (ps, pc, -ps, -pc)[n], cos = (pc, -ps, -pc, ps)[n]
  V q = k - 4.0 * Ls::floor(k * 0.25);
  auto swap = (q == 1.0) | (q == 3.0);
  V s0 = Ls::sel(swap, pc, ps), c0 = Ls::sel(swap, ps, pc);
  s = Ls::sel(q >= 2.0, -s0, s0);
  c = Ls::sel((q == 1.0) | (q == 2.0), -c0, c0);
}

// ---------------------------------------------------------------- the tables (see kernel.pack)

enum { L_PARENT, L_POINT, L_DX, L_DY, L_ROT, L_TREE, L_WELDED, L_ANISO, L_AX_FROM, L_AX_TO, L_SPRING, L_LIMIT, LI };
enum { F_MASS, F_INERTIA, F_COMX, F_COMY, F_ANCX, F_ANCY, F_POSEX, F_POSEY, F_POSEA, F_MU, F_JSPRING = 12, F_LIMIT = 15, LF = 19 };
enum { W_GRAVITY, W_GK, W_GC, W_SLIP, W_DT, W_SLOPE, W_HILL_H, W_HILL_W, W_HILL_C };
enum { W_TERRAIN, W_HIDDEN };

struct Model {
  int L, C, T, D, S, A, R, K, N, I;
  const int32_t *li, *ri, *rl, *rn, *ti, *ci, *si, *ai, *wi;
  const double *lf, *cf, *sf, *af, *wf, *rough;
};

// A tile's scratch: every per-creature value of a step, one V each, carved out of one block sized
// for the creature (tile_bytes); matrices are D x D, row-major.
template <class V> struct Tile {
  V *th, (*cs)[2], (*X)[2], (*com)[2], (*mc)[2], (*S)[2], *w, (*V_)[2];
  double *msum;
  V (*cp)[2], *depth, (*gn)[4], (*cv)[2];
  V *M, *A, *F, *Lf;
  V *Q, *u, *qd, *g, *x;
  V *total, *bits, *act;
};

template <class V> static size_t tile_values(const Model &m) {
  const size_t L = m.L, C = m.C, D = m.D;
  return L * 12 + L + C * 10 + 4 * D * D + 5 * D + 2 * m.N + m.S + m.A;
}

// Lays out a tile's scratch in `mem` (tile_values<V>(m) values of V, aligned like V).
template <class V> static Tile<V> tile_at(const Model &m, V *mem) {
  Tile<V> t;
  const int L = m.L, C = m.C, D = m.D;
  auto take = [&](size_t n) { V *r = mem; mem += n; return r; };
  t.th = take(L); t.cs = (V(*)[2])take(2 * L); t.X = (V(*)[2])take(2 * L); t.com = (V(*)[2])take(2 * L);
  t.mc = (V(*)[2])take(2 * L); t.S = (V(*)[2])take(2 * L); t.w = take(L); t.V_ = (V(*)[2])take(2 * L);
  t.msum = (double *)take(L);
  t.cp = (V(*)[2])take(2 * C); t.depth = take(C); t.gn = (V(*)[4])take(4 * C); t.cv = (V(*)[2])take(2 * C);
  t.M = take(D * D); t.A = take(D * D); t.F = take(D * D); t.Lf = take(D * D);
  t.Q = take(D); t.u = take(D); t.qd = take(D); t.g = take(D); t.x = take(D);
  t.total = take(m.N); t.bits = take(m.S); t.act = take(m.A);
  return t;
}

template <class V> static inline void positions(const Model &m, const V *q, Tile<V> &t) {
  using Ls = Lanes<V>;
  const int L = m.L;
  for (int i = 0; i < L; ++i) {
    const int32_t *l = m.li + i * LI;
    const double *f = m.lf + i * LF;
    int par = l[L_PARENT], rot = l[L_ROT];
    if (par < 0) {
      if (rot >= 0) t.th[i] = q[rot];
      else t.th[i] = V{} + (l[L_DX] < 0 ? f[F_POSEA] : 0.0);
    } else {
      t.th[i] = t.th[par] + q[rot];
    }
    sincos(t.th[i], t.cs[i][1], t.cs[i][0]);
  }
  for (int i = 0; i < L; ++i) {
    const int32_t *l = m.li + i * LI;
    const double *f = m.lf + i * LF;
    int par = l[L_PARENT];
    if (par < 0) {
      t.X[i][0] = V{} + (l[L_DX] < 0 ? f[F_POSEX] : 0.0);
      t.X[i][1] = V{} + (l[L_DX] < 0 ? f[F_POSEY] : 0.0);
    } else {
      V c = t.cs[par][0], s = t.cs[par][1];
      double ax = f[F_ANCX], ay = f[F_ANCY];
      t.X[i][0] = t.X[par][0] + (c * ax - s * ay);
      t.X[i][1] = t.X[par][1] + (s * ax + c * ay);
    }
  }
  for (int i = 0; i < L; ++i) {
    const double *f = m.lf + i * LF;
    V c = t.cs[i][0], s = t.cs[i][1];
    double rx = f[F_COMX], ry = f[F_COMY];
    t.com[i][0] = t.X[i][0] + (c * rx - s * ry);
    t.com[i][1] = t.X[i][1] + (s * rx + c * ry);
  }
  for (int tr = 0; tr < m.T; ++tr) {
    const int32_t *T = m.ti + tr * 3;
    if (T[1] == 0 || T[2] == 1) continue;
    int r = T[0];
    for (int i = L - 1; i >= 0; --i) {
      if (m.li[i * LI + L_TREE] != tr) continue;
      double mass = m.lf[i * LF + F_MASS], ms = mass;
      V mx = mass * t.com[i][0], my = mass * t.com[i][1];
      for (int j = 0; j < L; ++j)
        if (m.li[j * LI + L_PARENT] == i) {
          ms = ms + t.msum[j];
          mx = mx + t.mc[j][0];
          my = my + t.mc[j][1];
        }
      t.msum[i] = ms;
      t.mc[i][0] = mx;
      t.mc[i][1] = my;
    }
    double inv = 1.0 / t.msum[r];
    int dx = m.li[r * LI + L_DX], dy = m.li[r * LI + L_DY];
    V sx = q[dx] - t.mc[r][0] * inv, sy = q[dy] - t.mc[r][1] * inv;
    for (int k = 0; k < L; ++k) {
      if (m.li[k * LI + L_TREE] != tr) continue;
      if (m.li[k * LI + L_ROT] >= 0) {
        t.S[k][0] = (t.mc[k][0] - t.msum[k] * t.X[k][0]) * inv;
        t.S[k][1] = (t.mc[k][1] - t.msum[k] * t.X[k][1]) * inv;
      }
      t.X[k][0] = t.X[k][0] + sx;
      t.X[k][1] = t.X[k][1] + sy;
      t.com[k][0] = t.com[k][0] + sx;
      t.com[k][1] = t.com[k][1] + sy;
    }
  }
  const int kind = m.wi[W_TERRAIN];
  for (int c = 0; c < m.C; ++c) {
    int i = m.ci[c];
    double rx = m.cf[c * 2], ry = m.cf[c * 2 + 1];
    V cc = t.cs[i][0], ss = t.cs[i][1];
    V px = t.X[i][0] + (cc * rx - ss * ry), py = t.X[i][1] + (ss * rx + cc * ry);
    t.cp[c][0] = px;
    t.cp[c][1] = py;
    if (kind == 0) {
      t.gn[c][0] = V{};
      t.gn[c][1] = V{} + 1.0;
      t.gn[c][2] = V{} + 1.0;
      t.gn[c][3] = V{};
      t.depth[c] = (0.0 - py) * 1.0;
      continue;
    }
    V h, dh;
    if (kind == 1) {
      h = m.wf[W_SLOPE] * px;
      dh = V{} + m.wf[W_SLOPE];
    } else if (kind == 2) {
      double H = m.wf[W_HILL_H], hw = m.wf[W_HILL_W], cx = m.wf[W_HILL_C];
      V u = (px - cx) * (M_PI / hw), su, cu;
      sincos(u, su, cu);
      auto inside = Ls::abs(px - cx) < hw;
      h = Ls::sel(inside, 0.5 * H * (1.0 + cu), V{});
      dh = Ls::sel(inside, -0.5 * H * (M_PI / hw) * su, V{});
    } else {
      h = V{};
      dh = V{};
      for (int k = 0; k < m.K; ++k) {
        double a = m.rough[k * 3], w = m.rough[k * 3 + 1], ph = m.rough[k * 3 + 2];
        V s, co;
        sincos(w * px + ph, s, co);
        h = h + a * s;
        dh = dh + a * w * co;
      }
    }
    V inv = 1.0 / Ls::sqrt(1.0 + dh * dh);
    t.gn[c][0] = -dh * inv;
    t.gn[c][1] = inv;
    t.gn[c][2] = inv;
    t.gn[c][3] = dh * inv;
    t.depth[c] = (h - py) * inv;
  }
}

// The row g = J^T n of a world point (px, py) on link i along n, at the dofs of the link's chain
// (kernel.py: _point_row); returns the entry count.
template <class V> static inline int point_row(const Model &m, const Tile<V> &t, int i, V px, V py, V nx, V ny, V *g) {
  int n = m.rn[i];
  const int32_t *rl = m.rl + i * m.R;
  for (int a = 0; a < n; ++a) {
    int k = rl[a];
    if (k == -1) g[a] = nx;
    else if (k == -2) g[a] = ny;
    else if (k == -3) g[a] = V{};
    else g[a] = (-(py - t.X[k][1])) * nx + (px - t.X[k][0]) * ny;
  }
  return n;
}

// A += coef g g^T on the row's dofs, each product formed as (coef g_i) g_j, i >= j
template <class V> static inline void outer(V *A, int D, V coef, const int32_t *idx, const V *g, int n) {
  for (int a = 0; a < n; ++a) {
    int i = idx[a];
    V cgi = coef * g[a];
    for (int b = 0; b < a; ++b) {
      int j = idx[b];
      V v = cgi * g[b];
      A[i * D + j] += v;
      A[j * D + i] += v;
    }
    A[i * D + i] += cgi * g[a];
  }
}

template <class V> static inline void force(V *Q, V f, const int32_t *idx, const V *g, int n) {
  for (int a = 0; a < n; ++a) Q[idx[a]] += f * g[a];
}

template <class V> static inline void mass_matrix(const Model &m, Tile<V> &t) {
  const int D = m.D;
  for (int a = 0; a < D * D; ++a) t.M[a] = V{};
  for (int i = 0; i < m.L; ++i) {
    if (m.li[i * LI + L_WELDED]) continue;
    const int32_t *idx = m.ri + i * m.R;
    V mass = V{} + m.lf[i * LF + F_MASS], I = V{} + m.lf[i * LF + F_INERTIA];
    int n = point_row(m, t, i, t.com[i][0], t.com[i][1], V{} + 1.0, V{}, t.g);
    outer(t.M, D, mass, idx, t.g, n);
    n = point_row(m, t, i, t.com[i][0], t.com[i][1], V{}, V{} + 1.0, t.g);
    outer(t.M, D, mass, idx, t.g, n);
    for (int a = 0; a < n; ++a) t.g[a] = V{} + (m.rl[i * m.R + a] >= 0 ? 1.0 : 0.0);
    outer(t.M, D, I, idx, t.g, n);
  }
}

// x = A^-1 b by L D L^T in the elimination order D-1, ..., 0 (sparse.SymMatrix.solve; structural
// zeros carried as exact zeros)
template <class V> static inline void solve(Tile<V> &t, const V *A, const V *b, V *x, int D) {
  V *F = t.F, *Lf = t.Lf;
  // F holds the lower half: F[i][j], i >= j; Lf[k][i] = l_ik (i < k), Lf[k][k] = 1 / d_k
  for (int a = 0; a < D; ++a)
    for (int c = 0; c <= a; ++c) F[a * D + c] = A[a * D + c];
  for (int k = D - 1; k >= 0; --k) {
    V inv = 1.0 / F[k * D + k];
    Lf[k * D + k] = inv;
    for (int i = 0; i < k; ++i) Lf[k * D + i] = F[k * D + i] * inv;
    for (int i = k - 1; i >= 0; --i) {
      V l = Lf[k * D + i];
      for (int j = k - 1; j >= i; --j) F[j * D + i] = F[j * D + i] - l * F[k * D + j];
    }
  }
  for (int a = 0; a < D; ++a) x[a] = b[a];
  for (int k = D - 1; k >= 0; --k)
    for (int i = k - 1; i >= 0; --i) x[i] = x[i] - Lf[k * D + i] * x[k];
  for (int k = 0; k < D; ++k) x[k] = x[k] * Lf[k * D + k];
  for (int k = 0; k < D; ++k)
    for (int i = k - 1; i >= 0; --i) x[k] = x[k] - Lf[k * D + i] * x[i];
}

// Between state and tree coordinates of each free tree (dynamics._to_tree and friends):
// velocities (force = 0; sign +1: u = S v, -1: v = S^-1 u) or forces (force = 1; +1: S^T g,
// -1: S^-T f), in place
template <class V> static inline void turn(const Model &m, const Tile<V> &t, V *v, int sign, int force) {
  for (int tr = 0; tr < m.T; ++tr) {
    const int32_t *T = m.ti + tr * 3;
    if (T[1] == 0 || T[2] == 1) continue;
    int r = T[0], dx = m.li[r * LI + L_DX], dy = m.li[r * LI + L_DY];
    for (int k = 0; k < m.L; ++k) {
      if (m.li[k * LI + L_TREE] != tr || m.li[k * LI + L_ROT] < 0) continue;
      int d = m.li[k * LI + L_ROT];
      V tx = t.S[k][1], ty = -t.S[k][0];
      if (!force) {
        if (sign > 0) { v[dx] = v[dx] + tx * v[d]; v[dy] = v[dy] + ty * v[d]; }
        else { v[dx] = v[dx] - tx * v[d]; v[dy] = v[dy] - ty * v[d]; }
      } else if (sign > 0) {
        v[d] = v[d] + (tx * v[dx] + ty * v[dy]);
      } else {
        v[d] = v[d] - (tx * v[dx] + ty * v[dy]);
      }
    }
  }
}

template <class V> static inline void prepare(const Model &m, const V *q, const V *p, Tile<V> &t) {
  const int D = m.D;
  positions(m, q, t);
  mass_matrix(m, t);
  for (int d = 0; d < D; ++d) t.x[d] = p[d];
  turn(m, t, t.x, -1, 1);
  solve(t, t.M, t.x, t.u, D);
  for (int d = 0; d < D; ++d) t.qd[d] = t.u[d];
  turn(m, t, t.qd, -1, 0);
  for (int i = 0; i < m.L; ++i) {
    const int32_t *l = m.li + i * LI;
    int par = l[L_PARENT], rot = l[L_ROT];
    if (par < 0) {
      t.w[i] = rot >= 0 ? t.u[rot] : V{};
      t.V_[i][0] = l[L_DX] >= 0 ? t.u[l[L_DX]] : V{};
      t.V_[i][1] = l[L_DX] >= 0 ? t.u[l[L_DY]] : V{};
    } else {
      t.w[i] = t.w[par] + t.u[rot];
      V rx = t.X[i][0] - t.X[par][0], ry = t.X[i][1] - t.X[par][1];
      t.V_[i][0] = t.V_[par][0] - t.w[par] * ry;
      t.V_[i][1] = t.V_[par][1] + t.w[par] * rx;
    }
  }
  for (int c = 0; c < m.C; ++c) {
    int i = m.ci[c];
    V rx = t.cp[c][0] - t.X[i][0], ry = t.cp[c][1] - t.X[i][1];
    t.cv[c][0] = t.V_[i][0] - t.w[i] * ry;
    t.cv[c][1] = t.V_[i][1] + t.w[i] * rx;
  }
}

template <class V> static inline void joint(Tile<V> &t, int D, int d, double h, V f, V k, V c, V rate) {
  t.A[d * D + d] += h * c + (h * h) * k;
  t.Q[d] += f - (h * k) * rate;
}

// One step from a prepared tile with activations t.act: q, p, anchor advanced in place; dmax the
// deepest penetration so far
template <class V> static inline void advance(const Model &m, Tile<V> &t, V *q, V *p, V (*anchor)[2], V &dmax) {
  using Ls = Lanes<V>;
  const int D = m.D, L = m.L;
  const double h = m.wf[W_DT];
  for (int a = 0; a < D; ++a) t.Q[a] = V{};
  for (int a = 0; a < D * D; ++a) t.A[a] = t.M[a];
  // the inertial force dT/dq at fixed velocities
  for (int tr = 0; tr < m.T; ++tr) {
    const int32_t *T = m.ti + tr * 3;
    if (T[2] == 1) continue;
    bool free = T[1] == 1;
    int r = T[0];
    V vcx = free ? t.qd[m.li[r * LI + L_DX]] : V{}, vcy = free ? t.qd[m.li[r * LI + L_DY]] : V{};
    for (int i = 0; i < L; ++i) {
      const int32_t *l = m.li + i * LI;
      if (l[L_TREE] != tr || (l[L_PARENT] < 0 && !free)) continue;
      double mass = m.lf[i * LF + F_MASS];
      V rx = t.com[i][0] - t.X[i][0], ry = t.com[i][1] - t.X[i][1];
      V vx = t.V_[i][0] - t.w[i] * ry, vy = t.V_[i][1] + t.w[i] * rx;
      V ux = mass * (vx - vcx), uy = mass * (vy - vcy);
      V Px{}, Py{}, nx = t.com[i][0], ny = t.com[i][1];
      for (int k = i; k >= 0; k = m.li[k * LI + L_PARENT]) {
        Px = Px + t.w[k] * (nx - t.X[k][0]);
        Py = Py + t.w[k] * (ny - t.X[k][1]);
        nx = t.X[k][0];
        ny = t.X[k][1];
        int rot = m.li[k * LI + L_ROT];
        if (rot >= 0 && !(free && m.li[k * LI + L_PARENT] < 0)) t.Q[rot] += -(ux * Px + uy * Py);
      }
    }
  }
  // gravity
  const double grav = m.wf[W_GRAVITY];
  for (int a = 0; a < D; ++a) t.x[a] = V{};
  for (int tr = 0; tr < m.T; ++tr) {
    const int32_t *T = m.ti + tr * 3;
    int r = T[0];
    if (T[1] == 1) {
      double mt = 0.0;
      for (int i = 0; i < L; ++i)
        if (m.li[i * LI + L_TREE] == tr) mt = mt + m.lf[i * LF + F_MASS];
      t.x[m.li[r * LI + L_DY]] = V{} - (mt * grav);
      continue;
    }
    for (int i = 0; i < L; ++i) {
      if (m.li[i * LI + L_TREE] != tr || m.li[i * LI + L_PARENT] < 0) continue;
      int n = point_row(m, t, i, t.com[i][0], t.com[i][1], V{}, V{} + 1.0, t.g);
      force(t.Q, V{} - (m.lf[i * LF + F_MASS] * grav), m.ri + i * m.R, t.g, n);
    }
  }
  turn(m, t, t.x, -1, 1);
  for (int a = 0; a < D; ++a) t.Q[a] += t.x[a];
  // passive joint springs, then stops
  for (int i = 0; i < L; ++i) {
    const int32_t *l = m.li + i * LI;
    if (!l[L_SPRING]) continue;
    const double *f = m.lf + i * LF;
    int d = l[L_ROT];
    double k = f[F_JSPRING], c = f[F_JSPRING + 1], rest = f[F_JSPRING + 2];
    V phi = t.th[i] - t.th[l[L_PARENT]];
    joint(t, D, d, h, -k * (phi - rest) - c * t.u[d], V{} + k, V{} + c, t.u[d]);
  }
  for (int i = 0; i < L; ++i) {
    const int32_t *l = m.li + i * LI;
    if (!l[L_LIMIT]) continue;
    const double *f = m.lf + i * LF;
    int d = l[L_ROT];
    double lo = f[F_LIMIT], hi = f[F_LIMIT + 1], k = f[F_LIMIT + 2], c = f[F_LIMIT + 3];
    V phi = t.th[i] - t.th[l[L_PARENT]];
    V below = Ls::max(k * (lo - phi) - c * t.u[d], V{});
    V above = Ls::min(k * (hi - phi) - c * t.u[d], V{});
    auto on = ((phi < lo) & (below > 0.0)) | ((phi > hi) & (above < 0.0));
    V onv = Ls::sel(on, V{} + 1.0, V{});
    V torque = Ls::sel(phi < lo, below, Ls::sel(phi > hi, above, V{}));
    joint(t, D, d, h, torque, onv * k, onv * c, t.u[d]);
  }
  // actuators (angular servos)
  for (int a = 0; a < m.A; ++a) {
    int j = m.ai[a];
    int d = m.li[j * LI + L_ROT];
    const double *f = m.af + a * 4;
    V target = f[0] + t.act[a] * (f[1] - f[0]);
    V phi = t.th[j] - t.th[m.li[j * LI + L_PARENT]];
    joint(t, D, d, h, f[2] * (target - phi) - f[3] * t.u[d], V{} + f[2], V{} + f[3], t.u[d]);
  }
  // ground contact and stick-slip friction
  const double gk = m.wf[W_GK], gc = m.wf[W_GC], slip = m.wf[W_SLIP];
  const double cn = h * gc + (h * h) * gk;
  for (int c = 0; c < m.C; ++c) {
    int i = m.ci[c];
    const int32_t *l = m.li + i * LI;
    V nx = t.gn[c][0], ny = t.gn[c][1], tx = t.gn[c][2], ty = t.gn[c][3];
    V dep = t.depth[c];
    dmax = Ls::max(dmax, dep);
    V vx = t.cv[c][0], vy = t.cv[c][1];
    V vn = vx * nx + vy * ny, vt = vx * tx + vy * ty;
    V fn = gk * dep - gc * vn;
    auto on = (dep > 0.0) & (fn > 0.0);
    V N = Ls::sel(on, fn, V{});
    V stretch = (t.cp[c][0] - anchor[c][0]) * tx + (t.cp[c][1] - anchor[c][1]) * ty;
    V mu = V{} + m.lf[i * LF + F_MU];
    if (l[L_ANISO]) {
      int frm = l[L_AX_FROM], to = l[L_AX_TO];
      V axx = frm >= 0 ? t.X[to][0] - t.X[frm][0] : t.cs[i][0];
      V axy = frm >= 0 ? t.X[to][1] - t.X[frm][1] : t.cs[i][1];
      mu = Ls::sel((axx * tx + axy * ty) * (gk * stretch + vt) > 0.0, mu, V{} + m.lf[i * LF + F_MU + 1]);
    }
    V limit = mu * N;
    V cs_ = limit / slip;
    V s = Ls::min(Ls::max(stretch, -limit / gk), limit / gk);
    V trial = -gk * s - cs_ * vt;
    V slide = limit / Ls::max(Ls::abs(vt), V{} + slip);
    auto stick = (limit > 0.0) & (Ls::abs(trial) <= limit);
    V held = Ls::sel(stick, s, V{});
    const int32_t *idx = m.ri + i * m.R;
    if (Ls::any(on)) {
      int n = point_row(m, t, i, t.cp[c][0], t.cp[c][1], nx, ny, t.g);
      outer(t.A, D, Ls::sel(on, V{} + cn, V{}), idx, t.g, n);
      force(t.Q, Ls::sel(on, fn - (h * gk) * vn, V{}), idx, t.g, n);
    }
    if (Ls::any(limit > 0.0)) {
      int n = point_row(m, t, i, t.cp[c][0], t.cp[c][1], tx, ty, t.g);
      outer(t.A, D, Ls::sel(stick, h * cs_ + (h * h) * gk, h * slide), idx, t.g, n);
      force(t.Q, Ls::sel(stick, trial - (h * gk) * vt, -slide * vt), idx, t.g, n);
    }
    anchor[c][0] = t.cp[c][0] - held * tx;
    anchor[c][1] = t.cp[c][1] - held * ty;
  }
  // the step: A du = h Q; p += S^T M du; q += h v*
  for (int a = 0; a < D; ++a) t.Q[a] = h * t.Q[a];
  solve(t, t.A, t.Q, t.x, D);
  for (int a = 0; a < D; ++a) {
    V acc{};
    for (int b = 0; b < D; ++b) acc += t.M[a * D + b] * t.x[b];
    t.g[a] = acc;
  }
  turn(m, t, t.g, 1, 1);
  for (int a = 0; a < D; ++a) {
    p[a] = p[a] + t.g[a];
    t.x[a] = t.u[a] + t.x[a];
  }
  turn(m, t, t.x, -1, 0);
  for (int a = 0; a < D; ++a) {
    t.qd[a] = t.x[a];
    q[a] = q[a] + h * t.x[a];
  }
}

template <class V> static inline void sense(const Model &m, Tile<V> &t) {
  using Ls = Lanes<V>;
  for (int s = 0; s < m.S; ++s) {
    int kind = m.si[s * 2], link = m.si[s * 2 + 1];
    if (kind == 0) {
      t.bits[s] = Ls::sel(t.depth[link] > 0.0, V{} + 1.0, V{});
      continue;
    }
    int par = m.li[link * LI + L_PARENT];
    V ang = (par < 0 || kind == 2) ? t.th[link] : t.th[link] - t.th[par];
    V a = ang - (2 * M_PI) * Ls::floor((ang + M_PI) * (0.5 / M_PI));
    t.bits[s] = Ls::sel((a >= m.sf[s * 2]) & (a <= m.sf[s * 2 + 1]), V{} + 1.0, V{});
  }
}

// The SAN's node update (sanlab.san.San.apply): WT [I][N] lanes of weights, inputs the sensor
// bits then the nodes' previous outputs
template <class V> static inline void san(const Model &m, Tile<V> &t, const V *WT, const V *k1, const V *k2, V *istate, V *out) {
  using Ls = Lanes<V>;
  const int N = m.N, S = m.S, H = m.wi[W_HIDDEN];
  const double dt = m.wf[W_DT];
  for (int n = 0; n < N; ++n) t.total[n] = V{};
  for (int i = 0; i < S; ++i)
    for (int n = 0; n < N; ++n) t.total[n] += WT[i * N + n] * t.bits[i];
  for (int i = 0; i < N; ++i)
    for (int n = 0; n < N; ++n) t.total[n] += WT[(S + i) * N + n] * out[i];
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
