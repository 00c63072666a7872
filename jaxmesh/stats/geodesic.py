"""Geodesic distances and their distribution (thesis ch.5).

* :func:`graph_distances`: Dijkstra (``scipy.sparse.csgraph``) on the mesh's
  edge graph with Euclidean edge lengths, or on the symmetrised k-nearest-
  neighbour graph of the vertices (the thesis's Isomap-style construction).
  The edge graph overestimates surface distance (paths zig-zag along edges);
  the kNN graph can underestimate it (chords cut through the volume).
* :func:`heat_geodesics`: the heat method (Crane, Weischedel & Wardetzky 2013) of
  :func:`jaxmesh.geodesics.heat_distances` (its docstring has the steps), run on the
  intrinsic Delaunay triangulation of the mesh (:mod:`jaxmesh.intrinsic`) with the
  average of the Neumann and Dirichlet solutions at boundaries.  Before, it ran on the
  mesh's own triangles with the Neumann condition and negative cotangent weights
  clamped in the heat step: against exact geodesics its mean error was 6.10 % on the
  camel head and 8.15 % on the shark (thin triangles); now 1.4 % and 3.7 %
  (``experiments/results/stats/geodesic_error.md``).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .. import sparse as jsparse
from ..geodesics import heat_components, heat_solver
from ..intrinsic import intrinsic_delaunay
from ._graph import MeshOrView, single

__all__ = ["sample_sources", "graph_distances", "heat_geodesics", "geodesic_distances", "distance_blocks",
           "DistanceHistogram", "distance_histogram", "source_block", "HISTOGRAM_BINS", "BLOCK_BUDGET"]


def sample_sources(mesh: MeshOrView, count: int, seed: int = 0) -> np.ndarray:
    """``count`` distinct vertex indices drawn uniformly with a seeded generator
    (all vertices, in order, if ``count`` >= V).

    Arguments:
        mesh: a single mesh (or its graph view).
        count: how many sources.
        seed: the generator's seed.

    Returns:
        Vertex indices, (min(count, V),)."""
    n = mesh.num_vertices
    if count >= n:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, size=count, replace=False))


def _graph(mesh: MeshOrView, graph: str, k: int) -> sp.csr_matrix:
    """The weighted graph, symmetric by construction (each edge's length both ways; the kNN
    graph symmetrised): a directed search on it is the undirected one, and scipy's
    ``directed=False`` would only symmetrise it again on every call."""
    if graph == "edges":
        return jsparse.edge_length_matrix(mesh)
    v = np.asarray(mesh.vertices, np.float64)
    if graph == "knn":
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
            raise ValueError(f"knn must be a positive int, got {k!r}")
        k = int(min(k, len(v) - 1))  # a small mesh: every other vertex
        if k < 1:
            return sp.csr_matrix((len(v), len(v)))
        dist, idx = cKDTree(v).query(v, k=k + 1)
        rows = np.repeat(np.arange(len(v)), k)
        w = sp.csr_matrix((dist[:, 1:].ravel(), (rows, idx[:, 1:].ravel())), shape=(len(v), len(v)))
        return w.maximum(w.T).tocsr()
    raise ValueError(f"graph must be 'edges' or 'knn', got {graph!r}")


def graph_distances(mesh: MeshOrView, sources, graph: str = "edges", k: int = 8) -> np.ndarray:
    """Shortest-path lengths (S, V) from ``sources`` on the edge graph or the
    kNN graph (``k`` ≥ 1 neighbours, at most V − 1); inf where unreachable.

    Arguments:
        mesh: a single mesh (or its graph view).
        sources: source vertex indices, (S,) integers.
        graph: ``"edges"`` or ``"knn"``.
        k: neighbours per vertex of the kNN graph (1 ≤ k ≤ V − 1).

    Returns:
        Distances, (S, V), inf where unreachable."""
    single(mesh)
    return csgraph.dijkstra(_graph(mesh, graph, k), directed=True, indices=np.asarray(sources))


def heat_geodesics(mesh: MeshOrView, sources, t: float | None = None, block: int = 8) -> np.ndarray:
    """Heat-method distances (S, V) from ``sources``: :func:`jaxmesh.geodesics.heat_distances`
    on the intrinsic Delaunay triangulation with the averaged boundary condition, as
    numpy; vertices unreachable from a source (another component) get inf.

    Arguments:
        mesh: a single mesh (or its graph view).
        sources: source vertex indices, (S,) integers.
        t: the diffusion time (default ℓ̄²).
        block: sources solved at once.

    Returns:
        Distances, (S, V), inf where unreachable."""
    sources = np.atleast_1d(np.asarray(sources))
    rows = [d for _, d in distance_blocks(mesh, sources, "heat", block=block, t=t)]
    return np.concatenate(rows, axis=0) if rows else np.zeros((0, mesh.num_vertices))


def distance_blocks(mesh: MeshOrView, sources, method: str = "heat", k: int = 8, block: int = 4,
                    t: float | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The distances from ``sources`` by ``method``, ``block`` sources at a time: what
    :func:`geodesic_distances` returns, as consecutive row blocks, so that a caller that
    reduces them (a histogram, a mean) never holds the whole (S, V) array.  The set-up
    (the graph, or the intrinsic triangulation and the components) is built once.

    Arguments:
        mesh: a single mesh (or its graph view).
        sources: source vertex indices, (S,) integers.
        method: ``"heat"``, ``"edges"`` or ``"knn"``.
        k: neighbours per vertex of the kNN graph (1 ≤ k ≤ V − 1).
        block: sources per block (≥ 1).
        t: the heat method's diffusion time (default ℓ̄²).

    Returns:
        An iterator of (block's sources (b,), distances (b, V) float64, inf where unreachable)."""
    single(mesh)
    if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
        raise ValueError(f"block must be a positive int, got {block!r}")
    sources = np.atleast_1d(np.asarray(sources))
    if sources.ndim != 1 or (sources.size and not np.issubdtype(sources.dtype, np.integer)):
        raise ValueError(f"sources must be a 1-D array of vertex indices, got shape {sources.shape}")
    if sources.size and (sources.min() < 0 or sources.max() >= mesh.num_vertices):
        raise ValueError(f"sources must lie in [0, {mesh.num_vertices}), got {sources}")
    sources = sources.astype(np.int64)
    if method == "heat":
        return _heat_blocks(mesh, sources, t, int(block))
    if method not in ("edges", "knn"):
        raise ValueError(f"method must be 'heat', 'edges' or 'knn', got {method!r}")
    w = _graph(mesh, method, k)
    return ((sources[lo:lo + block], csgraph.dijkstra(w, directed=True, indices=sources[lo:lo + block]))
            for lo in range(0, len(sources), block))


