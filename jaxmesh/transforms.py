"""Similarity transforms of the vertex positions."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ._private import lift
from .mesh import Mesh

__all__ = ["normalize", "bounding_box_center", "unit_frame", "to_frame", "from_frame", "far_vertices", "FAR_RATIO"]

#: a used vertex farther than this many times the median distance from the median position is far
FAR_RATIO = 1e4


def bounding_box_center(mesh: Mesh):
    """Centre of the axis-aligned bounding box, shape (*batch, 3).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, 3)."""
    v = mesh.vertices
    return 0.5 * (jnp.max(v, axis=-2) + jnp.min(v, axis=-2))


def unit_frame(mesh: Mesh):
    """The library's one working frame: ``(centre (*batch, 3), scale (*batch,))``
    of the bounding box of the vertices that have neighbours (isolated and
    padding vertices left out), c its centre and s its diagonal, so that
    v' = (v - c) / s has a unit diagonal.  A box of zero diagonal gets s = 1.
    Used by :func:`normalize`, the CLI and the tuner alike.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (centre (*batch, 3), scale (*batch,))."""
    v = mesh.vertices
    used = lift((mesh.degree > 0)[:, None], v.ndim)
    hi = jnp.max(jnp.where(used, v, -jnp.inf), axis=-2)
    lo = jnp.min(jnp.where(used, v, jnp.inf), axis=-2)
    diag = jnp.sqrt(jnp.sum((hi - lo) ** 2, axis=-1))
    return 0.5 * (hi + lo), jnp.where(diag > 0, diag, jnp.ones_like(diag))


def to_frame(mesh: Mesh, centre, scale) -> Mesh:
    """v' = (v - c) / s.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        centre: c, (*batch, 3).
        scale: s, (*batch,).

    Returns:
        The mesh with v' = (v − c) / s."""
    return mesh.with_vertices((mesh.vertices - centre[..., None, :]) / scale[..., None, None])


def from_frame(mesh: Mesh, centre, scale) -> Mesh:
    """v = v' s + c (the inverse of :func:`to_frame`).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        centre: c, (*batch, 3).
        scale: s, (*batch,).

    Returns:
        The mesh with v = v' s + c."""
    return mesh.with_vertices(mesh.vertices * scale[..., None, None] + centre[..., None, :])


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
    """The used vertices that lie more than ``ratio`` times the median distance d̃ from the
    median position: ‖v_i − med(v)‖ > ratio · med_j ‖v_j − med(v)‖.  Such a vertex (a corrupt
    coordinate, 1e30) sets :func:`unit_frame` alone, and the other vertices lose their
    precision in it; the command line warns about them.

    Arguments:
        mesh: a single mesh.
        ratio: the distance, in median distances, beyond which a vertex is far.

    Returns:
        The far vertices' indices, (k,) int (empty for an ordinary mesh)."""
    if mesh.batch_shape:
        raise ValueError(f"far_vertices needs a single mesh, got batch shape {mesh.batch_shape}")
    used = np.flatnonzero(np.asarray(mesh.degree) > 0)
    x = np.asarray(mesh.vertices, np.float64)[used]
    if len(x) == 0:
        return used
    d = np.linalg.norm(x - np.median(x, axis=0), axis=1)
    typical = np.median(d)
    return used[d > ratio * typical] if typical > 0 else used[:0]
