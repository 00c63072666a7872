"""Degree statistics (thesis ch.5 eq.1–5): average degree, degree distribution,
average neighbour connectivity and the assortativity function, and Newman's
degree assortativity coefficient."""

from __future__ import annotations

import numpy as np

from ._graph import MeshOrView, edges_and_degree

__all__ = ["average_degree", "degree_distribution", "neighbor_connectivity",
           "assortativity_function", "degree_assortativity"]


def average_degree(mesh: MeshOrView) -> float:
    """d̄ = 2|E| / m (eq.1).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        d̄, a float."""
    e, _ = edges_and_degree(mesh)
    return 2 * len(e) / mesh.num_vertices


def degree_distribution(mesh: MeshOrView) -> tuple[np.ndarray, np.ndarray]:
    """(k, p_k) for every degree k present: p_k = m_k / m (eq.2–3).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        (degrees k, p_k)."""
    _, d = edges_and_degree(mesh)
    ks, counts = np.unique(d, return_counts=True)
    return ks, counts / mesh.num_vertices


def neighbor_connectivity(mesh: MeshOrView) -> np.ndarray:
    """K_nn(v_i) = (1/d_i) sum_{j~i} d_j (eq.4); 0 for isolated vertices
    (networkx's average_neighbor_degree convention).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        K_nn(v), (V,)."""
    e, d = edges_and_degree(mesh)
    s = np.bincount(e[:, 0], d[e[:, 1]], mesh.num_vertices) + np.bincount(e[:, 1], d[e[:, 0]], mesh.num_vertices)
    return np.where(d > 0, s / np.maximum(d, 1), 0.0)


def assortativity_function(mesh: MeshOrView, knn: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(k, K_nn(k)): the mean of K_nn(v) over the vertices of degree k (eq.5).

    Arguments:
        mesh: a single mesh (or its graph view).
        knn: K_nn per vertex (default: :func:`neighbor_connectivity`).

    Returns:
        (degrees k, mean K_nn(k))."""
    _, d = edges_and_degree(mesh)
    knn = neighbor_connectivity(mesh) if knn is None else knn
    ks, inv = np.unique(d, return_inverse=True)
    return ks, np.bincount(inv, knn) / np.bincount(inv)


def degree_assortativity(mesh: MeshOrView) -> float:
    """Newman's r: the Pearson correlation of the degrees at the two ends of an
    edge, over both orientations of every edge (Newman 2002).  NaN when every
    edge joins vertices of one degree (zero variance).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        r in [−1, 1], or NaN."""
    e, d = edges_and_degree(mesh)
    m = len(e)
    if m == 0:
        return float("nan")
    # Newman's closed form over the m undirected edges, each counted in both orientations: there
    # vertex v is an end d_v times, so Σ (j + k) = Σ_v d_v² and Σ (j² + k²) = Σ_v d_v³
    df = d.astype(np.float64)
    mean = float(df @ df) / (2 * m)
    var = float((df * df) @ df) / (2 * m) - mean * mean
    cov = float(df[e[:, 0]] @ df[e[:, 1]]) / m - mean * mean
    return float(cov / var) if var > 1e-12 * mean * mean else float("nan")
