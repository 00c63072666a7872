"""The host-side (numpy / scipy) vertex graph of a triangle mesh: one definition of
the adjacency, METIS labels and induced sub-meshes that the codec, the hashes and
the statistics share.

Everything here runs once per mesh on the host, outside JAX: it builds topology,
which does not flow.  The JAX operators use the mesh's own edge arrays
(``mesh.src``, ``mesh.dst``); :mod:`jaxmesh.sparse` gives the same operators as
scipy matrices.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["adjacency_from_faces", "metis_labels", "submesh"]


def adjacency_from_faces(faces: np.ndarray, num_vertices: int) -> sp.csr_matrix:
    """Symmetric 0/1 vertex adjacency A (V, V) of a triangle list: A_ij = 1 iff
    i ≠ j share an edge of some face.

    Arguments:
        faces: triangles, (F, 3) integer vertex indices.
        num_vertices: the vertex count V (isolated vertices included).

    Returns:
        A, (V, V) CSR with 0/1 entries."""
    f = np.asarray(faces, np.int64)
    a = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    b = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    a, b = a[a != b], b[a != b]                  # a face with a repeated index has no edge from a vertex to itself
    adj = sp.csr_matrix((np.ones(2 * len(a)), (np.r_[a, b], np.r_[b, a])), shape=(num_vertices,) * 2)
    adj.data[:] = 1.0
    return adj


def metis_labels(xadj: np.ndarray, adjncy: np.ndarray, parts: int, seed: int = 0) -> np.ndarray:
    """METIS's k-way labels (V,) for a graph in CSR form (``xadj``, ``adjncy``), fixed
    seed (Karypis & Kumar, through ``pymetis``): deterministic for a given graph in a
    given vertex order; the label values themselves are arbitrary.

    Arguments:
        xadj: CSR row pointers, (V + 1,).
        adjncy: CSR column indices.
        parts: the number of parts k.
        seed: METIS's seed.

    Returns:
        Labels (V,) in 0..k−1."""
    import pymetis   # imported here: only the codec's patches and the hashes need METIS

    adjacency = pymetis.CSRAdjacency(np.asarray(xadj, np.int32), np.asarray(adjncy, np.int32))
    _, labels = pymetis.part_graph(int(parts), adjacency=adjacency, options=pymetis.Options(seed=int(seed)))
    return np.asarray(labels, np.int64)


def submesh(vertices: np.ndarray, faces: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The faces whose three vertices all satisfy ``keep`` (bool, V), re-indexed.

    Returns ``(vertices_k, faces_k, index)`` with ``vertices_k = vertices[index]``;
    vertices of ``keep`` that lie on no kept face are left out.

    Arguments:
        vertices: positions, (V, 3).
        faces: triangles, (F, 3) integer vertex indices.
        keep: which vertices may stay, (V,) bool.

    Returns:
        ``(vertices_k, faces_k, index)``."""
    inside = keep[faces].all(axis=1)
    fk = faces[inside]
    index = np.unique(fk)
    remap = np.full(len(vertices), -1, np.int64)
    remap[index] = np.arange(len(index))
    return vertices[index], remap[fk], index
