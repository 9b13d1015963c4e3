"""Trace-time sparse algebra over scalars.

The simulator is written for one creature as straight-line code over scalars (0-d arrays that
``vmap`` turns into ``[batch]`` vectors). Python floats stand for structural constants: a 0.0
entry is simply absent and a 1.0 factor is dropped, at trace time, so that the compiled program
contains only the arithmetic the creature's structure really needs (the paper's dynamics
compiler: "structural zeros vanish").

A sparse vector is a ``dict[int, scalar]`` (dof -> value); a symmetric matrix is a
``dict[tuple[int, int], scalar]`` keyed by (row, col) with ``rank[row] >= rank[col]`` in the
elimination order.
"""

from __future__ import annotations

from typing import Any

Scalar = Any  # a Python float (structural constant) or a JAX scalar


def is_const(a: Scalar, value: float) -> bool:
    return isinstance(a, (int, float)) and a == value


def mul(a: Scalar, b: Scalar) -> Scalar:
    if is_const(a, 0.0) or is_const(b, 0.0):
        return 0.0
    if is_const(a, 1.0):
        return b
    if is_const(b, 1.0):
        return a
    if is_const(a, -1.0):
        return neg(b)
    if is_const(b, -1.0):
        return neg(a)
    return a * b


def add(a: Scalar, b: Scalar) -> Scalar:
    if is_const(a, 0.0):
        return b
    if is_const(b, 0.0):
        return a
    return a + b


def neg(a: Scalar) -> Scalar:
    return 0.0 if is_const(a, 0.0) else -a


def sub(a: Scalar, b: Scalar) -> Scalar:
    if is_const(b, 0.0):
        return a
    if is_const(a, 0.0):
        return neg(b)
    return a - b  # one operation, and bit-equal to a + (-b)


def axpy(y: dict, a: Scalar, x: dict) -> None:
    """y += a x, in place."""
    if is_const(a, 0.0):
        return
    for k, v in x.items():
        t = mul(a, v)
        if not is_const(t, 0.0):
            y[k] = add(y.get(k, 0.0), t)


class SymMatrix:
    """Symmetric sparse matrix accumulated term by term, then factorised as L D L^T."""

    def __init__(self, order: list[int]):
        self.order = list(order)
        self.rank = {d: i for i, d in enumerate(order)}
        self.a: dict[tuple[int, int], Scalar] = {}

    def _key(self, i: int, j: int) -> tuple[int, int]:
        return (i, j) if self.rank[i] >= self.rank[j] else (j, i)

    def add(self, i: int, j: int, v: Scalar) -> None:
        if is_const(v, 0.0):
            return
        k = self._key(i, j)
        self.a[k] = add(self.a.get(k, 0.0), v)

    def add_outer(self, c: Scalar, g: dict, h: dict | None = None) -> None:
        """self += c g g^T, or c (g h^T + h g^T) when ``h`` is given."""
        if is_const(c, 0.0):
            return
        if h is None:
            items = list(g.items())
            for x, (i, gi) in enumerate(items):
                cgi = mul(c, gi)
                for j, gj in items[: x + 1]:
                    self.add(i, j, mul(cgi, gj))
            return
        for i, gi in g.items():
            cgi = mul(c, gi)
            for j, hj in h.items():
                v = mul(cgi, hj)
                if i == j:
                    v = add(v, v)
                self.add(i, j, v)

    def matvec(self, x: dict) -> dict:
        """self x for a sparse vector x (absent entries are zero); returns a sparse dict."""
        out: dict = {}
        for (i, j), v in self.a.items():
            if j in x:
                out[i] = add(out.get(i, 0.0), mul(v, x[j]))
            if i != j and i in x:
                out[j] = add(out.get(j, 0.0), mul(v, x[i]))
        return out

    def solve(self, b: dict, fence=None) -> dict:
        """Solve self x = b (self symmetric positive definite) by L D L^T with the given
        elimination order; fill-in is tracked symbolically. Returns x as a dense dict.

        fence: optional callable that materialises a pytree (``dynamics._barrier``); it is applied
        to the forward substitution's result, which every entry of the back substitution reads,
        so that a compiler does not re-derive it inside each of them. Same arithmetic either way."""
        a = dict(self.a)
        cols: dict[int, dict[int, Scalar]] = {}
        inv: dict[int, Scalar] = {}
        for k in self.order:
            inv[k] = 1.0 / a[(k, k)]
            below = {i: a[(i, k)] for i in self.order[self.rank[k] + 1 :] if (i, k) in a}
            col = {i: mul(v, inv[k]) for i, v in below.items()}
            cols[k] = col
            items = list(below.items())
            for x, (i, _) in enumerate(items):
                li = col[i]
                for j, bj in items[: x + 1]:
                    key = self._key(i, j)
                    a[key] = sub(a.get(key, 0.0), mul(li, bj))
        y = {k: b.get(k, 0.0) for k in self.order}
        for k in self.order:
            for i, l in cols[k].items():
                y[i] = sub(y[i], mul(l, y[k]))
        if fence is not None:
            y = fence(y)
        for k in self.order:
            y[k] = mul(y[k], inv[k])
        for k in reversed(self.order):
            for i, l in cols[k].items():
                y[k] = sub(y[k], mul(l, y[i]))
        return y
