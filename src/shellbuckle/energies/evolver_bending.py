"""Surface Evolver's ``star_perp_sq_mean_curvature`` bending energy, exactly as Evolver 2.70 computes it.

Definition (Surface Evolver manual, "star_perp_sq_mean_curvature", and source ``sqcurve3.c``,
function ``star_sqcurve_method_all``, case ``PERP_SQ``). For every vertex ``i`` with the
star of faces ``f`` around it:

- ``F_i = sum_f d a_f / d x_i``, the area gradient at the vertex (3-vector);
- ``M_i = sum_f n_f / 2`` with ``n_f = (x1 - x0) x (x2 - x0)``, the sum of the face area
  vectors; on a closed star ``M_i = 3 N_i`` with ``N_i = dV / dx_i`` the volume gradient;
- ``S_i = sum_f a_f``, the area of the whole star (full face areas, not a third);
- ``h_i = (3/2) F_i . M_i / M_i . M_i = (1/2) F_i . N_i / N_i . N_i`` (mean curvature,
  ``+1/R`` on a sphere of radius ``R`` whose faces are oriented outwards);
- ``E = modulus * sum_i (h_i - h_zero)^2 S_i / 3``.

Evolver evaluates it as ``modulus * 0.75 * S * (fn/nn - 2 h_zero / 3)^2`` with
``fn = F.M``, ``nn = M.M``, which is the same number. Where ``M_i = 0`` Evolver sets ``h_i = 0``;
so do we.

Convention of this package: the bending energy is ``(1/2) kappa (c - c0)^2`` per area with
``c = c1 + c2 = 2 H``, so ``2 kappa (H - c0/2)^2``. Hence

    modulus = 2 kappa,      h_zero = c0 / 2,

and the stress-free sphere of radius ``R`` has ``c0 = 2/R`` (``h_zero = 1/R``).

Derivatives. ``E = sum_i g(q_i)`` with ``q_i = (F_i, M_i, S_i)`` in R^7, each a sum over the
(face, corner) pairs of vertex ``i`` of functions of the face's 9 coordinates. With ``J`` the
sparse ``(7V, 3V)`` Jacobian of all ``q_i`` and ``D_i`` the ``7 x 7`` Hessian of ``g`` at
``q_i``::

    grad E = J^T (dg/dq),      Hess E = J^T D J + sum_i sum_k (dg/dq_ik) Hess(q_ik).

The per-face pieces are written with the constant tensor ``B (3, 9, 9)`` such that
``n_k = (1/2) y^T B_k y`` for the face coordinates ``y = (x0, x1, x2)``: ``dn/dy = N`` with rows
``B_k y``, ``grad a = (1/2) N^T n_hat`` and ``Hess a = (1/2)[N^T (I - n_hat n_hat^T) N / |n| +
sum_k n_hat_k B_k]``. ``F`` is a block of ``grad a``, so the Hessian of ``lambda . F`` needs the
third derivative of the area contracted with ``v`` (``lambda`` at the corner's block):
with ``m = N v`` and ``psi = v . grad a = (1/2) m . n_hat``,

    Hess psi = (1/2)[Mv^T P N / |n| + N^T P Mv / |n| + sum_k (P m / |n|)_k B_k + N^T Q N],
    Q = [-(m n_hat^T + n_hat m^T) - (n_hat.m) I + 3 (n_hat.m) n_hat n_hat^T] / |n|^2,

where ``P = I - n_hat n_hat^T`` and ``Mv`` has rows ``B_k v``. All of this is exact (no finite
differences); the tests compare it with central differences.

Reference: K. A. Brakke, "The Surface Evolver", Experimental Mathematics 1 (1992) 141-165;
Surface Evolver 2.70 manual, section "Named methods", ``star_perp_sq_mean_curvature``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .assembly import ElementAssembler


# The face normal n = (x1 - x0) x (x2 - x0) is quadratic in y = (x0, x1, x2) (corner-major, 9
# entries): n_k = 1/2 y^T B_k y with B_k[3c+a, 3d+b] = A_cd eps_kab, A the cyclic antisymmetric
# 3x3 matrix below. Two identities are used instead of the dense B:
#   dn/dy = N(y), whose 3x3 block at corner c is [e_c]_x with e_c = x_{c+2} - x_{c+1};
#   sum_k z_k B_k = -A (kron) [z]_x  for any 3-vector z.
_CORNER_ANTISYM = np.array([[0.0, 1.0, -1.0], [-1.0, 0.0, 1.0], [1.0, -1.0, 0.0]])
_EYE3 = np.eye(3)


def _skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v]_x`` (``[v]_x w = v x w``) of ``v (..., 3)``, shape ``(..., 3, 3)``."""
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def _normal_jacobian(y: np.ndarray) -> np.ndarray:
    """``N(y) = dn/dy``, shape ``(F, 3, 9)``; linear in ``y (F, 9)``."""
    x = y.reshape(-1, 3, 3)
    e = x[:, [2, 0, 1]] - x[:, [1, 2, 0]]
    return _skew(e).transpose(0, 2, 1, 3).reshape(-1, 3, 9)


