"""Similarity transforms of the vertex positions."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ._private import lift, one_program
from .mesh import Mesh

__all__ = ["normalize", "bounding_box_center", "unit_frame", "segment_unit_frame", "to_frame", "from_frame", "far_mask",
           "far_vertices", "FAR_RATIO", "FAR_SAMPLE"]

#: a used vertex farther than this many times the median distance from the median position is far
FAR_RATIO = 1e4
#: the medians of the far test are taken over at most this many vertices (every k-th)
FAR_SAMPLE = 1024


def bounding_box_center(mesh: Mesh):
    """Centre of the axis-aligned bounding box, shape (*batch, 3).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, 3)."""
    v = mesh.vertices
    return 0.5 * (jnp.max(v, axis=-2) + jnp.min(v, axis=-2))


def _lower_median(x, valid, xp):
    """The lower median of ``x`` (*batch, n, d) over axis -2 where ``valid`` (*batch, n, 1);
    +inf where none is (numpy or jax.numpy, as ``xp``)."""
    x = xp.sort(xp.where(valid, x, xp.inf), axis=-2)
    k = (xp.sum(valid, axis=-2, keepdims=True) - 1) // 2
    return xp.take_along_axis(x, xp.broadcast_to(xp.maximum(k, 0), x.shape[:-2] + (1, x.shape[-1])), axis=-2)


def _far(v, used, ratio: float, xp):
    """The far test, written once for numpy (host) and jax.numpy (traced) alike: v (*batch, V, 3),
    used (*batch, V, 1) -> (*batch, V).  The medians are of every k-th vertex, at most
    :data:`FAR_SAMPLE` of them (a far vertex is 10⁴ median distances out: a sample's median does)."""
    step = -(-v.shape[-2] // FAR_SAMPLE)
    sample, in_sample = v[..., ::step, :], used[..., ::step, :]
    centre = _lower_median(sample, in_sample, xp)
    d = xp.sqrt(xp.sum((v - centre) ** 2, axis=-1, keepdims=True))     # inf where the square overflows: far
    typical = _lower_median(d[..., ::step, :], in_sample, xp)
    return (used & (typical > 0) & (typical < xp.inf) & (d > ratio * typical))[..., 0]


@one_program(static_argnames=("ratio",))
def far_mask(mesh: Mesh, ratio: float = FAR_RATIO):
    """The used vertices far from the rest, (*batch, V) bool: ‖v_i − m‖ > ratio · d̃, with m
    the coordinate-wise median of the used vertices and d̃ the median of their distances to
    m, both over every k-th vertex, k = ⌈V / :data:`FAR_SAMPLE`⌉ (lower medians; no vertex is
    far when d̃ = 0).  Such a vertex (a corrupt coordinate, 1e30) would set
    a bounding box alone; :func:`unit_frame` leaves it out.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        ratio: the distance, in median distances, beyond which a vertex is far.

    Returns:
        (*batch, V) bool."""
    v = mesh.vertices
    return _far(v, lift((mesh.degree > 0)[:, None], v.ndim), ratio, jnp)


@one_program
def unit_frame(mesh: Mesh, far=None):
    """The library's one working frame: ``(centre (*batch, 3), scale (*batch,))``
    of the bounding box of the vertices that have neighbours and are not far from
    the rest (:func:`far_mask`; isolated and padding vertices left out), c its
    centre and s its diagonal, so that v' = (v - c) / s has a unit diagonal.  A box
    of zero diagonal gets s = 1.  A far vertex is mapped too, far outside the unit
    box, and the others keep their precision.  Used by :func:`normalize`, the CLI
    and the tuner alike.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        far: :func:`far_mask` of ``mesh``, when the caller has it (default: computed).

    Returns:
        (centre (*batch, 3), scale (*batch,))."""
    v = mesh.vertices
    far = far_mask(mesh) if far is None else far
    used = lift((mesh.degree > 0)[:, None], v.ndim) & ~far[..., None]
    return _box_frame(jnp.max(jnp.where(used, v, -jnp.inf), axis=-2), jnp.min(jnp.where(used, v, jnp.inf), axis=-2))


@one_program(static_argnames=("count",))
def segment_unit_frame(mesh: Mesh, far, segment, count: int):
    """:func:`unit_frame` of each mesh of a disjoint union (:func:`jaxmesh.batch.pack_batch`):
    ``(centre (count, 3), scale (count,))`` of the box of segment k's used vertices that are
    not far.  A segment with no such vertex (the padding's) gets centre 0 and scale 1.

    Arguments:
        mesh: the union (single: vertices (V, 3)).
        far: the far vertices, (V,) bool (each mesh's own :func:`far_mask`).
        segment: the mesh each vertex belongs to, (V,) ints in [0, count).
        count: the number of segments (static).

    Returns:
        (centre (count, 3), scale (count,))."""
    v = mesh.vertices
    used = ((mesh.degree > 0) & ~far)[:, None]
    hi = jax.ops.segment_max(jnp.where(used, v, -jnp.inf), segment, count)
    lo = jax.ops.segment_min(jnp.where(used, v, jnp.inf), segment, count)
    empty = jnp.any(hi < lo, axis=-1)
    return _box_frame(jnp.where(empty[:, None], 0, hi), jnp.where(empty[:, None], 0, lo))


def _box_frame(hi, lo):
    """(centre, diagonal) of the box [lo, hi] (*batch, 3), the diagonal overflow-safe and 1
    where it is 0: the frame of :func:`unit_frame` and :func:`segment_unit_frame`."""
    side = hi - lo
    diag = jnp.sqrt(jnp.sum(side ** 2, axis=-1))
    big = jnp.max(jnp.abs(side), axis=-1)
    scaled = big * jnp.sqrt(jnp.sum((side / jnp.where(big > 0, big, 1)[..., None]) ** 2, axis=-1))
    diag = jnp.where(jnp.isfinite(diag), diag, scaled)            # the plain form overflowed (float32, > 1e19)
    return 0.5 * (hi + lo), jnp.where(diag > 0, diag, jnp.ones_like(diag))


@one_program
def to_frame(mesh: Mesh, centre, scale) -> Mesh:
    """v' = (v - c) / s.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        centre: c, (*batch, 3).
        scale: s, (*batch,).

    Returns:
        The mesh with v' = (v − c) / s."""
    return mesh.with_vertices((mesh.vertices - centre[..., None, :]) / scale[..., None, None])


@one_program
def from_frame(mesh: Mesh, centre, scale) -> Mesh:
    """v = v' s + c (the inverse of :func:`to_frame`).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        centre: c, (*batch, 3).
        scale: s, (*batch,).

    Returns:
        The mesh with v = v' s + c."""
    return mesh.with_vertices(mesh.vertices * scale[..., None, None] + centre[..., None, :])


@one_program(static_argnames=("return_transform",))
def normalize(mesh: Mesh, *, return_transform: bool = False):
    """Centre the bounding box at the origin and scale its diagonal to 1:
    v' = (v - c) / s with c, s from :func:`unit_frame` (the box of the vertices that
    have neighbours; isolated vertices follow the same map).  A mesh whose vertices
    all coincide (s = 0) is only centred (s is reported as 1).

    Arguments:
        mesh: the mesh (single or batched).
        return_transform: also return c and s.

    Returns:
        The normalised mesh, or ``(mesh, c, s)`` with ``return_transform=True``, so
        that ``v = v' * s + c`` undoes it."""
    c, s = unit_frame(mesh)
    out = to_frame(mesh, c, s)
    return (out, c, s) if return_transform else out


def far_vertices(mesh: Mesh, ratio: float = FAR_RATIO) -> np.ndarray:
    """The indices of the used vertices far from the rest (:func:`far_mask`, computed on the
    host): a corrupt coordinate, which :func:`unit_frame` leaves out of the frame and the
    command line names in a warning.

    Arguments:
        mesh: a single mesh.
        ratio: the distance, in median distances, beyond which a vertex is far.

    Returns:
        The far vertices' indices, (k,) int (empty for an ordinary mesh)."""
    if mesh.batch_shape:
        raise ValueError(f"far_vertices needs a single mesh, got batch shape {mesh.batch_shape}")
    used = np.asarray(mesh.degree)[:, None] > 0
    if not used.any():
        return np.flatnonzero(used)
    with np.errstate(over="ignore", invalid="ignore"):
        return np.flatnonzero(_far(np.asarray(mesh.vertices), used, ratio, np))
