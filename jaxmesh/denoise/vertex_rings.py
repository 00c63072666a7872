"""Vertex one-rings as padded tiers, built once on the host.

The flows that recompute per-vertex weights from the current positions (the kernel
flow) make two passes over the edges per iteration.  As segment sums over the directed
edge list each pass is a scatter; on a padded (V, k) neighbour table it is a dense
reduction along k and the per-vertex values need no gather back onto the edges.  The
table is padded to its widest row, and a few high-valence vertices would make every
row that wide (k = 11 against a mean of 6 on a subdivided scan), so the rows are split
into **tiers** by degree exactly as the guided filter's face rings are
(:func:`jaxmesh.denoise.ring_tiers` with linear work per row): each tier holds the vertices
whose degree fits its width, with their rows cut to it.

Like :func:`jaxmesh.denoise.face_graph`, :func:`vertex_rings` needs concrete connectivity;
pass its result as ``rings=`` to call a flow under ``jit`` with the mesh traced.

The sums along a tier run slot by slot in a loop, one gather of (W, 3) rows per
slot (:func:`jaxmesh._private.slot_sum`): XLA's CPU backend runs that several times
faster than a scatter-add over the edge list (``benchmarks/bench_ring_sums.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._private import lift, slot_sum
from ..mesh import Mesh, to_device
from .tiers import RING_TIERS, ring_tiers

__all__ = ["VertexTier", "VertexRings", "vertex_rings", "neighbor_table", "tiered_rings", "ring_umbrella"]


class VertexTier(NamedTuple):
    """The vertices of degree at most k: ``vertices`` (W,), their neighbours ``neighbors``
    (W, k) in the mesh's directed-edge order (padding: the vertex itself) and ``mask`` (W, k)."""

    vertices: Int[Array, " W"]
    neighbors: Int[Array, "W k"]
    mask: Bool[Array, "W k"]


class VertexRings(NamedTuple):
    """The one-rings split into tiers (module docstring): ``tiers``, and ``order`` (V,): each
    vertex's position in the tiers' vertices, concatenated (``concat[order]`` is in vertex order)."""

    tiers: tuple[VertexTier, ...]
    order: Int[Array, " V"]


def neighbor_table(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each vertex's neighbours in the mesh's directed-edge order, padded to the widest row
    (host, numpy; needs concrete connectivity).

    Arguments:
        mesh: a single mesh (one topology) with concrete (not traced) connectivity.

    Returns:
        (table (V, k) with padding the vertex itself, mask (V, k), degree (V,))."""
    if mesh.src.ndim != 1:
        raise ValueError("vertex_rings takes one topology, not a stacked batch of meshes")
    try:
        src, dst = np.asarray(mesh.src, np.int64), np.asarray(mesh.dst, np.int64)
    except jax.errors.TracerArrayConversionError as err:
        raise ValueError("vertex_rings needs the connectivity on the host: call it outside jit "
                         "and pass the result as rings=") from err
    n = mesh.num_vertices
    degree = np.bincount(src, minlength=n)
    start = np.cumsum(degree) - degree
    width = max(int(degree.max()) if n else 1, 1)
    table = np.repeat(np.arange(n)[:, None], width, axis=1)
    mask = np.zeros((n, width), bool)
    slot = np.arange(src.size) - start[src]
    table[src, slot] = dst
    mask[src, slot] = True
    return table, mask, degree


def tiered_rings(table: np.ndarray, mask: np.ndarray, groups: list[np.ndarray], widths: list[int]) -> VertexRings:
    """The :class:`VertexRings` whose tiers hold the rows ``groups[t]`` of the padded ``table`` and
    ``mask`` cut to ``widths[t]``.

    Arguments:
        table: each vertex's neighbours, padded, (V, k) (:func:`neighbor_table`).
        mask: the real entries, (V, k).
        groups: the rows of each tier; every row in exactly one.
        widths: each tier's width, at most k, at least its rows' degrees.

    Returns:
        The :class:`VertexRings`."""
    order = np.empty(table.shape[0], np.int64)
    order[np.concatenate(groups)] = np.arange(table.shape[0])
    as32 = lambda a: to_device(np.ascontiguousarray(a, dtype=np.int32))  # noqa: E731
    tiers = tuple(VertexTier(as32(g), as32(table[g, :k]), to_device(np.ascontiguousarray(mask[g, :k])))
                  for g, k in zip(groups, widths))
    return VertexRings(tiers, as32(order))


def vertex_rings(mesh: Mesh, most: int = RING_TIERS) -> VertexRings:
    """Build the :class:`VertexRings` of a single mesh (host, numpy; needs concrete connectivity).

    Arguments:
        mesh: a single mesh (one topology) with concrete (not traced) connectivity.
        most: the most tiers.

    Returns:
        Its :class:`VertexRings`."""
    table, mask, degree = neighbor_table(mesh)
    rows = np.maximum(degree, 1)                      # an isolated vertex: one masked slot
    widths = ring_tiers(rows, most, pairs=False)
    groups = [np.flatnonzero((rows > lower) & (rows <= k)) for lower, k in zip([0, *widths[:-1]], widths)]
    return tiered_rings(table, mask, groups, widths)


def rings_where_concrete(mesh: Mesh, rings: VertexRings | None) -> VertexRings | None:
    """``rings`` if given, else the mesh's own where its connectivity is concrete and one topology
    (built here), else None (the caller falls back to segment sums): the default of every flow that
    takes ``rings=``."""
    if rings is None and mesh.src.ndim == 1 and not isinstance(mesh.src, jax.core.Tracer):
        return vertex_rings(mesh)
    return rings


def ring_umbrella(rings: VertexRings, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """(K x)_i = (1/d_i) Σ_{j~i} x_j − x_i (:func:`jaxmesh.operators.umbrella`) as sums along the
    padded one-rings, one neighbour slot at a time (module docstring); 0 at isolated vertices.
    The neighbours are summed in the directed-edge order, as the segment sums do.

    Arguments:
        rings: the mesh's :class:`VertexRings`.
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d)."""
    parts = []
    for tier in rings.tiers:
        init = jnp.zeros((*x.shape[:-2], tier.vertices.shape[0], x.shape[-1]), x.dtype)
        total = slot_sum(lambda s: jnp.where(lift(s[1][:, None], x.ndim), x[..., s[0], :], 0),
                         (tier.neighbors.T, tier.mask.T), init)
        d = lift(jnp.sum(tier.mask, axis=-1)[:, None], x.ndim)
        mean = total / jnp.maximum(d, 1).astype(x.dtype)
        parts.append(jnp.where(d > 0, mean - x[..., tier.vertices, :], 0))
    return jnp.concatenate(parts, axis=-2)[..., rings.order, :]
