"""Denoising by multivariate kernel diffusion (thesis ch.2 eq.6–12).

One iteration updates all vertices at once (Jacobi) from weights recomputed on
the current positions x:

* c_i = (1/d_i) sum_{j~i} x_j                                   (neighbourhood mean)
* H_i = sum_{j~i} (x_j - c_i)(x_j - c_i)^T + λ I                (eq.9, regularised by eq.12)
* κ_ij = det(H_i)^{-1/2} (2π)^{-3/2} exp(-½ (x_i - x_j)^T H_i^{-1} (x_i - x_j))   (eq.6, eq.8)
* ``variant="paper"`` (eq.7):  x_i += sum_{j~i} κ_ij (1/sqrt d_i)(x_j/sqrt d_j - x_i/sqrt d_i)
* ``variant="random_walk"``:    x_i += sum_{j~i} κ_ij (x_j - x_i) / d_i

The paper's update uses the normalised-Laplacian difference, which is not zero
for a constant field where neighbouring degrees differ: translating the mesh
changes the result (the origin leaks into the update).  The random-walk
variant applies the same weights κ to x_j - x_i and is translation invariant.
λ is an absolute squared length: it is meaningful only for a given scale.

Everything is a segment sum over the directed edge list; 3×3 determinants and
inverses are closed-form (adjugate), so the flow is jittable, vmappable and
differentiable with respect to λ and the positions.
"""

from __future__ import annotations

from typing import Literal

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import safe_divide, segment_sum_rows
from ..mesh import Mesh
from ..operators import neighbor_sum

__all__ = ["neighborhood_covariances", "kernel_weights", "kernel_step", "kernel_diffusion",
           "VARIANTS"]

VARIANTS = ("paper", "random_walk")


def neighborhood_covariances(
    mesh: Mesh, x: Float[Array, "*batch V 3"], lam
) -> Float[Array, "*batch V 3 3"]:
    """H_i = sum_{j~i} (x_j - c_i)(x_j - c_i)^T + λ I, c_i the neighbour mean (eq.9, eq.12)."""
    d = mesh.degree.astype(x.dtype)[:, None]
    c = safe_divide(neighbor_sum(mesh, x), d)
    diff = x[..., mesh.dst, :] - c[..., mesh.src, :]
    outer = (diff[..., :, None] * diff[..., None, :]).reshape(*diff.shape[:-1], 9)
    h = segment_sum_rows(outer, mesh.src, mesh.num_vertices).reshape(*x.shape[:-1], 3, 3)
    return h + jnp.asarray(lam, x.dtype)[..., None, None, None] * jnp.eye(3, dtype=x.dtype)


def _det_and_inverse(h: Float[Array, "... 3 3"]):
    """Closed-form determinant and inverse (adjugate / det) of 3×3 matrices."""
    a, b, c = h[..., 0, 0], h[..., 0, 1], h[..., 0, 2]
    d, e, f = h[..., 1, 0], h[..., 1, 1], h[..., 1, 2]
    g, k, i = h[..., 2, 0], h[..., 2, 1], h[..., 2, 2]
    co = jnp.stack([
        jnp.stack([e * i - f * k, c * k - b * i, b * f - c * e], -1),
        jnp.stack([f * g - d * i, a * i - c * g, c * d - a * f], -1),
        jnp.stack([d * k - e * g, b * g - a * k, a * e - b * d], -1),
    ], -2)
    det = a * co[..., 0, 0] + b * co[..., 1, 0] + c * co[..., 2, 0]
    return det, co / det[..., None, None]


def kernel_weights(mesh: Mesh, x: Float[Array, "*batch V 3"], lam):
    """(κ_ij per directed edge (*batch, H), κ_ii per vertex (*batch, V)) — the
    off-diagonal and diagonal entries of the kernel matrix 𝒦 (eq.10):
    κ_ij = det(H_i)^{-1/2} (2π)^{-3/2} exp(-½ δ^T H_i^{-1} δ), δ = x_i - x_j,
    κ_ii = det(H_i)^{-1/2} (2π)^{-3/2}."""
    det, inv = _det_and_inverse(neighborhood_covariances(mesh, x, lam))
    norm = (2 * jnp.pi) ** -1.5 * jax.lax.rsqrt(det)
    delta = x[..., mesh.src, :] - x[..., mesh.dst, :]
    q = jnp.einsum("...hk,...hkl,...hl->...h", delta, inv[..., mesh.src, :, :], delta)
    return norm[..., mesh.src] * jnp.exp(-0.5 * q), norm


def kernel_step(
    mesh: Mesh, x: Float[Array, "*batch V 3"], lam,
    variant: Literal["paper", "random_walk"] = "random_walk",
) -> Float[Array, "*batch V 3"]:
    """One Jacobi iteration of the kernel flow (see the module docstring)."""
    kappa, _ = kernel_weights(mesh, x, lam)
    d = mesh.degree.astype(x.dtype)
    if variant == "paper":
        s = safe_divide(jnp.ones_like(d), jnp.sqrt(d))[:, None]
        y = s * x
        diff = y[..., mesh.dst, :] - y[..., mesh.src, :]
        return x + s * segment_sum_rows(kappa[..., None] * diff, mesh.src, mesh.num_vertices)
    if variant == "random_walk":
        diff = x[..., mesh.dst, :] - x[..., mesh.src, :]
        return x + safe_divide(segment_sum_rows(kappa[..., None] * diff, mesh.src, mesh.num_vertices),
                               d[:, None])
    raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")


def kernel_diffusion(
    mesh: Mesh, lam, iterations: int = 5,
    variant: Literal["paper", "random_walk"] = "random_walk",
) -> Mesh:
    """Run ``iterations`` steps of the kernel flow and return the smoothed mesh.

    ``lam`` > 0 (a float or a traced scalar; one per batch element for a
    batched mesh).  ``iterations`` is a Python int: the loop is a
    ``lax.fori_loop``, so compile time does not grow with it and reverse-mode
    gradients with respect to ``lam`` and the positions are available.
    ``variant="paper"`` is eq.7 exactly; ``"random_walk"`` (default) applies
    the same κ to x_j - x_i and is translation invariant (see the module doc).
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    if not isinstance(iterations, int) or iterations < 0:
        raise ValueError(f"iterations must be a non-negative int, got {iterations!r}")
    x0 = mesh.vertices
    x = jax.lax.fori_loop(0, iterations, lambda _, x: kernel_step(mesh, x, lam, variant), x0)
    return mesh.with_vertices(x)
