"""Compiled per-element kernels of the energies' values and gradients (Numba).

A minimization evaluates the energy and its gradient, and the enclosed volume, a few hundred
times per volume step (every line-search trial and every volume restoration), against about a
dozen Hessians. The NumPy kernels of :mod:`.hinge`, :mod:`.bending`, :mod:`.stretching` and
:mod:`.volume` do that in a dozen passes over ``(3, n)`` temporaries; the same formulas in
one compiled loop over the elements are 4-6 times faster (``benchmarks/bench_energies.py``).
The Hessians keep the NumPy kernels (low-rank element blocks scattered into a fixed CSR
pattern), and the tests compare both implementations of every gradient with each other and
with central differences.

Each kernel serves both the value alone and the value with the gradient (``gradient=False``
skips the second pass): the value is then the same number, bit for bit, whichever is asked,
which Newton's method relies on when it keeps the gradient of an accepted point.

Layout: positions ``X (V, 3)`` float64, elements coordinate-major ``(k, n)`` int64 (the
order of the callers' internal element arrays, sorted for memory locality); gradients
``(V, 3)``. No ``fastmath``: IEEE arithmetic in the written order, so results are
reproducible from run to run and machine to machine with the same compiled code.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def positions(X, n_vertices: int) -> np.ndarray:
    """``X`` as the compiled loops need it, a C-contiguous float64 ``(n_vertices, 3)`` array
    (they do not check bounds); a ``ValueError`` naming the shape otherwise."""
    X = np.ascontiguousarray(X, dtype=np.float64)
    if X.shape != (n_vertices, 3):
        raise ValueError(f"positions must have shape ({n_vertices}, 3), got {X.shape}")
    return X


@njit(cache=True, nogil=True)
def juelicher(X, HT, FT, kappa, c0, gradient):
    """Jülicher bending energy ``sum_i kappa/2 (2 M_i/A_i - c0)^2 A_i`` and its gradient
    (:mod:`.bending` for the formulas, :func:`.hinge.hinge_kernel` and
    :func:`.hinge.face_kernel` for the element derivatives). ``HT (4, E)`` hinges
    ``(i, j, k, l)`` with edge ``i -> j``, ``FT (3, F)`` faces. Returns ``(value, G)``; ``G``
    is ``(0, 3)`` without ``gradient``."""
    V, nh, nf = X.shape[0], HT.shape[1], FT.shape[1]
    M = np.zeros(V)
    A = np.zeros(V)
    dphi = np.empty((nh if gradient else 0, 4, 3))
    dA = np.empty((nf if gradient else 0, 3, 3))
    for h in range(nh):
        i, j, k, l = HT[0, h], HT[1, h], HT[2, h], HT[3, h]
        e0, e1, e2 = X[j, 0] - X[i, 0], X[j, 1] - X[i, 1], X[j, 2] - X[i, 2]
        a0, a1, a2 = X[k, 0] - X[i, 0], X[k, 1] - X[i, 1], X[k, 2] - X[i, 2]
        b0, b1, b2 = X[l, 0] - X[i, 0], X[l, 1] - X[i, 1], X[l, 2] - X[i, 2]
        n00, n01, n02 = e1 * a2 - e2 * a1, e2 * a0 - e0 * a2, e0 * a1 - e1 * a0  # e x a
        n10, n11, n12 = b1 * e2 - b2 * e1, b2 * e0 - b0 * e2, b0 * e1 - b1 * e0  # b x e
        LL = e0 * e0 + e1 * e1 + e2 * e2
        L = np.sqrt(LL)
        theta = np.arctan2(-L * (n00 * b0 + n01 * b1 + n02 * b2),
                           n00 * n10 + n01 * n11 + n02 * n12)
        phi = L * theta
        M[i] += phi
        M[j] += phi
        if gradient:
            Ls0 = L / (n00 * n00 + n01 * n01 + n02 * n02)
            Ls1 = L / (n10 * n10 + n11 * n11 + n12 * n12)
            t0 = (a0 * e0 + a1 * e1 + a2 * e2) / LL
            t1 = (b0 * e0 + b1 * e1 + b2 * e2) / LL
            for c in range(3):
                nc0 = n00 if c == 0 else (n01 if c == 1 else n02)
                nc1 = n10 if c == 0 else (n11 if c == 1 else n12)
                ec = e0 if c == 0 else (e1 if c == 1 else e2)
                g2 = -Ls0 * nc0
                g3 = -Ls1 * nc1
                d1 = L * -(t0 * g2 + t1 * g3) + theta * (ec / L)
                d2 = L * g2
                d3 = L * g3
                dphi[h, 1, c] = d1
                dphi[h, 2, c] = d2
                dphi[h, 3, c] = d3
                dphi[h, 0, c] = -(d1 + d2 + d3)
    for f in range(nf):
        p, q, r = FT[0, f], FT[1, f], FT[2, f]
        u0, u1, u2 = X[q, 0] - X[p, 0], X[q, 1] - X[p, 1], X[q, 2] - X[p, 2]
        v0, v1, v2 = X[r, 0] - X[p, 0], X[r, 1] - X[p, 1], X[r, 2] - X[p, 2]
        m0, m1, m2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
        norm = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        area = 0.5 * norm
        A[p] += area
        A[q] += area
        A[r] += area
        if gradient:
            h0, h1, h2 = m0 / norm, m1 / norm, m2 / norm
            gu0, gu1, gu2 = 0.5 * (v1 * h2 - v2 * h1), 0.5 * (v2 * h0 - v0 * h2), 0.5 * (v0 * h1 - v1 * h0)
            gv0, gv1, gv2 = 0.5 * (h1 * u2 - h2 * u1), 0.5 * (h2 * u0 - h0 * u2), 0.5 * (h0 * u1 - h1 * u0)
            dA[f, 1, 0], dA[f, 1, 1], dA[f, 1, 2] = gu0, gu1, gu2
            dA[f, 2, 0], dA[f, 2, 1], dA[f, 2, 2] = gv0, gv1, gv2
            dA[f, 0, 0], dA[f, 0, 1], dA[f, 0, 2] = -(gu0 + gv0), -(gu1 + gv1), -(gu2 + gv2)
    f_M = np.empty(V if gradient else 0)
    f_A = np.empty(V if gradient else 0)
    value = 0.0
    for v in range(V):
        Av = A[v] / 3.0
        H = 0.25 * M[v] / Av
        value += (2.0 * H - c0) ** 2 * Av
        if gradient:
            f_M[v] = 2.0 * kappa * (2.0 * H - c0)
            f_A[v] = 0.5 * kappa * (c0 * c0 - 4.0 * H * H)
    value *= 0.5 * kappa
    G = np.zeros((V if gradient else 0, 3))
    if gradient:
        for h in range(nh):
            w = 0.25 * (f_M[HT[0, h]] + f_M[HT[1, h]])
            for a in range(4):
                v = HT[a, h]
                for c in range(3):
                    G[v, c] += w * dphi[h, a, c]
        for f in range(nf):
            w = (f_A[FT[0, f]] + f_A[FT[1, f]] + f_A[FT[2, f]]) / 3.0
            for a in range(3):
                v = FT[a, f]
                for c in range(3):
                    G[v, c] += w * dA[f, a, c]
    return value, G


@njit(cache=True, nogil=True)
def stretching(X, f0, f1, f2, rest, gradient):
    """St Venant–Kirchhoff membrane energy of constant-strain triangles and its gradient
    (:mod:`.stretching`). Faces ``(f0, f1, f2)``; ``rest (9, F)`` rows ``a11, a12, a22`` (rest
    metric) and ``D11, D12, D13, D22, D23, D33`` (area-weighted Voigt stiffness on
    ``(E11, E22, 2 E12)``). Returns ``(value, G)``, ``G (0, 3)`` without ``gradient``."""
    V, nf = X.shape[0], f0.shape[0]
    G = np.zeros((V if gradient else 0, 3))
    value = 0.0
    for f in range(nf):
        p, q, r = f0[f], f1[f], f2[f]
        s0, s1, s2 = X[q, 0] - X[p, 0], X[q, 1] - X[p, 1], X[q, 2] - X[p, 2]
        t0, t1, t2 = X[r, 0] - X[p, 0], X[r, 1] - X[p, 1], X[r, 2] - X[p, 2]
        E11 = 0.5 * (s0 * s0 + s1 * s1 + s2 * s2 - rest[0, f])
        E12 = 0.5 * (s0 * t0 + s1 * t1 + s2 * t2 - rest[1, f])
        E22 = 0.5 * (t0 * t0 + t1 * t1 + t2 * t2 - rest[2, f])
        D11, D12, D13 = rest[3, f], rest[4, f], rest[5, f]
        D22, D23, D33 = rest[6, f], rest[7, f], rest[8, f]
        S11 = D11 * E11 + D12 * E22 + 2.0 * D13 * E12
        S22 = D12 * E11 + D22 * E22 + 2.0 * D23 * E12
        S12 = D13 * E11 + D23 * E22 + 2.0 * D33 * E12
        value += 0.5 * (E11 * S11 + E22 * S22) + E12 * S12
        if gradient:
            gs0, gs1, gs2 = S11 * s0 + S12 * t0, S11 * s1 + S12 * t1, S11 * s2 + S12 * t2
            gt0, gt1, gt2 = S12 * s0 + S22 * t0, S12 * s1 + S22 * t1, S12 * s2 + S22 * t2
            G[q, 0] += gs0
            G[q, 1] += gs1
            G[q, 2] += gs2
            G[r, 0] += gt0
            G[r, 1] += gt1
            G[r, 2] += gt2
            G[p, 0] -= gs0 + gt0
            G[p, 1] -= gs1 + gt1
            G[p, 2] -= gs2 + gt2
    return value, G


@njit(cache=True, nogil=True)
def volume(X, FT, gradient):
    """Enclosed volume ``sum_f x0 . (x1 x x2) / 6`` and its gradient (:mod:`.volume`).
    ``FT (3, F)``. Returns ``(value, G)``, ``G (0, 3)`` without ``gradient``."""
    V, nf = X.shape[0], FT.shape[1]
    G = np.zeros((V if gradient else 0, 3))
    value = 0.0
    for f in range(nf):
        p, q, r = FT[0, f], FT[1, f], FT[2, f]
        a0, a1, a2 = X[p, 0], X[p, 1], X[p, 2]
        b0, b1, b2 = X[q, 0], X[q, 1], X[q, 2]
        c0, c1, c2 = X[r, 0], X[r, 1], X[r, 2]
        bc0, bc1, bc2 = b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0
        value += a0 * bc0 + a1 * bc1 + a2 * bc2
        if gradient:
            G[p, 0] += bc0
            G[p, 1] += bc1
            G[p, 2] += bc2
            G[q, 0] += c1 * a2 - c2 * a1
            G[q, 1] += c2 * a0 - c0 * a2
            G[q, 2] += c0 * a1 - c1 * a0
            G[r, 0] += a1 * b2 - a2 * b1
            G[r, 1] += a2 * b0 - a0 * b2
            G[r, 2] += a0 * b1 - a1 * b0
    if gradient:
        for v in range(V):
            for c in range(3):
                G[v, c] /= 6.0
    return value / 6.0, G


@njit(cache=True, nogil=True)
def _triple(a0, a1, a2, b0, b1, b2, c0, c1, c2):
    """``a . (b x c)``."""
    return a0 * (b1 * c2 - b2 * c1) + a1 * (b2 * c0 - b0 * c2) + a2 * (b0 * c1 - b1 * c0)


@njit(cache=True, nogil=True)
def volume_along(X, D, FT):
    """Coefficients ``(c0, c1, c2, c3)`` of the exact cubic ``V(X + t D)``: the face's
    ``(a + t da) . ((b + t db) x (c + t dc))`` expanded in ``t``."""
    k0 = k1 = k2 = k3 = 0.0
    for f in range(FT.shape[1]):
        p, q, r = FT[0, f], FT[1, f], FT[2, f]
        a0, a1, a2, b0, b1, b2 = X[p, 0], X[p, 1], X[p, 2], X[q, 0], X[q, 1], X[q, 2]
        c0, c1, c2 = X[r, 0], X[r, 1], X[r, 2]
        d0, d1, d2, e0, e1, e2 = D[p, 0], D[p, 1], D[p, 2], D[q, 0], D[q, 1], D[q, 2]
        g0, g1, g2 = D[r, 0], D[r, 1], D[r, 2]
        k0 += _triple(a0, a1, a2, b0, b1, b2, c0, c1, c2)
        k1 += (_triple(d0, d1, d2, b0, b1, b2, c0, c1, c2) + _triple(a0, a1, a2, e0, e1, e2, c0, c1, c2)
               + _triple(a0, a1, a2, b0, b1, b2, g0, g1, g2))
        k2 += (_triple(a0, a1, a2, e0, e1, e2, g0, g1, g2) + _triple(d0, d1, d2, b0, b1, b2, g0, g1, g2)
               + _triple(d0, d1, d2, e0, e1, e2, c0, c1, c2))
        k3 += _triple(d0, d1, d2, e0, e1, e2, g0, g1, g2)
    out = np.empty(4)
    out[0], out[1], out[2], out[3] = k0 / 6.0, k1 / 6.0, k2 / 6.0, k3 / 6.0
    return out
