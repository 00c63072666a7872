"""The host eigensolvers, one place for every chapter: the codec's and the spectral
module's bases (smallest eigenpairs, canonical within clusters, fixed start vectors),
the hash's and the statistics' extreme eigenvalues.  Every start vector is fixed, so a
result is the same in every run.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["fixed_vectors", "start_vector", "smallest", "shifted_inverse", "largest_values", "smallest_values",
           "clusters", "canonical"]


def fixed_vectors(m: int, k: int, salt: int = 0) -> np.ndarray:
    """(m, k) pseudo-random values in [−1, 1), the same on every machine:
    splitmix64 of (row, column, salt), in numpy's wrapping uint64 arithmetic.

    Arguments:
        m: rows.
        k: columns.
        salt: a 64-bit salt that selects another sequence.

    Returns:
        (m, k) float64 array in [−1, 1)."""
    i = np.arange(m, dtype=np.uint64)[:, None]
    j = np.arange(k, dtype=np.uint64)[None, :]
    with np.errstate(over="ignore"):
        z = i * np.uint64(0x9E3779B97F4A7C15) + (j + np.uint64(salt) * np.uint64(65537)) * np.uint64(0xD1B54A32D192ED03)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0 ** -52 - 1.0


def start_vector(n: int) -> np.ndarray:
    """The seeded start vector of the extreme-eigenvalue solves: n standard normals (seed 0),
    never the constant vector, which a Laplacian maps to 0."""
    return np.random.default_rng(0).standard_normal(n)


def smallest(mat: sp.csr_matrix, k: int, dense: bool, sigma: float = -1e-2) -> tuple[np.ndarray, np.ndarray]:
    """The k smallest eigenpairs of a symmetric positive semi-definite matrix, ascending:
    dense ``eigh`` (only those), or ARPACK shift-invert around ``sigma`` < 0 (below the
    spectrum, so the factorization is definite) from a fixed start vector."""
    n = mat.shape[0]
    if dense or k >= n - 1:
        w, u = scipy.linalg.eigh(mat.toarray(), subset_by_index=[0, min(k, n) - 1], driver="evx")
        return w, u
    v0 = fixed_vectors(n, 1, salt=7)[:, 0]
    w, u = spla.eigsh(mat.tocsc(), k=k, sigma=sigma, which="LM", v0=v0, tol=0, OPinv=shifted_inverse(mat, sigma))
    order = np.argsort(w, kind="stable")
    return w[order], u[:, order]


def shifted_inverse(mat: sp.csr_matrix, sigma: float) -> spla.LinearOperator:
    """(mat − σI)⁻¹ as an operator, factored once by :mod:`jaxmesh.linalg`'s host
    factorization (sparse Cholesky when cholespy is installed: positive definite for
    σ < 0 below a semi-definite spectrum; SuperLU otherwise).  ARPACK's shift-invert
    mode calls it a few hundred times per patch: CHOLMOD's solve made the codec's
    eigensolves 25–30 % faster than ARPACK's own SuperLU (benchmarks/bench_compress.py)."""
    from .linalg import _Factor, default_backend

    n = mat.shape[0]
    upper = sp.triu(mat, k=1).tocoo()
    factor = _Factor(n, np.stack([upper.row, upper.col], 1), mat.diagonal() - sigma, upper.data, default_backend())
    return spla.LinearOperator((n, n), matvec=factor.solve, dtype=np.float64)


def largest_values(mat: sp.spmatrix, k: int, dense: bool) -> np.ndarray:
    """The ``k`` largest eigenvalues of a symmetric matrix, ascending: dense ``eigh`` (only
    those) or ARPACK (largest algebraic) from :func:`start_vector`."""
    n = mat.shape[0]
    if dense:
        return scipy.linalg.eigh(mat.toarray(), eigvals_only=True, subset_by_index=[n - k, n - 1])
    return np.sort(spla.eigsh(mat, k=k, which="LA", v0=start_vector(n), return_eigenvectors=False))


def smallest_values(mat: sp.spmatrix, k: int, sigma: float) -> np.ndarray:
    """The ``k`` smallest eigenvalues of a symmetric positive semi-definite matrix, ascending:
    ARPACK shift-invert around ``sigma`` < 0 (its own factorization) from :func:`start_vector`."""
    vals = spla.eigsh(mat, k=k, sigma=sigma, which="LM", v0=start_vector(mat.shape[0]), return_eigenvectors=False)
    return np.sort(vals)


def clusters(w: np.ndarray, tol: float) -> list[tuple[int, int]]:
    """(start, end) of each run of ascending ``w`` whose steps are at most ``tol``."""
    out = []
    s = 0
    for i in range(1, len(w) + 1):
        if i == len(w) or w[i] - w[i - 1] > tol:
            out.append((s, i))
            s = i
    return out


def canonical(u: np.ndarray, w: np.ndarray, tol: float) -> np.ndarray:
    """Canonical eigenvectors: one per cluster rotation and sign (see :mod:`jaxmesh.compress.basis`)."""
    m = u.shape[0]
    g1 = fixed_vectors(m, 1, salt=1)[:, 0]
    out = np.empty_like(u)
    for s, e in clusters(w, tol):
        if e - s == 1:
            x = u[:, s]
            out[:, s] = x if x @ g1 >= 0 else -x
            continue
        uc = u[:, s:e]
        y = uc @ (uc.T @ fixed_vectors(m, e - s, salt=2 + s))
        q, rr = np.linalg.qr(y)
        out[:, s:e] = q * np.where(np.diag(rr) < 0, -1.0, 1.0)
    return out
