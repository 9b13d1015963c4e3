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
  V *th, (*cs)[2], (*X)[2], (*com)[2], (*mc)[2], (*S)[2], *w, (*V_)[2];
  V *msum;
  // per contact: world point cp (m), depth below the ground (m), the ground's normal and tangent
  // gn (nx, ny, tx, ty) there, and the point's velocity cv (m/s)
  V (*cp)[2], *depth, (*gn)[4], (*cv)[2];
  // ndof x ndof: the mass matrix M, the step's matrix A = M + h D + h^2 K, and the L D L^T's
  // factors F, Lf (solve.h)
  V *M, *A, *F, *Lf;
  // per dof: the step's force Q, the velocity u in tree coordinates and qd in state coordinates,
  // a point's Jacobian row g (then the momentum change), the solve's x, a dense row of an element
  V *Q, *u, *qd, *g, *x, *row;
  // the SAN's node sums total [nnode], the sensor values bits [nsensor] (0 or 1), the
  // activations act [nact] in [0, 1]
  V *total, *bits, *act;
  // the articulated route (articulated.h): per body its spatial inertia about its tree's reference
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

}  // namespace sanlab
