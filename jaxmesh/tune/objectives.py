"""What the tuner minimises: the error against a clean mesh (supervised), or an
unbiased estimate of it from the noisy mesh alone (blind, Stein's unbiased risk
estimate).  Everything here is pure JAX and differentiable in the denoiser's
parameters.

SURE for the visual error.  With y = x + η, η ~ N(0, σ²I), a weakly
differentiable denoiser f and a linear operator A, Stein's lemma
E⟨A f(y), A η⟩ = σ² E tr(AᵀA J_f(y)) gives

    E ‖A(f(y) − x)‖² = E[ ‖A(f(y) − y)‖² + 2σ² tr(AᵀA J_f) − σ² tr(AᵀA) ].

The visual error (thesis ch.2 eq.13) is E = (1/2m)(‖f − x‖² + ‖K(f − x)‖²), the
sum of the cases A = I and A = K (K the umbrella operator), so with
M = I + KᵀK

    SURE = (1/2m) [ ‖f − y‖² + ‖K(f − y)‖² + 2σ² tr(M J_f) − σ² tr(M) ],

unbiased for E(f(y), x).  tr(M) is exact from the degrees
(‖row_i K‖² = 1 + 1/d_i); tr(M J_f) is Hutchinson's estimate
mean_z [ zᵀJ_f z + (Kz)ᵀ(K J_f z) ] over fixed Rademacher probes z, with J_f z
a Jacobian–vector product through the whole flow (``jax.linearize``).  With
the probes fixed, SURE is a smooth deterministic function of the parameters.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import safe_divide
from ..mesh import Mesh
from ..metrics import mean_normal_angle_error, nonlinear_visual_error, visual_error
from ..operators import umbrella

__all__ = ["OBJECTIVES", "relative_error", "sure_visual_error", "noisy_visual_error_expectation",
           "rademacher_probes"]

OBJECTIVES = ("visual", "nonlinear", "normal")


def _error(objective: str, clean: Mesh, estimate) -> Array:
    if objective == "visual":
        return visual_error(clean, estimate)
    if objective == "nonlinear":   # the translation-invariant form: the paper's leaks the origin
        return nonlinear_visual_error(clean, estimate, variant="translation_invariant")
    if objective == "normal":
        return mean_normal_angle_error(clean, estimate)
    raise ValueError(f"objective must be one of {OBJECTIVES}, got {objective!r}")


def relative_error(objective: str, clean: Mesh, noisy: Mesh, estimate) -> Array:
    """error(clean, estimate) / error(clean, noisy): 1 means no better than the
    input.  Dimensionless, so the same number for any units of the mesh.

    Arguments:
        objective: ``"visual"``, ``"nonlinear"`` or ``"normal"`` (:data:`OBJECTIVES`).
        clean: the reference.
        noisy: the input.
        estimate: the denoised mesh or its vertices (*batch, V, 3).

    Returns:
        The ratio, (*batch)."""
    return safe_divide(_error(objective, clean, estimate), _error(objective, clean, noisy))


def rademacher_probes(key, mesh: Mesh, count: int) -> Float[Array, "P V 3"]:
    """``count`` Rademacher (±1) fields on the vertices, 0 on isolated vertices
    (padding included: they carry no noise and are never moved).

    Arguments:
        key: the probes' random key (an int or a ``jax.random`` key).
        mesh: a single mesh.
        count: the number of probes P.

    Returns:
        (P, V, 3) of ±1 (0 on isolated vertices)."""
    z = jax.random.rademacher(key, (count, mesh.num_vertices, 3), dtype=mesh.dtype)
    return jnp.where((mesh.degree > 0)[:, None], z, 0)


def _trace_m(mesh: Mesh, dtype) -> Array:
    """tr(M), M = I + KᵀK on the three coordinates of the non-isolated vertices."""
    d = mesh.degree.astype(dtype)
    return 3 * jnp.sum(jnp.where(d > 0, 2 + safe_divide(jnp.ones_like(d), d), 0))


def noisy_visual_error_expectation(mesh: Mesh, sigma) -> Array:
    """E[E(y, x)] = σ² tr(M) / 2m: the expected visual error of the noisy input.

    Arguments:
        mesh: a single mesh.
        sigma: the noise σ per coordinate.

    Returns:
        The expectation (a scalar, or (*batch) for batched σ)."""
    return jnp.asarray(sigma, mesh.dtype) ** 2 * _trace_m(mesh, mesh.dtype) / (2 * mesh.num_vertices)


def sure_visual_error(
    noisy: Mesh, denoiser: Callable[[Array], Array], sigma, probes: Float[Array, "P V 3"]
) -> Array:
    """SURE of the visual error of ``denoiser(y)`` (module docstring), y the
    noisy positions (*batch, V, 3); ``sigma`` the noise standard deviation per
    coordinate, in the mesh's units.  Returns shape (*batch,).

    Arguments:
        noisy: the noisy mesh (single, or with batched vertices).
        denoiser: maps positions (*batch, V, 3) to positions.
        sigma: the noise σ per coordinate.
        probes: Rademacher fields, (P, V, 3) (:func:`rademacher_probes`).

    Returns:
        The estimate, (*batch)."""
    y = noisy.vertices
    fy, lin = jax.linearize(denoiser, y)
    r = fy - y
    kr = umbrella(noisy, r)
    m = noisy.num_vertices

    def quadratic(z):
        zb = jnp.broadcast_to(z, y.shape)
        jz = lin(zb)
        return jnp.sum(zb * jz, axis=(-2, -1)) + jnp.sum(umbrella(noisy, zb) * umbrella(noisy, jz), axis=(-2, -1))

    tr_mj = jnp.mean(jax.vmap(quadratic)(probes), axis=0)
    s2 = jnp.asarray(sigma, y.dtype) ** 2
    fit = jnp.sum(r * r, axis=(-2, -1)) + jnp.sum(kr * kr, axis=(-2, -1))
    return (fit + 2 * s2 * tr_mj - s2 * _trace_m(noisy, y.dtype)) / (2 * m)
