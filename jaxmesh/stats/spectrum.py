"""Laplacian spectra against normalised rank (thesis ch.5, fig 5.xb)."""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse.linalg as spla

from .. import sparse as jsparse
from ..mesh import Mesh
from ._graph import single

__all__ = ["laplacian_spectrum"]


def laplacian_spectrum(mesh: Mesh, kind: str = "combinatorial", k: int | None = None,
                       dense_max: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """(normalised rank r ∈ [0, 1], eigenvalues, ascending) of L = D - A
    (``kind="combinatorial"``) or 𝓛 = I - D^{-1/2} A D^{-1/2} (``"normalized"``).

    Meshes with at most ``dense_max`` vertices (and ``k=None``) get the whole
    spectrum from a dense symmetric solver; otherwise the ``k`` smallest and
    ``k`` largest eigenvalues (default k = 20) from ``eigsh`` (shift-invert
    just below 0 for the small end), placed at their true ranks i / (V - 1).

    Arguments:
        mesh: a single mesh (or its graph view).
        kind: ``"combinatorial"`` (L = D − A) or ``"normalized"``.
        k: eigenvalues from each end for large meshes (default 20; forces the sparse path).
        dense_max: matrices up to this size use a dense symmetric eigensolver, larger ones ARPACK.

    Returns:
        (normalised ranks r, eigenvalues), both ascending."""
    single(mesh)
    if kind == "combinatorial":
        mat = jsparse.laplacian_matrix(mesh)
    elif kind == "normalized":
        mat = jsparse.normalized_laplacian_matrix(mesh)
    else:
        raise ValueError(f"kind must be 'combinatorial' or 'normalized', got {kind!r}")
    n = mesh.num_vertices
    rank = np.arange(n) / max(n - 1, 1)
    if k is None and n <= dense_max:
        return rank, scipy.linalg.eigh(mat.toarray(), eigvals_only=True)
    k = min(k or 20, (n - 1) // 2)
    # a fixed (seeded) start vector: reproducible; not the constant vector, which L maps to 0
    v0 = np.random.default_rng(0).standard_normal(n)
    low = spla.eigsh(mat, k=k, sigma=-1e-3, which="LM", v0=v0, return_eigenvectors=False)
    high = spla.eigsh(mat, k=k, which="LA", v0=v0, return_eigenvectors=False)
    vals = np.r_[np.sort(low), np.sort(high)]
    return np.r_[rank[:k], rank[n - k:]], vals
