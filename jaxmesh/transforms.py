"""Similarity transforms of the vertex positions."""

from __future__ import annotations

import jax.numpy as jnp

from .geometry import bounding_box_diagonal
from .mesh import Mesh

__all__ = ["normalize", "bounding_box_center"]


def bounding_box_center(mesh: Mesh):
    """Centre of the axis-aligned bounding box, shape (*batch, 3)."""
    v = mesh.vertices
    return 0.5 * (jnp.max(v, axis=-2) + jnp.min(v, axis=-2))


def normalize(mesh: Mesh, *, return_transform: bool = False):
    """Centre the bounding box at the origin and scale its diagonal to 1:
    v' = (v - c) / s with c the box centre and s its diagonal.

    With ``return_transform=True`` returns ``(mesh, c, s)`` so that
    ``v = v' * s + c`` undoes it.  A mesh whose vertices all coincide (s = 0)
    is only centred (s is reported as 1).
    """
    c = bounding_box_center(mesh)
    s = bounding_box_diagonal(mesh)
    s = jnp.where(s > 0, s, jnp.ones_like(s))
    out = mesh.with_vertices((mesh.vertices - c[..., None, :]) / s[..., None, None])
    return (out, c, s) if return_transform else out
