// The forces of a step, each family an element of the implicit step: its gradient row g, stiffness
// k and damping c add (h c + h^2 k) g g^T to the matrix and F - h k (g . v) to the force
// (docs/simulator.md, "The step"): the inertial force dT/dq, gravity, passive joint springs and
// stops, the actuators (paper §3.3: T = ks (theta_d - theta) - kd theta'; F = ks (L_d - L) - kd L'),
// linear springs, and water (paper §3.4: F = k int (v . N) dA).
#pragma once
#include "solve.h"

namespace sanlab {

template <class V> static inline void joint(Tile<V> &t, int D, int d, V h, V f, V k, V c, V rate) {
  if (t.art) t.arm[d] += h * c + (h * h) * k;
  else t.A[d * D + d] += h * c + (h * h) * k;
  t.Q[d] += f - (h * k) * rate;
}

// A dense row over every dof: g = J_b^T e - J_a^T e, for an element between a point on link la
// and one on link lb
template <class V> static inline void two_point_row(const Model &m, Tile<V> &t, int la, V pax, V pay, int lb, V pbx,
                                                    V pby, V ex, V ey, Ptr<V> row) {
  const int D = m.ndof;
  Ptr<V> g = t.g;
  for (int d = 0; d < D; ++d) row[d] = V{};
  int n = point_row(m, t, lb, pbx, pby, ex, ey, g);
  for (int a = 0; a < n; ++a) row[m.ri[lb * m.nchain + a]] += g[a];
  n = point_row(m, t, la, pax, pay, ex, ey, g);
  for (int a = 0; a < n; ++a) row[m.ri[la * m.nchain + a]] += -g[a];
}

// A spring-damper between a point on link la and one on link lb (local points f[0..3]):
// F = ks (target - L) - kd L' along the line between them (paper §3.3), linearised implicitly
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

// dT/dq in O(n): for joint k, -sum over its subtree of
// u_i x (v_ci - V_k), u_i = m_i (v_ci - v_c), from the subtree sums of u_i x v_ci and of u_i
template <class V> static inline void inertial_linear(const Model &m, Tile<V> &t) {
  Ptr<V> Asum = t.uu;  // scratch, as Bsum: the solve that owns them runs later
  RowPtr<V, 3> Bsum = t.acc;
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

// The inertial force dT/dq at fixed velocities (the Lagrangian's, docs/simulator.md "The step"):
// on the articulated route in O(n) (two subtree sums), else link by link up each chain
template <class V> static inline void inertial_forces(const Model &m, Tile<V> &t) {
  const int L = m.nlink;
  if (m.world().articulated) inertial_linear(m, t);
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
}

// Gravity, in the vertical plane: on a free tree's centre of mass, link by link in a welded tree
template <class V> static inline void gravity(const Model &m, Tile<V> &t) {
  const int D = m.ndof, L = m.nlink;
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
        row_element(m, t, i, t.com[i][0], t.com[i][1], V{}, V{} + 1.0f, V{}, V{} - (t.link(i).mass * grav), false);
      }
    }
    turn(m, t, t.x, -1, 1);
    for (int a = 0; a < D; ++a) t.Q[a] += t.x[a];
  }
}

// Passive joint springs: -k (phi - rest) - c phi' at a joint
template <class V> static inline void joint_springs(const Model &m, Tile<V> &t) {
  const int D = m.ndof, L = m.nlink;
  const V h = t.world().dt;
  for (int i = 0; i < L; ++i) {
    const LinkInts &l = m.link(i);
    if (!l.spring) continue;
    const LinkNumbers<V> &f = t.link(i);
    int d = l.dof_rot;
    V k = f.jspring_k, c = f.jspring_c, rest = f.jspring_rest;
    V phi = t.th[i] - t.th[l.parent];
    joint(t, D, d, h, -k * (phi - rest) - c * t.u[d], V{} + k, V{} + c, t.u[d]);
  }
}

// Joint stops: a one-sided spring-damper outside [min, max], on only while it pushes back
template <class V> static inline void joint_stops(const Model &m, Tile<V> &t) {
  using Ls = Lanes<V>;
  const int D = m.ndof, L = m.nlink;
  const V h = t.world().dt;
  for (int i = 0; i < L; ++i) {
    const LinkInts &l = m.link(i);
    if (!l.limit) continue;
    const LinkNumbers<V> &f = t.link(i);
    int d = l.dof_rot;
    V lo = f.limit_min, hi = f.limit_max, k = f.limit_k, c = f.limit_c;
    V phi = t.th[i] - t.th[l.parent];
    V below = Ls::max(k * (lo - phi) - c * t.u[d], V{});
    V above = Ls::min(k * (hi - phi) - c * t.u[d], V{});
    auto on = ((phi < lo) & (below > 0.0f)) | ((phi > hi) & (above < 0.0f));
    V onv = Ls::sel(on, V{} + 1.0f, V{});
    V torque = Ls::sel(phi < lo, below, Ls::sel(phi > hi, above, V{}));
    joint(t, D, d, h, torque, onv * k, onv * c, t.u[d]);
  }
}

// The actuators (paper §3.3): angular servos at a joint, linear ones between two points, each a PD
// servo to the target min + u (max - min) of its activation u in [0, 1]
template <class V> static inline void actuators(const Model &m, Tile<V> &t) {
  const int D = m.ndof;
  const V h = t.world().dt;
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
}

// Passive linear springs between two points
template <class V> static inline void linear_springs(const Model &m, Tile<V> &t) {
  const V h = t.world().dt;
  for (int n = 0; n < m.nspring; ++n) {
    const SpringNumbers<V> &f = t.spring(n);
    const SpringInts &l = m.spring(n);
    linear(m, t, l.link_a, f.point_a_x, f.point_a_y, l.link_b, f.point_b_x, f.point_b_y, V{} + f.rest, f.ks, f.kd, h);
  }
}

// Water drag on each edge, exact for a rigid edge: normal -k int (v.N) N ds, tangential (skin)
// -k_t int (v.T) T ds (paper §3.4: F = k int (v.N) dA)
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
    V c1 = k * L, c2 = k * L * L / 2.0f, c3 = k * L * L * L / 3.0f;
    V vt = vax * tx + vay * ty, ct = kt * L;
    if (m.world().articulated) {  // the normal row on the body, and its rotation row (1, 0, 0)
      V an[3], aw[3] = {V{} + 1.0f, V{}, V{}};
      body_row(m, t, i, ax, ay, nx, ny, an);
      Ptr<V> E = t.E[i];
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
    Ptr<V> gw = t.row;  // the link's rotation row on the same dofs
    for (int a = 0; a < n; ++a) gw[a] = V{} + ((!point && m.rl[i * m.nchain + a] >= 0) ? 1.0f : 0.0f);
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

}  // namespace sanlab
