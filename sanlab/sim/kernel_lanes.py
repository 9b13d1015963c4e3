# ruff: noqa: RUF059
"""The kernel of :mod:`sanlab.sim.kernel` over lanes: a tile of ``W`` creatures per thread.

Same tables, same arithmetic per creature (each lane's results equal the scalar kernel's
bit for bit), but every per-creature value carries a trailing lane axis of ``W`` and every
statement is a loop over it, so that the compiler emits one vector instruction per operation
for the tile (throughput at large batches comes from SIMD across creatures, as today's XLA
engine gets it from its [B]-wide operations). Branches on a creature's state (touching or not,
sticking or sliding) become selects; a contact no lane of the tile touches is skipped.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sanlab.sim.kernel import (
    F_ANCX,
    F_ANCY,
    F_COMX,
    F_COMY,
    F_INERTIA,
    F_JSPRING,
    F_LIMIT,
    F_MASS,
    F_MU,
    F_POSEA,
    F_POSEX,
    F_POSEY,
    L_ANISO,
    L_AX_FROM,
    L_AX_TO,
    L_DX,
    L_DY,
    L_LIMIT,
    L_PARENT,
    L_ROT,
    L_SPRING,
    L_TREE,
    L_WELDED,
    W_DT,
    W_GC,
    W_GK,
    W_GRAVITY,
    W_HIDDEN,
    W_HILL_C,
    W_HILL_H,
    W_HILL_W,
    W_SLIP,
    W_SLOPE,
    W_TERRAIN,
)

W = 4  # lanes: one AVX register of float64



@njit(cache=True, error_model="numpy", boundscheck=False)
def _scratch(L, C, D, N, S, A):
    return (np.zeros((L, W)), np.zeros((L, 2, W)), np.zeros((L, 2, W)), np.zeros((L, 2, W)), np.zeros(L),
            np.zeros((L, 2, W)), np.zeros((L, 2, W)), np.zeros((C, 2, W)), np.zeros((C, W)), np.zeros((C, 4, W)),
            np.zeros((L, W)), np.zeros((L, 2, W)), np.zeros((C, 2, W)), np.zeros((D, D, W)), np.zeros((D, D, W)),
            np.zeros((D, D, W)), np.zeros((D, W)), np.zeros((D, W)), np.zeros((D, W)), np.zeros((D, W)),
            np.zeros((D, W)), np.zeros((D, D, W)), np.zeros((N, W)), np.zeros((S, W)), np.zeros((A, W)),
            np.zeros((16, W)))


@njit(cache=True, error_model="numpy", boundscheck=False)
def _positions(li, lf, ti, ci, cf, wi, wf, rough, q, th, cs, X, com, msum, mc, S, cp, depth, gn):
    L = li.shape[0]
    for i in range(L):
        par, rot = li[i, L_PARENT], li[i, L_ROT]
        if par < 0:
            if rot >= 0:
                for l in range(W):
                    th[i, l] = q[rot, l]
            else:
                a = lf[i, F_POSEA] if li[i, L_DX] < 0 else 0.0
                for l in range(W):
                    th[i, l] = a
        else:
            for l in range(W):
                th[i, l] = th[par, l] + q[rot, l]
        for l in range(W):
            cs[i, 0, l] = math.cos(th[i, l])
            cs[i, 1, l] = math.sin(th[i, l])
    for i in range(L):
        par = li[i, L_PARENT]
        if par < 0:
            x0 = lf[i, F_POSEX] if li[i, L_DX] < 0 else 0.0
            y0 = lf[i, F_POSEY] if li[i, L_DX] < 0 else 0.0
            for l in range(W):
                X[i, 0, l] = x0
                X[i, 1, l] = y0
        else:
            ax, ay = lf[i, F_ANCX], lf[i, F_ANCY]
            for l in range(W):
                c, s = cs[par, 0, l], cs[par, 1, l]
                X[i, 0, l] = X[par, 0, l] + (c * ax - s * ay)
                X[i, 1, l] = X[par, 1, l] + (s * ax + c * ay)
    for i in range(L):
        rx, ry = lf[i, F_COMX], lf[i, F_COMY]
        for l in range(W):
            c, s = cs[i, 0, l], cs[i, 1, l]
            com[i, 0, l] = X[i, 0, l] + (c * rx - s * ry)
            com[i, 1, l] = X[i, 1, l] + (s * rx + c * ry)
    for t in range(ti.shape[0]):
        if ti[t, 1] == 0 or ti[t, 2] == 1:
            continue
        r = ti[t, 0]
        for i in range(L - 1, -1, -1):
            if li[i, L_TREE] != t:
                continue
            m = lf[i, F_MASS]
            ms = m
            for l in range(W):
                mc[i, 0, l] = m * com[i, 0, l]
                mc[i, 1, l] = m * com[i, 1, l]
            for j in range(L):
                if li[j, L_PARENT] == i:
                    ms = ms + msum[j]
                    for l in range(W):
                        mc[i, 0, l] = mc[i, 0, l] + mc[j, 0, l]
                        mc[i, 1, l] = mc[i, 1, l] + mc[j, 1, l]
            msum[i] = ms
        inv = 1.0 / msum[r]
        dx, dy = li[r, L_DX], li[r, L_DY]
        for k in range(L):
            if li[k, L_TREE] != t:
                continue
            rot = li[k, L_ROT] >= 0
            mk = msum[k]
            for l in range(W):
                sx = q[dx, l] - mc[r, 0, l] * inv
                sy = q[dy, l] - mc[r, 1, l] * inv
                if rot:
                    S[k, 0, l] = (mc[k, 0, l] - mk * X[k, 0, l]) * inv
                    S[k, 1, l] = (mc[k, 1, l] - mk * X[k, 1, l]) * inv
                X[k, 0, l] = X[k, 0, l] + sx
                X[k, 1, l] = X[k, 1, l] + sy
                com[k, 0, l] = com[k, 0, l] + sx
                com[k, 1, l] = com[k, 1, l] + sy
    kind = wi[W_TERRAIN]
    for c in range(ci.shape[0]):
        i = ci[c]
        rx, ry = cf[c, 0], cf[c, 1]
        for l in range(W):
            cc, ss = cs[i, 0, l], cs[i, 1, l]
            px = X[i, 0, l] + (cc * rx - ss * ry)
            py = X[i, 1, l] + (ss * rx + cc * ry)
            cp[c, 0, l], cp[c, 1, l] = px, py
        if kind == 0:
            for l in range(W):
                gn[c, 0, l], gn[c, 1, l], gn[c, 2, l], gn[c, 3, l] = 0.0, 1.0, 1.0, 0.0
                depth[c, l] = (0.0 - cp[c, 1, l]) * 1.0
            continue
        for l in range(W):
            x = cp[c, 0, l]
            if kind == 1:
                hh, dh = wf[W_SLOPE] * x, wf[W_SLOPE]
            elif kind == 2:
                H, hw, cc = wf[W_HILL_H], wf[W_HILL_W], wf[W_HILL_C]
                u = (x - cc) * (math.pi / hw)
                inside = abs(x - cc) < hw
                hh = 0.5 * H * (1.0 + math.cos(u)) if inside else 0.0
                dh = -0.5 * H * (math.pi / hw) * math.sin(u) if inside else 0.0
            else:
                hh, dh = 0.0, 0.0
                for k in range(rough.shape[0]):
                    a, w, ph = rough[k, 0], rough[k, 1], rough[k, 2]
                    arg = w * x + ph
                    hh = hh + a * math.sin(arg)
                    dh = dh + a * w * math.cos(arg)
            inv = 1.0 / math.sqrt(1.0 + dh * dh)
            gn[c, 0, l], gn[c, 1, l], gn[c, 2, l], gn[c, 3, l] = -dh * inv, inv, inv, dh * inv
            depth[c, l] = (hh - cp[c, 1, l]) * inv


@njit(cache=True, error_model="numpy", boundscheck=False)
def _point_row(rl, rn, X, i, P, pc, nrm, val):
    """As ``kernel._point_row`` per lane: the point P[pc, :, l], the direction nrm [2 or 4, W]."""
    n = rn[i]
    for a in range(n):
        k = rl[i, a]
        if k == -1:
            for l in range(W):
                val[a, l] = nrm[0, l]
        elif k == -2:
            for l in range(W):
                val[a, l] = nrm[1, l]
        elif k == -3:
            for l in range(W):
                val[a, l] = 0.0
        else:
            for l in range(W):
                val[a, l] = (-(P[pc, 1, l] - X[k, 1, l])) * nrm[0, l] + (P[pc, 0, l] - X[k, 0, l]) * nrm[1, l]
    return n


@njit(cache=True, error_model="numpy", boundscheck=False)
def _outer(A, coef, idx, val, n):
    for a in range(n):
        i = idx[a]
        for b in range(a + 1):
            j = idx[b]
            if i != j:
                for l in range(W):
                    v = (coef[l] * val[a, l]) * val[b, l]
                    A[i, j, l] += v
                    A[j, i, l] += v
            else:
                for l in range(W):
                    A[i, i, l] += (coef[l] * val[a, l]) * val[b, l]


@njit(cache=True, error_model="numpy", boundscheck=False)
def _force(Q, f, idx, val, n):
    for a in range(n):
        d = idx[a]
        for l in range(W):
            Q[d, l] += f[l] * val[a, l]


@njit(cache=True, error_model="numpy", boundscheck=False)
def _mass_matrix(li, lf, ri, rl, rn, X, com, M, g, e, D):
    for a in range(D):
        for b in range(D):
            for l in range(W):
                M[a, b, l] = 0.0
    for i in range(li.shape[0]):
        if li[i, L_WELDED] == 1:
            continue
        m, I = lf[i, F_MASS], lf[i, F_INERTIA]
        for l in range(W):
            e[0, l], e[1, l] = m, I
        coef_m = e[0]
        for l in range(W):
            e[2, l], e[3, l] = 1.0, 0.0
        n = _point_row(rl, rn, X, i, com, i, e[2:4], g)
        _outer(M, coef_m, ri[i], g, n)
        for l in range(W):
            e[2, l], e[3, l] = 0.0, 1.0
        n = _point_row(rl, rn, X, i, com, i, e[2:4], g)
        _outer(M, coef_m, ri[i], g, n)
        n = rn[i]
        for a in range(n):
            one = 1.0 if rl[i, a] >= 0 else 0.0
            for l in range(W):
                g[a, l] = one
        _outer(M, e[1], ri[i], g, n)


@njit(cache=True, error_model="numpy", boundscheck=False)
def _solve(A, b, x, F, Lf, D):
    for a in range(D):
        for c in range(D):
            for l in range(W):
                F[a, c, l] = A[a, c, l]
    for k in range(D - 1, -1, -1):
        for l in range(W):
            Lf[k, k, l] = 1.0 / F[k, k, l]
        for i in range(k):
            for l in range(W):
                Lf[k, i, l] = F[i, k, l] * Lf[k, k, l]
        for i in range(k - 1, -1, -1):
            for j in range(k - 1, i - 1, -1):
                for l in range(W):
                    v = F[i, j, l] - Lf[k, i, l] * F[j, k, l]
                    F[i, j, l] = v
                    F[j, i, l] = v
    for a in range(D):
        for l in range(W):
            x[a, l] = b[a, l]
    for k in range(D - 1, -1, -1):
        for i in range(k - 1, -1, -1):
            for l in range(W):
                x[i, l] = x[i, l] - Lf[k, i, l] * x[k, l]
    for k in range(D):
        for l in range(W):
            x[k, l] = x[k, l] * Lf[k, k, l]
    for k in range(D):
        for i in range(k - 1, -1, -1):
            for l in range(W):
                x[k, l] = x[k, l] - Lf[k, i, l] * x[i, l]


@njit(cache=True, error_model="numpy", boundscheck=False)
def _turn(li, ti, S, v, sign, force):
    for t in range(ti.shape[0]):
        if ti[t, 1] == 0 or ti[t, 2] == 1:
            continue
        r = ti[t, 0]
        dx, dy = li[r, L_DX], li[r, L_DY]
        for k in range(li.shape[0]):
            if li[k, L_TREE] != t or li[k, L_ROT] < 0:
                continue
            d = li[k, L_ROT]
            for l in range(W):
                tx, ty = S[k, 1, l], -S[k, 0, l]
                if force == 0:
                    if sign > 0:
                        v[dx, l] = v[dx, l] + tx * v[d, l]
                        v[dy, l] = v[dy, l] + ty * v[d, l]
                    else:
                        v[dx, l] = v[dx, l] - tx * v[d, l]
                        v[dy, l] = v[dy, l] - ty * v[d, l]
                elif sign > 0:
                    v[d, l] = v[d, l] + (tx * v[dx, l] + ty * v[dy, l])
                else:
                    v[d, l] = v[d, l] - (tx * v[dx, l] + ty * v[dy, l])


@njit(cache=True, error_model="numpy", boundscheck=False)
def _velocities(li, ci, X, cp, u, w, V, cv):
    for i in range(li.shape[0]):
        par, rot = li[i, L_PARENT], li[i, L_ROT]
        if par < 0:
            dx, dy = li[i, L_DX], li[i, L_DY]
            for l in range(W):
                w[i, l] = u[rot, l] if rot >= 0 else 0.0
                V[i, 0, l] = u[dx, l] if dx >= 0 else 0.0
                V[i, 1, l] = u[dy, l] if dx >= 0 else 0.0
        else:
            for l in range(W):
                w[i, l] = w[par, l] + u[rot, l]
                rx, ry = X[i, 0, l] - X[par, 0, l], X[i, 1, l] - X[par, 1, l]
                V[i, 0, l] = V[par, 0, l] - w[par, l] * ry
                V[i, 1, l] = V[par, 1, l] + w[par, l] * rx
    for c in range(ci.shape[0]):
        i = ci[c]
        for l in range(W):
            rx, ry = cp[c, 0, l] - X[i, 0, l], cp[c, 1, l] - X[i, 1, l]
            cv[c, 0, l] = V[i, 0, l] - w[i, l] * ry
            cv[c, 1, l] = V[i, 1, l] + w[i, l] * rx


@njit(cache=True, error_model="numpy", boundscheck=False)
def _prepare(li, lf, ri, rl, rn, ti, ci, cf, wi, wf, rough, q, p, sc):
    th, cs, X, com, msum, mc, S, cp, depth, gn, w, V, cv, M, A, F, Q, u, qd, g, x, Lf, tot, bits, act, e = sc
    D = q.shape[0]
    _positions(li, lf, ti, ci, cf, wi, wf, rough, q, th, cs, X, com, msum, mc, S, cp, depth, gn)
    _mass_matrix(li, lf, ri, rl, rn, X, com, M, g, e, D)
    for d in range(D):
        for l in range(W):
            x[d, l] = p[d, l]
    _turn(li, ti, S, x, -1, 1)
    _solve(M, x, u, F, Lf, D)
    for d in range(D):
        for l in range(W):
            qd[d, l] = u[d, l]
    _turn(li, ti, S, qd, -1, 0)
    _velocities(li, ci, X, cp, u, w, V, cv)


@njit(cache=True, error_model="numpy", boundscheck=False)
def _joint(A, Q, d, h, force, k, c, rate, l):
    A[d, d, l] += h * c + (h * h) * k
    Q[d, l] += force - (h * k) * rate


@njit(cache=True, error_model="numpy", boundscheck=False)
def _advance(li, lf, ri, rl, rn, ti, ci, cf, ai, af, wi, wf, rough, q, p, anchor, sc, dmax):
    th, cs, X, com, msum, mc, S, cp, depth, gn, w, V, cv, M, A, F, Q, u, qd, g, x, Lf, tot, bits, act, e = sc
    D = q.shape[0]
    L = li.shape[0]
    h = wf[W_DT]
    for a in range(D):
        for l in range(W):
            Q[a, l] = 0.0
        for b in range(D):
            for l in range(W):
                A[a, b, l] = M[a, b, l]
    for t in range(ti.shape[0]):
        if ti[t, 2] == 1:
            continue
        free = ti[t, 1] == 1
        r = ti[t, 0]
        for i in range(L):
            if li[i, L_TREE] != t or (li[i, L_PARENT] < 0 and not free):
                continue
            m = lf[i, F_MASS]
            for l in range(W):
                vcx = qd[li[r, L_DX], l] if free else 0.0
                vcy = qd[li[r, L_DY], l] if free else 0.0
                rx, ry = com[i, 0, l] - X[i, 0, l], com[i, 1, l] - X[i, 1, l]
                vx, vy = V[i, 0, l] - w[i, l] * ry, V[i, 1, l] + w[i, l] * rx
                e[0, l], e[1, l] = m * (vx - vcx), m * (vy - vcy)
                e[2, l], e[3, l] = 0.0, 0.0  # suffix sums P
                e[4, l], e[5, l] = com[i, 0, l], com[i, 1, l]
            k = i
            while k >= 0:
                rot = li[k, L_ROT]
                apply = rot >= 0 and not (free and li[k, L_PARENT] < 0)
                for l in range(W):
                    e[2, l] = e[2, l] + w[k, l] * (e[4, l] - X[k, 0, l])
                    e[3, l] = e[3, l] + w[k, l] * (e[5, l] - X[k, 1, l])
                    e[4, l], e[5, l] = X[k, 0, l], X[k, 1, l]
                    if apply:
                        Q[rot, l] += -(e[0, l] * e[2, l] + e[1, l] * e[3, l])
                k = li[k, L_PARENT]
    grav = wf[W_GRAVITY]
    for a in range(D):
        for l in range(W):
            x[a, l] = 0.0
    for t in range(ti.shape[0]):
        r = ti[t, 0]
        if ti[t, 1] == 1:
            mt = 0.0
            for i in range(L):
                if li[i, L_TREE] == t:
                    mt = mt + lf[i, F_MASS]
            for l in range(W):
                x[li[r, L_DY], l] = -(mt * grav)
            continue
        for i in range(L):
            if li[i, L_TREE] != t or li[i, L_PARENT] < 0:
                continue
            for l in range(W):
                e[6, l], e[7, l], e[8, l] = 0.0, 1.0, -(lf[i, F_MASS] * grav)
            n = _point_row(rl, rn, X, i, com, i, e[6:8], g)
            _force(Q, e[8], ri[i], g, n)
    _turn(li, ti, S, x, -1, 1)
    for a in range(D):
        for l in range(W):
            Q[a, l] += x[a, l]
    for i in range(L):
        if li[i, L_SPRING] == 1:
            d, par = li[i, L_ROT], li[i, L_PARENT]
            k, c, rest = lf[i, F_JSPRING], lf[i, F_JSPRING + 1], lf[i, F_JSPRING + 2]
            for l in range(W):
                phi = th[i, l] - th[par, l]
                _joint(A, Q, d, h, -k * (phi - rest) - c * u[d, l], k, c, u[d, l], l)
    for i in range(L):
        if li[i, L_LIMIT] == 1:
            d, par = li[i, L_ROT], li[i, L_PARENT]
            lo, hi, k, c = lf[i, F_LIMIT], lf[i, F_LIMIT + 1], lf[i, F_LIMIT + 2], lf[i, F_LIMIT + 3]
            for l in range(W):
                phi = th[i, l] - th[par, l]
                below = max(k * (lo - phi) - c * u[d, l], 0.0)
                above = min(k * (hi - phi) - c * u[d, l], 0.0)
                on = 1.0 if ((phi < lo) and (below > 0)) or ((phi > hi) and (above < 0)) else 0.0
                torque = below if phi < lo else (above if phi > hi else 0.0)
                _joint(A, Q, d, h, torque, on * k, on * c, u[d, l], l)
    for a in range(ai.shape[0]):
        j = ai[a]
        d, par = li[j, L_ROT], li[j, L_PARENT]
        lo, hi, ks, kd = af[a, 0], af[a, 1], af[a, 2], af[a, 3]
        for l in range(W):
            target = lo + act[a, l] * (hi - lo)
            phi = th[j, l] - th[par, l]
            _joint(A, Q, d, h, ks * (target - phi) - kd * u[d, l], ks, kd, u[d, l], l)
    gk, gc, slip = wf[W_GK], wf[W_GC], wf[W_SLIP]
    cn = h * gc + (h * h) * gk
    for c in range(ci.shape[0]):
        i = ci[c]
        aniso = li[i, L_ANISO] == 1
        frm, to = li[i, L_AX_FROM], li[i, L_AX_TO]
        mu_f, mu_b = lf[i, F_MU], lf[i, F_MU + 1]
        any_on = False
        any_limit = False
        # e rows: 0 normal coef, 1 normal force, 2 tangent coef, 3 tangent force, 4 held, 5 limit
        for l in range(W):
            nx, ny, tx, ty = gn[c, 0, l], gn[c, 1, l], gn[c, 2, l], gn[c, 3, l]
            dep = depth[c, l]
            dmax[l] = max(dmax[l], dep)
            vx, vy = cv[c, 0, l], cv[c, 1, l]
            vn = vx * nx + vy * ny
            vt = vx * tx + vy * ty
            fn = gk * dep - gc * vn
            on = (dep > 0) & (fn > 0)
            N = fn if on else 0.0
            stretch = (cp[c, 0, l] - anchor[c, 0, l]) * tx + (cp[c, 1, l] - anchor[c, 1, l]) * ty
            if aniso:
                if frm >= 0:
                    axx, axy = X[to, 0, l] - X[frm, 0, l], X[to, 1, l] - X[frm, 1, l]
                else:
                    axx, axy = cs[i, 0, l], cs[i, 1, l]
                mu = mu_f if (axx * tx + axy * ty) * (gk * stretch + vt) > 0 else mu_b
            else:
                mu = mu_f
            limit = mu * N
            e[0, l] = cn if on else 0.0
            e[1, l] = fn - (h * gk) * vn if on else 0.0
            cs_ = limit / slip
            s = min(max(stretch, -limit / gk), limit / gk)
            trial = -gk * s - cs_ * vt
            slide = limit / max(abs(vt), slip)
            stick = (limit > 0) & (abs(trial) <= limit)
            e[2, l] = h * cs_ + (h * h) * gk if stick else h * slide
            e[3, l] = trial - (h * gk) * vt if stick else -slide * vt
            held = s if stick else 0.0
            anchor[c, 0, l] = cp[c, 0, l] - held * tx
            anchor[c, 1, l] = cp[c, 1, l] - held * ty
            any_on = any_on | on
            any_limit = any_limit | (limit > 0)
        if any_on:
            n = _point_row(rl, rn, X, i, cp, c, gn[c, 0:2], g)
            _outer(A, e[0], ri[i], g, n)
            _force(Q, e[1], ri[i], g, n)
        if any_limit:
            n = _point_row(rl, rn, X, i, cp, c, gn[c, 2:4], g)
            _outer(A, e[2], ri[i], g, n)
            _force(Q, e[3], ri[i], g, n)
    for a in range(D):
        for l in range(W):
            Q[a, l] = h * Q[a, l]
    _solve(A, Q, x, F, Lf, D)
    for a in range(D):
        for l in range(W):
            g[a, l] = 0.0
        for b in range(D):
            for l in range(W):
                g[a, l] += M[a, b, l] * x[b, l]
    _turn(li, ti, S, g, 1, 1)
    for a in range(D):
        for l in range(W):
            p[a, l] = p[a, l] + g[a, l]
            x[a, l] = u[a, l] + x[a, l]
    _turn(li, ti, S, x, -1, 0)
    for a in range(D):
        for l in range(W):
            qd[a, l] = x[a, l]
            q[a, l] = q[a, l] + h * x[a, l]


@njit(cache=True, error_model="numpy", boundscheck=False)
def _sense(li, si, sf, depth, th, bits):
    for s in range(si.shape[0]):
        kind, link = si[s, 0], si[s, 1]
        if kind == 0:
            for l in range(W):
                bits[s, l] = 1.0 if depth[link, l] > 0 else 0.0
        else:
            par = li[link, L_PARENT]
            rel = not (par < 0 or kind == 2)
            lo, hi = sf[s, 0], sf[s, 1]
            for l in range(W):
                ang = th[link, l] - th[par, l] if rel else th[link, l]
                a = ang - (2 * math.pi) * math.floor((ang + math.pi) * (0.5 / math.pi))
                bits[s, l] = 1.0 if (a >= lo and a <= hi) else 0.0


@njit(cache=True, error_model="numpy", boundscheck=False)
def _san(WT, k1, k2, bits, istate, out, total, act, dt, H):
    N = WT.shape[1]
    S = bits.shape[0]
    for n in range(N):
        for l in range(W):
            total[n, l] = 0.0
    for i in range(S):
        for n in range(N):
            for l in range(W):
                total[n, l] += WT[i, n, l] * bits[i, l]
    for i in range(N):
        for n in range(N):
            for l in range(W):
                total[n, l] += WT[S + i, n, l] * out[i, l]
    for n in range(N):
        for l in range(W):
            rate = k1[n, l] if total[n, l] > 0 else k2[n, l]
            s = min(max(istate[n, l] + rate * dt, 0.0), 1.0)
            istate[n, l] = s
            o = out[n, l]
            out[n, l] = 0.0 if (o == 1.0 and s == 0.0) else (1.0 if (o == 0.0 and s == 1.0) else o)
        if n >= H:
            for l in range(W):
                act[n - H, l] = (min(max(total[n, l], -2.0), 2.0) + 2.0) * 0.25


@njit(cache=True, error_model="numpy", boundscheck=False, parallel=True)
def rollout_san(li, lf, ri, rl, rn, ti, ci, cf, si, sf, ai, af, wf, wi, rough, WT, k1, k2, q, p, anchor, istate, out, t,
                steps):
    """As ``kernel.rollout_san`` over tiles: q, p [T, D, W], anchor [T, C, 2, W], istate, out [T, N, W],
    t [T, W], WT [T, I, N, W], k1, k2 [T, N, W]; returns the deepest penetration [T, W]."""
    T = q.shape[0]
    D = q.shape[1]
    L, C = li.shape[0], ci.shape[0]
    N = WT.shape[2]
    deepest = np.full((T, W), -np.inf)
    h = wf[W_DT]
    H = wi[W_HIDDEN]
    for b in prange(T):
        sc = _scratch(L, C, D, N, si.shape[0], ai.shape[0])
        tot, bits, act = sc[22], sc[23], sc[24]
        dm = deepest[b]
        for _ in range(steps):
            _prepare(li, lf, ri, rl, rn, ti, ci, cf, wi, wf, rough, q[b], p[b], sc)
            _sense(li, si, sf, sc[8], sc[0], bits)
            _san(WT[b], k1[b], k2[b], bits, istate[b], out[b], tot, act, h, H)
            _advance(li, lf, ri, rl, rn, ti, ci, cf, ai, af, wi, wf, rough, q[b], p[b], anchor[b], sc, dm)
            for l in range(W):
                t[b, l] += h
    return deepest
