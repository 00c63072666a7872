"""The r most significant eigenvalues of a (sub-)mesh's Laplace–Beltrami matrix
(thesis ch.4 eq.1–2, step 1.2).

L = D − W with w_ij = 3 (cot α_ij + cot β_ij) / η_i is not symmetric, but
L = diag(3/η) L_c with L_c = D_c − W_c the symmetric cotangent Laplacian, so
with P = diag(√(η/3)) the matrix S = P L P⁻¹ = diag(√(3/η)) L_c diag(√(3/η)) is
symmetric positive semi-definite with the same eigenvalues (each triangle adds
a P1 stiffness matrix, which is PSD whatever its angles).  "Most significant"
= largest magnitude = largest, since λ ≥ 0.  Eigenvalues only: with unit
eigenvectors ‖b_i‖² = 1 in the thesis's μ_k (SPEC resolution (b)).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._eigen import largest_values
from ..geometry import cotangents_of_corners

__all__ = ["cotangent_parts", "symmetric_laplace_beltrami",
           "laplace_beltrami_eigenvalues"]


def cotangent_parts(vertices: np.ndarray, faces: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """(L_c, η): L_c = D_c − W_c with (W_c)_ij = cot α_ij + cot β_ij, and η_i the total
    area of the faces around v_i.  Host numpy; the cotangents are
    :func:`jaxmesh.geometry.cotangents_of_corners` (a degenerate corner adds nothing).

    Arguments:
        vertices: positions, (V, 3).
        faces: triangles, (F, 3).

    Returns:
        (L_c (V, V) CSR, η (V,))."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    n = len(v)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    double_area = np.linalg.norm(cross, axis=1)
    cot = cotangents_of_corners(v[f], xp=np)  # (F, 3): the one definition, degenerate rule included
    rows, cols, vals = [], [], []
    for k in range(3):  # the corner k is opposite the edge (k+1, k+2)
        b, c = f[:, (k + 1) % 3], f[:, (k + 2) % 3]
        rows += [b, c]
        cols += [c, b]
        vals += [cot[:, k], cot[:, k]]
    w = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    lc = (sp.diags(np.asarray(w.sum(axis=1)).ravel()) - w).tocsr()
    eta = np.bincount(f.ravel(), weights=np.repeat(0.5 * double_area, 3), minlength=n)
    return lc, eta


def symmetric_laplace_beltrami(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """S = diag(√(3/η)) L_c diag(√(3/η)) (module docstring), over the vertices with η_i > 0.

    Arguments:
        vertices: positions, (V, 3).
        faces: triangles, (F, 3).

    Returns:
        S, CSR over the vertices with η > 0."""
    lc, eta = cotangent_parts(vertices, faces)
    keep = eta > 0
    q = sp.diags(np.sqrt(3.0 / eta[keep]))
    return (q @ lc[keep][:, keep] @ q).tocsr()


def laplace_beltrami_eigenvalues(vertices: np.ndarray, faces: np.ndarray, r: int,
                                 dense_max: int = 600) -> np.ndarray:
    """The ``r`` largest eigenvalues of the Laplace–Beltrami matrix, descending.

    Dense ``scipy.linalg.eigh`` (only the wanted index range) for small matrices
    or large ``r``; otherwise ARPACK's ``eigsh`` (largest algebraic, fixed seeded
    start vector, so the result is reproducible).  ``r`` is clipped to the size.

    Arguments:
        vertices: positions, (V, 3).
        faces: triangles, (F, 3).
        r: how many eigenvalues.
        dense_max: matrices up to this size use a dense symmetric eigensolver, larger ones ARPACK.

    Returns:
        (min(r, V),) eigenvalues, descending."""
    s = symmetric_laplace_beltrami(vertices, faces)
    n = s.shape[0]
    r = int(min(r, n))
    if r <= 0:
        return np.zeros(0)
    return largest_values(s, r, dense=n <= dense_max or 4 * r >= n)[::-1]
