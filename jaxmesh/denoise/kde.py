"""The mesh kernel density estimate (thesis ch.2 eq.11).

    f̂(x) = (1/m) sum_i det(H)^{-1/2} (2π)^{-3/2} exp(-½ (x - v_i)^T H^{-1} (x - v_i))

with one bandwidth matrix H for the whole mesh: H = s² Σ, Σ the (unbiased) covariance
of the vertex positions.  ``scale=1`` is the thesis's literal choice (H = Σ, a
single smooth blob); the default is Scott's rule s = m^{-1/7}, which resolves
the shape.  Evaluated in chunks of points so memory stays O(chunk · m).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import det_adjugate_3x3
from ..mesh import Mesh

__all__ = ["kernel_density"]


def kernel_density(mesh: Mesh, points: Float[Array, "P 3"], scale: float | None = None,
                   chunk: int = 1024) -> Float[Array, " P"]:
    """f̂ at ``points`` (module docstring) for a single (unbatched) mesh.

    Arguments:
        mesh: a single mesh.
        points: where to evaluate, (P, 3).
        scale: the bandwidth factor s in H = s²Σ (default: Scott's rule m^{-1/7}; 1 is the thesis's).
        chunk: points evaluated at once (memory O(chunk · m)).

    Returns:
        f̂ at each point, (P,)."""
    if mesh.batch_shape:
        raise ValueError("kernel_density takes a single mesh, not a batch")
    v = mesh.vertices
    m = v.shape[0]
    s = m ** (-1 / 7) if scale is None else scale
    centred = v - jnp.mean(v, axis=0, keepdims=True)
    h = (s * s) * (centred.T @ centred) / (m - 1)
    det, adj = det_adjugate_3x3(h)
    if not bool(det > 0):
        raise ValueError("the vertices are coplanar: their covariance is singular, so eq.11 "
                         "has no 3-D density")
    inv = adj / det
    norm = (2 * jnp.pi) ** -1.5 * jax.lax.rsqrt(det)
    pts = jnp.asarray(points, v.dtype)
    p = pts.shape[0]
    pad = (-p) % chunk
    blocks = jnp.concatenate([pts, jnp.zeros((pad, 3), v.dtype)]).reshape(-1, chunk, 3)

    def block(q):
        d = q[:, None, :] - v[None, :, :]
        e = jnp.einsum("pmk,kl,pml->pm", d, inv, d)
        return norm * jnp.mean(jnp.exp(-0.5 * e), axis=1)

    return jax.lax.map(block, blocks).reshape(-1)[:p]
