"""Compiled per-element kernels of the energies' values and gradients and of the bending Hessians (Numba).

A minimization evaluates the energy and its gradient, and the enclosed volume, a few hundred
times per volume step (every line-search trial and every volume restoration), against about a
dozen Hessians. The NumPy kernels of :mod:`.hinge`, :mod:`.bending`, :mod:`.stretching` and
:mod:`.volume` do that in a dozen passes over ``(3, n)`` temporaries; the same formulas in
one compiled loop over the elements are 4-6 times faster (``benchmarks/bench_energies.py``).
The bending Hessians (Jülicher's, which couples vertices two rings apart and was the
costliest part of an assembly of the Newton matrix, and Surface Evolver's
``star_perp_sq_mean_curvature``) are compiled too (:func:`juelicher_hessian`,
:func:`star_perp_hessian`: 12.0 -> 4.7 ms and 29.6 -> 10.9 ms at 2562 vertices; inside a run,
where the caches hold other data, Jülicher's 11.6 -> 10.0 ms on the paper's mesh; the
benchmarks/README has the measurements); the other Hessians keep the NumPy kernels. The tests
compare both implementations of every gradient and of the Jülicher Hessian with each other and
with central differences; Evolver's Hessian with central differences and its energies with
Surface Evolver's own.

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
def _juelicher_elements(X, HT, FT, gradient):
    """The element sums of :func:`juelicher`: ``M`` (``sum l theta`` over the edges at each
    vertex) and ``A`` (the areas of its faces), and with ``gradient`` the gradients of every
    hinge's ``phi = l theta`` over its vertices, ``(E, 4, 3)``, and of every face's area,
    ``(F, 3, 3)``."""
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
    return M, A, dphi, dA


@njit(cache=True, nogil=True)
def juelicher(X, HT, FT, kappa, c0, gradient):
    """Jülicher bending energy ``sum_i kappa/2 (2 M_i/A_i - c0_i)^2 A_i`` and its gradient
    (:mod:`.bending` for the formulas, :func:`.hinge.hinge_kernel` and
    :func:`.hinge.face_kernel` for the element derivatives). ``HT (4, E)`` hinges
    ``(i, j, k, l)`` with edge ``i -> j``, ``FT (3, F)`` faces. Returns ``(value, G)``; ``G``
    is ``(0, 3)`` without ``gradient``; ``c0 (V,)`` the spontaneous curvature of each vertex."""
    V, nh, nf = X.shape[0], HT.shape[1], FT.shape[1]
    M, A, dphi, dA = _juelicher_elements(X, HT, FT, gradient)
    f_M = np.empty(V if gradient else 0)
    f_A = np.empty(V if gradient else 0)
    value = 0.0
    for v in range(V):
        Av = A[v] / 3.0
        H = 0.25 * M[v] / Av
        value += (2.0 * H - c0[v]) ** 2 * Av
        if gradient:
            f_M[v] = 2.0 * kappa * (2.0 * H - c0[v])
            f_A[v] = 0.5 * kappa * (c0[v] * c0[v] - 4.0 * H * H)
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


@njit(cache=True, nogil=True, inline="always")
def _add(total, carry, term):
    """Neumaier's compensated sum: ``(total, carry)`` after adding ``term`` (the sum is
    ``total + carry``)."""
    t = total + term
    if abs(total) >= abs(term):
        carry += (total - t) + term
    else:
        carry += (term - t) + total
    return t, carry


@njit(cache=True, nogil=True)
def volume(X, FT, gradient):
    """Enclosed volume ``sum_f x0 . (x1 x x2) / 6`` and its gradient (:mod:`.volume`).
    ``FT (3, F)``. Returns ``(value, G)``, ``G (0, 3)`` without ``gradient``.

    The sum over the faces is compensated (Neumaier, Z. Angew. Math. Mech. 54, 39 (1974)): a
    plain running sum of ``F`` terms of size ``V/F`` errs by about ``sqrt(F) eps V``, 1e-14 of
    the volume at 80k faces, and the constrained energy inherits that times the pressure
    (``p V`` is many times ``E``), which is above the noise Newton's line search allows for
    and stalls minimizations on large meshes."""
    V, nf = X.shape[0], FT.shape[1]
    G = np.zeros((V if gradient else 0, 3))
    value = carry = 0.0
    for f in range(nf):
        p, q, r = FT[0, f], FT[1, f], FT[2, f]
        a0, a1, a2 = X[p, 0], X[p, 1], X[p, 2]
        b0, b1, b2 = X[q, 0], X[q, 1], X[q, 2]
        c0, c1, c2 = X[r, 0], X[r, 1], X[r, 2]
        bc0, bc1, bc2 = b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0
        value, carry = _add(value, carry, a0 * bc0 + a1 * bc1 + a2 * bc2)
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
    return (value + carry) / 6.0, G


@njit(cache=True, nogil=True)
def _triple(a0, a1, a2, b0, b1, b2, c0, c1, c2):
    """``a . (b x c)``."""
    return a0 * (b1 * c2 - b2 * c1) + a1 * (b2 * c0 - b0 * c2) + a2 * (b0 * c1 - b1 * c0)


@njit(cache=True, nogil=True)
def volume_along(X, D, FT):
    """Coefficients ``(c0, c1, c2, c3)`` of the exact cubic ``V(X + t D)``: the face's
    ``(a + t da) . ((b + t db) x (c + t dc))`` expanded in ``t``; the constant and linear
    ones summed with compensation, as in :func:`volume`."""
    k0 = k1 = k2 = k3 = carry0 = carry1 = 0.0
    for f in range(FT.shape[1]):
        p, q, r = FT[0, f], FT[1, f], FT[2, f]
        a0, a1, a2, b0, b1, b2 = X[p, 0], X[p, 1], X[p, 2], X[q, 0], X[q, 1], X[q, 2]
        c0, c1, c2 = X[r, 0], X[r, 1], X[r, 2]
        d0, d1, d2, e0, e1, e2 = D[p, 0], D[p, 1], D[p, 2], D[q, 0], D[q, 1], D[q, 2]
        g0, g1, g2 = D[r, 0], D[r, 1], D[r, 2]
        k0, carry0 = _add(k0, carry0, _triple(a0, a1, a2, b0, b1, b2, c0, c1, c2))
        k1, carry1 = _add(k1, carry1, _triple(d0, d1, d2, b0, b1, b2, c0, c1, c2)
                          + _triple(a0, a1, a2, e0, e1, e2, c0, c1, c2)
                          + _triple(a0, a1, a2, b0, b1, b2, g0, g1, g2))
        k2 += (_triple(a0, a1, a2, e0, e1, e2, g0, g1, g2) + _triple(d0, d1, d2, b0, b1, b2, g0, g1, g2)
               + _triple(d0, d1, d2, e0, e1, e2, c0, c1, c2))
        k3 += _triple(d0, d1, d2, e0, e1, e2, g0, g1, g2)
    out = np.empty(4)
    out[0], out[1] = (k0 + carry0) / 6.0, (k1 + carry1) / 6.0
    out[2], out[3] = k2 / 6.0, k3 / 6.0
    return out


@njit(cache=True, nogil=True)
def cubic_root(c, target, t, max_iter):
    """Root of ``c0 + c1 t + c2 t^2 + c3 t^3 = target`` reached by Newton's iteration from
    ``t``; NaN if it does not converge (:func:`shellbuckle.solve.linesearch.restore_volume`)."""
    c0, c1, c2, c3 = c[0], c[1], c[2], c[3]
    for _ in range(max_iter):
        f = (c0 - target) + t * (c1 + t * (c2 + t * c3))
        df = c1 + t * (2.0 * c2 + t * 3.0 * c3)
        if not (np.isfinite(f) and np.isfinite(df)) or df == 0.0:
            return np.nan
        dt = f / df
        t -= dt
        if abs(dt) <= 1e-16 * abs(t):
            return t
    return t if np.isfinite(t) else np.nan


@njit(cache=True, nogil=True)
def restore_volume(X, FT, V_target, rtol):
    """A copy of ``X`` moved along the volume gradient ``G`` at ``X`` to ``V = V_target``: the
    root of the exact cubic ``V(X + t G)`` next to the first-order step, then at most two
    first-order corrections along the same ``G`` for the round-off the cubic leaves, stopping
    as the generic restoration of :func:`shellbuckle.solve.linesearch.restore_volume` does
    (``rtol``, or round-off: the error no longer halves). The corrections reuse ``G`` and
    ``|G|^2``: the error they remove is round-off, about ``1e-15`` relative, so the change of
    the gradient along the cubic's move does not matter, and a correction costs one volume
    pass instead of three (gradient, cubic, volume). One call instead of about ten NumPy and
    kernel calls per line-search trial. Returns ``(X, relative error)``; the error is
    infinite where the restoration fails."""
    X = X.copy()
    value, G = volume(X, FT, True)
    residual = value - V_target
    err = abs(residual) / abs(V_target)
    if not np.isfinite(err):
        return X, np.inf
    if err <= rtol:
        return X, err
    gg = 0.0
    for v in range(G.shape[0]):
        gg += G[v, 0] * G[v, 0] + G[v, 1] * G[v, 1] + G[v, 2] * G[v, 2]
    if gg == 0.0:
        return X, np.inf
    t = cubic_root(volume_along(X, G, FT), V_target, -residual / gg, 30)
    if not np.isfinite(t):
        return X, np.inf
    previous = np.inf
    for it in range(3):
        for v in range(G.shape[0]):
            for k in range(3):
                X[v, k] += t * G[v, k]
        residual = volume(X, FT, False)[0] - V_target
        err = abs(residual) / abs(V_target)
        if not np.isfinite(err):
            return X, np.inf
        if err <= rtol or it == 2 or err >= 0.5 * previous:
            return X, err
        previous = err
        t = -residual / gg
    return X, err


@njit(cache=True, nogil=True, inline="always")
def _add_block(data, base, stride, w, B, transpose):
    """``data[base + c stride + d] += w B[c, d]`` (or ``B[d, c]``): one 3x3 block of a CSR
    matrix whose block rows are laid out as in :func:`juelicher_hessian`."""
    for c in range(3):
        for d in range(3):
            data[base + c * stride + d] += w * (B[d, c] if transpose else B[c, d])


@njit(cache=True, nogil=True, inline="always")
def _add_skew(B, s, v):
    """``B += s [v]_x`` for a 3x3 ``B`` (``[v]_x w = v x w``)."""
    B[0, 1] -= s * v[2]
    B[0, 2] += s * v[1]
    B[1, 0] += s * v[2]
    B[1, 2] -= s * v[0]
    B[2, 0] -= s * v[1]
    B[2, 1] += s * v[0]


@njit(cache=True, nogil=True)
def _mirror_mean(data, mirror):
    """Every entry above the diagonal and its transpose (``mirror (2, m)``) set to their mean:
    an exactly symmetric matrix (the two are sums of the same terms rounded in another order)."""
    for t in range(mirror.shape[1]):
        up, lo = mirror[0, t], mirror[1, t]
        mean = 0.5 * (data[up] + data[lo])
        data[up] = mean
        data[lo] = mean


@njit(cache=True, nogil=True)
def juelicher_hessian(X, HT, FT, kappa, c0, hinge_off, face_off, hinge_slot, face_slot,
                      star_ptr, star_member, star_sq_ptr, star_off, stride, mirror, data):
    """Exact Hessian of :func:`juelicher` (``c0 (V,)`` per vertex), added into the CSR ``data``
    of a fixed pattern.

    ``Hess E = sum_e w_e Hess(l_e theta_e) + sum_f u_f Hess(area_f)
    + sum_i (4 kappa / A_i) g_i g_i^T`` (:mod:`.bending`; element Hessians as in
    :class:`.hinge.HingeHessian` and :class:`.hinge.FaceAreaHessian`). Block ``(a, b)``
    entry ``(c, d)`` of the matrix lies at ``data[off + c stride[a] + d]``, with ``off`` from
    ``hinge_off (4, 4, E)`` for the vertices ``(p, q)`` of a hinge, ``face_off (3, 3, F)`` for
    the corners of a face and ``star_off`` for the pairs of star slots of a vertex ``v``
    (``n^2`` pairs from ``star_sq_ptr[v]``, ``n`` the slots of its star). ``hinge_slot (2, 4, E)``: star
    slot of each hinge vertex in the stars of the edge's end points, ``face_slot (3, 3, F)``:
    of each corner in the stars of the three corners; ``star_member`` the vertex of each slot.
    ``data`` is zeroed first. ``mirror (2, m)`` pairs every entry above the diagonal with its
    transpose; both get their mean, so that the matrix is exactly symmetric (the two are
    sums of the same terms, rounded in another order)."""
    V, nh, nf = X.shape[0], HT.shape[1], FT.shape[1]
    data[:] = 0.0
    M, A, dphi, dA = _juelicher_elements(X, HT, FT, True)  # phi = L theta, areas, gradients
    H = np.empty(V)
    f_M = np.empty(V)
    f_A = np.empty(V)
    star_w = np.empty(V)
    for v in range(V):
        Av = A[v] / 3.0
        H[v] = 0.25 * M[v] / Av
        f_M[v] = 2.0 * kappa * (2.0 * H[v] - c0[v])
        f_A[v] = 0.5 * kappa * (c0[v] * c0[v] - 4.0 * H[v] * H[v])
        star_w[v] = 4.0 * kappa / Av
    # pass 2: w_e Hess(phi_e), the low-rank form of hinge.HingeHessian for phi = L theta
    B = np.empty((4, 4, 3, 3))
    e, n0, n1, eh = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    av, bv, xaa, xbb = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    y0, y1, pv, qv, rv = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for h in range(nh):
        i, j, k, l = HT[0, h], HT[1, h], HT[2, h], HT[3, h]
        w = 0.25 * (f_M[i] + f_M[j])
        for c in range(3):
            e[c] = X[j, c] - X[i, c]
            av[c] = X[k, c] - X[i, c]
            bv[c] = X[l, c] - X[i, c]
        n0[0], n0[1], n0[2] = e[1] * av[2] - e[2] * av[1], e[2] * av[0] - e[0] * av[2], e[0] * av[1] - e[1] * av[0]
        n1[0], n1[1], n1[2] = bv[1] * e[2] - bv[2] * e[1], bv[2] * e[0] - bv[0] * e[2], bv[0] * e[1] - bv[1] * e[0]
        LL = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        L = np.sqrt(LL)
        theta = np.arctan2(-L * (n0[0] * bv[0] + n0[1] * bv[1] + n0[2] * bv[2]),
                           n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2])
        s0 = 1.0 / (n0[0] * n0[0] + n0[1] * n0[1] + n0[2] * n0[2])
        s1 = 1.0 / (n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2])
        Ls0, Ls1 = L * s0, L * s1
        t0 = (av[0] * e[0] + av[1] * e[1] + av[2] * e[2]) / LL
        t1 = (bv[0] * e[0] + bv[1] * e[1] + bv[2] * e[2]) / LL
        for c in range(3):
            eh[c] = e[c] / L
        for c in range(3):
            c1, c2 = (c + 1) % 3, (c + 2) % 3
            m0c = n0[c1] * av[c2] - n0[c2] * av[c1]  # n0 x a
            m1c = n1[c1] * bv[c2] - n1[c2] * bv[c1]  # n1 x b
            g1c = -(t0 * (-Ls0 * n0[c]) + t1 * (-Ls1 * n1[c]))
            xaa[c] = L * (Ls0 * s0) * (n0[c1] * e[c2] - n0[c2] * e[c1])
            xbb[c] = L * -(Ls1 * s1) * (n1[c1] * e[c2] - n1[c2] * e[c1])
            y0[c] = L * (-s0 * eh[c] - (2.0 * Ls0 * s0) * m0c) - Ls0 * eh[c]
            y1[c] = L * (-s1 * eh[c] + (2.0 * Ls1 * s1) * m1c) - Ls1 * eh[c]
            gt0 = (av[c] - (2.0 * t0) * e[c]) / LL
            gt1 = (bv[c] - (2.0 * t1) * e[c]) / LL
            pv[c] = (-0.5 * L) * -(Ls0 * gt0 + (t0 * s0) * eh[c] + (2.0 * t0 * Ls0 * s0) * m0c)
            qv[c] = (-0.5 * L) * -(Ls1 * gt1 + (t1 * s1) * eh[c] - (2.0 * t1 * Ls1 * s1) * m1c)
            rv[c] = g1c - (0.5 * theta / L) * eh[c]
        gam0, gam1, delta = L * Ls0, -L * Ls1, theta / L
        for c in range(3):
            for d in range(3):
                # (j, j) = d2/de2, (j, k) and (j, l) = d2/de da, d2/de db, (k, k), (l, l)
                ee = (n0[c] * pv[d] + n1[c] * qv[d] + eh[c] * rv[d]
                      + n0[d] * pv[c] + n1[d] * qv[c] + eh[d] * rv[c])
                B[1, 1, c, d] = ee + (delta if c == d else 0.0)
                B[1, 2, c, d] = y0[c] * n0[d]
                B[1, 3, c, d] = y1[c] * n1[d]
                B[2, 2, c, d] = n0[c] * xaa[d] + xaa[c] * n0[d]
                B[3, 3, c, d] = n1[c] * xbb[d] + xbb[c] * n1[d]
                B[2, 3, c, d] = 0.0
        _add_skew(B[1, 2], -gam0, av)  # (j, k) = y0 n0^T - gamma0 [a]_x
        _add_skew(B[1, 3], -gam1, bv)  # (j, l) = y1 n1^T - gamma1 [b]_x
        # vertex i enters through e, a, b = x - x_i: its blocks are minus the row sums
        for c in range(3):
            for d in range(3):
                B[0, 1, c, d] = -(B[1, 1, c, d] + B[1, 2, d, c] + B[1, 3, d, c])
                B[0, 2, c, d] = -(B[1, 2, c, d] + B[2, 2, c, d])
                B[0, 3, c, d] = -(B[1, 3, c, d] + B[3, 3, c, d])
        for c in range(3):
            for d in range(3):
                B[0, 0, c, d] = -(B[0, 1, c, d] + B[0, 2, c, d] + B[0, 3, c, d])
        for p in range(4):
            for q in range(p, 4):
                if p == 2 and q == 3:  # identically zero
                    continue
                _add_block(data, hinge_off[p, q, h], stride[HT[p, h]], w, B[p, q], False)
                if q != p:
                    _add_block(data, hinge_off[q, p, h], stride[HT[q, h]], w, B[p, q], True)
    # u_f Hess(area_f): c (E_p . E_q) nhat nhat^T + s_pq [nhat]_x / 2 (hinge.FaceAreaHessian)
    Ed = np.empty((3, 3))
    F3 = np.empty((3, 3))
    nh3, u, v = np.empty(3), np.empty(3), np.empty(3)
    for f in range(nf):
        p0, p1, p2 = FT[0, f], FT[1, f], FT[2, f]
        for c in range(3):
            u[c] = X[p1, c] - X[p0, c]
            v[c] = X[p2, c] - X[p0, c]
        nh3[0], nh3[1], nh3[2] = u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]
        norm = np.sqrt(nh3[0] * nh3[0] + nh3[1] * nh3[1] + nh3[2] * nh3[2])
        for c in range(3):
            nh3[c] /= norm
            Ed[0, c] = v[c] - u[c]
            Ed[1, c] = -v[c]
            Ed[2, c] = u[c]
        wu = (f_A[p0] + f_A[p1] + f_A[p2]) / 3.0
        cc = 0.5 / norm
        for p in range(3):
            for q in range(3):
                coef = cc * (Ed[p, 0] * Ed[q, 0] + Ed[p, 1] * Ed[q, 1] + Ed[p, 2] * Ed[q, 2])
                for c in range(3):
                    for d in range(3):
                        F3[c, d] = coef * nh3[c] * nh3[d]
                if q == (p + 1) % 3:
                    s = -0.5
                elif q == (p + 2) % 3:
                    s = 0.5
                else:
                    s = 0.0
                if s != 0.0:
                    _add_skew(F3, s, nh3)
                _add_block(data, face_off[p, q, f], stride[FT[p, f]], wu, F3, False)
    # sum_i (4 kappa / A_i) g_i g_i^T, g_i = grad M_i - H_i grad A_i on the star of i
    n_slots = star_member.shape[0]
    G = np.zeros((n_slots, 3))
    for h in range(nh):
        for s in range(2):
            for a in range(4):
                slot = hinge_slot[s, a, h]
                for c in range(3):
                    G[slot, c] += 0.25 * dphi[h, a, c]
    for f in range(nf):
        for p in range(3):
            wf = H[FT[p, f]] * (-1.0 / 3.0)
            for a in range(3):
                slot = face_slot[p, a, f]
                for c in range(3):
                    G[slot, c] += wf * dA[f, a, c]
    for v in range(V):
        lo, n = star_ptr[v], star_ptr[v + 1] - star_ptr[v]
        base = star_sq_ptr[v]
        wv = star_w[v]
        for P in range(n):
            rowstride = stride[star_member[lo + P]]
            for Q in range(n):
                off = star_off[base + P * n + Q]
                for c in range(3):
                    gPc = wv * G[lo + P, c]
                    for d in range(3):
                        data[off + c * rowstride + d] += gPc * G[lo + Q, d]
    _mirror_mean(data, mirror)
    return data


# ------------------------------------------------------------------ star_perp_sq_mean_curvature


@njit(cache=True, nogil=True, inline="always")
def _face_geometry(X, FT, f, e, ga):
    """Face ``f``: fills ``e[c] = x_{c+2} - x_{c+1}`` (edge opposite corner ``c``) and the
    area gradient ``ga[c] = nhat x e_c / 2``; returns ``(n0, n1, n2, rho)`` with ``n`` the
    area vector ``(x1 - x0) x (x2 - x0)`` and ``rho = |n|``."""
    p, q, r = FT[0, f], FT[1, f], FT[2, f]
    for k in range(3):
        e[0, k] = X[r, k] - X[q, k]
        e[1, k] = X[p, k] - X[r, k]
        e[2, k] = X[q, k] - X[p, k]
    u0, u1, u2 = X[q, 0] - X[p, 0], X[q, 1] - X[p, 1], X[q, 2] - X[p, 2]
    v0, v1, v2 = X[r, 0] - X[p, 0], X[r, 1] - X[p, 1], X[r, 2] - X[p, 2]
    n0, n1, n2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    rho = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    h0, h1, h2 = n0 / rho, n1 / rho, n2 / rho
    for c in range(3):
        ga[c, 0] = 0.5 * (h1 * e[c, 2] - h2 * e[c, 1])
        ga[c, 1] = 0.5 * (h2 * e[c, 0] - h0 * e[c, 2])
        ga[c, 2] = 0.5 * (h0 * e[c, 1] - h1 * e[c, 0])
    return n0, n1, n2, rho


@njit(cache=True, nogil=True)
def _star_perp_sums(X, FT, keep=None):
    """Evolver's vertex sums: ``F`` (area gradient), ``M`` (half area vectors), ``S`` (star
    area), :mod:`.evolver_bending`. ``keep (F, 22)``, if given, receives each face's geometry
    (``e``, ``ga``, ``n``, ``rho`` of :func:`_face_geometry`) for a later pass."""
    V = X.shape[0]
    Fv, Mv, S = np.zeros((V, 3)), np.zeros((V, 3)), np.zeros(V)
    e, ga = np.empty((3, 3)), np.empty((3, 3))
    for f in range(FT.shape[1]):
        n0, n1, n2, rho = _face_geometry(X, FT, f, e, ga)
        if keep is not None:
            for c in range(3):
                for k in range(3):
                    keep[f, 3 * c + k] = e[c, k]
                    keep[f, 9 + 3 * c + k] = ga[c, k]
            keep[f, 18], keep[f, 19], keep[f, 20], keep[f, 21] = n0, n1, n2, rho
        for c in range(3):
            v = FT[c, f]
            for k in range(3):
                Fv[v, k] += ga[c, k]
            Mv[v, 0] += 0.5 * n0
            Mv[v, 1] += 0.5 * n1
            Mv[v, 2] += 0.5 * n2
            S[v] += 0.5 * rho
    return Fv, Mv, S


@njit(cache=True, nogil=True, inline="always")
def _star_perp_vertex(Fv, Mv, S, v, modulus, h0, weight, dh, dg, D, hessian):
    """The vertex term ``g = modulus weight S (h - h0)^2 / 3`` of ``v``: returns it and fills its
    derivatives by ``q = (F, M, S)``, ``dg (7)`` and, with ``hessian``, ``D (7, 7)`` (``dh (6)``
    scratch: the derivatives of ``h``)."""
    u = Fv[v, 0] * Mv[v, 0] + Fv[v, 1] * Mv[v, 1] + Fv[v, 2] * Mv[v, 2]
    w = Mv[v, 0] * Mv[v, 0] + Mv[v, 1] * Mv[v, 1] + Mv[v, 2] * Mv[v, 2]
    ok = w > 0.0
    if not ok:
        w = 1.0
    h = 1.5 * u / w if ok else 0.0  # Evolver: h = 0 where M = 0
    r = h - h0[v]
    K = modulus * weight[v]
    dh[:] = 0.0
    if ok:
        for k in range(3):
            dh[k] = 1.5 * Mv[v, k] / w
            dh[3 + k] = 1.5 * (Fv[v, k] / w - 2.0 * u * Mv[v, k] / (w * w))
    for k in range(6):
        dg[k] = (2.0 * K * S[v] * r / 3.0) * dh[k]
    dg[6] = K * r * r / 3.0
    if hessian:
        cS, cr = 2.0 * K * S[v] / 3.0, 2.0 * K * r / 3.0
        for a in range(6):
            for b in range(6):
                D[a, b] = cS * dh[a] * dh[b]
            D[a, 6] = cr * dh[a]
            D[6, a] = cr * dh[a]
        D[6, 6] = 0.0
        if ok:
            w2, w3 = w * w, w * w * w
            for a in range(3):
                for b in range(3):
                    MM = Mv[v, a] * Mv[v, b]
                    eye = 1.0 if a == b else 0.0
                    h_FM = 1.5 * (eye / w - 2.0 * MM / w2)
                    h_MM = 1.5 * (-2.0 * (Fv[v, a] * Mv[v, b] + Mv[v, a] * Fv[v, b]) / w2
                                  - 2.0 * u * eye / w2 + 8.0 * u * MM / w3)
                    D[a, 3 + b] += cS * r * h_FM
                    D[3 + b, a] += cS * r * h_FM
                    D[3 + a, 3 + b] += cS * r * h_MM
    return modulus * weight[v] * S[v] * r * r / 3.0


@njit(cache=True, nogil=True, inline="always")
def _face_weights(dgv, FT, f, vF):
    """What face ``f`` gets of its corners' ``dg/dq``: ``vF[c] = dg/dF`` of corner ``c``
    (filled), and the sums over the corners of ``dg/dM`` and ``dg/dS``, returned."""
    gM0 = gM1 = gM2 = gS = 0.0
    for c in range(3):
        v = FT[c, f]
        for k in range(3):
            vF[c, k] = dgv[v, k]
        gM0 += dgv[v, 3]
        gM1 += dgv[v, 4]
        gM2 += dgv[v, 5]
        gS += dgv[v, 6]
    return gM0, gM1, gM2, gS


@njit(cache=True, nogil=True)
def star_perp(X, FT, modulus, h0, weight, gradient):
    """Surface Evolver's ``star_perp_sq_mean_curvature``, ``sum_v modulus weight_v S_v
    (h_v - h0_v)^2 / 3``, and its gradient (:mod:`.evolver_bending` for the formulas;
    ``h0``, ``weight`` per vertex). Returns ``(value, G)``, ``G (0, 3)`` without
    ``gradient``."""
    V = X.shape[0]
    keep = np.empty((FT.shape[1] if gradient else 0, 22))  # the faces' geometry, computed once
    Fv, Mv, S = _star_perp_sums(X, FT, keep if gradient else None)
    dgv = np.empty((V if gradient else 0, 7))
    dh, dg, D = np.empty(6), np.empty(7), np.empty((7, 7))
    value = 0.0
    for v in range(V):
        value += _star_perp_vertex(Fv, Mv, S, v, modulus, h0, weight, dh, dg, D, False)
        if gradient:
            dgv[v] = dg
    G = np.zeros((V if gradient else 0, 3))
    if not gradient:
        return value, G
    e, ga, vF, ev = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for f in range(FT.shape[1]):
        for c in range(3):
            for k in range(3):
                e[c, k] = keep[f, 3 * c + k]
                ga[c, k] = keep[f, 9 + 3 * c + k]
        n0, n1, n2, rho = keep[f, 18], keep[f, 19], keep[f, 20], keep[f, 21]
        h = (n0 / rho, n1 / rho, n2 / rho)  # nhat
        gM0, gM1, gM2, gS = _face_weights(dgv, FT, f, vF)
        # Hess(a) vF = 1/2 [(N^T N vF - 4 grad_a (grad_a . vF)) / rho + nhat x (vF_{c+2} - vF_{c+1})]
        Nv0 = Nv1 = Nv2 = ga_v = 0.0
        for c in range(3):
            Nv0 += e[c, 1] * vF[c, 2] - e[c, 2] * vF[c, 1]
            Nv1 += e[c, 2] * vF[c, 0] - e[c, 0] * vF[c, 2]
            Nv2 += e[c, 0] * vF[c, 1] - e[c, 1] * vF[c, 0]
            ga_v += ga[c, 0] * vF[c, 0] + ga[c, 1] * vF[c, 1] + ga[c, 2] * vF[c, 2]
            for k in range(3):
                ev[c, k] = vF[(c + 2) % 3, k] - vF[(c + 1) % 3, k]
        for c in range(3):
            v = FT[c, f]
            cr0 = Nv1 * e[c, 2] - Nv2 * e[c, 1]
            cr1 = Nv2 * e[c, 0] - Nv0 * e[c, 2]
            cr2 = Nv0 * e[c, 1] - Nv1 * e[c, 0]
            G[v, 0] += (0.5 * ((cr0 - 4.0 * ga[c, 0] * ga_v) / rho + (h[1] * ev[c, 2] - h[2] * ev[c, 1]))
                        + 0.5 * (gM1 * e[c, 2] - gM2 * e[c, 1]) + gS * ga[c, 0])
            G[v, 1] += (0.5 * ((cr1 - 4.0 * ga[c, 1] * ga_v) / rho + (h[2] * ev[c, 0] - h[0] * ev[c, 2]))
                        + 0.5 * (gM2 * e[c, 0] - gM0 * e[c, 2]) + gS * ga[c, 1])
            G[v, 2] += (0.5 * ((cr2 - 4.0 * ga[c, 2] * ga_v) / rho + (h[0] * ev[c, 1] - h[1] * ev[c, 0]))
                        + 0.5 * (gM0 * e[c, 1] - gM1 * e[c, 0]) + gS * ga[c, 2])
    return value, G


@njit(cache=True, nogil=True, inline="always")
def _skew_into(S, v0, v1, v2):
    """``S = [v]_x`` (``[v]_x w = v x w``)."""
    S[0, 0], S[0, 1], S[0, 2] = 0.0, -v2, v1
    S[1, 0], S[1, 1], S[1, 2] = v2, 0.0, -v0
    S[2, 0], S[2, 1], S[2, 2] = -v1, v0, 0.0


@njit(cache=True, nogil=True)
def star_perp_hessian(X, FT, modulus, h0, weight, face_slot, face_off, star_ptr, star_member,
                      star_sq_ptr, star_off, stride, mirror, data):
    """Exact Hessian of :func:`star_perp`, ``J^T D J + sum_k (dg/dq_k) Hess(q_k)``
    (:mod:`.evolver_bending`), added into the CSR ``data`` of a star pattern (zeroed first;
    layout and arguments as in :func:`juelicher_hessian`). Per face, with ``E_c = [e_c]_x``:
    ``Hess a`` has blocks ``((e_c . e_d) I - e_d e_c^T - 4 ga_c ga_d^T) / (2 rho)
    - A_cd [nhat]_x / 2`` (``A`` the cyclic antisymmetric 3x3 matrix of the corners), and the
    third derivative contracted with ``v`` has blocks ``(C_cd + C_dc^T - A_cd [P m / rho]_x
    + E_c^T Q E_d) / 2`` with ``C_cd = [v_{c+2} - v_{c+1}]_x^T P E_d / rho``. The face's term
    is a Hessian: its blocks ``(c, d)`` are computed for ``c <= d`` only and ``(d, c)`` is added
    as the transpose (a third fewer products in the face loop)."""
    V, nf = X.shape[0], FT.shape[1]
    data[:] = 0.0
    Fv, Mv, S = _star_perp_sums(X, FT)
    dgv, Dv = np.empty((V, 7)), np.empty((V, 7, 7))
    dh = np.empty(6)
    for v in range(V):
        _star_perp_vertex(Fv, Mv, S, v, modulus, h0, weight, dh, dgv[v], Dv[v], True)
    J = np.zeros((star_member.shape[0], 7, 3))  # per star slot: the 7 x 3 block of J
    A = np.array([[0.0, 1.0, -1.0], [-1.0, 0.0, 1.0], [1.0, -1.0, 0.0]])
    e, ga, vF = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    E, EV, PE, QE = np.empty((3, 3, 3)), np.empty((3, 3, 3)), np.empty((3, 3, 3)), np.empty((3, 3, 3))
    HA, L = np.empty((3, 3, 3, 3)), np.empty((3, 3))
    P, Q, Sn, Sm, Sg = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    nh, m = np.empty(3), np.empty(3)
    for f in range(nf):
        n0, n1, n2, rho = _face_geometry(X, FT, f, e, ga)
        nh[0], nh[1], nh[2] = n0 / rho, n1 / rho, n2 / rho
        _skew_into(Sn, nh[0], nh[1], nh[2])
        for c in range(3):
            _skew_into(E[c], e[c, 0], e[c, 1], e[c, 2])
        for c in range(3):
            for d in range(3):
                ecd = e[c, 0] * e[d, 0] + e[c, 1] * e[d, 1] + e[c, 2] * e[d, 2]
                for i in range(3):
                    for j in range(3):
                        val = ((ecd if i == j else 0.0) - e[d, i] * e[c, j]
                               - 4.0 * ga[c, i] * ga[d, j]) / rho - A[c, d] * Sn[i, j]
                        HA[c, d, i, j] = 0.5 * val
        # the rows of J of the three corners' vertices: F (Hess a), M (N / 2), S (grad a)
        for c in range(3):
            for a in range(3):
                slot = face_slot[c, a, f]
                for d in range(3):
                    for k in range(3):
                        J[slot, k, d] += HA[c, a, k, d]
                        J[slot, 3 + k, d] += 0.5 * E[a, k, d]
                    J[slot, 6, d] += ga[a, d]
        # sum_k (dg/dq_k) Hess(q_k): Hess(vF . grad a) + Hess(gM . n / 2) + gS Hess(a)
        gM0, gM1, gM2, gS = _face_weights(dgv, FT, f, vF)
        _skew_into(Sg, gM0, gM1, gM2)
        m[:] = 0.0
        for c in range(3):
            m[0] += e[c, 1] * vF[c, 2] - e[c, 2] * vF[c, 1]
            m[1] += e[c, 2] * vF[c, 0] - e[c, 0] * vF[c, 2]
            m[2] += e[c, 0] * vF[c, 1] - e[c, 1] * vF[c, 0]
            _skew_into(EV[c], vF[(c + 2) % 3, 0] - vF[(c + 1) % 3, 0],
                       vF[(c + 2) % 3, 1] - vF[(c + 1) % 3, 1], vF[(c + 2) % 3, 2] - vF[(c + 1) % 3, 2])
        nm = nh[0] * m[0] + nh[1] * m[1] + nh[2] * m[2]
        for i in range(3):
            for j in range(3):
                P[i, j] = (1.0 if i == j else 0.0) - nh[i] * nh[j]
                Q[i, j] = (-(m[i] * nh[j] + nh[i] * m[j]) - (nm if i == j else 0.0)
                           + 3.0 * nm * nh[i] * nh[j]) / (rho * rho)
        Pm0 = (P[0, 0] * m[0] + P[0, 1] * m[1] + P[0, 2] * m[2]) / rho
        Pm1 = (P[1, 0] * m[0] + P[1, 1] * m[1] + P[1, 2] * m[2]) / rho
        Pm2 = (P[2, 0] * m[0] + P[2, 1] * m[1] + P[2, 2] * m[2]) / rho
        _skew_into(Sm, Pm0, Pm1, Pm2)
        for d in range(3):
            for i in range(3):
                for j in range(3):
                    PE[d, i, j] = (P[i, 0] * E[d, 0, j] + P[i, 1] * E[d, 1, j]
                                   + P[i, 2] * E[d, 2, j]) / rho
                    QE[d, i, j] = Q[i, 0] * E[d, 0, j] + Q[i, 1] * E[d, 1, j] + Q[i, 2] * E[d, 2, j]
        for c in range(3):
            for d in range(c, 3):  # the block (d, c) is the transpose of (c, d)
                for i in range(3):
                    for j in range(3):
                        cross_cd = EV[c, 0, i] * PE[d, 0, j] + EV[c, 1, i] * PE[d, 1, j] + EV[c, 2, i] * PE[d, 2, j]
                        cross_dc = EV[d, 0, j] * PE[c, 0, i] + EV[d, 1, j] * PE[c, 1, i] + EV[d, 2, j] * PE[c, 2, i]
                        nqn = E[c, 0, i] * QE[d, 0, j] + E[c, 1, i] * QE[d, 1, j] + E[c, 2, i] * QE[d, 2, j]
                        L[i, j] = (0.5 * (cross_cd + cross_dc - A[c, d] * Sm[i, j] + nqn)
                                   - 0.5 * A[c, d] * Sg[i, j] + gS * HA[c, d, i, j])
                _add_block(data, face_off[c, d, f], stride[FT[c, f]], 1.0, L, False)
                if d != c:
                    _add_block(data, face_off[d, c, f], stride[FT[d, f]], 1.0, L, True)
    # J^T D J, vertex by vertex over the pairs of slots of its star
    DJ = np.empty((64, 7, 3))  # D J of each slot of one star (grown for a larger star)
    for v in range(V):
        lo, n = star_ptr[v], star_ptr[v + 1] - star_ptr[v]
        if n > DJ.shape[0]:
            DJ = np.empty((n, 7, 3))
        for b in range(n):
            for k in range(7):
                for d in range(3):
                    acc = 0.0
                    for l in range(7):
                        acc += Dv[v, k, l] * J[lo + b, l, d]
                    DJ[b, k, d] = acc
        base = star_sq_ptr[v]
        for a in range(n):
            row_a = stride[star_member[lo + a]]
            for b in range(a, n):  # (b, a) is the transpose of (a, b)
                off_ab, off_ba = star_off[base + a * n + b], star_off[base + b * n + a]
                row_b = stride[star_member[lo + b]]
                for c in range(3):
                    for d in range(3):
                        acc = 0.0
                        for k in range(7):
                            acc += J[lo + a, k, c] * DJ[b, k, d]
                        data[off_ab + c * row_a + d] += acc
                        if b != a:
                            data[off_ba + d * row_b + c] += acc
    _mirror_mean(data, mirror)
    return data


# ------------------------------------------------------------------ mesh measures


@njit(cache=True, nogil=True)
def face_side_lengths(X, faces):
    """Lengths of the sides of every face, ``(3 F,)``: side ``c`` of face ``f`` (from corner
    ``c`` to corner ``c + 1``) at ``3 f + c``, each ``sqrt((dx dx + dy dy) + dz dz)`` as NumPy's
    ``norm`` over the last axis rounds it."""
    out = np.empty(faces.shape[0] * 3)
    for f in range(faces.shape[0]):
        for c in range(3):
            p, q = faces[f, c], faces[f, (c + 1) % 3]
            dx, dy, dz = X[q, 0] - X[p, 0], X[q, 1] - X[p, 1], X[q, 2] - X[p, 2]
            out[3 * f + c] = np.sqrt(dx * dx + dy * dy + dz * dz)
    return out


# ------------------------------------------------------------------ sparse assembly


@njit(cache=True, nogil=True)
def add_scaled_at(data, slot, values, keep, coef):
    """``data[slot[i]] += coef values[keep[i]]`` for every ``i`` in order (the slots of one
    call distinct: the same sums as NumPy's ``data[slot] += coef * values[keep]``, in one pass
    instead of a gather, a product, a gather and a scatter)."""
    for i in range(len(slot)):
        data[slot[i]] += coef * values[keep[i]]
