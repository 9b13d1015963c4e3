// The articulated route of the solve.
//
// For trees of rigid links (no point masses, nothing that joins two bodies): the step's matrices
// are never formed. Each body's mass and each element acting on one body is a planar spatial
// inertia (a symmetric 3 x 3 over the body's spatial velocity (w, vx, vy) at its tree's
// reference point, the root's origin); joint-space elements add to their joint's diagonal.
// Featherstone's articulated-body recursion solves with that matrix and the composite-body
// recursion multiplies by M, each in O(n) (Featherstone, Rigid Body Dynamics Algorithms, 2008,
// §7.3 and §6.2).
#pragma once
#include "kinematics.h"

namespace sanlab {

// the reference point of link i's tree: its root's origin
template <class V> static inline void ref_of(const Model &m, const Tile<V> &t, int i, V &rx, V &ry) {
  int r = m.tree(m.link(i).tree).root;
  rx = t.X[r][0];
  ry = t.X[r][1];
}

// (these three over any pointers: a tile's rows and the small arrays a function keeps of its own)
template <class V, class PA, class Pa> static inline void sym_outer(PA A, V c, Pa a) {
  A[0] += (c * a[0]) * a[0]; A[1] += (c * a[0]) * a[1]; A[2] += (c * a[0]) * a[2];
  A[3] += (c * a[1]) * a[1]; A[4] += (c * a[1]) * a[2]; A[5] += (c * a[2]) * a[2];
}

template <class PA, class PX, class PY> static inline void sym_vec(PA A, PX x, PY y) {
  y[0] = A[0] * x[0] + A[1] * x[1] + A[2] * x[2];
  y[1] = A[1] * x[0] + A[3] * x[1] + A[4] * x[2];
  y[2] = A[2] * x[0] + A[4] * x[1] + A[5] * x[2];
}

template <class PA, class PB> static inline auto dot3(PA a, PB b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

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

// Each body's spatial inertia and each joint's motion subspace (Featherstone 2008, ch. 7)
template <class V> static inline void bodies(const Model &m, Tile<V> &t) {
  for (int i = 0; i < m.nlink; ++i) {
    const LinkInts &l = m.link(i);
    if (l.welded) continue;
    V rx, ry;
    ref_of(m, t, i, rx, ry);
    V mass = t.link(i).mass, cx = t.com[i][0] - rx, cy = t.com[i][1] - ry;
    V mcx = mass * cx, mcy = mass * cy;
    Ptr<V> I = t.I[i];
    I[0] = t.link(i).inertia + (mcx * cx + mcy * cy);
    I[1] = -mcy; I[2] = mcx; I[3] = mass; I[4] = V{}; I[5] = mass;
    if (l.parent >= 0) {
      t.s[i][0] = V{} + 1.0f;
      t.s[i][1] = t.X[i][1] - ry;
      t.s[i][2] = -(t.X[i][0] - rx);
    }
  }
}

// y = M x in tree coordinates: body momenta summed leaves first, projected on each joint
template <class V> static inline void art_matvec(const Model &m, Tile<V> &t, Ptr<const V> x, Ptr<V> y) {
  for (int d = 0; d < m.ndof; ++d) y[d] = V{};
  RowPtr<V, 3> Vb = t.acc;
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
// (Featherstone 2008, §7.3); with_terms = 0 solves with M alone
template <class V> static inline void art_solve(const Model &m, Tile<V> &t, Ptr<const V> b, Ptr<V> x, int with_terms) {
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
    Ptr<V> s = t.s[i];
    V Ui[3];
    sym_vec(t.IA[i], s, Ui);
    V D = dot3(s, Ui) + (with_terms ? t.arm[d] : V{});
    V inv = 1.0f / D, ui = b[d] - dot3(s, t.pA[i]);
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
    // order y, x, w
    const LinkInts &l = m.link(r);
    const int dofs[3] = {l.dof_rot, l.dof_x, l.dof_y};
    V K[3][3], rhs[3];
    Ptr<const V> A = t.IA[r];
    K[0][0] = A[0]; K[0][1] = K[1][0] = A[1]; K[0][2] = K[2][0] = A[2];
    K[1][1] = A[3]; K[1][2] = K[2][1] = A[4]; K[2][2] = A[5];
    for (int k = 0; k < 3; ++k) {
      if (with_terms) K[k][k] = K[k][k] + t.arm[dofs[k]];
      rhs[k] = b[dofs[k]] - t.pA[r][k];
    }
    V Lf[3][3], dinv[3];
    for (int k = 2; k >= 0; --k) {
      dinv[k] = 1.0f / K[k][k];
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

}  // namespace sanlab
