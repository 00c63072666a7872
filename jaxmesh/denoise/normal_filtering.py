"""Mean and angle-median filtering of face normals followed by vertex updating
(Yagou, Ohtake & Belyaev 2002).

One outer iteration:

1. face normals n_f of the current mesh, face areas A_f;
2. ``normal_iterations`` times, each normal replaced by a filter over its ring
   N(f) (the faces sharing at least one vertex with f, f included):
   * mean:   n_f <- normalize( sum_{g∈N(f)} A_g n_g );
   * median: n_f <- the n_g, g ∈ N(f), minimising sum_{h∈N(f)} ∠(n_g, n_h)
     (Yagou's angle median: the ring normal closest to all others);
3. ``vertex_iterations`` times, every vertex moved towards the planes of its
   faces:  x_i <- x_i + (1 / sum_{f∋i} A_f) sum_{f∋i} A_f n_f (n_f · (c_f - x_i)),
   c_f the centroid of f (Yagou/Taubin vertex updating; the face normals stay fixed).

The mean over N(f) is assembled from per-vertex and per-edge segment sums
(T_f = sum_{v∈f} S_v counts edge neighbours twice and f three times, so
sum_{g∈N(f)} = T_f - sum_{e∈f} U_e + A_f n_f), fully inside jit.  The median
needs the explicit ring: :func:`face_rings` builds it on the host as a padded
(F, K) index array, once per connectivity; pass it as ``rings=`` to call the
median filter under ``jit``.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
from jaxtyping import Array, Bool, Float, Int

from .._private import safe_divide, safe_normalize, segment_sum_rows, segment_sum_scalars
from ..geometry import face_areas, face_corners, face_normals
from ..mesh import Mesh
from ._loop import check_iterations, iterate

__all__ = ["FaceRings", "face_rings", "ring_sum", "filter_normals", "update_vertices", "normal_filtering"]


class FaceRings(NamedTuple):
    """Padded vertex-sharing face neighbourhoods: ``index[f, k]`` is the k-th
    face of N(f) (f itself included) where ``mask[f, k]``; padding repeats f."""

    index: Int[Array, "F K"]
    mask: Bool[Array, "F K"]


def face_rings(mesh: Mesh) -> FaceRings:
    """N(f) for every face, built on the host (needs concrete ``mesh.faces``)."""
    try:
        faces = np.asarray(mesh.faces)
    except jax.errors.TracerArrayConversionError as err:
        raise ValueError(
            "face_rings needs the connectivity on the host: call it outside jit and pass "
            "the result as rings=") from err
    nf, nv = faces.shape[0], mesh.num_vertices
    inc = sp.csr_matrix((np.ones(3 * nf), (np.repeat(np.arange(nf), 3), faces.reshape(-1))),
                        shape=(nf, nv))
    pairs = (inc @ inc.T).tocsr()
    counts = np.diff(pairs.indptr)
    k = int(counts.max()) if nf else 1
    row = np.repeat(np.arange(nf), counts)
    col = np.arange(pairs.indices.size) - np.repeat(pairs.indptr[:-1], counts)
    index = np.repeat(np.arange(nf)[:, None], k, axis=1)
    mask = np.zeros((nf, k), bool)
    index[row, col] = pairs.indices
    mask[row, col] = True
    return FaceRings(jnp.asarray(index, jnp.int32), jnp.asarray(mask))


def ring_sum(mesh: Mesh, values: Float[Array, "*batch F d"]) -> Float[Array, "*batch F d"]:
    """sum_{g∈N(f)} values_g over the faces sharing a vertex with f (f included),
    by segment sums: T_f - sum_{e∈f} U_e + values_f (module docstring)."""
    nv, ne = mesh.num_vertices, mesh.num_edges
    per_vertex = segment_sum_rows(jnp.repeat(values, 3, axis=-2), mesh.faces.reshape(-1), nv)
    per_edge = segment_sum_rows(jnp.repeat(values, 3, axis=-2), mesh.face_edges.reshape(-1), ne)
    t = jnp.sum(per_vertex[..., mesh.faces, :], axis=-2)
    u = jnp.sum(per_edge[..., mesh.face_edges, :], axis=-2)
    return t - u + values


def filter_normals(
    mesh: Mesh, normals: Float[Array, "*batch F 3"], areas: Float[Array, "*batch F"],
    kind: Literal["mean", "median"] = "mean", rings: FaceRings | None = None,
) -> Float[Array, "*batch F 3"]:
    """One pass of the mean or angle-median filter over N(f)."""
    if kind == "mean":
        return safe_normalize(ring_sum(mesh, areas[..., None] * normals))
    if kind == "median":
        if rings is None:
            rings = face_rings(mesh)
        ring = normals[..., rings.index, :]                        # (*b, F, K, 3)
        # the choice is piecewise constant: the cost needs no gradient, so the cheap arccos
        unit = jax.lax.stop_gradient(ring)
        dots = jnp.einsum("...ka,...la->...kl", unit, unit)
        cost = jnp.arccos(jnp.clip(dots, -1, 1))                   # (*b, F, K, K)
        cost = jnp.sum(jnp.where(rings.mask[:, None, :], cost, 0), axis=-1)
        cost = jnp.where(rings.mask, cost, jnp.inf)
        best = jnp.argmin(cost, axis=-1)                           # (*b, F)
        return jnp.take_along_axis(ring, best[..., None, None], axis=-2)[..., 0, :]
    raise ValueError(f"kind must be 'mean' or 'median', got {kind!r}")


def update_vertices(
    mesh: Mesh, x: Float[Array, "*batch V 3"], normals: Float[Array, "*batch F 3"],
    areas: Float[Array, "*batch F"], iterations: int,
) -> Float[Array, "*batch V 3"]:
    """x_i <- x_i + (1/sum_f A_f) sum_{f∋i} A_f n_f (n_f · (c_f - x_i)), ``iterations`` times."""
    corners = mesh.faces.reshape(-1)
    total = segment_sum_scalars(jnp.repeat(areas, 3, axis=-1), corners, mesh.num_vertices)

    def step(x):
        c = jnp.mean(face_corners(mesh.with_vertices(x)), axis=-2)            # (*b, F, 3)
        offset = c[..., :, None, :] - x[..., mesh.faces, :]                    # (*b, F, 3, 3)
        proj = jnp.sum(offset * normals[..., :, None, :], axis=-1)             # (*b, F, 3)
        move = (areas[..., :, None] * proj)[..., None] * normals[..., :, None, :]
        flat = move.reshape(*move.shape[:-3], -1, 3)
        return x + safe_divide(segment_sum_rows(flat, corners, mesh.num_vertices), total[..., None])

    return iterate(step, x, iterations)


def normal_filtering(
    mesh: Mesh, iterations: int = 1, normal_iterations: int = 5, vertex_iterations: int = 10,
    kind: Literal["mean", "median"] = "mean", rings: FaceRings | None = None,
) -> Mesh:
    """Yagou et al. 2002 (module docstring): ``iterations`` rounds of
    (filter the face normals ``normal_iterations`` times, then
    ``vertex_iterations`` vertex updates)."""
    check_iterations(normal_iterations, "normal_iterations")
    check_iterations(vertex_iterations, "vertex_iterations")
    if kind == "median" and rings is None:
        rings = face_rings(mesh)

    def step(x):
        geo = mesh.with_vertices(x)
        n, a = face_normals(geo), face_areas(geo)
        n = iterate(lambda n: filter_normals(mesh, n, a, kind, rings), n, normal_iterations)
        return update_vertices(mesh, x, n, a, vertex_iterations)

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))
