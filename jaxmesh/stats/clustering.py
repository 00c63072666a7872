"""Clustering coefficients (thesis ch.5 eq.6–7).

* General graph definition: C(v) = t_v / (d_v (d_v - 1) / 2), t_v the number of
  edges among the neighbours of v (= triangles of the graph through v);
  0 where d_v < 2.
* The thesis's formula C(v) = 2 / (d_v - 1): exact for an interior vertex of a
  manifold mesh whose neighbours form a single cycle of d_v edges and have no
  chords (then t_v = d_v).  It differs on boundary vertices (their link is a
  path: t_v = d_v - 1), on non-manifold vertices, where chords exist (an edge
  between two neighbours that is not a face with v, e.g. in a tetrahedron),
  and it is undefined for d_v <= 1 (reported as NaN) and > 1 for d_v = 2.
* C(k): the mean of C(v) over the vertices of degree k.

Triangles are counted exactly for any graph with the degree-ordered "forward"
algorithm, vectorised: orient every edge from lower to higher (degree, index)
rank, so each vertex keeps few out-neighbours (on meshes at most a handful);
every triangle is then found exactly once as u -> v, u -> w, v -> w by
intersecting the padded out-neighbour rows of u and v.  The ordering is numpy
on the host; the intersection is one jitted XLA kernel (compiled once per
graph size).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ._graph import MeshOrView, edges_and_degree

__all__ = ["triangle_counts", "clustering", "thesis_clustering", "clustering_by_degree"]


@functools.partial(jax.jit, static_argnums=3)
def _forward_triangles(u, v, out, n: int):
    """Per vertex, the triangles u -> v, u -> w, v -> w found by intersecting the
    out-neighbour rows of u and v (fused by XLA; no (E, K, K) array is stored).
    The top vertex w = out[u, a] is credited through its slot: hits are summed per
    (u, a) with a sorted segment sum (u is grouped), then scattered once per slot."""
    ou, ov = out[u], out[v]                                            # (E, K)
    hit = jnp.any(ou[:, :, None] == ov[:, None, :], axis=-1) & (ou >= 0)
    per_edge = jnp.sum(hit, axis=1, dtype=jnp.int32)
    t = jax.ops.segment_sum(per_edge, u, n, indices_are_sorted=True)
    t = t + jax.ops.segment_sum(per_edge, v, n)
    per_slot = jax.ops.segment_sum(hit.astype(jnp.int32), u, n, indices_are_sorted=True)   # (V, K)
    tops = jnp.where(out >= 0, out, n).reshape(-1)
    return t + jax.ops.segment_sum(per_slot.reshape(-1), tops, n + 1)[:n]


def triangle_counts(mesh: MeshOrView) -> np.ndarray:
    """t_v: number of graph triangles through each vertex (exact), shape (V,).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        t_v, (V,) integers."""
    _, deg = edges_and_degree(mesh)
    n = mesh.num_vertices
    src, dst = np.asarray(mesh.src, np.int32), np.asarray(mesh.dst, np.int32)  # grouped by src
    rank = np.empty(n, np.int32)
    rank[np.argsort(deg, kind="stable")] = np.arange(n, dtype=np.int32)
    keep = rank[src] < rank[dst]                       # u -> v from lower to higher rank
    u, v = src[keep], dst[keep]                        # still grouped by u
    if len(u) == 0:
        return np.zeros(n, np.int64)
    count = np.bincount(u, minlength=n)
    start = np.cumsum(count) - count
    out = np.full((n, int(count.max())), -1, np.int32)
    out[u, np.arange(len(u)) - start[u]] = v
    return np.asarray(_forward_triangles(u, v, out, n), np.int64)


def clustering(mesh: MeshOrView) -> np.ndarray:
    """C(v) = 2 t_v / (d_v (d_v - 1)), 0 where d_v < 2 (the networkx convention).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        C(v), (V,)."""
    _, d = edges_and_degree(mesh)
    t = triangle_counts(mesh)
    den = d * (d - 1)
    return np.where(den > 0, 2 * t / np.where(den > 0, den, 1), 0.0)


def thesis_clustering(mesh: MeshOrView) -> np.ndarray:
    """C(v) = 2 / (d_v - 1) (thesis ch.5 eq.6); NaN where d_v <= 1.

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        C(v), (V,), NaN where d_v ≤ 1."""
    _, d = edges_and_degree(mesh)
    return np.where(d > 1, 2 / np.where(d > 1, d - 1, 1), np.nan)


def clustering_by_degree(mesh: MeshOrView, values: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(k, C(k)): mean clustering over the vertices of each degree k present (eq.7).

    Arguments:
        mesh: a single mesh (or its graph view).
        values: per-vertex clustering (default: :func:`clustering`).

    Returns:
        (degrees k, mean C(k))."""
    _, d = edges_and_degree(mesh)
    c = clustering(mesh) if values is None else np.asarray(values)
    ks = np.unique(d)
    return ks, np.array([np.nanmean(c[d == k]) for k in ks])
