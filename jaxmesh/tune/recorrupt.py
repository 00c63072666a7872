"""The recorrupted normal-error estimate that ranks denoisers blind.

**The error.**  For a displacement field u (V, 3) and fixed unit face normals
ν_f, let

    (A u)_{f,e} = ν_f · (u_b − u_c) / ℓ̄     for the three edges e = (b, c) of f,

the tilt of face f's edges out of the plane ν_f, in radians for small u.  With
u = f(y) − x, ‖A u‖²/F approximates the mean squared face-normal angle error
(A is linear in u and does not depend on triangle shapes, unlike the
hat-function gradient, whose 1/height blows up on slivers).  ν_f are the face
normals of a pilot estimate, held fixed.

**The estimate** (recorrupted-to-recorrupted, Pang et al. 2021).  With noise
y = x + η, η ~ N(0, Σ), draw z ~ N(0, Σ) and set ŷ = y + a z, ỹ = y − z / a.
ŷ − x and ỹ − x are independent Gaussians (their covariance is Σ − Σ = 0), so

    E ‖A(f(ŷ) − ỹ)‖² = E ‖A(f(ŷ) − x)‖² + (1 + 1/a²) tr(AᵀAΣ):

the left side, computed from the noisy mesh alone, minus a known constant is
an unbiased estimate of the error of f at the noise level σ√(1 + a²), for any
denoiser f, differentiable or not.  Σ is block diagonal, split along the
vertex normals n_i: Σ_i = s_i² n_i n_iᵀ + σ_t² (I − n_i n_iᵀ), with one s_i = σ
for Gaussian noise, or each vertex's own level for impulsive noise
(:mod:`jaxmesh.tune.impulsive`).

**Antithetic draws.**  z and −z have the same law, so the draws are taken in
pairs (z_k, −z_k), each still an unbiased estimate.  To first order in z,
f(y + a z) − (y − z/a) = (f(y) − y) + (a J + I/a) z with J the Jacobian of f
at y, so one draw's estimate carries the term 2⟨A(f(y) − y), A(a J + I/a) z⟩,
of mean zero, which differs from candidate to candidate and is the largest
source of noise in their ranking; it changes sign with z, so the pair's mean
cancels it (exactly for a linear f, whose pair mean is
‖A(f(y) − y)‖² + ‖A(a W + I/a) z‖² for f(y) = W y).  What is left is the
quadratic term, a Hutchinson-type estimate of the divergence that makes the
estimate unbiased; it is even in z, so a pair holds one sample of it where two
independent draws hold two.  Pairs pay off only where the linear term dominates
the noise of the ranking; measured (the denoising guide, *Ranking on patches*),
they were no better than independent draws on the bunny's patches and worse on
the fandisk at 0.7ℓ̄, so the chooser draws independently unless asked.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._exported import stored_jit
from .._private import RECORRUPTION_STREAM, dot, library_key, lift, one_program
from ..mesh import Mesh

__all__ = ["edge_tilt", "recorruptions", "FIELD_CAPACITY"]

#: the fields are drawn in one program for the count rounded up to a multiple of this, and the first
#: ``draws`` taken: JAX's counter-based random bits make them the fields a program for ``draws`` would
#: draw, and one program serves the race's draws and the blend's
FIELD_CAPACITY = 8


@one_program
def edge_tilt(mesh: Mesh, nu: Float[Array, "F 3"], ell, u: Float[Array, "*batch V 3"]) -> Float[Array, "*batch F 3"]:
    """(A u)_{f,e} = ν_f · (u_b − u_c) / ℓ̄ for the edges (b, c) opposite each corner (module docstring).

    Arguments:
        mesh: a single mesh.
        nu: unit face normals, (F, 3).
        ell: the mean edge length ℓ̄.
        u: a displacement field, (*batch, V, 3).

    Returns:
        (*batch, F, 3)."""
    h = dot(u[..., mesh.faces, :], lift(nu[:, None, :], u.ndim + 1))                  # (*b, F, 3)
    return (h[..., [1, 2, 0]] - h[..., [2, 0, 1]]) / ell


def recorruptions(noisy: Mesh, nu, n, ell, s, s_t: float, draws: int, key, salt: int = 0,
                  antithetic: bool = False, vertices: int | None = None):
    """``draws`` fields z ~ N(0, Σ_i = s_i² n_i n_iᵀ + s_t² (I − n_i n_iᵀ)) and the trace
    tr(AᵀAΣ)/F of the module docstring (each edge difference sees its two vertices).
    With ``antithetic`` the fields are ⌈draws/2⌉ independent ones, each followed by its
    negative (module docstring), cut to ``draws``.

    Arguments:
        noisy: the noisy mesh (single).
        nu: the pilot's unit face normals, (F, 3) (a zero row: a face that does not count).
        n: the pilot's unit vertex normals, (V, 3).
        ell: the mean edge length ℓ̄.
        s: the normal noise level, one σ or each vertex's s_i, (V,).
        s_t: the noise level within the surface, per tangential axis (at most min s_i).
        draws: how many fields.
        key: the key (or int seed) of the draws.
        salt: nonzero draws an independent set.
        antithetic: draw in (z, −z) pairs.
        vertices: draw on the first ``vertices`` vertices, z = 0 on the others (the padding of
            :mod:`jaxmesh.tune.ladder`: the draws are then those of the unpadded mesh); None: all.

    Returns:
        (z (draws, V, 3), tr(AᵀAΣ)/F)."""
    k = library_key(key, RECORRUPTION_STREAM, salt)
    s_v = jnp.asarray(np.broadcast_to(np.asarray(s, dtype=np.float64), (noisy.num_vertices,)), noisy.dtype)
    real = noisy.num_vertices if vertices is None else int(vertices)
    capacity = FIELD_CAPACITY * -(-draws // FIELD_CAPACITY)
    zs = _fields(k, s_v, n, np.asarray(s_t, noisy.dtype), capacity, antithetic, real)[:draws]
    return zs, float(_trace(noisy, nu, n, s_v, np.asarray(s_t, noisy.dtype), ell))


@stored_jit(static_argnames=("draws", "antithetic", "real"))
def _fields(k, s_v, n, s_t, draws: int, antithetic: bool, real: int):
    """The fields z of :func:`recorruptions`, (draws, V, 3), in one program: drawn on the first
    ``real`` vertices, zero on the others."""
    fresh = (draws + 1) // 2 if antithetic else draws
    s_v, n, extra = s_v[:real], n[:real], s_v.shape[0] - real
    zs = s_v[None, :, None] * jax.random.normal(k, (fresh, real, 1), s_v.dtype) * n[None]
    xi = jax.random.normal(jax.random.fold_in(k, 1), (fresh, real, 3), s_v.dtype)
    zs = zs + s_t * (xi - jnp.sum(xi * n[None], axis=-1, keepdims=True) * n[None])    # + 0 exactly when s_t = 0
    if antithetic:
        zs = jnp.stack([zs, -zs], axis=1).reshape(2 * fresh, *zs.shape[1:])[:draws]   # z_0, −z_0, z_1, −z_1, …
    return jnp.pad(zs, ((0, 0), (0, extra), (0, 0)))


@stored_jit
def _trace(noisy: Mesh, nu, n, s_v, s_t, ell):
    """tr(AᵀAΣ)/F of :func:`recorruptions` (each edge difference sees its two vertices)."""
    dots = jnp.sum(nu[:, None, :] * n[noisy.faces], axis=-1) ** 2                # (F, 3)
    per_vertex = s_t**2 * jnp.sum(nu * nu, axis=-1)[:, None] + (s_v[noisy.faces] ** 2 - s_t**2) * dots  # Var(ν_f·z_v)
    return jnp.sum(per_vertex[:, [1, 2, 0]] + per_vertex[:, [2, 0, 1]]) / ell**2 / noisy.num_faces
