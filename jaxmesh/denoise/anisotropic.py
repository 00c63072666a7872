"""Vertex-based anisotropic diffusion (Zhang & Ben Hamza 2006; thesis ch.2 eq.2–5).

    x_i <- x_i + dt · sum_{j~i} φ_ij D_ij(x),   φ_ij = g(|∇x_i|) + g(|∇x_j|),
    g(s) = 1 / (1 + s²/c²)  (Cauchy weight),

``variant="paper"``: D_ij = (1/sqrt d_i)(x_j/sqrt d_j - x_i/sqrt d_i) and
|∇x_i| = (sum_j ||x_i/sqrt d_i - x_j/sqrt d_j||²)^{1/2}, exactly the thesis's
eq.2–5 (with dt = 1 it is the thesis's update; that overshoots wherever
φ ≈ 2, so the default dt is 0.25).  Like eq.7 of the kernel flow it is not
translation invariant.  ``variant="random_walk"``: D_ij = (x_j - x_i)/d_i and
|∇x_i| = (sum_j ||x_j - x_i||²)^{1/2}, translation invariant.

Scale: the thesis's c is an absolute length.  Here ``c`` is relative: the
Cauchy scale is c · (mean |∇x| over the input's connected vertices), so the method is scale free.
"""

from __future__ import annotations

from typing import Literal

import jax.numpy as jnp

from .._private import Scalar, lift, safe_divide, segment_sum_rows
from ..mesh import Mesh
from ..metrics import cauchy_weight
from ..operators import gradient_magnitude
from ._loop import iterate

__all__ = ["anisotropic_diffusion"]

_GRADIENT = {"paper": "paper", "random_walk": "translation_invariant"}


def anisotropic_diffusion(
    mesh: Mesh, dt: Scalar = 0.25, c: Scalar = 1.0, iterations: int = 10,
    variant: Literal["paper", "random_walk"] = "random_walk",
) -> Mesh:
    """``iterations`` steps of Zhang–Ben Hamza diffusion (module docstring).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        dt: the time step.
        c: the Cauchy scale, relative to the input's mean gradient magnitude.
        iterations: the number of outer iterations (a Python int: the loop is compiled once).
        variant: ``"random_walk"`` (default, translation invariant) or ``"paper"`` (the thesis's formula).

    Returns:
        The smoothed mesh."""
    if variant not in _GRADIENT:
        raise ValueError(f"variant must be one of {tuple(_GRADIENT)}, got {variant!r}")
    nd = mesh.vertices.ndim
    d = lift(mesh.degree.astype(mesh.dtype), nd - 1)
    connected = lift((mesh.degree > 0).astype(mesh.dtype), nd - 1)  # isolated and padding vertices do not count
    mean_grad = jnp.sum(gradient_magnitude(mesh, mesh.vertices, _GRADIENT[variant]) * connected,
                        axis=-1) / jnp.maximum(jnp.sum(connected), 1)
    scale = jnp.asarray(c, mesh.dtype) * mean_grad
    scale = jnp.where(scale > 0, scale, 1)[..., None]  # a mesh collapsed to a point
    dt = lift(jnp.asarray(dt, mesh.dtype)[..., None, None], nd)
    inv_sqrt = safe_divide(jnp.ones_like(d), jnp.sqrt(d))[..., None]

    def step(x):
        g = cauchy_weight(gradient_magnitude(mesh, x, _GRADIENT[variant]), scale)
        phi = (g[..., mesh.src] + g[..., mesh.dst])[..., None]
        if variant == "paper":
            y = inv_sqrt * x
            flow = inv_sqrt * segment_sum_rows(phi * (y[..., mesh.dst, :] - y[..., mesh.src, :]),
                                               mesh.src, mesh.num_vertices)
        else:
            flow = safe_divide(segment_sum_rows(phi * (x[..., mesh.dst, :] - x[..., mesh.src, :]),
                                                mesh.src, mesh.num_vertices), d[..., None])
        return x + dt * flow

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))