def _contract_B(z: np.ndarray) -> np.ndarray:
    """``sum_k z_k B_k`` for ``z (F, 3)``, shape ``(F, 9, 9)``."""
    blocks = -_CORNER_ANTISYM[None, :, None, :, None] * _skew(z)[:, None, :, None, :]
    return blocks.reshape(-1, 9, 9)


def _area_hessian(y: np.ndarray, rho: np.ndarray, nhat: np.ndarray, grad_a: np.ndarray):
    """``N = dn/dy (F, 3, 9)`` and the face-area Hessian ``(F, 9, 9)`` for face coordinates
    ``y (F, 9)``, given ``rho = |n|``, ``nhat`` and the area gradient ``grad_a (F, 9)``:
    ``Hess a = (1/2)[(N^T N - 4 grad_a grad_a^T) / rho + sum_k nhat_k B_k]``."""
    N = _normal_jacobian(y)
    NtN = np.matmul(N.transpose(0, 2, 1), N)
    hess_a = 0.5 * ((NtN - 4.0 * grad_a[:, :, None] * grad_a[:, None, :]) / rho[:, None, None]
                    + _contract_B(nhat))
    return N, hess_a


def _hess_area_directional(N, rho, nhat, v):
    """Hessian of ``psi = v . grad a`` for constant ``v (F, 9)``: the area's third derivative
    contracted with ``v``, shape ``(F, 9, 9)`` (formula in the module docstring)."""
    Nt = N.transpose(0, 2, 1)
    m = np.matmul(N, v[:, :, None])[:, :, 0]
    Mv = _normal_jacobian(v)
    P = _EYE3 - nhat[:, :, None] * nhat[:, None, :]
    PN = np.matmul(P, N) / rho[:, None, None]
    cross = np.matmul(Mv.transpose(0, 2, 1), PN)
    Pm = np.matmul(P, m[:, :, None])[:, :, 0] / rho[:, None]
    nm = np.einsum("fk,fk->f", nhat, m)
    Q = (-(m[:, :, None] * nhat[:, None, :] + nhat[:, :, None] * m[:, None, :])
         - nm[:, None, None] * _EYE3 + 3.0 * nm[:, None, None] * nhat[:, :, None] * nhat[:, None, :])
    Q /= (rho ** 2)[:, None, None]
    NQN = np.matmul(Nt, np.matmul(Q, N))
    return 0.5 * (cross + cross.transpose(0, 2, 1) + _contract_B(Pm) + NQN)


