"""Laplacian flow and Taubin's λ|μ smoothing (Taubin 1995).

Both use the umbrella operator K x_i = (1/d_i) sum_{j~i} x_j - x_i:

* Laplacian flow:  x <- x + λ K x                       (0 < λ <= 1 keeps every
  vertex in the convex hull of itself and its neighbours; the mesh shrinks)
* Taubin λ|μ:      x <- x + λ K x, then x <- x + μ K x, μ < -λ < 0
  (a low-pass filter with pass-band frequency k_PB = 1/λ + 1/μ > 0 that does
  not shrink the low frequencies).

* HC (Vollmer, Mencl & Müller 1999; "Humphrey's classes"), a Laplacian step
  pulled back towards the original o and the previous positions q:
  p = q + K q,  b = p - (α o + (1 - α) q),  q <- p - (β b + (1 - β)(b + K b)).
  Not a thesis baseline; included because it is the strongest of the simple
  filters on the visual error (trimesh ships it as ``filter_humphrey``).

Translation and scale invariant; the parameters are dimensionless.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..mesh import Mesh
from ..operators import umbrella
from ._loop import iterate

__all__ = ["laplacian_smoothing", "taubin_smoothing", "hc_smoothing"]


def laplacian_smoothing(mesh: Mesh, lam=0.5, iterations: int = 10) -> Mesh:
    """``iterations`` explicit steps of x <- x + λ K x (umbrella flow)."""
    lam = jnp.asarray(lam, mesh.dtype)[..., None, None]
    return mesh.with_vertices(iterate(lambda x: x + lam * umbrella(mesh, x), mesh.vertices, iterations))


def taubin_smoothing(mesh: Mesh, lam=0.5, mu=-0.53, iterations: int = 10) -> Mesh:
    """``iterations`` Taubin pairs: x <- x + λ K x, then x <- x + μ K x (μ < -λ)."""
    lam = jnp.asarray(lam, mesh.dtype)[..., None, None]
    mu = jnp.asarray(mu, mesh.dtype)[..., None, None]

    def step(x):
        x = x + lam * umbrella(mesh, x)
        return x + mu * umbrella(mesh, x)

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))


def hc_smoothing(mesh: Mesh, alpha=0.1, beta=0.5, iterations: int = 10) -> Mesh:
    """``iterations`` HC-Laplacian steps (Vollmer et al. 1999; module docstring)."""
    alpha = jnp.asarray(alpha, mesh.dtype)[..., None, None]
    beta = jnp.asarray(beta, mesh.dtype)[..., None, None]
    o = mesh.vertices

    def step(q):
        p = q + umbrella(mesh, q)
        b = p - (alpha * o + (1 - alpha) * q)
        return p - (beta * b + (1 - beta) * (b + umbrella(mesh, b)))

    return mesh.with_vertices(iterate(step, o, iterations))