def _heat_blocks(mesh: MeshOrView, sources: np.ndarray, t, block: int):
    base = getattr(mesh, "mesh", mesh)                    # a GraphView carries its mesh
    if base.dtype != np.float64 and jax.config.jax_enable_x64:
        base = base.with_vertices(jnp.asarray(base.vertices, jnp.float64))
    tri = intrinsic_delaunay(base)
    adjacency = jsparse.adjacency_matrix(base)      # built once: the components and the reach probe
    _, labels = csgraph.connected_components(adjacency, directed=False)   # reachable: the source's component
    components = heat_components(base)              # once, not once a block
    if not len(sources):
        return
    solver = (_reaching_solver(base, tri, adjacency, components, int(sources[0]), block) if t is None else
              heat_solver(base, t, triangulation=tri, components=components))
    for lo in range(0, len(sources), block):
        part = sources[lo:lo + block]
        if len(part) < block and lo:                  # the last block padded: one compiled program
            padded = np.r_[part, np.full(block - len(part), part[-1])]
        else:
            padded = part
        phi = np.array(solver(padded, block=block), np.float64)[:len(part)]
        phi[labels[part][:, None] != labels[None, :]] = np.inf
        yield part, phi


def _reaching_solver(mesh, tri, adjacency, components, source: int, block: int):
    """The :func:`~jaxmesh.geodesics.heat_solver` at the default t = ℓ̄² when the heat flow from the
    ends of the mesh's longest hop paths reaches all of their component, else at t = 2 · 4^j ℓ̄²
    for the least j ≤ 8 at which it does:
    the flow decays like exp(−d/√t) and underflows in float64 a few hundred ℓ̄ from a source at
    t = ℓ̄², so on a mesh that spans more (a 556k-vertex scan) the default cannot reach across it.
    The probes are a double sweep of breadth-first searches over ``adjacency`` from ``source``
    (each the vertex farthest in hops from the last: the ends of a diameter, nearly); the factor
    2 is a margin for sources a little farther out.  A larger t gives smoother distances (Crane et al. 2013, §3.2)."""
    from ..geometry import mean_edge_length

    probes = []
    for _ in range(block):
        hops = csgraph.dijkstra(adjacency, directed=False, indices=source, unweighted=True)
        source = int(np.argmax(np.where(np.isfinite(hops), hops, -1)))
        probes.append(source)
    ell2 = float(jax.jit(mean_edge_length)(mesh)) ** 2
    for j in range(9):
        solver = heat_solver(mesh, None if j == 0 else 2.0 * 4.0 ** j * ell2, triangulation=tri,
                             components=components)
        try:
            solver(np.asarray(probes), block=block)
            return solver
        except ValueError as err:
            if "underflows" not in str(err) or mesh.dtype != np.float64:
                raise
    raise ValueError("heat_distances: the heat flow underflows even at t = 2 · 4⁸ ℓ̄²; use method='edges'")


