// Kinematics (paper §3.1: rigid links joined at joints; docs/simulator.md, "Units and
// coordinates"): each link's frame from the coordinates, the world points on a link, the row
// g = J^T n of a point's Jacobian along a direction, the change between state and tree
// coordinates of a free tree, and each link's velocity from the dofs'.
#pragma once
#include "tables.h"

namespace sanlab {

// Each link's frame from the coordinates q: its absolute angle th and (cos, sin) cs, its origin X
// and centre of mass com in the world; a free tree's coordinates are its centre of mass, so its
// links are placed about their own centre of mass first and shifted (docs/simulator.md, "Units
// and coordinates"), S the turning rates that shift takes (used by turn)
template <class V> static inline void link_frames(const Model &m, Ptr<const V> q, Tile<V> &t) {
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
    V inv = 1.0f / t.msum[r];
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
}

template <class V> static inline void point_at(const Tile<V> &t, int i, V rx, V ry, V &px, V &py) {
  V c = t.cs[i][0], s = t.cs[i][1];
  px = t.X[i][0] + (c * rx - s * ry);
  py = t.X[i][1] + (s * rx + c * ry);
}

template <class V> static inline void point_vel(const Tile<V> &t, int i, V px, V py, V &vx, V &vy) {
  V rx = px - t.X[i][0], ry = py - t.X[i][1];
  vx = t.V_[i][0] - t.w[i] * ry;
  vy = t.V_[i][1] + t.w[i] * rx;
}

// The row g = J^T n of a world point (px, py) on link i along n, at the dofs of the link's chain
//; returns the entry count.
template <class V> static inline int point_row(const Model &m, const Tile<V> &t, int i, V px, V py, V nx, V ny, Ptr<V> g) {
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

// Between state and tree coordinates of each free tree (docs/simulator.md, "Units and coordinates"):
// velocities (force = 0; sign +1: u = S v, -1: v = S^-1 u) or forces (force = 1; +1: S^T g,
// -1: S^-T f), in place
template <class V> static inline void turn(const Model &m, const Tile<V> &t, Ptr<V> v, int sign, int force) {
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

// Each link's angular velocity w and its origin's velocity V_, and each contact's velocity cv, from
// the velocities u in tree coordinates (a tile whose frames and contact points are computed)
template <class V> static inline void link_velocities(const Model &m, Tile<V> &t) {
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

}  // namespace sanlab
