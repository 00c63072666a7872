"""The thesis's noise model (ch.2 eq.1): v = u + η, η ~ N(0, σ² I) per vertex."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .geometry import mean_edge_length, vertex_normals
from .mesh import Mesh

__all__ = ["add_noise"]


def _key(key):
    if isinstance(key, int):
        return jax.random.PRNGKey(key)
    return key


def add_noise(mesh: Mesh, sigma: float, key, *, along_normals: bool = False,
              relative: bool = True) -> Mesh:
    """Add Gaussian noise of standard deviation σ = sigma · ℓ̄ per coordinate
    (ℓ̄ the mean edge length of ``mesh``).

    Jittable and differentiable with respect to the vertices and ``sigma``.  A batched
    mesh gets independent noise per batch element, each scaled by its own ℓ̄.

    Arguments:
        mesh: the mesh (single or batched).
        sigma: the noise level, in mean edge lengths (in mesh units when
            ``relative=False``).
        key: a ``jax.random`` key or an int seed.
        along_normals: displace each vertex along its (area-weighted) unit normal by
            a scalar N(0, σ²) instead of isotropically in 3-D.
        relative: sigma in mean edge lengths (default) or in mesh units.

    Returns:
        The mesh with noisy vertices (same topology)."""
    v = mesh.vertices
    scale = sigma * mean_edge_length(mesh) if relative else jnp.asarray(sigma, v.dtype)
    scale = jnp.asarray(scale, v.dtype)[..., None, None]
    k = _key(key)
    if along_normals:
        n = vertex_normals(mesh, "area")
        eta = jax.random.normal(k, v.shape[:-1] + (1,), v.dtype) * n
    else:
        eta = jax.random.normal(k, v.shape, v.dtype)
    return mesh.with_vertices(v + scale * eta)
