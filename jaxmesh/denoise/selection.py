"""Where a denoiser may move vertices: pins, regions and the boundary.

Every method of the registry takes ``where=`` (:func:`~jaxmesh.denoise.denoise`): a
per-vertex weight w ∈ [0, 1] (or a boolean mask) that blends the method's result x with
the input y,

    x'_i = y_i + w_i (x_i − y_i),

so a vertex with w_i = 0 keeps its input position bit for bit (y + 0·(x − y) = y for a
finite x), one with w_i = 1 gets the method's, and weights in between give a smooth
transition.  The method itself runs on the whole mesh, so the vertices next to a pinned
one are smoothed as if it could move: the blend holds vertices, it does not make the
flow see them as constraints.  Differentiable in y, in w and in the method's parameters;
``jit`` and ``vmap`` take w as an array.

* :func:`region_weights` builds weights from a selection: 1 on it, falling linearly to 0
  over ``transition`` rings of edges outside it;
* :func:`pin_weights` the complement: 0 on the pinned vertices, 1 elsewhere
  (:func:`jaxmesh.geodesics.boundary_vertices` gives the boundary, ``--pin boundary``).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..mesh import Mesh

__all__ = ["hold", "region_weights", "pin_weights", "selection_mask"]


def hold(noisy: Mesh, denoised: Mesh, where) -> Mesh:
    """x' = y + w (x − y): the blend of the module docstring.

    Arguments:
        noisy: the input mesh y (single or batched).
        denoised: the method's result x (the same shape).
        where: the weights w, (V,) or broadcastable to (*batch, V); bool or float.

    Returns:
        The blended mesh."""
    y, x = noisy.vertices, denoised.vertices
    w = jnp.asarray(where).astype(y.dtype)
    if w.shape[-1:] != y.shape[-2:-1]:
        raise ValueError(f"where has shape {w.shape}; expected one weight per vertex ({y.shape[-2]},)")
    return denoised.with_vertices(y + w[..., None] * (x - y))


def selection_mask(num_vertices: int, indices) -> np.ndarray:
    """A boolean mask of the given vertex indices, each checked to be in range.

    Arguments:
        num_vertices: V.
        indices: vertex indices (any integer array-like).

    Returns:
        (V,) bool."""
    idx = np.asarray(indices)
    if idx.size and not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"vertex indices must be integers, got dtype {idx.dtype}")
    idx = idx.astype(np.int64).ravel()
    bad = idx[(idx < 0) | (idx >= num_vertices)]
    if bad.size:
        raise ValueError(f"vertex index {int(bad[0])} is out of range for a mesh of {num_vertices} vertices")
    mask = np.zeros(num_vertices, bool)
    mask[idx] = True
    return mask


def _hops(mesh: Mesh, mask: np.ndarray, limit: int) -> np.ndarray:
    """Edge hops from the masked vertices (breadth first, up to ``limit``; beyond: limit + 1)."""
    src, dst = np.asarray(mesh.src), np.asarray(mesh.dst)
    hops = np.where(mask, 0, limit + 1)
    frontier = mask.copy()
    for h in range(1, limit + 1):
        reached = np.zeros_like(frontier)
        reached[dst[frontier[src]]] = True
        frontier = reached & (hops > h)
        hops[frontier] = h
    return hops


def region_weights(mesh: Mesh, selected, transition: int = 2) -> Float[Array, " V"]:
    """w_i = max(0, 1 − h_i / (transition + 1)), h_i the number of edges from vertex i to the
    selection (0 on it): 1 on the selection, 0 beyond ``transition`` rings around it.

    Arguments:
        mesh: the mesh (its topology).
        selected: (V,) bool mask, or vertex indices.
        transition: rings of the linear fall-off (0: a hard edge).

    Returns:
        (V,) weights in the mesh's dtype."""
    if isinstance(transition, bool) or not isinstance(transition, int) or transition < 0:
        raise ValueError(f"transition must be an int >= 0, got {transition!r}")
    mask = _as_mask(mesh, selected)
    w = np.maximum(0.0, 1.0 - _hops(mesh, mask, transition) / (transition + 1))
    return jnp.asarray(w, mesh.dtype)


def pin_weights(mesh: Mesh, pinned) -> Float[Array, " V"]:
    """w = 0 on the pinned vertices, 1 elsewhere.

    Arguments:
        mesh: the mesh.
        pinned: (V,) bool mask, or vertex indices.

    Returns:
        (V,) weights in the mesh's dtype."""
    return jnp.asarray(~_as_mask(mesh, pinned), mesh.dtype)


def _as_mask(mesh: Mesh, selected) -> np.ndarray:
    a = np.asarray(selected)
    if a.dtype == bool:
        if a.shape != (mesh.num_vertices,):
            raise ValueError(f"a vertex mask needs shape ({mesh.num_vertices},), got {a.shape}")
        return a
    return selection_mask(mesh.num_vertices, a)