class DistanceHistogram(NamedTuple):
    """The distribution of source-to-vertex distances (self-distances and unreachable
    pairs left out), reduced block by block (:func:`distance_histogram`).

    Attributes:
        edges: bin edges, (B + 1,): ``k · top / B``, ``top`` the smallest power of two above
            every distance, so each bin ``[edges[k], edges[k+1])`` is half-open and exact.
        counts: distances in each bin, (B,) int64.
        mean: their mean (from the float64 distances, not the bins).
        std: their standard deviation (population)."""
    edges: np.ndarray
    counts: np.ndarray
    mean: float
    std: float

    @property
    def count(self) -> int:
        """The number of distances."""
        return int(self.counts.sum())

    def density(self, bins: int = 60) -> tuple[np.ndarray, np.ndarray]:
        """At most ``bins`` bins over the occupied range, each a group of fine bins.

        Arguments:
            bins: the most bins wanted (the fine bins are merged in groups of a power of two).

        Returns:
            (edges (b + 1,), probability density (b,)), integrating to 1."""
        if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
            raise ValueError(f"bins must be a positive int, got {bins!r}")
        used = int(np.flatnonzero(self.counts)[-1]) + 1 if self.count else 1
        group = 1
        while -(-used // group) > bins and group < len(self.counts):
            group *= 2
        b = -(-used // group)
        c = self.counts.reshape(-1, group).sum(axis=1)[:b]
        e = self.edges[::group][:b + 1]
        return e, c / max(self.count, 1) / np.diff(e)


HISTOGRAM_BINS = 4096


#: :func:`distance_histogram`'s default block: the most sources, a power of two in [4, 16], whose
#: heat-method intermediates (F · block · 3 floats each) stay within ``BLOCK_BUDGET`` face-sources
BLOCK_BUDGET = 2 ** 20


def source_block(num_faces: int) -> int:
    """Sources per block for a mesh of ``num_faces`` faces: the largest power of two in [4, 16]
    with ``num_faces · block ≤ BLOCK_BUDGET`` (4 above that budget): few blocks on a small mesh
    (each block costs a few solves and program calls), bounded memory on a large one.

    Arguments:
        num_faces: F.

    Returns:
        4, 8 or 16."""
    block = 16
    while block > 4 and num_faces * block > BLOCK_BUDGET:
        block //= 2
    return block


def distance_histogram(mesh: MeshOrView, sources, method: str = "heat", k: int = 8, block: int | None = None,
                       bins: int = HISTOGRAM_BINS) -> DistanceHistogram:
    """The histogram, mean and deviation of the finite distances from ``sources`` by
    ``method`` (self-distances left out), from :func:`distance_blocks`: memory O(block · V
    + bins), never the (S, V) array.  The range doubles when a block's distance reaches it,
    merging bins in pairs, so the counts are those of one pass over the final edges.  The
    moments merge the blocks' counts, means and squared deviations (Chan, Golub & LeVeque).

    Arguments:
        mesh: a single mesh (or its graph view).
        sources: source vertex indices, (S,) integers.
        method: ``"heat"``, ``"edges"`` or ``"knn"``.
        k: neighbours per vertex of the kNN graph.
        block: sources per block (default :func:`source_block` of the mesh's faces).
        bins: fine bins, a power of two (≥ 2).

    Returns:
        A :class:`DistanceHistogram`."""
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 2 or bins & (bins - 1):
        raise ValueError(f"bins must be a power of two >= 2, got {bins!r}")
    if block is None:
        block = source_block(mesh.num_faces)
    counts, top, n, mean, m2 = np.zeros(bins, np.int64), 0.0, 0, 0.0, 0.0
    for src, d in distance_blocks(mesh, sources, method, k, block):
        keep = np.isfinite(d)
        keep[np.arange(len(src)), src] = False
        x = d[keep]
        if not x.size:
            continue
        mb = float(x.mean())
        delta, total = mb - mean, n + x.size
        mean, m2 = mean + delta * x.size / total, m2 + float(((x - mb) ** 2).sum()) + delta ** 2 * n * x.size / total
        n = total
        x = np.maximum(x, 0.0)        # the heat method's rare tiny negatives (> −0.2% of the size) in bin 0
        peak = float(x.max())
        if not top and peak:              # the first range: the power of two just above the largest distance
            top = float(2.0 ** (np.floor(np.log2(peak)) + 1))
        while top and peak >= top:        # a block beyond it: double the range, merging bins in pairs
            counts, top = np.r_[counts.reshape(-1, 2).sum(axis=1), np.zeros(bins // 2, np.int64)], top * 2
        counts += np.bincount((x * (bins / top)).astype(np.int64) if top else np.zeros(x.size, np.int64),
                              minlength=bins)
    top = top or 1.0
    return DistanceHistogram(np.arange(bins + 1) * (top / bins), counts, mean if n else float("nan"),
                             float(np.sqrt(m2 / n)) if n else float("nan"))


def geodesic_distances(mesh: MeshOrView, sources, method: str = "heat", k: int = 8) -> np.ndarray:
    """Distances (S, V) by ``method``: "heat", "edges" or "knn".

    Arguments:
        mesh: a single mesh (or its graph view).
        sources: source vertex indices, (S,) integers.
        method: ``"heat"``, ``"edges"`` or ``"knn"``.
        k: neighbours per vertex of the kNN graph (1 ≤ k ≤ V − 1).

    Returns:
        Distances, (S, V)."""
    if method == "heat":
        return heat_geodesics(mesh, sources)
    return graph_distances(mesh, sources, method, k)
