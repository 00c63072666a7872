"""Spectral bases of a mesh graph, reproducible bit for bit (thesis ch.3 §3.2–3.3).

Two bases, both of the vertex graph (connectivity only):

* **umbrella** (the thesis): eigenvectors of K = D⁻¹A − I (eq.2).  K is similar
  to the symmetric S = D^{-1/2} A D^{-1/2} − I = −𝓛, so with 𝓛u = νu the
  eigenpairs of K are (μ = −ν, b = D^{-1/2}u), μ ∈ [−2, 0].  The basis keeps
  the r eigenvalues of smallest |μ| (SPEC ch.3 resolution), the constant first.
  The columns are D-orthonormal (BᵀDB = I), not orthonormal, hence eq.5's
  pseudo-inverse.
* **laplacian** (Karni & Gotsman 2000): eigenvectors of L = D − A with the r
  smallest eigenvalues, orthonormal.

An isolated vertex (degree 0, e.g. in a patch) is its own component: its row of
𝓛 is zero and D is taken as 1 there.

**Reproducibility.**  A decoder rebuilds the basis from the connectivity, so the
basis must not depend on the solver's whims:

* start vectors are fixed (a counter-based hash, identical on every machine and
  numpy version);
* eigenvalues closer than ``CLUSTER_RTOL`` times the spectrum's bound are one
  *cluster* (symmetric meshes have exactly repeated eigenvalues, and then any
  rotation of the eigenvectors is as valid as another).  r is extended to the
  end of a cluster it would cut, and each cluster's vectors are replaced by the
  canonical basis Q of the QR factorisation (diag R > 0) of U Uᵀ G, G fixed
  vectors: U Uᵀ is the same whatever basis the solver returned, so Q is too;
* for a single eigenvector that is its sign, fixed by uᵀg > 0.

Solvers: dense ``scipy.linalg.eigh`` (only the wanted eigenpairs) up to
``dense_max`` vertices, else ARPACK shift-invert ``eigsh`` around −0.01 (below
the spectrum, so the factorisation is definite), the inverse applied by a sparse
Cholesky factor (:mod:`jaxmesh.linalg`'s host factorization).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .._eigen import canonical, smallest

__all__ = [
    "SpectralBasis",
    "KINDS",
    "CLUSTER_RTOL",
    "graph_basis",
    "spectral_basis",
]

KINDS = ("umbrella", "laplacian")
CLUSTER_RTOL = 1e-8
_PAD = 8  # extra eigenpairs computed to see whether the last cluster goes on


@dataclass(frozen=True)
class SpectralBasis:
    """``values`` (r,): eigenvalues (umbrella: μ of K in [−2, 0], nearest 0 first;
    laplacian: λ of L, ascending); ``vectors`` (V, r): the basis B_r; ``kind``."""

    values: np.ndarray
    vectors: np.ndarray
    kind: str

    @property
    def r(self) -> int:
        return self.vectors.shape[1]


def _operator(adjacency: sp.csr_matrix, kind: str) -> tuple[sp.csr_matrix, np.ndarray, float]:
    """(symmetric M whose smallest eigenpairs we want, D (clamped to 1), bound on M's spectrum)."""
    d = np.asarray(adjacency.sum(axis=1)).ravel()
    if kind == "laplacian":
        return (sp.diags(d) - adjacency).tocsr(), d, 2.0 * max(float(d.max()), 1.0)
    if kind == "umbrella":
        dc = np.where(d > 0, d, 1.0)
        s = 1.0 / np.sqrt(dc)
        mat = sp.diags((d > 0).astype(np.float64)) - sp.diags(s) @ adjacency @ sp.diags(s)
        return mat.tocsr(), dc, 2.0
    raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")


def graph_basis(adjacency: sp.csr_matrix, r: int, kind: str = "umbrella", *,
                dense_max: int = 1200, extend_clusters: bool = True) -> SpectralBasis:
    """The r-vector basis of a graph given by its symmetric adjacency (see module doc).

    ``r`` is clipped to [1, V]; with ``extend_clusters`` it grows to the end of
    an eigenvalue cluster it would otherwise cut (the basis then has more than
    r columns), so the spanned space is well defined.

    Arguments:
        adjacency: the symmetric 0/1 vertex adjacency, (V, V) CSR.
        r: the number of basis vectors, clipped to [1, V].
        kind: ``"umbrella"`` (the thesis's K, default) or ``"laplacian"`` (Karni–Gotsman's L = D − A).
        dense_max: matrices up to this size use a dense symmetric eigensolver, larger ones ARPACK.
        extend_clusters: grow r to the end of an eigenvalue cluster it would cut.

    Returns:
        A :class:`SpectralBasis` (eigenvalues ascending, vectors (V, r') with r' ≥ r)."""
    n = adjacency.shape[0]
    if n == 0:
        raise ValueError("empty graph")
    r = int(min(max(int(r), 1), n))
    mat, d, bound = _operator(adjacency, kind)
    tol = CLUSTER_RTOL * bound
    dense = n <= dense_max
    k = min(n, r + _PAD)
    while True:
        w, u = smallest(mat, k, dense)
        end = r
        if extend_clusters:
            while end < len(w) and w[end] - w[end - 1] <= tol:
                end += 1
        if end < len(w) or len(w) == n:
            break
        k = min(n, 2 * k)  # the cluster runs past what we computed: compute more
    w, u = w[:end], u[:, :end]
    u = canonical(u, w, tol)
    if kind == "umbrella":
        return SpectralBasis(values=-w, vectors=u / np.sqrt(d)[:, None], kind=kind)
    return SpectralBasis(values=w, vectors=u, kind=kind)


def spectral_basis(mesh, r: int, kind: str = "umbrella", *, dense_max: int = 1200,
                   extend_clusters: bool = True) -> SpectralBasis:
    """:func:`graph_basis` of a :class:`~jaxmesh.Mesh`'s vertex graph (r ≥ 1 columns).

    Arguments:
        mesh: a single mesh; only its connectivity is used.
        r: the number of basis vectors, clipped to [1, V].
        kind: ``"umbrella"`` (the thesis's K, default) or ``"laplacian"`` (Karni–Gotsman's L = D − A).
        dense_max: matrices up to this size use a dense symmetric eigensolver, larger ones ARPACK.
        extend_clusters: grow r to the end of an eigenvalue cluster it would cut.

    Returns:
        A :class:`SpectralBasis` (eigenvalues ascending, vectors (V, r') with r' ≥ r)."""
    if mesh.batch_shape:
        raise ValueError(f"spectral_basis needs a single mesh, got batch shape {mesh.batch_shape}")
    from ..sparse import adjacency_matrix

    return graph_basis(adjacency_matrix(mesh), r, kind, dense_max=dense_max, extend_clusters=extend_clusters)
