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

Stability.  κ_ij grows like λ^{-3/2}: once s_i = (1/d_i) sum_j κ_ij exceeds 1
the random-walk step overshoots the neighbour mean and, past 2, the flow
diverges (on unit-diagonal meshes this happens for λ below ~0.1).  With
``safeguard=True`` (default) the random-walk step is scaled by
α_i = min(1, 1/s_i), so every vertex moves to a convex combination of itself
and its κ-weighted neighbour mean: the flow cannot diverge for any λ > 0, and
it is unchanged wherever s_i <= 1 (all λ of practical interest).
``safeguard=False`` is the unmodified step; the paper variant has no
safeguard (use :func:`jaxmesh.denoise.diverged` to detect a blow-up).

Everything is a sum over each vertex's neighbours: segment sums over the directed
edge list, or, faster, sums over the slots of the padded one-ring tiers of
:mod:`.vertex_rings` (the same step up to the order of summation); 3×3 determinants
and inverses are closed-form (adjugate), so the flow is jittable, vmappable and
differentiable with respect to λ and the positions.
"""

from __future__ import annotations

from typing import Literal

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import Scalar, lift, one_program, safe_divide, segment_sum_rows
from ..mesh import Mesh
from ..operators import neighbor_sum
from ._loop import iterate
from .vertex_rings import VertexRings, VertexTier, rings_where_concrete

__all__ = ["neighborhood_covariances", "kernel_weights", "kernel_step", "kernel_diffusion",
           "VARIANTS"]

VARIANTS = ("paper", "random_walk")


@one_program
def neighborhood_covariances(
    mesh: Mesh, x: Float[Array, "*batch V 3"], lam
) -> Float[Array, "*batch V 3 3"]:
    """H_i = sum_{j~i} (x_j - c_i)(x_j - c_i)^T + λ I, c_i the neighbour mean (eq.9, eq.12).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        lam: the regularisation λ > 0.

    Returns:
        H_i, (*batch, V, 3, 3)."""
    d = lift(mesh.degree.astype(x.dtype)[:, None], x.ndim)
    c = safe_divide(neighbor_sum(mesh, x), d)
    diff = x[..., mesh.dst, :] - c[..., mesh.src, :]
    outer = (diff[..., :, None] * diff[..., None, :]).reshape(*diff.shape[:-1], 9)
    h = segment_sum_rows(outer, mesh.src, mesh.num_vertices).reshape(*x.shape[:-1], 3, 3)
    lam = lift(jnp.asarray(lam, x.dtype)[..., None, None, None], h.ndim)
    return h + lam * lift(jnp.eye(3, dtype=x.dtype), h.ndim)


def _symmetric_adjugate(h):
    """det and the 6 distinct adjugate entries (xx, yy, zz, xy, xz, yz) of symmetric
    3×3 matrices given by their 6 distinct entries in the same order."""
    xx, yy, zz, xy, xz, yz = (h[..., k] for k in range(6))
    co = jnp.stack([yy * zz - yz * yz, xx * zz - xz * xz, xx * yy - xy * xy,
                    xz * yz - xy * zz, xy * yz - xz * yy, xy * xz - xx * yz], axis=-1)
    det = xx * co[..., 0] + xy * co[..., 3] + xz * co[..., 4]
    return det, co


def _quadratic(co, d):
    """d^T C d for symmetric C given by its 6 distinct entries (last axis of ``co``)."""
    return _quadratic_parts([co[..., k] for k in range(6)], d[..., 0], d[..., 1], d[..., 2])


def _quadratic_parts(c, dx, dy, dz):
    """d^T C d from the 6 distinct entries of C (xx, yy, zz, xy, xz, yz) and d's components."""
    return (c[0] * dx * dx + c[1] * dy * dy + c[2] * dz * dz
            + 2 * (c[3] * dx * dy + c[4] * dx * dz + c[5] * dy * dz))


def _kernel_parts(mesh: Mesh, x: Float[Array, "*batch V 3"], lam):
    """(norm_i = det(H_i)^{-1/2} (2π)^{-3/2} per vertex, p_ij = exp(-½ δ^T H_i^{-1} δ)
    per directed edge, δ_ij = x_j - x_i per directed edge), so that κ_ij = norm_i p_ij.

    One pass over the edges: with δ̄_i = (1/d_i) sum_j δ_ij = c_i - x_i,
    H_i - λI = sum_j (δ_ij - δ̄_i)(δ_ij - δ̄_i)^T = sum_j δ_ij δ_ij^T - d_i δ̄_i δ̄_i^T,
    accumulated as 6 + 3 columns of one segment sum (differences, not positions, so
    the subtraction does not cancel at large coordinates).  det is floored at the
    dtype's smallest normal number so that an underflow cannot give inf/NaN."""
    delta = x[..., mesh.dst, :] - x[..., mesh.src, :]
    sums = segment_sum_rows(jnp.stack(_moment_parts(delta[..., 0], delta[..., 1], delta[..., 2]), axis=-1),
                            mesh.src, mesh.num_vertices)
    d = lift(mesh.degree.astype(x.dtype)[:, None], x.ndim)
    norm, inverse = _norm_and_inverse(sums, d, lift(jnp.asarray(lam, x.dtype)[..., None], x.ndim - 1), x.dtype)
    q = _quadratic(inverse[..., mesh.src, :], delta)      # H_i^{-1}, per vertex: one 6-column gather
    return norm, jnp.exp(-0.5 * q), delta


