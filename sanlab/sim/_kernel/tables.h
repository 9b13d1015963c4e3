// The creature as tables (kernel.py: pack, as sanlab/sim/layout.py declares them, each row read
// through its layout.h struct) and a tile's scratch: every per-creature value of a step.
#pragma once
#include <cstddef>
#include <cstdint>

#include "lanes.h"
#include "layout.h"

namespace sanlab {

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

// ---------------------------------------------------------------- where a step keeps its values
//
// A step reaches every value it keeps per creature (a tile's scratch below, the state, the
// controller's parameters and state, the observers' sums) through Ptr<V> (one value after
// another) and RowPtr<V, N> (rows of N values, as V (*)[N]). On the CPU they are V * and
// V (*)[N]: a tile's values lie one after another, each a SIMD register of W lanes, and the
// tiles' code is what it always was. On a GPU (__CUDACC_RTC__) a thread steps one creature and a
// warp of 32 threads reads the same value of 32 creatures together; there they are Strided: value
// k of a thread lies SANLAB_WARP values after value k - 1, the 32 threads of a warp interleaved
// (gpu.cu), so that the warp's 32 reads of a value are 32 neighbouring addresses (256 bytes of
// float64, 128 of float32) rather than 32 addresses a whole scratch apart.
#ifndef SANLAB_WARP
#define SANLAB_WARP 32
#endif
template <class T> struct Strided {
  T *p;
  T &operator[](int64_t k) const { return p[k * SANLAB_WARP]; }
  T &operator*() const { return *p; }
  Strided operator+(int64_t k) const { return {p + k * SANLAB_WARP}; }
  explicit operator bool() const { return p != nullptr; }
  template <class U> operator Strided<U>() const { return {p}; }  // V to const V
};
template <class T, int N> struct StridedRows {
  T *p;
  Strided<T> operator[](int64_t i) const { return {p + i * N * SANLAB_WARP}; }
  StridedRows operator+(int64_t i) const { return {p + i * N * SANLAB_WARP}; }
};
// (through a member type: a parameter of these types never deduces V, which comes from the
// Tile<V> or the V beside it, so a V pointer passes where a const V one is asked for on both)
template <class T> struct same_type {
  using type = T;
};
#ifdef __CUDACC_RTC__
template <class V> using Ptr = typename same_type<Strided<V>>::type;
template <class V, int N> using RowPtr = typename same_type<StridedRows<V, N>>::type;
#else
template <class V> using Ptr = typename same_type<V *>::type;
template <class V, int N> using RowPtr = typename same_type<V (*)[N]>::type;
#endif
// values taken as rows of N, and rows as values (the state: q, p, then the anchors' rows)
template <int N, class V> static inline V (*rows(V *p))[N] { return (V(*)[N])p; }
template <class V, int N> static inline V *flat(V (*p)[N]) { return (V *)p; }
template <int N, class V> static inline StridedRows<V, N> rows(Strided<V> p) { return {p.p}; }
template <class V, int N> static inline Strided<V> flat(StridedRows<V, N> p) { return {p.p}; }
// where a tile's numbers lie: on the CPU its own copy in its scratch (rollout.h: fill_numbers); a
// GPU thread reads them where they are (gpu.cu points them at the tables), their room left unused
template <class V> static inline V *numbers_at(V *p) { return p; }
template <class V> static inline V *numbers_at(Strided<V>) { return nullptr; }

// A tile's scratch: every per-creature value of a step, one V each, carved out of one block sized
// for the creature (tile_values); matrices are ndof x ndof, row-major.
template <class V> struct Tile {
  // the creature's numbers, one V each: a lane's own where rows carry their own (mixed batches),
  // else the shared value on every lane (kernel.cpp fills them as a tile starts); read through
  // the rows' structs below
  V *lf, *cf, *sf, *af, *pf, *ef, *wf, *rough;
  // per link: absolute angle th (rad) and its (cos, sin) cs; origin X and centre of mass com in
  // the world (m); over its subtree, the mass msum (kg) and mass-weighted centres mc (kg m); S how
  // its tree's centre-of-mass coordinates turn with its joint (kinematics.h: turn); angular
  // velocity w (rad/s) and its origin's velocity V_ (m/s)
  Ptr<V> th;
  RowPtr<V, 2> cs, X, com, mc, S;
  Ptr<V> w;
  RowPtr<V, 2> V_;
  Ptr<V> msum;
  // per contact: world point cp (m), depth below the ground (m), the ground's normal and tangent
  // gn (nx, ny, tx, ty) there, and the point's velocity cv (m/s)
  RowPtr<V, 2> cp;
  Ptr<V> depth;
  RowPtr<V, 4> gn;
  RowPtr<V, 2> cv;
  // ndof x ndof: the mass matrix M, the step's matrix A = M + h D + h^2 K, and the L D L^T's
  // factors F, Lf (solve.h)
  Ptr<V> M, A, F, Lf;
  // per dof: the step's force Q, the velocity u in tree coordinates and qd in state coordinates,
  // a point's Jacobian row g (then the momentum change), the solve's x, a dense row of an element
  Ptr<V> Q, u, qd, g, x, row;
  // the SAN's node sums total [nnode], the sensor values bits [nsensor] (0 or 1), the
  // activations act [nact] in [0, 1]
  Ptr<V> total, bits, act;
  // the articulated route (articulated.h): per body its spatial inertia about its tree's reference
  // point, joint motion subspace, the step's extra inertia E and spatial force F, and the
  // recursion's articulated inertias and biases; per dof the extra diagonal (armature)
  RowPtr<V, 6> I;
  RowPtr<V, 3> s;
  RowPtr<V, 6> E;
  RowPtr<V, 3> Fb;
  RowPtr<V, 6> IA;
  RowPtr<V, 3> pA, U;
  Ptr<V> invD, uu;
  RowPtr<V, 3> acc, Hb;
  Ptr<V> arm;
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
template <class V> static size_t tile_layout(const Model &m, Ptr<V> mem, Tile<V> &t) {
  const int L = m.nlink, C = m.ncontact, D = m.ndof;
  size_t used = 0;
  auto take = [&](size_t n) { Ptr<V> r = mem ? mem + used : Ptr<V>{}; used += n; return r; };
  auto nums = [&](size_t n) { return numbers_at(take(n)); };
  auto take2 = [&](size_t n) { return rows<2>(take(2 * n)); };
  auto take3 = [&](size_t n) { return rows<3>(take(3 * n)); };
  auto take6 = [&](size_t n) { return rows<6>(take(6 * n)); };
  t.lf = nums(L * LF_WIDTH); t.cf = nums(C * CF_WIDTH); t.sf = nums(m.nsensor * SF_WIDTH); t.af = nums(m.nact * AF_WIDTH);
  t.pf = nums(m.nspring * PF_WIDTH); t.ef = nums(m.nedge * EF_WIDTH); t.wf = nums(WF_WIDTH); t.rough = nums(m.nrough * ROUGH_WIDTH);
  t.th = take(L); t.cs = take2(L); t.X = take2(L); t.com = take2(L);
  t.mc = take2(L); t.S = take2(L); t.w = take(L); t.V_ = take2(L);
  t.msum = take(L);
  t.cp = take2(C); t.depth = take(C); t.gn = rows<4>(take(4 * C)); t.cv = take2(C);
  t.M = take(D * D); t.A = take(D * D); t.F = take(D * D); t.Lf = take(D * D);
  t.Q = take(D); t.u = take(D); t.qd = take(D); t.g = take(D); t.x = take(D); t.row = take(D);
  t.total = take(m.nnode); t.bits = take(m.nsensor); t.act = take(m.nact);
  t.I = take6(L); t.s = take3(L); t.E = take6(L); t.Fb = take3(L);
  t.IA = take6(L); t.pA = take3(L); t.U = take3(L); t.invD = take(L);
  t.uu = take(L); t.acc = take3(L); t.Hb = take3(L); t.arm = take(D);
  return used;
}

template <class V> static size_t tile_values(const Model &m) {
  Tile<V> t;
  return tile_layout<V>(m, Ptr<V>{}, t);
}

template <class V> static Tile<V> tile_at(const Model &m, Ptr<V> mem) {
  Tile<V> t;
  tile_layout<V>(m, mem, t);
  t.art = m.world().articulated != 0;
  return t;
}

}  // namespace sanlab
