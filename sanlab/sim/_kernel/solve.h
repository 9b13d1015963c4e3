// The linear algebra of a step (paper §3.4: "generates and solves a set of linear equations Ax = b";
// docs/simulator.md, "The step"): the matrix A = M + h D + h^2 K and force Q that the elements
// assemble, the velocity M^-1 p of a state, and the step's solve A du = h Q. Two routes, the same
// to round-off: the dense L D L^T below, and the articulated one (articulated.h) for trees of
// rigid links.
#pragma once
#include "articulated.h"

namespace sanlab {

// A += coef g g^T on the row's dofs, each product formed as (coef g_i) g_j, i >= j
template <class V> static inline void outer(Ptr<V> A, int D, V coef, const int32_t *idx, Ptr<const V> g, int n) {
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

// A += coef (g h^T + h g^T) for two rows on the same dofs
template <class V> static inline void outer2(Ptr<V> A, int D, V coef, const int32_t *idx, Ptr<const V> g, Ptr<const V> h,
                                     int n) {
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

template <class V> static inline void force(Ptr<V> Q, V f, const int32_t *idx, Ptr<const V> g, int n) {
  for (int a = 0; a < n; ++a) Q[idx[a]] += f * g[a];
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
    int n = point_row(m, t, i, t.com[i][0], t.com[i][1], V{} + 1.0f, V{}, t.g);
    outer(t.M, D, mass, idx, t.g, n);
    n = point_row(m, t, i, t.com[i][0], t.com[i][1], V{}, V{} + 1.0f, t.g);
    outer(t.M, D, mass, idx, t.g, n);
    for (int a = 0; a < n; ++a) t.g[a] = V{} + (m.rl[i * m.nchain + a] >= 0 ? 1.0f : 0.0f);
    outer(t.M, D, I, idx, t.g, n);
  }
}

// x = A^-1 b by L D L^T in the elimination order D-1, ..., 0 (structural zeros carried as exact
// zeros)
template <class V> static inline void solve(Tile<V> &t, Ptr<const V> A, Ptr<const V> b, Ptr<V> x, int D) {
  Ptr<V> F = t.F, Lf = t.Lf;
  // F holds the lower half: F[i][j], i >= j; Lf[k][i] = l_ik (i < k), Lf[k][k] = 1 / d_k
  for (int a = 0; a < D; ++a)
    for (int c = 0; c <= a; ++c) F[a * D + c] = A[a * D + c];
  for (int k = D - 1; k >= 0; --k) {
    V inv = 1.0f / F[k * D + k];
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

// The velocity of a state: u = M^-1 p in tree coordinates, qd in state coordinates, then each
// link's and contact's velocity (a tile whose positions are computed)
template <class V> static inline void velocities(const Model &m, Ptr<const V> p, Tile<V> &t) {
  const int D = m.ndof;
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
  link_velocities(m, t);
}

// The step's matrix and force before any element: A = M (dense) or no extra terms (articulated),
// Q = 0
template <class V> static inline void start_step(const Model &m, Tile<V> &t) {
  const int D = m.ndof, L = m.nlink;
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
}

// The step's solve A du = h Q, and the momentum change g = M du (state coordinates: turned by
// integrate)
template <class V> static inline void solve_step(const Model &m, Tile<V> &t) {
  const int D = m.ndof, L = m.nlink;
  const V h = t.world().dt;
  const bool art = m.world().articulated;
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
}

// Semi-implicit Euler in momentum form (docs/simulator.md, "The step"): p += S^T M du, the
// velocity v* = u + du, q += h v*
template <class V> static inline void integrate(const Model &m, Tile<V> &t, Ptr<V> q, Ptr<V> p) {
  const int D = m.ndof;
  const V h = t.world().dt;
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

}  // namespace sanlab
