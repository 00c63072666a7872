"""Export of the mesh operators as ``scipy.sparse`` matrices (host side).

Each matrix is built from the same edge list and JAX-computed weights as the
matrix-free operators in :mod:`jaxmesh.operators`, so ``M @ x`` equals the
operator applied to ``x`` (tested).  Use these for eigensolvers
(``scipy.sparse.linalg.eigsh``) and linear solves.  Matrices are CSR, float64,
shape (V, V); they need a single (unbatched) mesh.
"""

from __future__ import annotations

import jax
import numpy as np
import scipy.sparse as sp

from . import operators as ops
from .geometry import edge_lengths
from .mesh import Mesh

__all__ = [
    "directed_matrix",
    "adjacency_matrix",
    "degree_matrix",
    "laplacian_matrix",
    "normalized_laplacian_matrix",
    "umbrella_matrix",
    "edge_length_matrix",
    "cotangent_weight_matrix",
    "cotangent_laplacian_matrix",
    "laplace_beltrami_matrix",
]

#: :func:`~jaxmesh.geometry.edge_lengths` as one compiled program (eagerly: several, each
#: compiled on first use in every process)
_edge_lengths = jax.jit(edge_lengths)


def _single(mesh: Mesh) -> None:
    if mesh.batch_shape:
        raise ValueError(f"sparse export needs a single mesh, got batch shape {mesh.batch_shape}")


def directed_matrix(mesh: Mesh, weights=None, diagonal=None) -> sp.csr_matrix:
    """M with M[src_h, dst_h] = weights[h] (directed-edge order) and ``diagonal``.

    Arguments:
        mesh: a single mesh.
        weights: the entry of each directed edge, in ``mesh.src`` order (default 1).
        diagonal: the diagonal entries, (V,) (default none).

    Returns:
        (V, V) float64 CSR matrix."""
    _single(mesh)
    m = mesh.num_vertices
    src, dst = np.asarray(mesh.src), np.asarray(mesh.dst)
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=np.float64)
    out = sp.csr_matrix((w, (src, dst)), shape=(m, m))
    if diagonal is not None:
        out = out + sp.diags(np.asarray(diagonal, dtype=np.float64), format="csr")
    return out.tocsr()


def adjacency_matrix(mesh: Mesh) -> sp.csr_matrix:
    """A: a_ij = 1 if j ~ i, else 0.

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    return directed_matrix(mesh)


def degree_matrix(mesh: Mesh) -> sp.csr_matrix:
    """D = diag(d_i).

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    _single(mesh)
    return sp.diags(np.asarray(mesh.degree, dtype=np.float64), format="csr")


def laplacian_matrix(mesh: Mesh) -> sp.csr_matrix:
    """L = D - A (thesis ch.1 eq.6).

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    return directed_matrix(mesh, -np.ones(2 * mesh.num_edges), np.asarray(mesh.degree))


def normalized_laplacian_matrix(mesh: Mesh) -> sp.csr_matrix:
    """𝓛 = I - D^{-1/2} A D^{-1/2} (thesis ch.1 eq.7); 𝓛_ii = 0 for isolated vertices.

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    d = np.asarray(mesh.degree, dtype=np.float64)
    w = -1.0 / np.sqrt(d[np.asarray(mesh.src)] * d[np.asarray(mesh.dst)])
    return directed_matrix(mesh, w, (d > 0).astype(np.float64))


def umbrella_matrix(mesh: Mesh) -> sp.csr_matrix:
    """K = D^{-1} A - I (thesis ch.3 eq.2); rows of isolated vertices are 0.

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    d = np.asarray(mesh.degree, dtype=np.float64)
    w = 1.0 / d[np.asarray(mesh.src)]
    return directed_matrix(mesh, w, -(d > 0).astype(np.float64))


def edge_length_matrix(mesh: Mesh) -> sp.csr_matrix:
    """E with e_ij = ||v_i - v_j|| for j ~ i (thesis ch.1 eq.5).

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    _single(mesh)
    lengths = np.asarray(_edge_lengths(mesh), dtype=np.float64)
    return directed_matrix(mesh, lengths[np.asarray(mesh.edge_of)])


def cotangent_weight_matrix(mesh: Mesh) -> sp.csr_matrix:
    """W_c with W_ij = cot α_ij + cot β_ij (symmetric, zero diagonal).

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    _single(mesh)
    c = np.asarray(ops.cotangent_weights(mesh), dtype=np.float64)
    return directed_matrix(mesh, c[np.asarray(mesh.edge_of)])


def cotangent_laplacian_matrix(mesh: Mesh) -> sp.csr_matrix:
    """L_c = (1/2)(W_c - diag(W_c 1)): matrix of :func:`jaxmesh.operators.cotangent_laplacian`.

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    w = 0.5 * cotangent_weight_matrix(mesh)
    return (w - sp.diags(np.asarray(w.sum(axis=1)).ravel())).tocsr()


def laplace_beltrami_matrix(mesh: Mesh) -> sp.csr_matrix:
    """L = D - W, w_ij = 3 (cot α_ij + cot β_ij) / η_i, D_ii = sum_j w_ij
    (thesis ch.4 eq.2).  Not symmetric.  L x = -Δ_m x.

    Arguments:
        mesh: a single mesh.

    Returns:
        (V, V) float64 CSR matrix."""
    _single(mesh)
    w = np.asarray(ops.laplace_beltrami_weights(mesh), dtype=np.float64)
    wm = directed_matrix(mesh, w)
    return (sp.diags(np.asarray(wm.sum(axis=1)).ravel()) - wm).tocsr()
