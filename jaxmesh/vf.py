"""`(V, F)` arrays in, libigl's conventions out: the bridge for code written
against libigl or gpytoolbox.

Each function takes numpy-like `V` (n, 3) floats and `F` (m, 3) vertex indices,
and returns numpy arrays or `scipy.sparse` CSR matrices in float64 with libigl's
names, signs and normalisations, so `igl.cotmatrix(V, F)` ports as
`jaxmesh.vf.cotmatrix(V, F)`.  The numbers come from the same definitions as the
differentiable :class:`~jaxmesh.Mesh` API (evaluated in float64 whatever
`jax_enable_x64` says), so a result here is the result of the JAX operator:

| here | libigl / gpytoolbox | the differentiable equivalent |
|---|---|---|
| `cotmatrix(V, F)` | `igl.cotmatrix` | `operators.cotangent_laplacian(mesh, x)` |
| `massmatrix(V, F, kind)` | `igl.massmatrix` (VORONOI, BARYCENTRIC) | `geometry.vertex_voronoi_areas`, `vertex_areas / 3` |
| `adjacency_matrix(F)` | `igl.adjacency_matrix` | `operators.neighbor_sum(mesh, x)` |
| `per_face_normals(V, F)` | `igl.per_face_normals` | `geometry.face_normals(mesh)` |
| `per_vertex_normals(V, F)` | `igl.per_vertex_normals` | `geometry.vertex_normals(mesh, weighting)` |
| `doublearea(V, F)` | `igl.doublearea` | `2 * geometry.face_areas(mesh)` |
| `boundary_loop(F)` | `igl.boundary_loop` | host topology (`topology.boundary_edges`) |

Conventions (libigl's): the cotangent matrix is L_ij = ½ (cot α_ij + cot β_ij) for an
edge ij, L_ii = -Σ_j L_ij — negative semi-definite, no mass matrix; the mass matrix is
diagonal.  Where this module differs from libigl it says so: a degenerate (zero-area)
face gets the zero normal here (libigl substitutes a fixed vector) and cotangent 0 at
its corners (the guard of :func:`jaxmesh.geometry.cotangents_of_corners`); faces with a
repeated vertex are refused (:meth:`jaxmesh.Mesh.from_arrays`), not used.

To move to the differentiable side, :func:`to_mesh` builds the :class:`~jaxmesh.Mesh`
(float64 where x64 is enabled) and `np.asarray(mesh.vertices), np.asarray(mesh.faces)`
comes back.
"""

from __future__ import annotations

import contextlib
from typing import Literal

import numpy as np
import scipy.sparse as sp

from . import geometry, sparse
from ._private import x64_context
from .graph import adjacency_from_faces
from .mesh import Mesh

__all__ = ["to_mesh", "cotmatrix", "massmatrix", "adjacency_matrix", "per_face_normals",
           "per_vertex_normals", "doublearea", "boundary_loop", "boundary_loops"]

MASS_KINDS = ("voronoi", "barycentric")
NORMAL_WEIGHTINGS = ("area", "angle", "uniform")


def to_mesh(V, F) -> Mesh:
    """The :class:`~jaxmesh.Mesh` of ``(V, F)``, validated (:meth:`Mesh.from_arrays`,
    without its warnings).

    Arguments:
        V: (n, 3) vertex positions.
        F: (m, 3) vertex indices of the triangles.

    Returns:
        The mesh, float64 when ``jax_enable_x64`` is on, else float32."""
    return Mesh.from_arrays(np.asarray(V), np.asarray(F), warn=False)


@contextlib.contextmanager
def _mesh64(V, F):
    with x64_context():
        yield Mesh.from_arrays(np.asarray(V, dtype=np.float64), np.asarray(F), dtype=np.float64, warn=False)


def _faces(F, num_vertices: int | None = None) -> tuple[np.ndarray, int]:
    f = np.asarray(F)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"F must be an (m, 3) array of triangles, got shape {f.shape}")
    if f.size and not np.issubdtype(f.dtype, np.integer):
        if not np.all(np.isfinite(f)) or np.any(f != np.round(f)):
            raise ValueError("F must hold integer vertex indices")
    f = f.astype(np.int64)
    if f.size and f.min() < 0:
        raise ValueError(f"F holds a negative vertex index ({int(f.min())})")
    n = int(f.max()) + 1 if f.size else 0
    if num_vertices is not None:
        if n > num_vertices:
            raise ValueError(f"F refers to vertex {n - 1} but num_vertices is {num_vertices}")
        n = int(num_vertices)
    return f, n


def cotmatrix(V, F) -> sp.csr_matrix:
    """The cotangent matrix L (libigl's ``cotmatrix``): L_ij = ½ (cot α_ij + cot β_ij)
    over the corners opposite edge ij, L_ii = -Σ_{j≠i} L_ij.  Negative semi-definite,
    rows sum to 0; the matrix of :func:`jaxmesh.operators.cotangent_laplacian`.

    Arguments:
        V: (n, 3) vertex positions.
        F: (m, 3) triangles.

    Returns:
        (n, n) float64 CSR matrix."""
    with _mesh64(V, F) as mesh:
        return sparse.cotangent_laplacian_matrix(mesh)


