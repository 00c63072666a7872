"""Minimal spanning trees and the Tsallis entropy estimate (thesis 4.2.2, 4.3.2 step 1.1).

Hero et al.'s entropic spanning graphs: for n points with minimal spanning tree
length L*, the α-entropy estimate with α = 1/2 in 3-D is, as the thesis writes it,

    ξ ≈ 2 (L* / √n − 1)            (bias constant β = 1)

The Euclidean MST (over all point pairs) is a subgraph of the Delaunay
triangulation, so it is computed exactly from the Delaunay edges (scipy's Qhull)
with scipy's MST; degenerate point sets (coplanar, collinear, fewer than five)
fall back to the complete graph.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree
from scipy.spatial import Delaunay, QhullError

__all__ = ["euclidean_mst", "euclidean_mst_length", "graph_mst_length", "tsallis_entropy"]

_DENSE_MAX = 3000


def _mst_of_edges(points: np.ndarray, i: np.ndarray, j: np.ndarray) -> sp.coo_matrix:
    w = np.linalg.norm(points[i] - points[j], axis=1)
    n = len(points)
    # zero-length edges (coincident points) would vanish from a sparse matrix
    g = sp.coo_matrix((np.maximum(w, np.finfo(float).tiny), (i, j)), shape=(n, n)).tocsr()
    return minimum_spanning_tree(g).tocoo()


def _delaunay_edges(points: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    try:
        tri = Delaunay(points)
    except (QhullError, ValueError):
        return None
    if len(getattr(tri, "coplanar", ())):  # points Qhull left out of the triangulation
        return None
    s = tri.simplices
    pairs = np.concatenate([s[:, [a, b]] for a in range(4) for b in range(a + 1, 4)])
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    return pairs[:, 0], pairs[:, 1]


def euclidean_mst(points) -> tuple[np.ndarray, np.ndarray]:
    """The Euclidean minimal spanning tree of a point set (n, 3).

    Returns ``(edges (n-1, 2), lengths (n-1,))``.  Exact: the MST of the Delaunay
    graph (which contains the Euclidean MST); coincident points are merged first
    (joined by zero-length edges) and degenerate sets use the complete graph.

    Arguments:
        points: the point set, (n, 3).

    Returns:
        (edges (n−1, 2), lengths (n−1,))."""
    p = np.asarray(points, np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or infinite coordinates")
    n = len(p)
    if n < 2:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    uniq, first, inverse = np.unique(p, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    dups = np.flatnonzero(first[inverse] != np.arange(n))
    dup_edges = np.stack([first[inverse[dups]], dups], axis=1)
    edges = _delaunay_edges(uniq) if len(uniq) >= 5 else None
    if edges is None:
        if len(uniq) > _DENSE_MAX:
            raise ValueError(f"{len(uniq)} degenerate (coplanar) points: too many for the "
                             "complete-graph fallback")
        edges = np.triu_indices(len(uniq), 1)
    tree = _mst_of_edges(uniq, *edges)
    if len(uniq) > 1 and connected_components(tree, directed=False)[0] != 1:  # pragma: no cover
        raise RuntimeError("Euclidean MST is not connected")
    e = np.stack([first[tree.row], first[tree.col]], axis=1).astype(np.int64)
    e = np.concatenate([e, dup_edges.astype(np.int64)])
    lengths = np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)
    return e, lengths


def euclidean_mst_length(points) -> float:
    """L*: total length of the Euclidean minimal spanning tree of ``points``.

    Arguments:
        points: the point set, (n, 3).

    Returns:
        L*, a float."""
    return float(euclidean_mst(points)[1].sum())


def graph_mst_length(points, edges) -> float:
    """Total length of the minimal spanning forest of the graph with ``edges`` (k, 2)
    weighted by Euclidean length (the mesh-edge MST, when ``edges`` are mesh edges).

    Arguments:
        points: the positions, (n, 3).
        edges: the graph's edges, (k, 2).

    Returns:
        The forest's total length."""
    p = np.asarray(points, np.float64)
    e = np.asarray(edges, np.int64).reshape(-1, 2)
    if len(e) == 0:
        return 0.0
    return float(_mst_of_edges(p, e[:, 0], e[:, 1]).data.sum())


def tsallis_entropy(mst_length: float, n: int) -> float:
    """ξ = 2 (L* / √n − 1), the thesis's α = 1/2 Tsallis entropy estimate.

    Arguments:
        mst_length: L*.
        n: the number of points.

    Returns:
        ξ, a float."""
    if n < 1:
        raise ValueError("the entropy of an empty point set is undefined")
    return 2.0 * (mst_length / np.sqrt(n) - 1.0)