def _moment_parts(dx, dy, dz) -> list:
    """The 6 + 3 columns δδ^T (xx, yy, zz, xy, xz, yz) and δ whose sums over j give H_i."""
    return [dx * dx, dy * dy, dz * dz, dx * dy, dx * dz, dy * dz, dx, dy, dz]


def _norm_and_inverse(sums, d, lam, dtype):
    """(det(H_i)^{-1/2} (2π)^{-3/2}, H_i^{-1} as 6 entries) from the summed moment columns
    (…, 9), the degree d (…, 1) and λ shaped to broadcast with (…): H_i = Σ δδ^T − d δ̄δ̄^T + λI
    (see :func:`_kernel_parts`)."""
    mean = safe_divide(sums[..., 6:], d)
    mx, my, mz = mean[..., 0], mean[..., 1], mean[..., 2]
    outer = jnp.stack([mx * mx, my * my, mz * mz, mx * my, mx * mz, my * mz], axis=-1)
    h = sums[..., :6] - d * outer + lam[..., None] * lift(jnp.array([1, 1, 1, 0, 0, 0], dtype), sums.ndim)
    det, co = _symmetric_adjugate(h)
    det = jnp.maximum(det, jnp.finfo(dtype).tiny)
    return (2 * jnp.pi) ** -1.5 * jax.lax.rsqrt(det), co / det[..., None]


def _tier_step(x, y, tier: VertexTier, lam, safeguard: bool):
    """The new positions of one tier's vertices, vertex-major: ``x`` and the result are
    (V, 3, *batch) and (W, 3, *batch), so every gather takes whole rows whatever the batch.
    The step of :func:`kernel_step` as sums over the tier's k neighbour slots, written out
    slot by slot (k gathers of rows and elementwise sums: on CPU several times faster than
    a reduction over a (W, k, 3) array).  Padding is the vertex itself (δ = 0) with its
    weight masked.  ``y`` = x/sqrt(d) for the paper's update, None for the random walk;
    ``lam`` is a scalar or (*batch,)."""
    def rows(a):                                 # (W,) -> (W, 1, ..., 1) against (W, *batch)
        return jnp.reshape(a, a.shape + (1,) * (x.ndim - 2))

    xi = x[tier.vertices]
    slots = range(tier.neighbors.shape[1])
    delta = [x[tier.neighbors[:, j]] - xi for j in slots]                  # k × (W, 3, *batch)
    d = rows(jnp.sum(tier.mask, axis=-1).astype(x.dtype))                   # (W, 1, …)
    cols = [sum(col) for col in zip(*(_moment_parts(g[:, 0], g[:, 1], g[:, 2]) for g in delta))]
    norm, inverse = _norm_and_inverse(jnp.stack(cols, axis=-1), d[..., None], lift(lam, x.ndim - 1), x.dtype)
    c = [inverse[..., k] for k in range(6)]
    p = [jnp.where(rows(tier.mask[:, j]), jnp.exp(-0.5 * _quadratic_parts(c, g[:, 0], g[:, 1], g[:, 2])), 0)
         for j, g in zip(slots, delta)]                                       # k × (W, *batch)
    if y is not None:
        yi = y[tier.vertices]
        step = sum(pj[:, None] * (y[tier.neighbors[:, j]] - yi) for j, pj in zip(slots, p))
        return xi + (safe_divide(jnp.ones_like(d), jnp.sqrt(d)) * norm)[:, None] * step
    pull = sum(pj[:, None] * g for pj, g in zip(p, delta))
    den = d / norm
    if safeguard:
        den = jnp.maximum(den, sum(p))
    return xi + safe_divide(pull, den[:, None])


@one_program
def kernel_weights(mesh: Mesh, x: Float[Array, "*batch V 3"], lam):
    """(κ_ij per directed edge (*batch, H), κ_ii per vertex (*batch, V)) — the
    off-diagonal and diagonal entries of the kernel matrix 𝒦 (eq.10):
    κ_ij = det(H_i)^{-1/2} (2π)^{-3/2} exp(-½ δ^T H_i^{-1} δ), δ = x_i - x_j,
    κ_ii = det(H_i)^{-1/2} (2π)^{-3/2}.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        lam: the regularisation λ > 0.

    Returns:
        (κ_ij (*batch, H), κ_ii (*batch, V))."""
    norm, p, _ = _kernel_parts(mesh, x, lam)
    return norm[..., mesh.src] * p, norm


