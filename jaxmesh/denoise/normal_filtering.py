"""Mean and angle-median filtering of face normals followed by vertex updating
(Yagou, Ohtake & Belyaev 2002).

One outer iteration:

1. face normals n_f of the current mesh, face areas A_f;
2. ``normal_iterations`` times, each normal replaced by a filter over its ring
   N(f) (the faces sharing at least one vertex with f, f included):
   * mean:   n_f <- normalize( sum_{g∈N(f)} A_g n_g );
   * median: n_f <- the n_g, g ∈ N(f), minimising sum_{h∈N(f)} ∠(n_g, n_h)
     (Yagou's angle median: the ring normal closest to all others);
3. ``vertex_iterations`` steps of the vertex update shared by every two-step
   method (:mod:`.vertex_update`, Sun et al. 2007):
   x_i <- x_i + (1/|F_i|) sum_{f∋i} n_f (n_f · (c_f - x_i)), c_f the centroid of f
   at the current positions (the filtered normals stay fixed).  Until 2026-11 this
   module used Yagou's area-weighted form with the areas frozen at the start of
   the round; the uniform, shared update is what the two-step literature uses.

The mean over N(f) is assembled from per-vertex and per-edge segment sums
(T_f = sum_{v∈f} S_v counts edge neighbours twice and f three times, so
sum_{g∈N(f)} = T_f - sum_{e∈f} U_e + A_f n_f), fully inside jit.  The median
needs the explicit ring: :func:`~jaxmesh.denoise.face_graph` builds it on the
host as a padded (F, K) index array, once per connectivity; pass it as
``graph=`` to call the median filter under ``jit``.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._private import safe_normalize, segment_sum_rows
from ..geometry import face_areas, face_normals
from ..mesh import Mesh
from ._loop import check_iterations, iterate
from .face_graph import FaceGraph, face_graph
from .vertex_update import vertex_update

__all__ = ["FaceRings", "face_rings", "ring_sum", "filter_normals", "normal_filtering"]


class FaceRings(NamedTuple):
    """Padded vertex-sharing face neighbourhoods: ``index[f, k]`` is the k-th
    face of N(f) (f itself included) where ``mask[f, k]``; padding repeats f."""

    index: Int[Array, "F K"]
    mask: Bool[Array, "F K"]


def face_rings(mesh: Mesh) -> FaceRings:
    """N(f) for every face, built on the host (needs concrete ``mesh.faces``);
    the ring part of :func:`~jaxmesh.denoise.face_graph`.

    Arguments:
        mesh: a mesh with concrete (not traced) faces.

    Returns:
        Its :class:`FaceRings`."""
    g = face_graph(mesh)
    return FaceRings(g.ring, g.ring_mask)


def ring_sum(mesh: Mesh, values: Float[Array, "*batch F d"]) -> Float[Array, "*batch F d"]:
    """sum_{g∈N(f)} values_g over the faces sharing a vertex with f (f included),
    by segment sums: T_f - sum_{e∈f} U_e + values_f (module docstring).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        values: per-face values, (*batch, F, d).

    Returns:
        The sums, (*batch, F, d)."""
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
    """One pass of the mean or angle-median filter over N(f).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        normals: unit face normals, (*batch, F, 3).
        areas: face areas, (*batch, F).
        kind: ``"mean"`` (area-weighted mean) or ``"median"`` (angle median).
        rings: the face rings (built from ``mesh`` when None).

    Returns:
        The filtered unit normals, (*batch, F, 3)."""
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


def normal_filtering(
    mesh: Mesh, iterations: int = 1, normal_iterations: int = 5, vertex_iterations: int = 10,
    kind: Literal["mean", "median"] = "mean", graph: FaceGraph | None = None,
) -> Mesh:
    """Yagou et al. 2002 (module docstring): ``iterations`` rounds of
    (filter the face normals ``normal_iterations`` times, then
    ``vertex_iterations`` steps of the shared vertex update).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        iterations: the number of outer iterations (a Python int: the loop is compiled once).
        normal_iterations: normal-filtering passes per round.
        vertex_iterations: vertex-update steps per round.
        kind: ``"mean"`` or ``"median"``.
        graph: the face graph from :func:`~jaxmesh.denoise.face_graph` (built from ``mesh`` when None).

    Returns:
        The denoised mesh."""
    check_iterations(normal_iterations, "normal_iterations")
    check_iterations(vertex_iterations, "vertex_iterations")
    rings = None
    if kind == "median":
        graph = face_graph(mesh) if graph is None else graph
        rings = FaceRings(graph.ring, graph.ring_mask)

    def step(x):
        geo = mesh.with_vertices(x)
        n, a = face_normals(geo), face_areas(geo)
        n = iterate(lambda n: filter_normals(mesh, n, a, kind, rings), n, normal_iterations)
        return vertex_update(mesh, x, n, vertex_iterations)

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))
