"""Face neighbourhoods for the normal-filtering denoisers, built once on the host.

The two-step denoisers (filter the face normals, then move the vertices to fit
them) need, for every face f:

* its **vertex ring** N(f): the faces that share at least one vertex with f,
  f included (the neighbourhood of bilateral and guided normal filtering, and
  the candidate patches of guided filtering);
* the **interior edges of the patch** N(f): edges whose two faces both lie in
  N(f) (the edge saliency sums of guided filtering's consistency measure);

and, for every edge with exactly two faces, those faces and the two vertices
opposite the edge (the edge-based operator of L0 denoising).

The rings are padded to the widest one, K; on meshes with a few high-valence
vertices K is two to three times the mean ring.  What is quadratic in the ring
(the largest normal difference within each patch, :mod:`.guided`) therefore runs
on the rings split into **tiers** (:class:`RingTier`): each tier holds the faces
whose rings fit its width k_t, with their rings cut to k_t.  The widths minimise
Σ_t |tier t| · k_t(k_t + 1)/2, the pairs computed, over at most ``RING_TIERS``
tiers (:func:`~jaxmesh.denoise.ring_tiers`).

All of this depends on the connectivity only, so :func:`face_graph` builds it
with numpy/scipy once per mesh, as padded integer arrays with masks (the
jittable form); pass the result as ``graph=`` to call a method under ``jit``.
Boundary and non-manifold edges (one face, or more than two) are masked out of
the edge arrays.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
from jaxtyping import Array, Bool, Float, Int

from .._private import lift, safe_divide, safe_norm
from ..mesh import Mesh, ranks_in_runs, to_device
from .tiers import ring_tiers
from .vertex_rings import VertexRings, vertex_rings

__all__ = ["FaceGraph", "RingTier", "face_graph", "face_centroids", "centroid_spacing"]


class RingTier(NamedTuple):
    """The faces whose vertex rings hold at most k entries: ``faces`` (W,), and their ``ring``
    and ``ring_mask`` cut to width k, (W, k)."""

    faces: Int[Array, " W"]
    ring: Int[Array, "W k"]
    ring_mask: Bool[Array, "W k"]


class FaceGraph(NamedTuple):
    """Padded host-built face neighbourhoods (module docstring).

    * ``ring`` (F, K), ``ring_mask`` (F, K): N(f); padding repeats f;
    * ``patch_edges`` (F, L), ``patch_edge_mask`` (F, L): interior edges of N(f)
      (indices into the edge arrays below; padding repeats a valid index);
    * ``edge_faces`` (E, 2), ``edge_apex`` (E, 2), ``edge_mask`` (E,): for each
      mesh edge (``mesh.edges`` order), its two faces and the vertex of each
      face opposite the edge; ``edge_mask`` is False for boundary and
      non-manifold edges;
    * ``tiers``: the rings split by width (:class:`RingTier`, module docstring),
      ``tier_order`` (F,): each face's position in the tiers' faces, concatenated;
    * ``vertex_corners`` (V, C): the corners 3f + k of each vertex (``faces[f, k]``),
      padding 3F (a zero row appended to per-corner values), for the vertex update's
      sums (:func:`~jaxmesh.denoise.vertex_update`);
    * ``vertex_rings``: the vertex one-rings (:func:`~jaxmesh.denoise.vertex_rings`), for
      its umbrella operator.
    """

    ring: Int[Array, "F K"]
    ring_mask: Bool[Array, "F K"]
    patch_edges: Int[Array, "F L"]
    patch_edge_mask: Bool[Array, "F L"]
    edge_faces: Int[Array, "E 2"]
    edge_apex: Int[Array, "E 2"]
    edge_mask: Bool[Array, " E"]
    tiers: tuple[RingTier, ...]
    tier_order: Int[Array, " F"]
    vertex_corners: Int[Array, "V C"]
    vertex_rings: VertexRings


def _padded_rows(mat: sp.csr_matrix, fill: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The column indices of each row of a CSR matrix as a padded (R, K) array
    (padding: ``fill[row]``) and its mask."""
    mat = mat.tocsr()
    mat.sort_indices()
    counts = np.diff(mat.indptr)
    k = max(int(counts.max()) if counts.size else 1, 1)
    rows = mat.shape[0]
    index = np.repeat(np.asarray(fill)[:, None], k, axis=1)
    mask = np.zeros((rows, k), bool)
    row = np.repeat(np.arange(rows), counts)
    col = ranks_in_runs(counts)
    index[row, col] = mat.indices
    mask[row, col] = True
    return index, mask