def kernel_step(
    mesh: Mesh, x: Float[Array, "*batch V 3"], lam,
    variant: Literal["paper", "random_walk"] = "random_walk",
    safeguard: bool = True, rings: VertexRings | None = None,
) -> Float[Array, "*batch V 3"]:
    """One Jacobi iteration of the kernel flow (see the module docstring): segment sums
    over the directed edges, or, given ``rings``, dense sums along the padded one-rings
    (:func:`jaxmesh.denoise.vertex_rings`; the same step up to the order of summation).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        lam: the regularisation λ > 0.
        variant: ``"random_walk"`` (default, translation invariant) or ``"paper"`` (the thesis's formula).
        safeguard: cap the random-walk step so the flow cannot diverge.
        rings: the mesh's :class:`~jaxmesh.denoise.VertexRings` (None: segment sums).

    Returns:
        The positions after one step, (*batch, V, 3)."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    d = lift(mesh.degree.astype(x.dtype), x.ndim - 1)
    if rings is not None:      # vertex-major (V, 3, *batch) for the tiers, then back
        y = safe_divide(jnp.ones_like(d), jnp.sqrt(d))[..., None] * x if variant == "paper" else None
        xt, yt = (None if a is None else jnp.moveaxis(a, (-2, -1), (0, 1)) for a in (x, y))
        parts = [_tier_step(xt, yt, tier, jnp.asarray(lam, x.dtype), safeguard) for tier in rings.tiers]
        return jnp.moveaxis(jnp.concatenate(parts, axis=0)[rings.order], (0, 1), (-2, -1))
    norm, p, diff = _kernel_parts(mesh, x, lam)
    if variant == "paper":
        s = safe_divide(jnp.ones_like(d), jnp.sqrt(d))[..., None]
        y = s * x
        diff = y[..., mesh.dst, :] - y[..., mesh.src, :]
        kappa = norm[..., mesh.src] * p
        return x + s * segment_sum_rows(kappa[..., None] * diff, mesh.src, mesh.num_vertices)
    # Σ_j p_ij δ_ij and Σ_j p_ij in one pass over the edges (4 columns)
    sums = segment_sum_rows(jnp.concatenate([p[..., None] * diff, p[..., None]], axis=-1), mesh.src,
                            mesh.num_vertices)
    pull = sums[..., :3]
    # step_i = norm_i * pull_i / d_i; with the safeguard norm_i * pull_i / max(d_i, norm_i sum_j p_ij),
    # written as pull_i / max(d_i / norm_i, sum_j p_ij) so that a huge norm_i cannot overflow.
    den = d / norm
    if safeguard:
        den = jnp.maximum(den, sums[..., 3])
    return x + safe_divide(pull, den[..., None])


def kernel_diffusion(
    mesh: Mesh, lam: Scalar = 0.4, iterations: int = 5,
    variant: Literal["paper", "random_walk"] = "random_walk",
    safeguard: bool = True, rings: VertexRings | None = None,
) -> Mesh:
    """Run ``iterations`` steps of the kernel flow and return the smoothed mesh.

    ``lam`` > 0 (a float or a traced scalar; one per batch element for a
    batched mesh).  ``iterations`` is a Python int: the loop is a
    ``lax.fori_loop``, so compile time does not grow with it and reverse-mode
    gradients with respect to ``lam`` and the positions are available.
    ``variant="paper"`` is eq.7 exactly; ``"random_walk"`` (default) applies
    the same κ to x_j - x_i and is translation invariant (see the module doc);
    ``safeguard`` (random walk only) caps the step so the flow cannot diverge.
    The steps run on the mesh's one-ring tiers (:func:`jaxmesh.denoise.vertex_rings`), built
    here when the connectivity is concrete and one topology; pass ``rings=`` to have them
    under ``jit`` with the mesh traced (without, the segment sums: the same flow, slower).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        lam: the regularisation λ > 0 (one per batch element, or one for all).
        iterations: the number of outer iterations (a Python int: the loop is compiled once).
        variant: ``"random_walk"`` (default, translation invariant) or ``"paper"`` (the thesis's formula).
        safeguard: cap the random-walk step so the flow cannot diverge.
        rings: the mesh's :class:`~jaxmesh.denoise.VertexRings` (default: built when possible).

    Returns:
        The smoothed mesh."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    rings = rings_where_concrete(mesh, rings)
    x = iterate(lambda x: kernel_step(mesh, x, lam, variant, safeguard, rings), mesh.vertices, iterations)
    return mesh.with_vertices(x)