@dataclass(frozen=True, eq=False)
class StarPerpBending:
    """Surface Evolver's ``star_perp_sq_mean_curvature`` in the package's bending convention.

    ``E = 2 kappa * sum_i (h_i - c0_i / 2)^2 S_i / 3`` over the vertices that carry the energy,
    i.e. Evolver's ``modulus (h - h_zero)^2 S / 3`` with ``modulus = 2 kappa`` and
    ``h_zero = c0 / 2`` (``c = c1 + c2``; ``c0 = 2/R`` is the stress-free sphere). See the module
    docstring for ``h_i`` and ``S_i``. Faces must be oriented outwards (then ``h = +1/R`` on a
    sphere); Evolver measures ``h`` along the facets' own orientation.

    Parameters
    ----------
    faces : (F, 3) int
        Triangles of a closed surface.
    n_vertices : int
    kappa : float
        Bending modulus (energy). Evolver's quantity modulus is ``2 kappa``.
    c0 : float or (V,) array
        Spontaneous curvature in the ``c1 + c2`` convention, one value or one per vertex
        (Evolver's ``h_zero`` parameter or vertex attribute is ``c0 / 2``).
    vertices : (k,) int or None
        Vertices whose term is counted (a non-global Evolver quantity); ``None`` means all.

    ``value(X) -> float``, ``gradient(X) -> (V, 3)``, ``hessian(X) -> csr (3V, 3V)`` (exact,
    not projected), ``mean_curvature(X) -> (V,)``.
    """

    faces: np.ndarray
    n_vertices: int
    kappa: float = 1.0
    c0: float | np.ndarray = 2.0
    vertices: np.ndarray | None = None
    _tables: dict | None = field(default=None, repr=False)
    """Topology tables (face assembler; Hessian pattern once built), shared by the copies that
    ``dataclasses.replace`` makes (``with_c0`` in the c0 cycle), as ``Bending._plan`` is."""
    _weight: np.ndarray = field(init=False, repr=False)
    _h0: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        faces = np.ascontiguousarray(self.faces, dtype=np.int64)
        V = int(self.n_vertices)
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise ValueError(f"faces must be a non-empty (F, 3) integer array, got shape {faces.shape}")
        if not np.isfinite(self.kappa):
            raise ValueError(f"kappa must be a finite number, got {self.kappa!r}")
        c0 = np.asarray(self.c0, dtype=np.float64)
        if c0.ndim == 0:
            c0 = np.full(V, float(c0))
        if c0.shape != (V,) or not np.isfinite(c0).all():
            raise ValueError(f"c0 must be a finite number or a ({V},) array of finite numbers")
        weight = np.ones(V)
        if self.vertices is not None:
            chosen = np.asarray(self.vertices, dtype=np.int64)
            if chosen.size and (chosen.min() < 0 or chosen.max() >= V):
                raise ValueError(f"vertices must be indices in [0, {V}), got range "
                                 f"[{chosen.min()}, {chosen.max()}]")
            weight = np.zeros(V)
            weight[chosen] = 1.0
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "n_vertices", V)
        object.__setattr__(self, "_h0", 0.5 * c0)
        object.__setattr__(self, "_weight", weight)
        if self._tables is None:  # the Hessian pattern is added on the first hessian() call
            object.__setattr__(self, "_tables", {"face_asm": ElementAssembler(faces, V)})

    @classmethod
    def from_evolver(cls, faces, n_vertices, modulus: float, h_zero=0.0, vertices=None):
        """Build from Evolver's quantity ``modulus`` and ``h_zero`` (kappa = modulus/2, c0 = 2 h_zero)."""
        return cls(faces, n_vertices, kappa=0.5 * float(modulus),
                   c0=2.0 * np.asarray(h_zero, dtype=np.float64), vertices=vertices)

    @property
    def modulus(self) -> float:
        """Evolver's quantity modulus, ``2 kappa``."""
        return 2.0 * float(self.kappa)

    @property
    def h_zero(self) -> np.ndarray:
        """Evolver's ``h_zero`` per vertex, ``c0 / 2``, shape ``(V,)``."""
        return self._h0.copy()

    # -- per-vertex quantities -------------------------------------------------------------
    @staticmethod
    def _hessian_pattern(faces, V):
        """Index maps built once for the Hessian.

        ``J`` (the (7V, 3V) Jacobian of q = (F, M, S)) is stored in CSR order: the seven rows of
        vertex ``i`` share the same sorted columns, the dofs of its closed 1-ring, so its data
        for vertex ``i`` is one contiguous ``7 x w_i`` block. Vertices are grouped by ``w_i``;
        each group's ``J_i^T D_i J_i`` blocks and the per-face second-order terms are summed
        into one CSR pattern with one ``bincount``.
        """
        nf = len(faces)
        n_dofs = 3 * V
        rows = 7 * faces[:, :, None, None] + np.arange(7)[None, None, :, None]  # (F,3,7,1)
        cols = (3 * faces[:, None, :, None] + np.arange(3)).reshape(nf, 1, 1, 9)  # (F,1,1,9)
        rows, cols = np.broadcast_arrays(rows, cols)
        jkey = rows.ravel() * n_dofs + cols.ravel()
        junique, jslot = np.unique(jkey, return_inverse=True)
        jcols = junique % n_dofs
        jptr = np.zeros(7 * V + 1, dtype=np.int64)
        np.cumsum(np.bincount(junique // n_dofs, minlength=7 * V), out=jptr[1:])
        width = jptr[7 * np.arange(V) + 1] - jptr[7 * np.arange(V)]
        groups, keys = [], []
        for w in np.unique(width):
            verts = np.flatnonzero(width == w)
            start = jptr[7 * verts]
            gather = start[:, None] + np.arange(7 * w)  # (n, 7w): the 7 x w block, row-major
            ring = jcols[start[:, None] + np.arange(w)]  # (n, w) dofs of the closed ring
            groups.append((verts, int(w), gather))
            keys.append((ring[:, :, None] * n_dofs + ring[:, None, :]).ravel())
        fdofs = (3 * faces[:, :, None] + np.arange(3)).reshape(nf, 9)
        keys.append((fdofs[:, :, None] * n_dofs + fdofs[:, None, :]).ravel())
        unique, slot = np.unique(np.concatenate(keys), return_inverse=True)
        indices = (unique % n_dofs).astype(np.int32)
        indptr = np.zeros(n_dofs + 1, dtype=np.int64)
        np.cumsum(np.bincount(unique // n_dofs, minlength=n_dofs), out=indptr[1:])
        return {"jslot": jslot.ravel(), "jnnz": len(junique), "groups": groups,
                "slot": slot.ravel(), "nnz": len(unique), "indices": indices, "indptr": indptr}

    def _vertex_sums(self, X):
        """Face data ``(x, e, n, rho, nhat, grad_a)`` and the vertex sums ``F, M (V, 3)``, ``S (V,)``.

        ``e[:, c] = x_{c+2} - x_{c+1}`` is the edge opposite corner ``c``; the area gradient at
        corner ``c`` is ``grad_a[:, c] = (1/2) n_hat x e_c``.
        """
        X = np.asarray(X, dtype=np.float64)
        x = X[self.faces]  # (F, 3, 3)
        e = x[:, [2, 0, 1]] - x[:, [1, 2, 0]]
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        rho = np.sqrt(np.einsum("fk,fk->f", n, n))
        nhat = n / rho[:, None]
        grad_a = 0.5 * np.cross(nhat[:, None, :], e)  # (F, 3 corners, 3)
        V = self.n_vertices
        idx = self.faces.ravel()  # (face, corner) pairs, corner-fastest
        F = np.stack([np.bincount(idx, weights=grad_a[:, :, k].ravel(), minlength=V)
                      for k in range(3)], axis=1)
        M = np.stack([np.bincount(idx, weights=np.repeat(0.5 * n[:, k], 3), minlength=V)
                      for k in range(3)], axis=1)
        S = np.bincount(idx, weights=np.repeat(0.5 * rho, 3), minlength=V)
        return (x, e, n, rho, nhat, grad_a), F, M, S

    def _curvature(self, F, M):
        u = np.einsum("vk,vk->v", F, M)
        w = np.einsum("vk,vk->v", M, M)
        ok = w > 0.0
        w_safe = np.where(ok, w, 1.0)
        h = np.where(ok, 1.5 * u / w_safe, 0.0)  # Evolver: nn == 0 -> h = 0
        return h, u, w_safe, ok

    def mean_curvature(self, X) -> np.ndarray:
        """Evolver's vertex mean curvature ``h = (1/2) F.N / N.N``, shape ``(V,)``."""
        _, F, M, _ = self._vertex_sums(X)
        return self._curvature(F, M)[0]

    def value(self, X) -> float:
        _, F, M, S = self._vertex_sums(X)
        h = self._curvature(F, M)[0]
        return float(self.modulus / 3.0 * np.sum(self._weight * S * (h - self._h0) ** 2))

    def _g_derivatives(self, F, M, S, hessian: bool):
        """First (and second) derivatives of g(F, M, S) per vertex: (V, 7) and (V, 7, 7)."""
        K = self.modulus * self._weight
        h, u, w, ok = self._curvature(F, M)
        r = h - self._h0
        okf = ok.astype(float)
        h_F = 1.5 * M / w[:, None] * okf[:, None]
        h_M = 1.5 * (F / w[:, None] - 2.0 * u[:, None] * M / (w ** 2)[:, None]) * okf[:, None]
        dh = np.concatenate([h_F, h_M], axis=1)  # (V, 6)
        dg = np.empty((len(F), 7))
        dg[:, :6] = (2.0 * K * S * r / 3.0)[:, None] * dh
        dg[:, 6] = K * r ** 2 / 3.0
        if not hessian:
            return dg, None
        MM = M[:, :, None] * M[:, None, :]
        h_FM = 1.5 * (_EYE3 / w[:, None, None] - 2.0 * MM / (w ** 2)[:, None, None])
        FM = F[:, :, None] * M[:, None, :]
        h_MM = 1.5 * (-2.0 * (FM + FM.transpose(0, 2, 1)) / (w ** 2)[:, None, None]
                      - 2.0 * u[:, None, None] * _EYE3 / (w ** 2)[:, None, None]
                      + 8.0 * u[:, None, None] * MM / (w ** 3)[:, None, None])
        d2h = np.zeros((len(F), 6, 6))
        d2h[:, :3, 3:] = h_FM
        d2h[:, 3:, :3] = h_FM.transpose(0, 2, 1)
        d2h[:, 3:, 3:] = h_MM
        d2h *= okf[:, None, None]
        D = np.zeros((len(F), 7, 7))
        D[:, :6, :6] = (2.0 * K * S / 3.0)[:, None, None] * (dh[:, :, None] * dh[:, None, :]
                                                              + r[:, None, None] * d2h)
        D[:, 6, :6] = D[:, :6, 6] = (2.0 * K * r / 3.0)[:, None] * dh
        return dg, D

    def gradient(self, X) -> np.ndarray:
        (x, e, n, rho, nhat, grad_a), F, M, S = self._vertex_sums(X)
        dg, _ = self._g_derivatives(F, M, S, hessian=False)
        g = dg[self.faces]  # (F, 3 corners, 7)
        vF = g[:, :, :3]
        gM = g[:, :, 3:6].sum(axis=1)
        gS = g[:, :, 6].sum(axis=1)
        # Hess(a) vF = 1/2 [(N^T N vF - 4 grad_a (grad_a . vF)) / rho + sum_k nhat_k B_k vF] with
        # N w = sum_c e_c x w_c, (N^T lam)_c = lam x e_c and (sum_k nhat_k B_k vF)_c = nhat x e_c(vF)
        Nv = np.cross(e, vF).sum(axis=1)
        ga_v = np.einsum("fck,fck->f", grad_a, vF)
        ev = vF[:, [2, 0, 1]] - vF[:, [1, 2, 0]]
        hv = 0.5 * ((np.cross(Nv[:, None, :], e) - 4.0 * grad_a * ga_v[:, None, None])
                    / rho[:, None, None] + np.cross(nhat[:, None, :], ev))
        local = hv + 0.5 * np.cross(gM[:, None, :], e) + gS[:, None, None] * grad_a
        return self._tables["face_asm"].gradient(local)

    def hessian(self, X) -> sp.csr_matrix:
        (x, e, n, rho, nhat, grad_a), F, M, S = self._vertex_sums(X)
        dg, D = self._g_derivatives(F, M, S, hessian=True)
        grad_a = grad_a.reshape(-1, 9)
        N, hess_a = _area_hessian(x.reshape(-1, 9), rho, nhat, grad_a)
        # J^T D J with J the (7V, 3V) Jacobian of q = (F, M, S): per (face, corner c) the rows of
        # vertex faces[f, c] are (Hess a)[3c:3c+3, :], N / 2 and grad a.
        local_J = np.empty((len(self.faces), 3, 7, 9))
        local_J[:, :, 0:3, :] = hess_a.reshape(-1, 3, 3, 9)
        local_J[:, :, 3:6, :] = 0.5 * N[:, None]
        local_J[:, :, 6, :] = grad_a[:, None, :]
        pat = self._tables.get("hessian")
        if pat is None:
            pat = self._tables["hessian"] = self._hessian_pattern(self.faces, self.n_vertices)
        jdata = np.bincount(pat["jslot"], weights=local_J.ravel(), minlength=pat["jnnz"])
        parts = []
        for verts, w, gather in pat["groups"]:
            Ji = jdata[gather].reshape(-1, 7, w)
            parts.append(np.matmul(Ji.transpose(0, 2, 1), np.matmul(D[verts], Ji)).ravel())
        # sum_k (dg/dq_k) Hess(q_k), gathered per face: the corner sums of dg enter linearly
        g = dg[self.faces]
        vF = g[:, :, :3].reshape(-1, 9)
        gM = g[:, :, 3:6].sum(axis=1)
        gS = g[:, :, 6].sum(axis=1)
        local = (_hess_area_directional(N, rho, nhat, vF) + 0.5 * _contract_B(gM)
                 + gS[:, None, None] * hess_a)
        parts.append(local.ravel())
        data = np.bincount(pat["slot"], weights=np.concatenate(parts), minlength=pat["nnz"])
        n_dofs = 3 * self.n_vertices
        return sp.csr_matrix((data, pat["indices"], pat["indptr"]), shape=(n_dofs, n_dofs))