def _tiers(ring: np.ndarray, ring_mask: np.ndarray) -> tuple[list[tuple], np.ndarray]:
    """(faces, ring, mask) of each tier (:func:`~jaxmesh.denoise.ring_tiers`) and each face's position in
    their concatenation."""
    counts = ring_mask.sum(axis=1)
    groups, lower = [], 0
    for k in ring_tiers(counts):
        faces = np.flatnonzero((counts > lower) & (counts <= k))
        groups.append((faces, ring[faces, :k], ring_mask[faces, :k]))
        lower = k
    order = np.empty(len(ring), np.int64)
    order[np.concatenate([g[0] for g in groups])] = np.arange(len(ring))
    return groups, order


def _host_arrays(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, int]:
    try:
        faces = np.asarray(mesh.faces)
        face_edges = np.asarray(mesh.face_edges)
    except jax.errors.TracerArrayConversionError as err:
        raise ValueError(
            "face_graph needs the connectivity on the host: call jaxmesh.denoise.face_graph(mesh) "
            "outside jit and pass the result as graph=") from err
    return faces, face_edges, mesh.num_edges


def face_graph(mesh: Mesh) -> FaceGraph:
    """Build the :class:`FaceGraph` of ``mesh`` (host, numpy; needs concrete faces).

    Arguments:
        mesh: a mesh with concrete (not traced) faces.

    Returns:
        Its :class:`FaceGraph`."""
    faces, face_edges, ne = _host_arrays(mesh)
    nf, nv = faces.shape[0], mesh.num_vertices
    inc = sp.csr_matrix((np.ones(3 * nf), (np.repeat(np.arange(nf), 3), faces.reshape(-1))),
                        shape=(nf, nv))
    ring_mat = (inc @ inc.T).tocsr()
    ring, ring_mask = _padded_rows(ring_mat, np.arange(nf))

    # faces of each edge: the slots (f, k) whose opposite edge is e
    slot_edge = face_edges.reshape(-1)
    order = np.argsort(slot_edge, kind="stable")
    count = np.bincount(slot_edge, minlength=ne)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    first = order[start]
    second = order[np.minimum(start + 1, order.size - 1)]
    interior = count == 2
    second = np.where(interior, second, first)
    slots = np.stack([first, second], axis=1)                  # (E, 2) flat slot ids f*3+k
    edge_faces = slots // 3
    edge_apex = faces.reshape(-1)[slots]

    # interior edges of each patch N(j): both faces of the edge in N(j)
    ie = np.flatnonzero(interior)
    if ie.size:
        ef = sp.csr_matrix((np.ones(2 * ie.size), (edge_faces[ie].reshape(-1), np.repeat(ie, 2))),
                           shape=(nf, ne))
        both = (((ring_mat > 0).astype(np.float64)) @ ef).tocsr()
        both.data = (both.data >= 2).astype(np.float64)
        both.eliminate_zeros()
        fill = np.full(nf, ie[0])
    else:
        both = sp.csr_matrix((nf, ne))
        fill = np.zeros(nf, np.int64)
    patch_edges, patch_edge_mask = _padded_rows(both, fill)

    as32 = lambda a: to_device(np.ascontiguousarray(a, dtype=np.int32))  # noqa: E731
    groups, order = _tiers(ring, ring_mask)
    tiers = tuple(RingTier(as32(f), as32(r), to_device(np.ascontiguousarray(m))) for f, r, m in groups)
    corners = sp.csr_matrix((np.ones(3 * nf), (faces.reshape(-1), np.arange(3 * nf))), shape=(nv, 3 * nf))
    vertex_corners, _ = _padded_rows(corners, np.full(nv, 3 * nf))
    return FaceGraph(as32(ring), to_device(ring_mask), as32(patch_edges), to_device(patch_edge_mask),
                     as32(edge_faces), as32(edge_apex), to_device(np.asarray(interior)), tiers, as32(order),
                     as32(vertex_corners), vertex_rings(mesh))


def face_centroids(mesh: Mesh) -> Float[Array, "*batch F 3"]:
    """c_f = (v_a + v_b + v_c) / 3.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, F, 3)."""
    return jnp.mean(mesh.vertices[..., mesh.faces, :], axis=-2)


def centroid_spacing(graph: FaceGraph, centroids: Float[Array, "*batch F 3"]) -> Float[Array, "*batch"]:
    """Mean distance between the centroids of edge-adjacent faces: the length
    unit of the spatial kernels (Zheng et al. 2011's σ_c default).

    Arguments:
        graph: the face graph.
        centroids: face centroids, (*batch, F, 3).

    Returns:
        s̄ per mesh, (*batch)."""
    a = centroids[..., graph.edge_faces[:, 0], :]
    b = centroids[..., graph.edge_faces[:, 1], :]
    w = graph.edge_mask.astype(centroids.dtype)
    return safe_divide(jnp.sum(safe_norm(a - b) * lift(w, a.ndim - 1), axis=-1), jnp.sum(w))
