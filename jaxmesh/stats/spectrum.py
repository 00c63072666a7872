"""Laplacian spectra against normalised rank (thesis ch.5, fig 5.xb): exact on small
meshes, the quantile function of the kernel-polynomial density (:mod:`.density`) on large
ones, or exact eigenvalues at the two ends."""

from __future__ import annotations

import numpy as np
import scipy.linalg

from .._eigen import largest_values, smallest_values
from ..mesh import Mesh
from ._graph import single
from .density import density_quantiles, laplacian_of_kind, spectral_density

__all__ = ["laplacian_spectrum", "QUANTILE_POINTS", "DENSE_MAX"]

#: the ranks at which a large mesh's estimated spectrum is given
QUANTILE_POINTS = 513
#: meshes up to this many vertices get their whole spectrum exactly (a dense solver, cubic in V:
#: about 0.3 s a spectrum at 2,000 vertices on 2 cores, 1 s at 2,930, 16 s at 6,475); larger
#: ones the kernel-polynomial estimate (within 0.24% of the range in W₁ on the shared meshes)
DENSE_MAX = 2000


def laplacian_spectrum(mesh: Mesh, kind: str = "combinatorial", k: int | None = None,
                       dense_max: int = DENSE_MAX) -> tuple[np.ndarray, np.ndarray]:
    """(normalised rank r ∈ [0, 1], eigenvalues, ascending) of L = D - A
    (``kind="combinatorial"``) or 𝓛 = I - D^{-1/2} A D^{-1/2} (``"normalized"``).

    Meshes with at most ``dense_max`` vertices (and ``k=None``) get the whole
    spectrum from a dense symmetric solver.  Larger ones get the spectrum's quantile
    function F⁻¹ at ``QUANTILE_POINTS`` ranks from the kernel polynomial method
    (:func:`~jaxmesh.stats.spectral_density`; estimated, within a fraction of a percent
    of the spectrum's range in the Wasserstein-1 distance on the shared meshes).  With
    ``k`` given, the ``k`` smallest and ``k`` largest eigenvalues, exact, from ``eigsh``
    (shift-invert just below 0 for the small end), placed at their true ranks i / (V - 1).

    Arguments:
        mesh: a single mesh (or its graph view).
        kind: ``"combinatorial"`` (L = D − A) or ``"normalized"``.
        k: exact eigenvalues from each end (forces the sparse path; None: the whole spectrum).
        dense_max: matrices up to this size use a dense symmetric eigensolver, larger ones the
            estimated density.

    Returns:
        (normalised ranks r, eigenvalues), both ascending."""
    single(mesh)
    mat, _ = laplacian_of_kind(mesh, kind)
    n = mesh.num_vertices
    rank = np.arange(n) / max(n - 1, 1)
    if k is None and n <= dense_max:
        return rank, scipy.linalg.eigh(mat.toarray(), eigvals_only=True)
    if k is None:
        ranks = np.linspace(0.0, 1.0, QUANTILE_POINTS)
        return ranks, density_quantiles(spectral_density(mesh, kind), ranks)
    k = min(k, (n - 1) // 2)
    vals = np.r_[smallest_values(mat, k, sigma=-1e-3), largest_values(mat, k, dense=False)]
    return np.r_[rank[:k], rank[n - k:]], vals
