// The step of sanlab's simulator over a tile of W creatures, reading the creature as data.
//
// One template serves every target: V is the lane type, a GCC vector of W doubles on the CPU (one
// SIMD register per value: every operation below is one vector instruction for the whole tile),
// or plain double (one creature per thread: the GPU's form, and a test's reference). The tables
// are those of sanlab/sim/kernel.py's pack(); the arithmetic follows the XLA engine it replaced,
// sanlab/sim/dynamics.py (removed after issue 46; `git show 019d665:sanlab/sim/dynamics.py`), term
// for term (docs/simulator.md for the physics): the same coordinates, the same momentum-form
// semi-implicit step with implicitly linearised elements, the same stick-slip contact laws and the
// same L D L^T elimination order. A name in parentheses below, dynamics.f, is the function of that
// module a part was ported from.
#pragma once
#include <cmath>
#include <cstdint>

#include "layout.h"

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
  static bool on(bool m, int) { return m; }
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
  static bool on(vm m, int l) { return m[l] != 0; }
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

// ---------------------------------------------------------------- the tables (see layout.h)

// The creature as tables (kernel.py: Packed, in the order of layout.ORDER), each row read through
// its struct (layout.h): m.link(i).parent, t.link(i).mass, t.actuator(a).ks
struct Model {
  int nlink, ncontact, ntree, ndof, nsensor, nact, nchain, nrough, nnode, ninput, nspring, nedge, nfollow;
  const int32_t *li, *ri, *rl, *rn, *ti, *ci, *si, *ai, *pi, *ei, *wi;
  const double *lf, *cf, *sf, *af, *pf, *ef, *wf, *rough, *follow;
  const int32_t *dense_idx;  // 0, 1, ..., ndof - 1: a row over every dof
  const int32_t *kid_start, *kids;  // each link's children, in link order: kids[kid_start[i] .. kid_start[i + 1])
  const LinkInts &link(int i) const { return ((const LinkInts *)li)[i]; }
  const TreeInts &tree(int i) const { return ((const TreeInts *)ti)[i]; }
  const SensorInts &sensor(int i) const { return ((const SensorInts *)si)[i]; }
  const ActuatorInts &actuator(int i) const { return ((const ActuatorInts *)ai)[i]; }
  const SpringInts &spring(int i) const { return ((const SpringInts *)pi)[i]; }
  const WorldInts &world() const { return *(const WorldInts *)wi; }
};
static_assert(sizeof(LinkInts) == LI_WIDTH * sizeof(int32_t) && sizeof(TreeInts) == TI_WIDTH * sizeof(int32_t) &&
              sizeof(SensorInts) == SI_WIDTH * sizeof(int32_t) && sizeof(ActuatorInts) == AI_WIDTH * sizeof(int32_t) &&
              sizeof(SpringInts) == PI_WIDTH * sizeof(int32_t) && sizeof(WorldInts) == WI_WIDTH * sizeof(int32_t),
              "layout.h's rows are packed tables");

// A tile's scratch: every per-creature value of a step, one V each, carved out of one block sized
// for the creature (tile_bytes); matrices are ndof x ndof, row-major.
template <class V> struct Tile {
  // the creature's numbers, one V each: a lane's own where rows carry their own (mixed batches),
  // else the shared value on every lane (kernel.cpp fills them as a tile starts); read through
  // the rows' structs below
  V *lf, *cf, *sf, *af, *pf, *ef, *wf, *rough;
  V *th, (*cs)[2], (*X)[2], (*com)[2], (*mc)[2], (*S)[2], *w, (*V_)[2];
  V *msum;
  V (*cp)[2], *depth, (*gn)[4], (*cv)[2];
  V *M, *A, *F, *Lf;
  V *Q, *u, *qd, *g, *x, *row;
  V *total, *bits, *act;
  // the articulated route (art.h): per body its spatial inertia about its tree's reference
  // point, joint motion subspace, the step's extra inertia E and spatial force F, and the
  // recursion's articulated inertias and biases; per dof the extra diagonal (armature)
  V (*I)[6], (*s)[3], (*E)[6], (*Fb)[3], (*IA)[6], (*pA)[3], (*U)[3], *invD, *uu, (*acc)[3], (*Hb)[3], *arm;
  bool art;  // which route: the model's world().articulated
  const LinkNumbers<V> &link(int i) const { return ((const LinkNumbers<V> *)lf)[i]; }
  const ContactNumbers<V> &contact(int i) const { return ((const ContactNumbers<V> *)cf)[i]; }
  const SensorNumbers<V> &sensor(int i) const { return ((const SensorNumbers<V> *)sf)[i]; }
  const ActuatorNumbers<V> &actuator(int i) const { return ((const ActuatorNumbers<V> *)af)[i]; }
  const SpringNumbers<V> &spring(int i) const { return ((const SpringNumbers<V> *)pf)[i]; }
  const EdgeNumbers<V> &edge(int i) const { return ((const EdgeNumbers<V> *)ef)[i]; }
  const WorldNumbers<V> &world() const { return *(const WorldNumbers<V> *)wf; }
  const RoughTerm<V> &rough_term(int k) const { return ((const RoughTerm<V> *)rough)[k]; }
  static_assert(sizeof(LinkNumbers<V>) == LF_WIDTH * sizeof(V) && sizeof(WorldNumbers<V>) == WF_WIDTH * sizeof(V) &&
                sizeof(ActuatorNumbers<V>) == AF_WIDTH * sizeof(V) && sizeof(SensorNumbers<V>) == SF_WIDTH * sizeof(V),
                "layout.h's rows are packed tables");
};

// Lays out a tile's scratch from `mem` on; returns how many values of V it takes (the layout is
// the only count of them: tile_values asks it with no memory).
template <class V> static size_t tile_layout(const Model &m, V *mem, Tile<V> &t) {
  const int L = m.nlink, C = m.ncontact, D = m.ndof;
  size_t used = 0;
  auto take = [&](size_t n) { V *r = mem ? mem + used : nullptr; used += n; return r; };
  t.lf = take(L * LF_WIDTH); t.cf = take(C * CF_WIDTH); t.sf = take(m.nsensor * SF_WIDTH); t.af = take(m.nact * AF_WIDTH);
  t.pf = take(m.nspring * PF_WIDTH); t.ef = take(m.nedge * EF_WIDTH); t.wf = take(WF_WIDTH); t.rough = take(m.nrough * ROUGH_WIDTH);
  t.th = take(L); t.cs = (V(*)[2])take(2 * L); t.X = (V(*)[2])take(2 * L); t.com = (V(*)[2])take(2 * L);
  t.mc = (V(*)[2])take(2 * L); t.S = (V(*)[2])take(2 * L); t.w = take(L); t.V_ = (V(*)[2])take(2 * L);
  t.msum = take(L);
  t.cp = (V(*)[2])take(2 * C); t.depth = take(C); t.gn = (V(*)[4])take(4 * C); t.cv = (V(*)[2])take(2 * C);
  t.M = take(D * D); t.A = take(D * D); t.F = take(D * D); t.Lf = take(D * D);
  t.Q = take(D); t.u = take(D); t.qd = take(D); t.g = take(D); t.x = take(D); t.row = take(D);
  t.total = take(m.nnode); t.bits = take(m.nsensor); t.act = take(m.nact);
  t.I = (V(*)[6])take(6 * L); t.s = (V(*)[3])take(3 * L); t.E = (V(*)[6])take(6 * L); t.Fb = (V(*)[3])take(3 * L);
  t.IA = (V(*)[6])take(6 * L); t.pA = (V(*)[3])take(3 * L); t.U = (V(*)[3])take(3 * L); t.invD = take(L);
  t.uu = take(L); t.acc = (V(*)[3])take(3 * L); t.Hb = (V(*)[3])take(3 * L); t.arm = take(D);
  return used;
}

template <class V> static size_t tile_values(const Model &m) {
  Tile<V> t;
  return tile_layout<V>(m, nullptr, t);
}

template <class V> static Tile<V> tile_at(const Model &m, V *mem) {
  Tile<V> t;
  tile_layout<V>(m, mem, t);
  t.art = m.world().articulated != 0;
  return t;
}

