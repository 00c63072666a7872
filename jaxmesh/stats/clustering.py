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
rank, so each vertex keeps few out-neighbours (on meshes at most a handful, about
three on average); every triangle is then found exactly once as u -> v, u -> w,
v -> w, as an entry w of u's out-row found in the out-row of v, another entry of
u's row.  The orientation and the padded out-rows are numpy on the host; the
search is one jitted XLA kernel (compiled once per graph); on a large graph it takes
the rows grouped by out-degree, so that a row of three out-neighbours looks up three
rows, not as many as the widest row has.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..mesh import radix_argsort, ranks_in_runs
from ._graph import MeshOrView, edges_and_degree, graph_view

__all__ = ["triangle_counts", "clustering", "thesis_clustering", "clustering_by_degree"]


#: graphs of at least this many vertices search their rows one group per out-degree (the search
#: 1.6x faster at 556k vertices; its program about 0.4 s longer to compile); smaller ones
#: as one group, as wide as the widest row
GROUPED_VERTICES = 100_000


@functools.partial(jax.jit, static_argnums=(2, 3))
def _forward_triangles(out, order, groups: tuple[tuple[int, int, int], ...], n: int):
    """t_v, for the out-rows ``out`` (V, K) (-1 padded) of an acyclic orientation.

    Each group (start, size, width) is ``size`` rows ``order[start:start + size]`` of at
    most ``width`` out-neighbours r_a.  A triangle u -> r_a -> r_b, u -> r_b is a hit
    r_b ∈ out[r_a]; it is credited to u, to r_a and to r_b."""
    t = jnp.zeros(n + 1, jnp.int32)
    for start, size, width in groups:
        rows = order[start:start + size]
        r = out[rows, :width]                                                   # (m, w)
        nb = out[jnp.maximum(r, 0)]                                             # (m, w, K): out[r_a]
        real = r >= 0
        hit = (jnp.any(r[:, None, :, None] == nb[:, :, None, :], axis=-1)
               & real[:, :, None] & real[:, None, :])                           # (m, a, b)
        t = t.at[rows].add(jnp.sum(hit, axis=(1, 2), dtype=jnp.int32))
        credit = jnp.sum(hit, axis=2, dtype=jnp.int32) + jnp.sum(hit, axis=1, dtype=jnp.int32)
        t = t.at[jnp.where(real, r, n).reshape(-1)].add(credit.reshape(-1))
    return t[:n]


def _out_rows(graph) -> tuple[np.ndarray, np.ndarray]:
    """(out-rows (V, K) int32, -1 padded, out-degrees (V,)) of the orientation from lower to
    higher (degree, index): u -> v iff (d_u, u) < (d_v, v)."""
    _, deg = edges_and_degree(graph)
    n = graph.num_vertices
    src, dst = np.asarray(graph.src, np.int32), np.asarray(graph.dst, np.int32)  # grouped by src, in order
    d = deg.astype(np.int32)
    d_src, d_dst = np.repeat(d, deg), d[dst]
    keep = (d_src < d_dst) | ((d_src == d_dst) & (src < dst))
    u, v = src[keep], dst[keep]                        # still grouped by u
    count = np.bincount(u, minlength=n)
    width = max(int(count.max(initial=0)), 1)
    out = np.full(n * width, -1, np.int32)
    out[u.astype(np.int64) * width + ranks_in_runs(count)] = v
    return out.reshape(n, width), count


def _groups(count: np.ndarray) -> tuple[np.ndarray, tuple[tuple[int, int, int], ...]]:
    """(rows by ascending out-degree, ((start, size, width), ...)): the rows of out-degree ≥ 1,
    one group per out-degree on a graph of :data:`GROUPED_VERTICES` or more, else one group."""
    order = radix_argsort(count).astype(np.int32)
    by_degree = count[order]
    present = np.flatnonzero(np.bincount(count)[1:]) + 1                # the out-degrees ≥ 1 that occur
    widths = present if len(count) >= GROUPED_VERTICES else present[-1:]
    starts = np.searchsorted(by_degree, np.r_[1, widths[:-1] + 1])
    ends = np.searchsorted(by_degree, widths, side="right")
    return order, tuple((int(a), int(b - a), int(w)) for a, b, w in zip(starts, ends, widths))


def triangle_counts(mesh: MeshOrView) -> np.ndarray:
    """t_v: number of graph triangles through each vertex (exact), shape (V,).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        t_v, (V,) integers."""
    graph = graph_view(mesh)
    out, count = _out_rows(graph)
    if not count.any():
        return np.zeros(graph.num_vertices, np.int64)
    order, groups = _groups(count)
    return np.asarray(_forward_triangles(out, order, groups, graph.num_vertices), np.int64)


def clustering(mesh: MeshOrView) -> np.ndarray:
    """C(v) = 2 t_v / (d_v (d_v - 1)), 0 where d_v < 2 (the networkx convention).

    Arguments:
        mesh: a single mesh (or its graph view).

    Returns:
        C(v), (V,)."""
    graph = graph_view(mesh)
    _, d = edges_and_degree(graph)
    t = triangle_counts(graph)
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
