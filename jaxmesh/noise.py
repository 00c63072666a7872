"""Noise models of the denoising literature, in mean edge lengths ℓ̄.

* Gaussian (thesis ch.2 eq.1): v_i = u_i + η_i, η_i ~ N(0, σ² I), or along the
  normals, v_i = u_i + ξ_i n_i, ξ_i ~ N(0, σ²).
* Impulsive (the feature-preserving filters' benchmarks: L0 minimisation, guided and
  bilateral normal filtering): each vertex is displaced with probability p, the
  rest are untouched, v_i = u_i + b_i ξ_i n_i with b_i ~ Bernoulli(p) and
  ξ_i ~ N(0, σ²) along the normal n_i.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .geometry import mean_edge_length, vertex_normals
from .mesh import Mesh
from ._private import key_argument, seed_key

__all__ = ["add_noise", "add_impulsive_noise", "IMPULSIVE_FRACTION", "IMPULSIVE_MASK_STREAM"]

#: the impulsive model's default probability that a vertex is displaced
IMPULSIVE_FRACTION = 0.5
#: folded into the key for the impulsive mask b (the displacements ξ use the key itself)
IMPULSIVE_MASK_STREAM = 1


def add_noise(mesh: Mesh, sigma: float | Float[Array, "..."], key, *, along_normals: bool = False,
              relative: bool = True, fraction: float | Float[Array, ""] = 1.0) -> Mesh:
    """Add Gaussian noise of standard deviation σ = sigma · ℓ̄ per coordinate
    (ℓ̄ the mean edge length of ``mesh``) to every vertex, or, with ``fraction``
    p < 1, to each vertex with probability p (v_i = u_i + b_i η_i,
    b_i ~ Bernoulli(p); module docstring).

    Jittable and differentiable with respect to the vertices and ``sigma``.  A batched
    mesh gets independent noise per batch element, each scaled by its own ℓ̄.  The
    displacements η do not depend on ``fraction``: the same key with p = 1 moves every
    vertex by the η that a smaller p applies to some of them.

    Arguments:
        mesh: the mesh (single or batched).
        sigma: the noise level, in mean edge lengths (in mesh units when
            ``relative=False``).
        key: a ``jax.random`` key or an int seed.
        along_normals: displace each vertex along its (area-weighted) unit normal by
            a scalar N(0, σ²) instead of isotropically in 3-D.
        relative: sigma in mean edge lengths (default) or in mesh units.
        fraction: the probability p ∈ [0, 1] that a vertex is displaced (1: every vertex).

    Returns:
        The mesh with noisy vertices (same topology)."""
    if isinstance(fraction, (int, float)) and not 0.0 <= fraction <= 1.0:
        raise ValueError(f"fraction must be in [0, 1], got {fraction!r}")
    every = isinstance(fraction, (int, float)) and fraction == 1.0
    return mesh.with_vertices(_noisy_vertices(mesh, sigma, key_argument(key), fraction, along_normals, relative, every))


# Jitted: an eager call compiles one program per shape instead of one per primitive.
@functools.partial(jax.jit, static_argnames=("along_normals", "relative", "every"))
def _noisy_vertices(mesh: Mesh, sigma, k, fraction, along_normals: bool, relative: bool, every: bool):
    v, k = mesh.vertices, seed_key(k)
    scale = sigma * mean_edge_length(mesh) if relative else jnp.asarray(sigma, v.dtype)
    scale = jnp.asarray(scale, v.dtype)[..., None, None]
    if along_normals:
        n = vertex_normals(mesh, "area")
        eta = jax.random.normal(k, v.shape[:-1] + (1,), v.dtype) * n
    else:
        eta = jax.random.normal(k, v.shape, v.dtype)
    if not every:
        u = jax.random.uniform(jax.random.fold_in(k, IMPULSIVE_MASK_STREAM), v.shape[:-1] + (1,), v.dtype)
        eta = jnp.where(u < fraction, eta, jnp.zeros_like(eta))
    return v + scale * eta


def add_impulsive_noise(mesh: Mesh, sigma: float | Float[Array, "..."], key,
                        fraction: float | Float[Array, ""] = IMPULSIVE_FRACTION, *, relative: bool = True) -> Mesh:
    """Impulsive noise (module docstring): each vertex, with probability ``fraction``,
    moved along its area-weighted normal by ξ ~ N(0, σ²), σ = sigma · ℓ̄; the others
    untouched.  ``add_noise(mesh, sigma, key, along_normals=True, fraction=fraction)``.

    Arguments:
        mesh: the mesh (single or batched).
        sigma: the displacement's standard deviation, in mean edge lengths (mesh units
            when ``relative=False``).
        key: a ``jax.random`` key or an int seed.
        fraction: the probability p that a vertex is displaced.
        relative: sigma in mean edge lengths (default) or in mesh units.

    Returns:
        The mesh with noisy vertices (same topology)."""
    return add_noise(mesh, sigma, key, along_normals=True, relative=relative, fraction=fraction)