def massmatrix(V, F, kind: Literal["voronoi", "barycentric"] = "voronoi") -> sp.csr_matrix:
    """The diagonal mass matrix M (libigl's ``massmatrix``).  Both kinds sum to the
    surface area.

    Arguments:
        V: (n, 3) vertex positions.
        F: (m, 3) triangles.
        kind: ``"voronoi"`` (libigl's default, MASSMATRIX_TYPE_VORONOI): the mixed
            Voronoi area of each vertex (Meyer et al. 2003,
            :func:`jaxmesh.geometry.voronoi_areas_of_corners`); ``"barycentric"``: a
            third of the area of the faces around it.

    Returns:
        (n, n) float64 diagonal CSR matrix."""
    if kind not in MASS_KINDS:
        raise ValueError(f"kind must be one of {MASS_KINDS}, got {kind!r}")
    with _mesh64(V, F) as mesh:
        mass = geometry.vertex_voronoi_areas(mesh) if kind == "voronoi" else geometry.vertex_areas(mesh) / 3
        return sp.diags(np.asarray(mass, dtype=np.float64), format="csr")


def adjacency_matrix(F, num_vertices: int | None = None) -> sp.csr_matrix:
    """The vertex adjacency matrix (libigl's ``adjacency_matrix``): A_ij = 1 where ij
    is an edge of a face.

    Arguments:
        F: (m, 3) triangles.
        num_vertices: n (default: the largest index + 1).

    Returns:
        (n, n) int CSR matrix, symmetric, zero diagonal."""
    f, n = _faces(F, num_vertices)
    return adjacency_from_faces(f, n).astype(np.int64)


def per_face_normals(V, F) -> np.ndarray:
    """Unit face normals n_f = (v_b − v_a) × (v_c − v_a) / ‖·‖ (libigl's
    ``per_face_normals``): counter-clockwise faces face outward.

    Arguments:
        V: (n, 3) vertex positions.
        F: (m, 3) triangles.

    Returns:
        (m, 3) float64; the zero vector for a degenerate face."""
    with _mesh64(V, F) as mesh:
        return np.asarray(geometry.face_normals(mesh), dtype=np.float64)


def per_vertex_normals(V, F, weighting: Literal["area", "angle", "uniform"] = "area") -> np.ndarray:
    """Unit vertex normals (libigl's ``per_vertex_normals``): the face normals around
    each vertex, weighted, summed and normalised.

    Arguments:
        V: (n, 3) vertex positions.
        F: (m, 3) triangles.
        weighting: ``"area"`` (libigl's default), ``"angle"`` (the corner angle) or
            ``"uniform"``.

    Returns:
        (n, 3) float64; the zero vector for an isolated vertex."""
    if weighting not in NORMAL_WEIGHTINGS:
        raise ValueError(f"weighting must be one of {NORMAL_WEIGHTINGS}, got {weighting!r}")
    with _mesh64(V, F) as mesh:
        return np.asarray(geometry.vertex_normals(mesh, weighting), dtype=np.float64)


def doublearea(V, F) -> np.ndarray:
    """Twice the area of each face, ‖(v_b − v_a) × (v_c − v_a)‖ (libigl's
    ``doublearea``).

    Arguments:
        V: (n, 3) vertex positions.
        F: (m, 3) triangles.

    Returns:
        (m,) float64."""
    with _mesh64(V, F) as mesh:
        return 2 * np.asarray(geometry.face_areas(mesh), dtype=np.float64)


def boundary_loops(F) -> list[np.ndarray]:
    """Every boundary loop (libigl's ``boundary_loop_all``).

    A boundary half-edge is a face's directed edge a→b whose edge no other face uses;
    a loop follows them, so it runs in the faces' orientation.  A vertex where several
    loops touch is left by the first unused half-edge out of it.

    Arguments:
        F: (m, 3) triangles.

    Returns:
        A list of int64 arrays, each a loop's vertex indices in order, longest first."""
    f, _ = _faces(F)
    if not len(f):
        return []
    half = np.stack([f, np.roll(f, -1, axis=1)], axis=-1).reshape(-1, 2)     # a -> b, face order
    key = np.sort(half, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = half[counts[inverse.ravel()] == 1]
    out_of: dict[int, list[int]] = {}
    for a, b in boundary:
        out_of.setdefault(int(a), []).append(int(b))
    loops = []
    for start in sorted(out_of):
        while out_of.get(start):
            loop, v = [start], out_of[start].pop()
            while v != start:
                loop.append(v)
                nxt = out_of.get(v)
                if not nxt:
                    break            # an open chain (inconsistent orientation): keep what was walked
                v = nxt.pop()
            loops.append(np.asarray(loop, dtype=np.int64))
    loops.sort(key=len, reverse=True)
    return loops


def boundary_loop(F) -> np.ndarray:
    """The longest boundary loop (libigl's ``boundary_loop``); see
    :func:`boundary_loops`.

    Arguments:
        F: (m, 3) triangles.

    Returns:
        The loop's vertex indices in order (int64), or an empty array for a closed mesh."""
    loops = boundary_loops(F)
    return loops[0] if loops else np.zeros(0, np.int64)
