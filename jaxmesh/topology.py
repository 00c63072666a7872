"""Discrete, host-side topology queries (numpy / scipy, not traced).

These read the integer arrays of a :class:`~jaxmesh.Mesh` and answer once:
Euler characteristic, boundary, components, manifoldness, orientation, genus.
They cannot run inside ``jax.jit`` (they need concrete arrays).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order
from scipy.sparse.csgraph import connected_components as _cc

from ._exported import stored_jit
from .mesh import Mesh, zero_area_faces
from .sparse import adjacency_matrix

__all__ = [
    "euler_characteristic",
    "edge_face_counts",
    "boundary_edges",
    "boundary_loop_count",
    "non_manifold_edges",
    "non_manifold_vertices",
    "connected_components",
    "is_consistently_oriented",
    "orientation_flips",
    "genus",
    "duplicate_vertices",
    "face_adjacency",
    "mesh_info",
]


def euler_characteristic(mesh: Mesh) -> int:
    """χ = |V| - |E| + |T| (thesis ch.1 §1.3.3).

    Arguments:
        mesh: a single mesh.

    Returns:
        χ."""
    return mesh.num_vertices - mesh.num_edges + mesh.num_faces


def edge_face_counts(mesh: Mesh) -> np.ndarray:
    """Number of faces using each undirected edge (``mesh.edges`` order).

    Arguments:
        mesh: a single mesh.

    Returns:
        (E,) int array."""
    return np.bincount(np.asarray(mesh.face_edges).ravel(), minlength=mesh.num_edges)


def boundary_edges(mesh: Mesh) -> np.ndarray:
    """(B, 2) edges used by exactly one face.

    Arguments:
        mesh: a single mesh.

    Returns:
        (B, 2) int array."""
    return np.asarray(mesh.edges)[edge_face_counts(mesh) == 1]


def non_manifold_edges(mesh: Mesh) -> np.ndarray:
    """(K, 2) edges used by more than two faces.

    Arguments:
        mesh: a single mesh.

    Returns:
        (K, 2) int array."""
    return np.asarray(mesh.edges)[edge_face_counts(mesh) > 2]


def boundary_loop_count(mesh: Mesh) -> int:
    """Number of connected chains of boundary edges (holes, for a manifold mesh).
    Loops that touch at a vertex count as one chain here; :func:`jaxmesh.vf.boundary_loops`
    walks them apart and returns each loop's vertices.

    Arguments:
        mesh: a single mesh.

    Returns:
        The count."""
    b = boundary_edges(mesh)
    if len(b) == 0:
        return 0
    used, inv = np.unique(b.ravel(), return_inverse=True)
    inv = inv.reshape(-1, 2)
    g = sp.coo_matrix((np.ones(len(b)), (inv[:, 0], inv[:, 1])), shape=(len(used),) * 2)
    return int(_cc(g, directed=False)[0])


def connected_components(mesh: Mesh) -> tuple[int, np.ndarray]:
    """(count, labels) of the vertex graph; an isolated vertex is its own component.

    Arguments:
        mesh: a single mesh.

    Returns:
        (count, labels (V,))."""
    n, labels = _cc(adjacency_matrix(mesh), directed=False)
    return int(n), labels


def non_manifold_vertices(mesh: Mesh) -> np.ndarray:
    """Indices of vertices whose incident faces do not form a single fan.

    For each vertex v the 'link' graph joins the neighbours a, b of every face
    (v, a, b); a manifold vertex (interior or boundary) has a connected link.
    Computed for all vertices at once: the nodes are the directed edges v -> a,
    and each face corner joins v -> a with v -> b.

    Arguments:
        mesh: a single mesh.

    Returns:
        Sorted vertex indices."""
    f = np.asarray(mesh.faces, dtype=np.int64)
    src, dst = np.asarray(mesh.src, np.int64), np.asarray(mesh.dst, np.int64)
    m = mesh.num_vertices
    key = src * m + dst  # sorted, because src/dst are sorted by (src, dst)
    v, a, b = f.ravel(), f[:, [1, 2, 0]].ravel(), f[:, [2, 0, 1]].ravel()
    ia = np.searchsorted(key, v * m + a)
    ib = np.searchsorted(key, v * m + b)
    h = len(src)
    g = sp.coo_matrix((np.ones(len(ia)), (ia, ib)), shape=(h, h))
    _, labels = _cc(g, directed=False)
    first = np.unique(labels, return_index=True)[1]
    pieces = np.bincount(src[first], minlength=m)
    return np.flatnonzero(pieces > 1)


def is_consistently_oriented(mesh: Mesh) -> bool:
    """True when no directed edge (a, b) is used by two faces (so every interior
    edge is traversed once in each direction).

    Arguments:
        mesh: a single mesh.

    Returns:
        A bool."""
    f = np.asarray(mesh.faces, dtype=np.int64)
    m = mesh.num_vertices
    he = (f * m + f[:, [1, 2, 0]]).ravel()
    return len(np.unique(he)) == len(he)


def orientation_flips(faces: np.ndarray, face_edges: np.ndarray, num_edges: int) -> np.ndarray:
    """Which faces to reverse so that every edge of two faces is traversed once each way
    wherever the surface allows it: the faces joined across their two-face edges form a
    graph, a breadth-first spanning forest of it fixes each face's winding relative to its
    tree's first face, and a face is reversed when the parity of the disagreeing edges on
    its tree path is odd.  On an orientable surface every two-face edge then agrees; on a
    non-orientable one (a Möbius strip) the edges off the forest where the windings cannot
    agree remain.  Non-manifold and boundary edges join nothing.

    Arguments:
        faces: (F, 3) vertex indices.
        face_edges: (F, 3) the edge opposite each corner (the numbering of ``mesh.edges``).
        num_edges: E.

    Returns:
        (F,) bool: the faces to reverse (none for a consistently oriented mesh)."""
    f, fe = np.asarray(faces, np.int64), np.asarray(face_edges, np.int64)
    nf = f.shape[0]
    edge, origin = fe[:, [2, 0, 1]].ravel(), f.ravel()        # half-edge 3i + j: corner j -> j + 1
    two = np.flatnonzero(np.bincount(edge, minlength=num_edges)[edge] == 2)
    order = two[np.argsort(edge[two], kind="stable")]
    h1, h2 = order[0::2], order[1::2]
    apart = h1 // 3 != h2 // 3
    h1, h2 = h1[apart], h2[apart]
    f1, f2, disagree = h1 // 3, h2 // 3, origin[h1] == origin[h2]
    if not disagree.any():
        return np.zeros(nf, bool)
    # a virtual root (node nf) joined to the first face of each component: one breadth-first search
    _, labels = _cc(sp.coo_matrix((np.ones(len(f1)), (f1, f2)), shape=(nf, nf)), directed=False)
    roots = np.unique(labels, return_index=True)[1]
    rows, cols = np.r_[f1, np.full(len(roots), nf)], np.r_[f2, roots]
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(nf + 1, nf + 1)).tocsr()
    _, pred = breadth_first_order(graph, nf, directed=False, return_predecessors=True)
    parent = np.where(pred[:nf] == nf, np.arange(nf), pred[:nf])
    # each face's disagreement with its parent, looked up by the unordered pair of faces
    pair = np.minimum(f1, f2) * nf + np.maximum(f1, f2)
    keys, first = np.unique(pair, return_index=True)
    child = np.minimum(np.arange(nf), parent) * nf + np.maximum(np.arange(nf), parent)
    at = np.minimum(np.searchsorted(keys, child), len(keys) - 1)
    odd = np.where((parent != np.arange(nf)) & (keys[at] == child), disagree[first][at], False)
    while (parent != parent[parent]).any():                    # pointer jumping: parity to the root
        odd, parent = odd ^ odd[parent], parent[parent]
    return odd


def genus(mesh: Mesh) -> int | None:
    """Genus g of a connected, orientable, manifold mesh from χ = 2 - 2g - b
    (b boundary loops); ``None`` where it is not defined (several components,
    non-manifold, inconsistently oriented, or isolated vertices).

    Arguments:
        mesh: a single mesh.

    Returns:
        g, or None."""
    n_comp, _ = connected_components(mesh)
    if (
        n_comp != 1
        or len(non_manifold_edges(mesh))
        or len(non_manifold_vertices(mesh))
        or not is_consistently_oriented(mesh)
    ):
        return None
    twice_g = 2 - euler_characteristic(mesh) - boundary_loop_count(mesh)
    return twice_g // 2 if twice_g >= 0 and twice_g % 2 == 0 else None


def face_adjacency(mesh: Mesh) -> np.ndarray:
    """(P, 2) pairs of faces (f < g) sharing an edge, sorted; on a non-manifold
    edge every pair of its faces is listed.  The face-neighbourhood of the
    normal-filtering methods (Yagou et al., Fleishman et al.).

    Arguments:
        mesh: a single mesh.

    Returns:
        (P, 2) int array."""
    fe = np.asarray(mesh.face_edges).ravel()
    face = np.repeat(np.arange(mesh.num_faces), 3)
    order = np.argsort(fe, kind="stable")
    fe, face = fe[order], face[order]
    starts = np.flatnonzero(np.r_[True, fe[1:] != fe[:-1]])
    counts = np.diff(np.r_[starts, len(fe)])
    pairs = [np.stack([face[starts[counts == 2]], face[starts[counts == 2] + 1]], 1)]
    for s, c in zip(starts[counts > 2], counts[counts > 2]):  # rare: non-manifold edges
        group = face[s:s + c]
        i, j = np.triu_indices(c, 1)
        pairs.append(np.stack([group[i], group[j]], 1))
    out = np.sort(np.concatenate(pairs), axis=1)
    return np.unique(out, axis=0)


def duplicate_vertices(mesh: Mesh) -> int:
    """Number of vertices whose exact position repeats an earlier vertex.

    Arguments:
        mesh: a single mesh.

    Returns:
        The count."""
    v = np.asarray(mesh.vertices)
    if v.ndim != 2:
        raise ValueError("duplicate_vertices needs a single mesh")
    return int(len(v) - len(np.unique(v, axis=0)))


@stored_jit
def _scales(mesh: Mesh):
    """(ℓ̄, bounding-box diagonal) in one compiled program (kept between processes)."""
    from .geometry import bounding_box_diagonal, mean_edge_length

    return mean_edge_length(mesh), bounding_box_diagonal(mesh)


def mesh_info(mesh: Mesh) -> dict:
    """Everything ``jaxmesh info`` prints, as a JSON-ready dict.

    Arguments:
        mesh: a single mesh.

    Returns:
        A JSON-ready dict: counts, boundary, components, χ, genus, manifoldness, orientation, mean edge length, box diagonal, degrees."""
    if mesh.batch_shape:
        raise ValueError("mesh_info needs a single mesh, not a batch")
    counts = edge_face_counts(mesh)
    n_comp, _ = connected_components(mesh)
    nm_edges = int((counts > 2).sum())
    nm_verts = len(non_manifold_vertices(mesh))
    deg = np.asarray(mesh.degree)
    faces = np.asarray(mesh.faces)
    oriented = is_consistently_oriented(mesh)
    dup_faces = len(faces) - len(np.unique(np.sort(faces, axis=1), axis=0))
    ell, diagonal = _scales(mesh)
    return {
        "vertices": mesh.num_vertices,
        "faces": mesh.num_faces,
        "edges": mesh.num_edges,
        "boundary_edges": int((counts == 1).sum()),
        "boundary_loops": boundary_loop_count(mesh),
        "components": n_comp,
        "euler_characteristic": euler_characteristic(mesh),
        "genus": genus(mesh),
        "watertight": bool((counts == 2).all()),
        "manifold": nm_edges == 0 and nm_verts == 0,
        "non_manifold_edges": nm_edges,
        "non_manifold_vertices": nm_verts,
        "consistently_oriented": oriented,
        "mean_edge_length": float(ell),
        "bbox_diagonal": float(diagonal),
        "degree_min": int(deg.min()),
        "degree_max": int(deg.max()),
        "degree_mean": float(deg.mean()),
        "isolated_vertices": int((deg == 0).sum()),
        "degenerate_faces": int(zero_area_faces(np.asarray(mesh.vertices), faces).sum()),
        "duplicate_faces": int(dup_faces),
        "duplicate_vertices": duplicate_vertices(mesh),
        "dtype": str(mesh.dtype),
    }