template <class V> static inline void positions(const Model &m, const V *q, Tile<V> &t) {
  using Ls = Lanes<V>;
  const int L = m.nlink;
  for (int i = 0; i < L; ++i) {
    const LinkInts &l = m.link(i);
    const LinkNumbers<V> &f = t.link(i);
    int par = l.parent, rot = l.dof_rot;
    if (par < 0) {
      if (rot >= 0) t.th[i] = q[rot];
      else t.th[i] = l.dof_x < 0 ? f.pose_angle : V{};
    } else {
      t.th[i] = t.th[par] + q[rot];
    }
    sincos(t.th[i], t.cs[i][1], t.cs[i][0]);
  }
  for (int i = 0; i < L; ++i) {
    const LinkInts &l = m.link(i);
    const LinkNumbers<V> &f = t.link(i);
    int par = l.parent;
    if (par < 0) {
      if (l.dof_x >= 0 && l.point) {  // a free point mass sits at its coordinates
        t.X[i][0] = q[l.dof_x];
        t.X[i][1] = q[l.dof_y];
      } else {  // welded to the world where the file puts it, or a free tree's root (placed below)
        t.X[i][0] = l.dof_x < 0 ? f.pose_x : V{};
        t.X[i][1] = l.dof_x < 0 ? f.pose_y : V{};
      }
    } else {
      V c = t.cs[par][0], s = t.cs[par][1];
      V ax = f.anchor_x, ay = f.anchor_y;
      t.X[i][0] = t.X[par][0] + (c * ax - s * ay);
      t.X[i][1] = t.X[par][1] + (s * ax + c * ay);
    }
  }
  for (int i = 0; i < L; ++i) {
    const LinkNumbers<V> &f = t.link(i);
    if (m.link(i).point) {
      t.com[i][0] = t.X[i][0];
      t.com[i][1] = t.X[i][1];
      continue;
    }
    V c = t.cs[i][0], s = t.cs[i][1];
    V rx = f.com_x, ry = f.com_y;
    t.com[i][0] = t.X[i][0] + (c * rx - s * ry);
    t.com[i][1] = t.X[i][1] + (s * rx + c * ry);
  }
  for (int tr = 0; tr < m.ntree; ++tr) {
    const TreeInts &T = m.tree(tr);
    if (T.free == 0 || T.point == 1) continue;
    int r = T.root;
    for (int i = L - 1; i >= 0; --i) {
      if (m.link(i).tree != tr) continue;
      V mass = t.link(i).mass, ms = mass;
      V mx = mass * t.com[i][0], my = mass * t.com[i][1];
      for (int k = m.kid_start[i]; k < m.kid_start[i + 1]; ++k) {
        int j = m.kids[k];
        ms = ms + t.msum[j];
        mx = mx + t.mc[j][0];
        my = my + t.mc[j][1];
      }
      t.msum[i] = ms;
      t.mc[i][0] = mx;
      t.mc[i][1] = my;
    }
    V inv = 1.0 / t.msum[r];
    int dx = m.link(r).dof_x, dy = m.link(r).dof_y;
    V sx = q[dx] - t.mc[r][0] * inv, sy = q[dy] - t.mc[r][1] * inv;
    for (int k = 0; k < L; ++k) {
      if (m.link(k).tree != tr) continue;
      if (m.link(k).dof_rot >= 0) {
        t.S[k][0] = (t.mc[k][0] - t.msum[k] * t.X[k][0]) * inv;
        t.S[k][1] = (t.mc[k][1] - t.msum[k] * t.X[k][1]) * inv;
      }
      t.X[k][0] = t.X[k][0] + sx;
      t.X[k][1] = t.X[k][1] + sy;
      t.com[k][0] = t.com[k][0] + sx;
      t.com[k][1] = t.com[k][1] + sy;
    }
  }
  const int kind = m.world().terrain;
  for (int c = 0; c < m.ncontact; ++c) {
    int i = m.ci[c];
    V rx = t.contact(c).point_x, ry = t.contact(c).point_y;
    V cc = t.cs[i][0], ss = t.cs[i][1];
    V px = t.X[i][0] + (cc * rx - ss * ry), py = t.X[i][1] + (ss * rx + cc * ry);
    t.cp[c][0] = px;
    t.cp[c][1] = py;
    if (m.world().plane == PLANE_HORIZONTAL) {  // seen from above: every contact always rests on the floor
      t.depth[c] = V{} + 1.0;
      continue;
    }
    if (kind == TERRAIN_FLAT) {
      t.gn[c][0] = V{};
      t.gn[c][1] = V{} + 1.0;
      t.gn[c][2] = V{} + 1.0;
      t.gn[c][3] = V{};
      t.depth[c] = (0.0 - py) * 1.0;
      continue;
    }
    V h, dh;
    if (kind == TERRAIN_SLOPE) {
      h = t.world().slope * px;
      dh = V{} + t.world().slope;
    } else if (kind == TERRAIN_HILL) {
      V H = t.world().hill_height, hw = t.world().hill_half_width, cx = t.world().hill_centre;
      V u = (px - cx) * (M_PI / hw), su, cu;
      sincos(u, su, cu);
      auto inside = Ls::abs(px - cx) < hw;
      h = Ls::sel(inside, 0.5 * H * (1.0 + cu), V{});
      dh = Ls::sel(inside, -0.5 * H * (M_PI / hw) * su, V{});
    } else {
      h = V{};
      dh = V{};
      for (int k = 0; k < m.nrough; ++k) {
        V a = t.rough_term(k).amplitude, w = t.rough_term(k).wavenumber, ph = t.rough_term(k).phase;
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
  const int32_t *rl = m.rl + i * m.nchain;
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

// A += coef (g h^T + h g^T) for two rows on the same dofs (sparse.SymMatrix.add_outer with h)
template <class V> static inline void outer2(V *A, int D, V coef, const int32_t *idx, const V *g, const V *h, int n) {
  for (int a = 0; a < n; ++a) {
    int i = idx[a];
    V cgi = coef * g[a];
    for (int b = 0; b < n; ++b) {
      int j = idx[b];
      V v = cgi * h[b];
      if (i == j) {
        A[i * D + i] += v + v;
      } else {
        A[i * D + j] += v;
        A[j * D + i] += v;
      }
    }
  }
}

template <class V> static inline void force(V *Q, V f, const int32_t *idx, const V *g, int n) {
  for (int a = 0; a < n; ++a) Q[idx[a]] += f * g[a];
}

// ---------------------------------------------------------------- the articulated route
//
// For trees of rigid links (no point masses, nothing that joins two bodies): the step's matrices
// are never formed. Each body's mass and each element acting on one body is a planar spatial
// inertia (a symmetric 3 x 3 over the body's spatial velocity (w, vx, vy) at its tree's
// reference point, the root's origin); joint-space elements add to their joint's diagonal.
// Featherstone's articulated-body recursion solves with that matrix and the composite-body
// recursion multiplies by M, each in O(n) (sanlab/sim/articulated.py, the engine's same route).

// the reference point of link i's tree: its root's origin
template <class V> static inline void ref_of(const Model &m, const Tile<V> &t, int i, V &rx, V &ry) {
  int r = m.tree(m.link(i).tree).root;
  rx = t.X[r][0];
  ry = t.X[r][1];
}

template <class V> static inline void sym_outer(V *A, V c, const V *a) {
  A[0] += (c * a[0]) * a[0]; A[1] += (c * a[0]) * a[1]; A[2] += (c * a[0]) * a[2];
  A[3] += (c * a[1]) * a[1]; A[4] += (c * a[1]) * a[2]; A[5] += (c * a[2]) * a[2];
}

template <class V> static inline void sym_vec(const V *A, const V *x, V *y) {
  y[0] = A[0] * x[0] + A[1] * x[1] + A[2] * x[2];
  y[1] = A[1] * x[0] + A[3] * x[1] + A[4] * x[2];
  y[2] = A[2] * x[0] + A[4] * x[1] + A[5] * x[2];
}

template <class V> static inline V dot3(const V *a, const V *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// The body row of a world point (px, py) on link i along n: (r x n, n_x, n_y), r from the
// tree's reference point
template <class V> static inline void body_row(const Model &m, const Tile<V> &t, int i, V px, V py, V nx, V ny, V *a) {
  V rx, ry;
  ref_of(m, t, i, rx, ry);
  rx = px - rx;
  ry = py - ry;
  a[0] = rx * ny - ry * nx;
  a[1] = nx;
  a[2] = ny;
}

// Each body's spatial inertia and each joint's motion subspace (articulated.Bodies)
template <class V> static inline void bodies(const Model &m, Tile<V> &t) {
  for (int i = 0; i < m.nlink; ++i) {
    const LinkInts &l = m.link(i);
    if (l.welded) continue;
    V rx, ry;
    ref_of(m, t, i, rx, ry);
    V mass = t.link(i).mass, cx = t.com[i][0] - rx, cy = t.com[i][1] - ry;
    V mcx = mass * cx, mcy = mass * cy;
    V *I = t.I[i];
    I[0] = t.link(i).inertia + (mcx * cx + mcy * cy);
    I[1] = -mcy; I[2] = mcx; I[3] = mass; I[4] = V{}; I[5] = mass;
    if (l.parent >= 0) {
      t.s[i][0] = V{} + 1.0;
      t.s[i][1] = t.X[i][1] - ry;
      t.s[i][2] = -(t.X[i][0] - rx);
    }
  }
}

// y = M x in tree coordinates: body momenta summed leaves first, projected on each joint
template <class V> static inline void art_matvec(const Model &m, Tile<V> &t, const V *x, V *y) {
  for (int d = 0; d < m.ndof; ++d) y[d] = V{};
  V (*Vb)[3] = t.acc;
  for (int i = 0; i < m.nlink; ++i) {
    const LinkInts &l = m.link(i);
    if (l.welded) continue;
    int par = l.parent;
    if (par < 0) {
      Vb[i][0] = x[l.dof_rot]; Vb[i][1] = x[l.dof_x]; Vb[i][2] = x[l.dof_y];
    } else if (m.link(par).welded) {
      for (int k = 0; k < 3; ++k) Vb[i][k] = x[l.dof_rot] * t.s[i][k];
    } else {
      for (int k = 0; k < 3; ++k) Vb[i][k] = Vb[par][k] + x[l.dof_rot] * t.s[i][k];
    }
  }
  for (int i = m.nlink - 1; i >= 0; --i) {
    const LinkInts &l = m.link(i);
    if (l.welded) continue;
    V h[3];
    sym_vec(t.I[i], Vb[i], h);
    for (int k = m.kid_start[i]; k < m.kid_start[i + 1]; ++k)
      for (int q = 0; q < 3; ++q) h[q] = h[q] + t.Hb[m.kids[k]][q];
    for (int k = 0; k < 3; ++k) t.Hb[i][k] = h[k];
    if (l.parent >= 0) y[l.dof_rot] = dot3(t.s[i], h);
    else { y[l.dof_rot] = h[0]; y[l.dof_x] = h[1]; y[l.dof_y] = h[2]; }
  }
}

// x = (M + sum J^T E J + diag(arm))^-1 (b + sum J^T F): the articulated-body recursion
// (articulated.Bodies.solve); with_terms = 0 solves with M alone
template <class V> static inline void art_solve(const Model &m, Tile<V> &t, const V *b, V *x, int with_terms) {
  using Ls = Lanes<V>;
  for (int i = 0; i < m.nlink; ++i) {
    if (m.link(i).welded) continue;
    for (int k = 0; k < 6; ++k) t.IA[i][k] = with_terms ? t.I[i][k] + t.E[i][k] : t.I[i][k];
    for (int k = 0; k < 3; ++k) t.pA[i][k] = with_terms ? -t.Fb[i][k] : V{};
  }
  for (int i = m.nlink - 1; i >= 0; --i) {
    const LinkInts &l = m.link(i);
    int par = l.parent, d = l.dof_rot;
    if (par < 0) continue;
    V *s = t.s[i], Ui[3];
    sym_vec(t.IA[i], s, Ui);
    V D = dot3(s, Ui) + (with_terms ? t.arm[d] : V{});
    V inv = 1.0 / D, ui = b[d] - dot3(s, t.pA[i]);
    for (int k = 0; k < 3; ++k) t.U[i][k] = Ui[k];
    t.invD[i] = inv;
    t.uu[i] = ui;
    if (m.link(par).welded) continue;  // the world takes it
    V Uinv[3] = {Ui[0] * inv, Ui[1] * inv, Ui[2] * inv};
    static const int P[6] = {0, 0, 0, 1, 1, 2}, Qi[6] = {0, 1, 2, 1, 2, 2};
    for (int k = 0; k < 6; ++k) t.IA[par][k] = t.IA[par][k] + (t.IA[i][k] - Uinv[P[k]] * Ui[Qi[k]]);
    for (int k = 0; k < 3; ++k) t.pA[par][k] = t.pA[par][k] + (t.pA[i][k] + ui * Uinv[k]);
  }
  for (int tr = 0; tr < m.ntree; ++tr) {
    const TreeInts &T = m.tree(tr);
    int r = T.root;
    if (!T.free) continue;
    // the free root: a 3 x 3 system over (root angle rate, root origin velocity), L D L^T in the
    // order y, x, w (the engine's SymMatrix([2, 1, 0]))
    const LinkInts &l = m.link(r);
    const int dofs[3] = {l.dof_rot, l.dof_x, l.dof_y};
    V K[3][3], rhs[3];
    const V *A = t.IA[r];
    K[0][0] = A[0]; K[0][1] = K[1][0] = A[1]; K[0][2] = K[2][0] = A[2];
    K[1][1] = A[3]; K[1][2] = K[2][1] = A[4]; K[2][2] = A[5];
    for (int k = 0; k < 3; ++k) {
      if (with_terms) K[k][k] = K[k][k] + t.arm[dofs[k]];
      rhs[k] = b[dofs[k]] - t.pA[r][k];
    }
    V Lf[3][3], dinv[3];
    for (int k = 2; k >= 0; --k) {
      dinv[k] = 1.0 / K[k][k];
      for (int i = 0; i < k; ++i) Lf[k][i] = K[i][k] * dinv[k];
      for (int i = k - 1; i >= 0; --i)
        for (int j = k - 1; j >= i; --j) K[j][i] = K[i][j] = K[i][j] - Lf[k][i] * K[j][k];
    }
    V y[3] = {rhs[0], rhs[1], rhs[2]};
    for (int k = 2; k >= 0; --k)
      for (int i = k - 1; i >= 0; --i) y[i] = y[i] - Lf[k][i] * y[k];
    for (int k = 0; k < 3; ++k) y[k] = y[k] * dinv[k];
    for (int k = 0; k < 3; ++k)
      for (int i = k - 1; i >= 0; --i) y[k] = y[k] - Lf[k][i] * y[i];
    for (int k = 0; k < 3; ++k) {
      t.acc[r][k] = y[k];
      x[dofs[k]] = y[k];
    }
  }
  for (int i = 0; i < m.nlink; ++i) {
    const LinkInts &l = m.link(i);
    int par = l.parent;
    if (par < 0) continue;
    V ap[3] = {V{}, V{}, V{}};
    if (!m.link(par).welded) for (int k = 0; k < 3; ++k) ap[k] = t.acc[par][k];
    V xi = (t.uu[i] - dot3(t.U[i], ap)) * t.invD[i];
    x[l.dof_rot] = xi;
    for (int k = 0; k < 3; ++k) t.acc[i][k] = ap[k] + xi * t.s[i][k];
  }
  (void)sizeof(Ls);
}

// An element along a point's row: the step's matrix gains coef g g^T and its force f g, for the
// row g = J^T n of world point (px, py) on link i (dense), or the body row's (articulated)
template <class V> static inline void row_element(const Model &m, Tile<V> &t, int i, V px, V py, V nx, V ny, V coef,
                                                  V f, bool with_matrix = true) {
  if (m.world().articulated) {
    V a[3];
    body_row(m, t, i, px, py, nx, ny, a);
    if (with_matrix) sym_outer(t.E[i], coef, a);
    for (int k = 0; k < 3; ++k) t.Fb[i][k] = t.Fb[i][k] + f * a[k];
    return;
  }
  int n = point_row(m, t, i, px, py, nx, ny, t.g);
  if (with_matrix) outer(t.A, m.ndof, coef, m.ri + i * m.nchain, t.g, n);
  force(t.Q, f, m.ri + i * m.nchain, t.g, n);
}

template <class V> static inline void mass_matrix(const Model &m, Tile<V> &t) {
  const int D = m.ndof;
  for (int a = 0; a < D * D; ++a) t.M[a] = V{};
  for (int i = 0; i < m.nlink; ++i) {
    if (m.link(i).welded) continue;
    const int32_t *idx = m.ri + i * m.nchain;
    V mass = V{} + t.link(i).mass, I = V{} + t.link(i).inertia;
    int n = point_row(m, t, i, t.com[i][0], t.com[i][1], V{} + 1.0, V{}, t.g);
    outer(t.M, D, mass, idx, t.g, n);
    n = point_row(m, t, i, t.com[i][0], t.com[i][1], V{}, V{} + 1.0, t.g);
    outer(t.M, D, mass, idx, t.g, n);
    for (int a = 0; a < n; ++a) t.g[a] = V{} + (m.rl[i * m.nchain + a] >= 0 ? 1.0 : 0.0);
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
  for (int tr = 0; tr < m.ntree; ++tr) {
    const TreeInts &T = m.tree(tr);
    if (T.free == 0 || T.point == 1) continue;
    int r = T.root, dx = m.link(r).dof_x, dy = m.link(r).dof_y;
    for (int k = 0; k < m.nlink; ++k) {
      if (m.link(k).tree != tr || m.link(k).dof_rot < 0) continue;
      int d = m.link(k).dof_rot;
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
  const int D = m.ndof;
  positions(m, q, t);
  for (int d = 0; d < D; ++d) t.x[d] = p[d];
  turn(m, t, t.x, -1, 1);
  if (m.world().articulated) {
    bodies(m, t);
    art_solve(m, t, t.x, t.u, 0);
  } else {
    mass_matrix(m, t);
    solve(t, t.M, t.x, t.u, D);
  }
  for (int d = 0; d < D; ++d) t.qd[d] = t.u[d];
  turn(m, t, t.qd, -1, 0);
  for (int i = 0; i < m.nlink; ++i) {
    const LinkInts &l = m.link(i);
    int par = l.parent, rot = l.dof_rot;
    if (par < 0) {
      t.w[i] = rot >= 0 ? t.u[rot] : V{};
      t.V_[i][0] = l.dof_x >= 0 ? t.u[l.dof_x] : V{};
      t.V_[i][1] = l.dof_x >= 0 ? t.u[l.dof_y] : V{};
    } else {
      t.w[i] = t.w[par] + t.u[rot];
      V rx = t.X[i][0] - t.X[par][0], ry = t.X[i][1] - t.X[par][1];
      t.V_[i][0] = t.V_[par][0] - t.w[par] * ry;
      t.V_[i][1] = t.V_[par][1] + t.w[par] * rx;
    }
  }
  for (int c = 0; c < m.ncontact; ++c) {
    int i = m.ci[c];
    V rx = t.cp[c][0] - t.X[i][0], ry = t.cp[c][1] - t.X[i][1];
    t.cv[c][0] = t.V_[i][0] - t.w[i] * ry;
    t.cv[c][1] = t.V_[i][1] + t.w[i] * rx;
  }
}

template <class V> static inline void joint(Tile<V> &t, int D, int d, V h, V f, V k, V c, V rate) {
  if (t.art) t.arm[d] += h * c + (h * h) * k;
  else t.A[d * D + d] += h * c + (h * h) * k;
  t.Q[d] += f - (h * k) * rate;
}

template <class V> static inline void point_vel(const Tile<V> &t, int i, V px, V py, V &vx, V &vy) {
  V rx = px - t.X[i][0], ry = py - t.X[i][1];
  vx = t.V_[i][0] - t.w[i] * ry;
  vy = t.V_[i][1] + t.w[i] * rx;
}

template <class V> static inline void point_at(const Tile<V> &t, int i, V rx, V ry, V &px, V &py) {
  V c = t.cs[i][0], s = t.cs[i][1];
  px = t.X[i][0] + (c * rx - s * ry);
  py = t.X[i][1] + (s * rx + c * ry);
}

// A dense row over every dof: g = J_b^T e - J_a^T e, for an element between a point on link la
// and one on link lb (dynamics._linear)
template <class V> static inline void two_point_row(const Model &m, Tile<V> &t, int la, V pax, V pay, int lb, V pbx,
                                                    V pby, V ex, V ey, V *row) {
  const int D = m.ndof;
  V *g = t.g;
  for (int d = 0; d < D; ++d) row[d] = V{};
  int n = point_row(m, t, lb, pbx, pby, ex, ey, g);
  for (int a = 0; a < n; ++a) row[m.ri[lb * m.nchain + a]] += g[a];
  n = point_row(m, t, la, pax, pay, ex, ey, g);
  for (int a = 0; a < n; ++a) row[m.ri[la * m.nchain + a]] += -g[a];
}

// A spring-damper between a point on link la and one on link lb (local points f[0..3]):
// F = ks (target - L) - kd L' along the line between them (dynamics._linear)
template <class V> static inline void linear(const Model &m, Tile<V> &t, int la, V ax, V ay, int lb, V bx, V by,
                                             V target, V ks, V kd, V h) {
  const int D = m.ndof;
  V pax, pay, pbx, pby;
  point_at(t, la, ax, ay, pax, pay);
  point_at(t, lb, bx, by, pbx, pby);
  V dx = pbx - pax, dy = pby - pay;
  V L = Lanes<V>::sqrt(dx * dx + dy * dy);
  V ex = dx / L, ey = dy / L;
  two_point_row(m, t, la, pax, pay, lb, pbx, pby, ex, ey, t.row);
  V vax, vay, vbx, vby;
  point_vel(t, la, pax, pay, vax, vay);
  point_vel(t, lb, pbx, pby, vbx, vby);
  V rate = (vbx - vax) * ex + (vby - vay) * ey;
  outer(t.A, D, V{} + (h * kd + (h * h) * ks), m.dense_idx, t.row, D);
  force(t.Q, ks * (target - L) - kd * rate - (h * ks) * rate, m.dense_idx, t.row, D);
}

// The stick-slip decision along one tangent (dynamics._stick_law and _stick_element): the element's
// matrix coefficient and force, and how far behind the contact its anchor stays
template <class V> static inline void stick_slip(V stretch, V v, V limit, V gk, V slip, V h, V &coef,
                                                 V &f, V &held) {
  using Ls = Lanes<V>;
  V c = limit / slip;
  V s = Ls::min(Ls::max(stretch, -limit / gk), limit / gk);
  V trial = -gk * s - c * v;
  V slide = limit / Ls::max(Ls::abs(v), V{} + slip);
  auto stick = (limit > 0.0) & (Ls::abs(trial) <= limit);
  coef = Ls::sel(stick, h * c + (h * h) * gk, h * slide);
  f = Ls::sel(stick, trial - (h * gk) * v, -slide * v);
  held = Ls::sel(stick, s, V{});
}

// Horizontal plane: every contact's friction against the floor under its constant load
// (dynamics._plane_laws): anisotropic along a link axis, or isotropic within a disc
template <class V> static inline void plane_laws(const Model &m, Tile<V> &t, V (*anchor)[2]) {
  using Ls = Lanes<V>;
  const V h = t.world().dt, gk = t.world().ground_k, slip = t.world().slip;
  for (int c = 0; c < m.ncontact; ++c) {
    int i = m.ci[c];
    const LinkInts &l = m.link(i);
    const LinkNumbers<V> &f = t.link(i);
    V px = t.cp[c][0], py = t.cp[c][1], vx = t.cv[c][0], vy = t.cv[c][1];
    V N = t.contact(c).load;
    V dx = px - anchor[c][0], dy = py - anchor[c][1];
    if (l.aniso) {
      int frm = l.axis_from, to = l.axis_to;
      V ax = frm >= 0 ? t.X[to][0] - t.X[frm][0] : t.cs[i][0];
      V ay = frm >= 0 ? t.X[to][1] - t.X[frm][1] : t.cs[i][1];
      V inv = 1.0 / Ls::sqrt(ax * ax + ay * ay + 1e-12);
      V e1x = ax * inv, e1y = ay * inv, e2x = -e1y, e2y = e1x;
      V va = vx * e1x + vy * e1y, vl = vx * e2x + vy * e2y;
      V s1 = dx * e1x + dy * e1y, s2 = dx * e2x + dy * e2y;
      V mu = Ls::sel(gk * s1 + va > 0.0, V{} + f.mu_forward, V{} + f.mu_backward);
      V c1, f1, h1, c2, f2, h2;
      stick_slip(s1, va, mu * N, gk, slip, h, c1, f1, h1);
      stick_slip(s2, vl, V{} + f.mu_lateral * N, gk, slip, h, c2, f2, h2);
      row_element(m, t, i, px, py, e1x, e1y, c1, f1);
      row_element(m, t, i, px, py, e2x, e2y, c2, f2);
      anchor[c][0] = px - h1 * e1x - h2 * e2x;
      anchor[c][1] = py - h1 * e1y - h2 * e2y;
    } else {
      V limit = f.mu_forward * N, cc = limit / slip;
      V r = Ls::sqrt(dx * dx + dy * dy);
      V scale = Ls::min(V{} + 1.0, (limit / gk) / Ls::max(r, V{} + 1e-30));
      V sx = dx * scale, sy = dy * scale;
      V tx = -gk * sx - cc * vx, ty = -gk * sy - cc * vy;
      auto stick = (V{} + limit > 0.0) & (tx * tx + ty * ty <= limit * limit);
      V speed = Ls::sqrt(vx * vx + vy * vy);
      V slide = limit / Ls::max(speed, V{} + slip);
      V ks = Ls::sel(stick, V{} + gk, V{}), damp = Ls::sel(stick, V{} + cc, slide);
      V coef = h * damp + (h * h) * ks;
      V e0[2] = {V{} + 1.0, V{}}, e1[2] = {V{}, V{} + 1.0};
      V trial[2] = {tx, ty}, vel[2] = {vx, vy};
      for (int a = 0; a < 2; ++a) {
        V *e = a == 0 ? e0 : e1;
        row_element(m, t, i, px, py, e[0], e[1], coef, Ls::sel(stick, trial[a], -slide * vel[a]) - (h * ks) * vel[a]);
      }
      anchor[c][0] = px - Ls::sel(stick, sx, V{});
      anchor[c][1] = py - Ls::sel(stick, sy, V{});
    }
  }
}

// Water drag on each edge, exact for a rigid edge: normal -k int (v.N) N ds, tangential (skin)
// -k_t int (v.T) T ds (dynamics.advance)
template <class V> static inline void water(const Model &m, Tile<V> &t) {
  const int D = m.ndof;
  const V h = t.world().dt, k = t.world().water_k, kt = t.world().water_t;
  for (int e = 0; e < m.nedge; ++e) {
    int i = m.ei[e];
    const EdgeNumbers<V> &f = t.edge(e);
    const int32_t *idx = m.ri + i * m.nchain;
    V ax, ay, bx, by;
    point_at(t, i, f.a_x, f.a_y, ax, ay);
    point_at(t, i, f.b_x, f.b_y, bx, by);
    V dx = bx - ax, dy = by - ay;
    V L = Lanes<V>::sqrt(dx * dx + dy * dy);
    V tx = dx / L, ty = dy / L, nx = -ty, ny = tx;
    V vax, vay;
    point_vel(t, i, ax, ay, vax, vay);
    V vn = vax * nx + vay * ny;
    bool point = m.link(i).point;
    V w = point ? V{} : t.w[i];
    V c1 = k * L, c2 = k * L * L / 2.0, c3 = k * L * L * L / 3.0;
    V vt = vax * tx + vay * ty, ct = kt * L;
    if (m.world().articulated) {  // the normal row on the body, and its rotation row (1, 0, 0)
      V an[3], aw[3] = {V{} + 1.0, V{}, V{}};
      body_row(m, t, i, ax, ay, nx, ny, an);
      V *E = t.E[i];
      sym_outer(E, h * c1, an);
      static const int P[6] = {0, 0, 0, 1, 1, 2}, Qi[6] = {0, 1, 2, 1, 2, 2};
      for (int q = 0; q < 6; ++q) E[q] += (h * c2 * an[P[q]]) * aw[Qi[q]] + (h * c2 * aw[P[q]]) * an[Qi[q]];
      sym_outer(E, h * c3, aw);
      V fn_ = -(c1 * vn + c2 * w), fw = -(c2 * vn + c3 * w);
      for (int q = 0; q < 3; ++q) t.Fb[i][q] = t.Fb[i][q] + fn_ * an[q] + fw * aw[q];
      row_element(m, t, i, ax, ay, tx, ty, h * ct, -ct * vt);
      continue;
    }
    int n = point_row(m, t, i, ax, ay, nx, ny, t.g);
    V *gw = t.row;  // the link's rotation row on the same dofs
    for (int a = 0; a < n; ++a) gw[a] = V{} + ((!point && m.rl[i * m.nchain + a] >= 0) ? 1.0 : 0.0);
    outer(t.A, D, h * c1, idx, t.g, n);
    outer2(t.A, D, h * c2, idx, t.g, gw, n);
    outer(t.A, D, h * c3, idx, gw, n);
    force(t.Q, -(c1 * vn + c2 * w), idx, t.g, n);
    force(t.Q, -(c2 * vn + c3 * w), idx, gw, n);
    n = point_row(m, t, i, ax, ay, tx, ty, t.g);
    outer(t.A, D, h * ct, idx, t.g, n);
    force(t.Q, -ct * vt, idx, t.g, n);
  }
}

// Vertical plane: every contact's normal force and stick-slip friction against the ground, as
// elements of the step (dynamics._ground_laws); a contact no lane touches adds nothing
template <class V> static inline void ground_laws(const Model &m, Tile<V> &t, V (*anchor)[2], V &dmax) {
  using Ls = Lanes<V>;
  const V h = t.world().dt;
  const V gk = t.world().ground_k, gc = t.world().ground_c, slip = t.world().slip;
  const V cn = h * gc + (h * h) * gk;
  for (int c = 0; c < m.ncontact; ++c) {
    int i = m.ci[c];
    const LinkInts &l = m.link(i);
    V nx = t.gn[c][0], ny = t.gn[c][1], tx = t.gn[c][2], ty = t.gn[c][3];
    V dep = t.depth[c];
    dmax = Ls::max(dmax, dep);
    V vx = t.cv[c][0], vy = t.cv[c][1];
    V vn = vx * nx + vy * ny, vt = vx * tx + vy * ty;
    V fn = gk * dep - gc * vn;
    auto on = (dep > 0.0) & (fn > 0.0);
    V N = Ls::sel(on, fn, V{});
    V stretch = (t.cp[c][0] - anchor[c][0]) * tx + (t.cp[c][1] - anchor[c][1]) * ty;
    V mu = V{} + t.link(i).mu_forward;
    if (l.aniso) {
      int frm = l.axis_from, to = l.axis_to;
      V axx = frm >= 0 ? t.X[to][0] - t.X[frm][0] : t.cs[i][0];
      V axy = frm >= 0 ? t.X[to][1] - t.X[frm][1] : t.cs[i][1];
      mu = Ls::sel((axx * tx + axy * ty) * (gk * stretch + vt) > 0.0, mu, V{} + t.link(i).mu_backward);
    }
    V limit = mu * N;
    V cs_ = limit / slip;
    V s = Ls::min(Ls::max(stretch, -limit / gk), limit / gk);
    V trial = -gk * s - cs_ * vt;
    V slide = limit / Ls::max(Ls::abs(vt), V{} + slip);
    auto stick = (limit > 0.0) & (Ls::abs(trial) <= limit);
    V held = Ls::sel(stick, s, V{});
    if (Ls::any(on)) {
      row_element(m, t, i, t.cp[c][0], t.cp[c][1], nx, ny, Ls::sel(on, V{} + cn, V{}),
                  Ls::sel(on, fn - (h * gk) * vn, V{}));
    }
    if (Ls::any(limit > 0.0)) {
      row_element(m, t, i, t.cp[c][0], t.cp[c][1], tx, ty, Ls::sel(stick, h * cs_ + (h * h) * gk, h * slide),
                  Ls::sel(stick, trial - (h * gk) * vt, -slide * vt));
    }
    anchor[c][0] = t.cp[c][0] - held * tx;
    anchor[c][1] = t.cp[c][1] - held * ty;
  }
}

// dT/dq in O(n) (dynamics._inertial_force_linear): for joint k, -sum over its subtree of
// u_i x (v_ci - V_k), u_i = m_i (v_ci - v_c), from the subtree sums of u_i x v_ci and of u_i
template <class V> static inline void inertial_linear(const Model &m, Tile<V> &t) {
  V *Asum = t.uu, (*Bsum)[3] = t.acc;  // scratch: the solve that owns them runs later
  for (int tr = 0; tr < m.ntree; ++tr) {
    const TreeInts &T = m.tree(tr);
    if (T.point == 1) continue;
    bool free = T.free == 1;
    int r = T.root;
    V vcx = free ? t.qd[m.link(r).dof_x] : V{}, vcy = free ? t.qd[m.link(r).dof_y] : V{};
    for (int i = m.nlink - 1; i >= 0; --i) {
      const LinkInts &l = m.link(i);
      if (l.tree != tr || (l.parent < 0 && !free)) continue;
      V mass = t.link(i).mass;
      V vx, vy;
      point_vel(t, i, t.com[i][0], t.com[i][1], vx, vy);
      V ux = mass * (vx - vcx), uy = mass * (vy - vcy);
      V a = ux * vy - uy * vx, bx = ux, by = uy;
      for (int k = m.kid_start[i]; k < m.kid_start[i + 1]; ++k) {
        int c = m.kids[k];
        a = a + Asum[c];
        bx = bx + Bsum[c][0];
        by = by + Bsum[c][1];
      }
      Asum[i] = a;
      Bsum[i][0] = bx;
      Bsum[i][1] = by;
      if (l.dof_rot >= 0 && l.parent >= 0) t.Q[l.dof_rot] += -a + (bx * t.V_[i][1] - by * t.V_[i][0]);
    }
  }
}

// One step from a prepared tile with activations t.act: q, p, anchor advanced in place; dmax the
// deepest penetration so far
template <class V> static inline void advance(const Model &m, Tile<V> &t, V *q, V *p, V (*anchor)[2], V &dmax) {
  using Ls = Lanes<V>;
  const int D = m.ndof, L = m.nlink;
  const V h = t.world().dt;
  const bool art = m.world().articulated;
  for (int a = 0; a < D; ++a) t.Q[a] = V{};
  if (art) {
    for (int a = 0; a < D; ++a) t.arm[a] = V{};
    for (int i = 0; i < L; ++i) {
      for (int k = 0; k < 6; ++k) t.E[i][k] = V{};
      for (int k = 0; k < 3; ++k) t.Fb[i][k] = V{};
    }
  } else {
    for (int a = 0; a < D * D; ++a) t.A[a] = t.M[a];
  }
  // the inertial force dT/dq at fixed velocities: on the articulated route in O(n)
  // (dynamics._inertial_force_linear: two subtree sums), else link by link up each chain
  if (art) inertial_linear(m, t);
  else for (int tr = 0; tr < m.ntree; ++tr) {
    const TreeInts &T = m.tree(tr);
    if (T.point == 1) continue;
    bool free = T.free == 1;
    int r = T.root;
    V vcx = free ? t.qd[m.link(r).dof_x] : V{}, vcy = free ? t.qd[m.link(r).dof_y] : V{};
    for (int i = 0; i < L; ++i) {
      const LinkInts &l = m.link(i);
      if (l.tree != tr || (l.parent < 0 && !free)) continue;
      V mass = t.link(i).mass;
      V rx = t.com[i][0] - t.X[i][0], ry = t.com[i][1] - t.X[i][1];
      V vx = t.V_[i][0] - t.w[i] * ry, vy = t.V_[i][1] + t.w[i] * rx;
      V ux = mass * (vx - vcx), uy = mass * (vy - vcy);
      V Px{}, Py{}, nx = t.com[i][0], ny = t.com[i][1];
      for (int k = i; k >= 0; k = m.link(k).parent) {
        Px = Px + t.w[k] * (nx - t.X[k][0]);
        Py = Py + t.w[k] * (ny - t.X[k][1]);
        nx = t.X[k][0];
        ny = t.X[k][1];
        int rot = m.link(k).dof_rot;
        if (rot >= 0 && !(free && m.link(k).parent < 0)) t.Q[rot] += -(ux * Px + uy * Py);
      }
    }
  }
  // gravity, in the vertical plane: on a free tree's centre of mass, link by link in a welded tree
  if (m.world().plane == PLANE_VERTICAL) {
    const V grav = t.world().gravity;
    for (int a = 0; a < D; ++a) t.x[a] = V{};
    for (int tr = 0; tr < m.ntree; ++tr) {
      const TreeInts &T = m.tree(tr);
      int r = T.root;
      if (T.free == 1) {
        V mt{};
        for (int i = 0; i < L; ++i)
          if (m.link(i).tree == tr) mt = mt + t.link(i).mass;
        t.x[m.link(r).dof_y] = V{} - (mt * grav);
        continue;
      }
      for (int i = 0; i < L; ++i) {
        if (m.link(i).tree != tr || m.link(i).parent < 0) continue;
        row_element(m, t, i, t.com[i][0], t.com[i][1], V{}, V{} + 1.0, V{}, V{} - (t.link(i).mass * grav), false);
      }
    }
    turn(m, t, t.x, -1, 1);
    for (int a = 0; a < D; ++a) t.Q[a] += t.x[a];
  }
  // passive joint springs, then stops
  for (int i = 0; i < L; ++i) {
    const LinkInts &l = m.link(i);
    if (!l.spring) continue;
    const LinkNumbers<V> &f = t.link(i);
    int d = l.dof_rot;
    V k = f.jspring_k, c = f.jspring_c, rest = f.jspring_rest;
    V phi = t.th[i] - t.th[l.parent];
    joint(t, D, d, h, -k * (phi - rest) - c * t.u[d], V{} + k, V{} + c, t.u[d]);
  }
  for (int i = 0; i < L; ++i) {
    const LinkInts &l = m.link(i);
    if (!l.limit) continue;
    const LinkNumbers<V> &f = t.link(i);
    int d = l.dof_rot;
    V lo = f.limit_min, hi = f.limit_max, k = f.limit_k, c = f.limit_c;
    V phi = t.th[i] - t.th[l.parent];
    V below = Ls::max(k * (lo - phi) - c * t.u[d], V{});
    V above = Ls::min(k * (hi - phi) - c * t.u[d], V{});
    auto on = ((phi < lo) & (below > 0.0)) | ((phi > hi) & (above < 0.0));
    V onv = Ls::sel(on, V{} + 1.0, V{});
    V torque = Ls::sel(phi < lo, below, Ls::sel(phi > hi, above, V{}));
    joint(t, D, d, h, torque, onv * k, onv * c, t.u[d]);
  }
  // actuators: angular servos at a joint, linear ones between two points
  for (int a = 0; a < m.nact; ++a) {
    const ActuatorInts &ai = m.actuator(a);
    const ActuatorNumbers<V> &f = t.actuator(a);
    V target = f.min + t.act[a] * (f.max - f.min);
    if (ai.kind == ACT_ANGULAR) {
      int j = ai.link, d = m.link(j).dof_rot;
      V phi = t.th[j] - t.th[m.link(j).parent];
      joint(t, D, d, h, f.ks * (target - phi) - f.kd * t.u[d], V{} + f.ks, V{} + f.kd, t.u[d]);
    } else {
      linear(m, t, ai.link, f.point_a_x, f.point_a_y, ai.link_b, f.point_b_x, f.point_b_y, target, f.ks, f.kd, h);
    }
  }
  for (int n = 0; n < m.nspring; ++n) {
    const SpringNumbers<V> &f = t.spring(n);
    const SpringInts &l = m.spring(n);
    linear(m, t, l.link_a, f.point_a_x, f.point_a_y, l.link_b, f.point_b_x, f.point_b_y, V{} + f.rest, f.ks, f.kd, h);
  }
  if (m.world().plane == PLANE_VERTICAL) ground_laws(m, t, anchor, dmax);
  else plane_laws(m, t, anchor);
  if (m.nedge) water(m, t);
  // the step: A du = h Q; p += S^T M du; q += h v*
  for (int a = 0; a < D; ++a) t.Q[a] = h * t.Q[a];
  if (art) {
    for (int i = 0; i < L; ++i)
      for (int k = 0; k < 3; ++k) t.Fb[i][k] = h * t.Fb[i][k];
    art_solve(m, t, t.Q, t.x, 1);
    art_matvec(m, t, t.x, t.g);
  } else {
    solve(t, t.A, t.Q, t.x, D);
    for (int a = 0; a < D; ++a) {
      V acc{};
      for (int b = 0; b < D; ++b) acc += t.M[a * D + b] * t.x[b];
      t.g[a] = acc;
    }
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

// The follow point at time `time` (s): linear interpolation in the path's arc-length table
// (dynamics.follow_point)
template <class V> static inline void follow_point(const Model &m, const Tile<V> &t, V time, V &x, V &y) {
  using Ls = Lanes<V>;
  const int n = m.nfollow;
  V u = t.world().follow_speed * time / t.world().follow_ds;
  for (int l = 0; l < Ls::W; ++l) {
    double ul = Ls::lane(u, l);
    if (m.world().follow_loop) ul = ul - (n - 1) * __builtin_floor(ul / (n - 1));
    ul = ul < 0.0 ? 0.0 : (ul > n - 1 ? n - 1 : ul);
    int i0 = ul >= 0.0 ? (int)__builtin_floor(ul) : 0;  // NaN (a NaN time): no int of it, NaN out
    if (i0 > n - 2) i0 = n - 2;
    double f = ul - i0;
    const double *a = m.follow + 2 * i0, *b = a + 2;
    Ls::set(x, l, a[0] + f * (b[0] - a[0]));
    Ls::set(y, l, a[1] + f * (b[1] - a[1]));
  }
}

// Binary sensor values (dynamics.sense) of a prepared tile at time `time`
template <class V> static inline void sense(const Model &m, Tile<V> &t, V time) {
  using Ls = Lanes<V>;
  V fx{}, fy{};
  if (m.world().follow) follow_point(m, t, time, fx, fy);
  for (int s = 0; s < m.nsensor; ++s) {
    const SensorInts &si = m.sensor(s);
    const SensorNumbers<V> &sf = t.sensor(s);
    int kind = si.kind;
    if (kind == S_TOUCH) {
      t.bits[s] = m.world().plane == PLANE_HORIZONTAL ? V{} + 1.0 : Ls::sel(t.depth[si.on] > 0.0, V{} + 1.0, V{});
      continue;
    }
    V a;
    if (kind == S_ANGLE || kind == S_TILT) {
      int link = si.on, par = m.link(link).parent;
      V ang = (par < 0 || kind == S_TILT) ? t.th[link] : t.th[link] - t.th[par];
      a = ang - (2 * M_PI) * Ls::floor((ang + M_PI) * (0.5 / M_PI));
    } else if (kind == S_EYE) {
      int li = si.on, frm = si.second, to = si.third;
      V ex, ey;
      point_at(t, li, sf.point_x, sf.point_y, ex, ey);
      V ax = frm >= 0 ? t.X[to][0] - t.X[frm][0] : t.cs[li][0];
      V ay = frm >= 0 ? t.X[to][1] - t.X[frm][1] : t.cs[li][1];
      V dx = fx - ex, dy = fy - ey;
      V num = ax * dy - ay * dx, den = ax * dx + ay * dy;
      for (int l = 0; l < Ls::W; ++l) Ls::set(a, l, __builtin_atan2(Ls::lane(num, l), Ls::lane(den, l)));
    } else {
      V pax, pay, pbx, pby;
      point_at(t, si.on, sf.point_x, sf.point_y, pax, pay);
      point_at(t, si.second, sf.point_b_x, sf.point_b_y, pbx, pby);
      V dx = pbx - pax, dy = pby - pay;
      a = Ls::sqrt(dx * dx + dy * dy);
    }
    t.bits[s] = Ls::sel((a >= sf.min) & (a <= sf.max), V{} + 1.0, V{});
  }
}

// The SAN's node update (sanlab.san.San.apply). The weights are small integers and every input is
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

// ---------------------------------------------------------------- observers
//
// What a rollout accumulates besides the state (sanlab.metrics.Metric and
// sanlab.descriptors.Descriptors, the XLA engine's observers): the metric's ingredients and the
// behaviour descriptors, per lane, updated before each step from its prepared tile. The host turns
// them into scores with the same functions as before (metrics.scores, descriptors.values).
//
// Config oi (layout.OBSERVE): kind (layout.METRIC_KINDS), fell_com (0/1), fell_link (0/1), depth
// (0/1: track the deepest contact), root (descriptors' rotating root, -1 none), sensors
// (descriptors' word: 0 = no word), n_fell, n_joints, n_touch, then the fell links, the joints'
// dofs and the touch sensors' indices; of (layout.OBSERVE_F): fell angle (rad), fell COM height,
// fell link height (m). Accumulators (layout.ACC), one V each: the metric's, then the descriptors'
// (duty [n_touch], words and times [EVENTS] at the end); tracking's gap: the sum over steps of the
// distance from the centre of mass to the follow point, and that distance at the first step.
constexpr double DEBOUNCE_S = 0.02;

inline int obs_values(const int32_t *oi) { return A_FIXED + oi[O_N_TOUCH] + 2 * EVENTS; }

// Whole-creature centre of mass (and, with a velocity-prepared tile, its velocity); links welded
// to the world do not count (dynamics.centre_of_mass)
template <class V> static inline void centre_of_mass(const Model &m, const Tile<V> &t, V &cx, V &cy, V *vx, V *vy) {
  V mx{}, my{}, total{}, sx{}, sy{};
  for (int i = 0; i < m.nlink; ++i) {
    if (m.link(i).welded) continue;
    V mass = t.link(i).mass;
    mx = mx + mass * t.com[i][0];
    my = my + mass * t.com[i][1];
    if (vx) {
      V ux, uy;
      point_vel(t, i, t.com[i][0], t.com[i][1], ux, uy);
      sx = sx + mass * ux;
      sy = sy + mass * uy;
    }
    total = total + mass;
  }
  V inv = 1.0 / total;
  cx = mx * inv;
  cy = my * inv;
  if (vx) {
    *vx = sx * inv;
    *vy = sy * inv;
  }
}

// Mechanical energy of a prepared tile (J; dynamics.energy): kinetic (of the velocity M^-1 p),
// gravitational (m g y of each centre of mass, vertical plane) and elastic (passive joint and
// linear springs; actuators, stops and the ground excluded). Links welded to the world do not count.
template <class V> static inline void energy(const Model &m, const Tile<V> &t, V &kin, V &grav, V &elastic) {
  kin = V{};
  grav = V{};
  elastic = V{};
  const bool vertical = m.world().plane == PLANE_VERTICAL;
  for (int i = 0; i < m.nlink; ++i) {
    if (m.link(i).welded) continue;
    const LinkNumbers<V> &f = t.link(i);
    V vx, vy;
    point_vel(t, i, t.com[i][0], t.com[i][1], vx, vy);
    // the engine's association, term by term: (0.5 m) |v|^2 and ((0.5 I) w) w
    kin = kin + (0.5 * f.mass) * (vx * vx + vy * vy) + ((0.5 * f.inertia) * t.w[i]) * t.w[i];
    if (vertical) grav = grav + (f.mass * t.world().gravity) * t.com[i][1];
  }
  for (int i = 0; i < m.nlink; ++i) {
    const LinkInts &l = m.link(i);
    if (!l.spring) continue;
    const LinkNumbers<V> &f = t.link(i);
    V d = (t.th[i] - t.th[l.parent]) - f.jspring_rest;
    elastic = elastic + (0.5 * f.jspring_k) * (d * d);
  }
  for (int n = 0; n < m.nspring; ++n) {
    const SpringNumbers<V> &f = t.spring(n);
    V pax, pay, pbx, pby;
    point_at(t, m.spring(n).link_a, f.point_a_x, f.point_a_y, pax, pay);
    point_at(t, m.spring(n).link_b, f.point_b_x, f.point_b_y, pbx, pby);
    V dx = pbx - pax, dy = pby - pay;
    V d = Lanes<V>::sqrt(dx * dx + dy * dy) - f.rest;
    elastic = elastic + (0.5 * f.ks) * (d * d);
  }
}

// The momenta p = M(q) qd (dynamics.make_state) of a tile whose positions are computed, for
// velocities qd in state coordinates: turned into tree coordinates, multiplied by the mass matrix
// (formed, or composite bodies on the articulated route), turned back as a force.
template <class V> static inline void momenta(const Model &m, Tile<V> &t, const V *qd, V *p) {
  const int D = m.ndof;
  for (int d = 0; d < D; ++d) t.x[d] = qd[d];
  turn(m, t, t.x, 1, 0);
  if (m.world().articulated) {
    bodies(m, t);
    art_matvec(m, t, t.x, p);
  } else {
    mass_matrix(m, t);
    for (int a = 0; a < D; ++a) {
      V acc{};
      for (int b = 0; b < D; ++b) acc += t.M[a * D + b] * t.x[b];
      p[a] = acc;
    }
  }
  turn(m, t, p, 1, 1);
}

template <class V> static inline V ground_height(const Model &m, const Tile<V> &t, V x) {
  using Ls = Lanes<V>;
  const int kind = m.world().terrain;
  if (kind == TERRAIN_FLAT) return V{};
  if (kind == TERRAIN_SLOPE) return t.world().slope * x;
  if (kind == TERRAIN_HILL) {
    V H = t.world().hill_height, hw = t.world().hill_half_width, cx = t.world().hill_centre, su, cu;
    sincos((x - cx) * (M_PI / hw), su, cu);
    return Ls::sel(Ls::abs(x - cx) < hw, 0.5 * H * (1.0 + cu), V{});
  }
  V h{};
  for (int k = 0; k < m.nrough; ++k) {
    V s, c;
    sincos(t.rough_term(k).wavenumber * x + t.rough_term(k).phase, s, c);
    h = h + t.rough_term(k).amplitude * s;
  }
  return h;
}

// the accumulators at the start (positions of the tile already computed)
template <class V> static inline void observe_init(const Model &m, const Tile<V> &t, const int32_t *oi, V *acc) {
  for (int k = 0; k < obs_values(oi); ++k) acc[k] = V{};
  V cx, cy;
  centre_of_mass(m, t, cx, cy, (V *)nullptr, (V *)nullptr);
  acc[A_P0X] = acc[A_PX] = cx;
  acc[A_P0Y] = acc[A_PY] = acc[A_Y0] = cy;
  acc[A_WORD] = acc[A_CANDIDATE] = V{} - 1.0;
}

// one step's update, from a prepared tile at time `time` (Metric.update, Descriptors.update)
template <class V> static inline void observe(const Model &m, const Tile<V> &t, const int32_t *oi, const double *of,
                                              V time, V *acc) {
  using Ls = Lanes<V>;
  const bool vertical = m.world().plane == PLANE_VERTICAL;
  const int32_t *fell = oi + O_LISTS, *joints = fell + oi[O_N_FELL], *touch = joints + oi[O_N_JOINTS];
  const V dt = t.world().dt;
  // the metric
  V f = acc[A_FELL];
  for (int k = 0; k < oi[O_N_FELL]; ++k) {
    int i = fell[k];
    V a = t.th[i] - (2 * M_PI) * Ls::floor((t.th[i] + M_PI) * (0.5 / M_PI));
    f = Ls::sel(Ls::abs(a) > of[OF_FELL_ANGLE], V{} + 1.0, f);
    if (oi[O_FELL_LINK] && vertical)
      f = Ls::sel(t.com[i][1] - ground_height(m, t, t.com[i][0]) < of[OF_FELL_LINK_HEIGHT], V{} + 1.0, f);
  }
  V px, py, vx, vy;
  centre_of_mass(m, t, px, py, &vx, &vy);
  if (oi[O_FELL_COM] && vertical) f = Ls::sel(py - ground_height(m, t, px) < of[OF_FELL_COM_HEIGHT], V{} + 1.0, f);
  acc[A_FELL] = f;
  if (oi[O_KIND] == M_HOPPING) {
    V up = Ls::max(py - acc[A_Y0], V{});
    acc[A_HOP] = acc[A_HOP] + up * up * dt;
  } else if (oi[O_KIND] == M_PURSUIT) {
    V fx, fy;
    follow_point(m, t, time, fx, fy);
    V dx = fx - px, dy = fy - py;
    V inv = 1.0 / Ls::max(Ls::sqrt(dx * dx + dy * dy), V{} + 1e-9);
    acc[A_PURSUIT] = acc[A_PURSUIT] + (vx * dx + vy * dy) * inv * dt;
  } else if (oi[O_KIND] == M_TRACKING) {
    V fx, fy;
    follow_point(m, t, time, fx, fy);
    V dx = fx - px, dy = fy - py;
    V gap = Ls::sqrt(dx * dx + dy * dy);
    acc[A_GAP0] = Ls::sel(acc[A_STEPS] > 0.0, acc[A_GAP0], gap);
    acc[A_GAP] = acc[A_GAP] + gap;
  }
  if (oi[O_DEPTH] && m.ncontact) {
    V d = t.depth[0];
    for (int c = 1; c < m.ncontact; ++c) d = Ls::max(d, t.depth[c]);
    acc[A_DEEPEST] = Ls::max(acc[A_DEEPEST], d);
  }
  // the descriptors
  V y{}, air{};
  if (vertical) {
    y = py - ground_height(m, t, px);
    auto any = V{} < 0.0;  // all false
    for (int c = 0; c < m.ncontact; ++c) any = any | (t.depth[c] > 0.0);
    air = Ls::sel(any, V{}, V{} + 1.0);
  }
  const int root = oi[O_ROOT];
  if (root >= 0) {
    V th = t.th[root], d = th - acc[A_ANGLE];
    d = d - (2 * M_PI) * Ls::floor((d + M_PI) * (0.5 / M_PI));
    acc[A_TURN] = acc[A_TURN] + Ls::sel(acc[A_STEPS] > 0.0, d, V{});
    acc[A_ANGLE] = th;
  }
  if (oi[O_N_JOINTS]) {
    V js{};
    for (int k = 0; k < oi[O_N_JOINTS]; ++k) js = js + Ls::abs(t.qd[joints[k]]);
    acc[A_JOINT_SPEED] = acc[A_JOINT_SPEED] + js / (double)oi[O_N_JOINTS];
  }
  V *duty = acc + A_FIXED, *words = duty + oi[O_N_TOUCH], *times = words + EVENTS;
  for (int k = 0; k < oi[O_N_TOUCH]; ++k) duty[k] = duty[k] + t.bits[touch[k]];
  if (oi[O_SENSORS]) {
    V w{};
    for (int s = 0; s < oi[O_SENSORS]; ++s) w = w + Ls::sel(t.bits[s] > 0.5, V{} + (double)(1 << s), V{});
    V since = Ls::sel(w == acc[A_CANDIDATE], acc[A_SINCE], time);
    acc[A_SINCE] = since;
    acc[A_CANDIDATE] = w;
    auto fresh = (w != acc[A_WORD]) & (time - since + dt >= DEBOUNCE_S);
    for (int l = 0; l < Ls::W; ++l) {
      if (!Ls::on(fresh, l)) continue;
      int slot = (int)Ls::lane(acc[A_CHANGES], l) % EVENTS;
      Ls::set(words[slot], l, Ls::lane(w, l));
      Ls::set(times[slot], l, Ls::lane(since, l));
    }
    acc[A_CHANGES] = acc[A_CHANGES] + Ls::sel(fresh, V{} + 1.0, V{});
    acc[A_WORD] = Ls::sel(fresh, w, acc[A_WORD]);
  }
  acc[A_STEPS] = acc[A_STEPS] + 1.0;
  acc[A_HEIGHT] = acc[A_HEIGHT] + y;
  acc[A_HEIGHT2] = acc[A_HEIGHT2] + y * y;
  acc[A_AIRBORNE] = acc[A_AIRBORNE] + air;
}

// ---------------------------------------------------------------- start states

// Lifts every free tree just enough that none of its contact points is below the ground (the
// vertical plane; dynamics.seat_on_ground), in place on q; then the tile holds q's positions.
template <class V> static inline void seat(const Model &m, Tile<V> &t, V *q) {
  using Ls = Lanes<V>;
  positions(m, q, t);
  for (int tr = 0; tr < m.ntree; ++tr) {
    const TreeInts &T = m.tree(tr);
    if (!T.free) continue;
    V lift{};
    for (int c = 0; c < m.ncontact; ++c)
      if (m.link(m.ci[c]).tree == tr) lift = Ls::max(lift, ground_height(m, t, t.cp[c][0]) - t.cp[c][1]);
    int dy = m.link(T.root).dof_y;
    q[dy] = q[dy] + lift;
  }
  positions(m, q, t);
}

}  // namespace sanlab
