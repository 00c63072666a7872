"""Host-side views of a mesh's edge graph (not public API)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..mesh import Mesh


def single(mesh: Mesh) -> None:
    if mesh.batch_shape:
        raise ValueError("mesh statistics take a single mesh, not a batch")


def edges_and_degree(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """(edges (E, 2) int64 with i < j, degree (V,) int64) on the host."""
    single(mesh)
    return np.asarray(mesh.edges, np.int64), np.asarray(mesh.degree, np.int64)


def adjacency(mesh: Mesh, weights: np.ndarray | None = None) -> sp.csr_matrix:
    """Symmetric adjacency (or weight) matrix of the edge graph, CSR."""
    e, _ = edges_and_degree(mesh)
    n = mesh.num_vertices
    w = np.ones(len(e)) if weights is None else np.asarray(weights, np.float64)
    a = sp.coo_matrix((np.r_[w, w], (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n))
    return a.tocsr()
