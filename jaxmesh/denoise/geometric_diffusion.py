"""Anisotropic geometric diffusion (Clarenz, Diewald & Rumpf 2000).

The surface is evolved by  ∂_t x - div_M(a(x) ∇_M x) = 0  with a diffusion
tensor that smooths along directions of small curvature and stops across
features.  Discretised here with linear finite elements, one tensor per face:

* shape operator S_T of face T, fitted (least squares, Rusinkiewicz 2004) to
  the change of the vertex normals along its three edges: S_T e_k = Δn_k in the
  face's tangent basis (u, v);
* principal curvatures κ_1, κ_2 and directions w_1, w_2 of S_T (closed form);
* a_T = G(κ_1) w_1 w_1^T + G(κ_2) w_2 w_2^T,  G(s) = 1 / (1 + s²/ρ²),
  ρ = rho / ℓ̄ (ℓ̄ the input's mean edge length: ``rho`` is dimensionless);
* stiffness of edge (k, l) of T: k_kl = -A_T ∇φ_k^T a_T ∇φ_l, ∇φ_k = (n_T × e_k) / (2 A_T)
  (for a_T = I this is ½ cot θ_m: the cotangent Laplacian);
* one semi-implicit step (M + τ K_a) x' = M x per iteration (weights frozen,
  τ = dt · Ā as in :mod:`jaxmesh.denoise.curvature`), solved by CG.

a_T is positive semi-definite, so K_a is too and CG applies.  This is the
paper's scheme without its pre-smoothing of the tensor (the curvature is taken
from the current surface's area-weighted vertex normals).
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import Scalar, det_adjugate_3x3, safe_divide, safe_normalize, segment_sum_scalars
from ..geometry import face_corners, face_normals, hat_gradients, mean_edge_length, vertex_normals
from ..metrics import cauchy_weight
from ..mesh import Mesh
from ._loop import iterate
from .curvature import implicit_diffusion_step

__all__ = ["face_curvatures", "anisotropic_stiffness", "geometric_diffusion"]


def _dot(a, b):
    return jnp.sum(a * b, axis=-1)


def face_curvatures(mesh: Mesh):
    """Per face: (κ_1, κ_2, w_1, w_2), the principal curvatures and directions of
    the least-squares shape operator (module docstring).  Shapes (*b, F) and (*b, F, 3).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (κ₁, κ₂, w₁, w₂): (*batch, F) curvatures and (*batch, F, 3) directions."""
    p = face_corners(mesh)                                   # (*b, F, 3, 3): corner k
    nv = vertex_normals(mesh, "area")[..., mesh.faces, :]   # (*b, F, 3, 3)
    n = face_normals(mesh)
    u = safe_normalize(p[..., 1, :] - p[..., 0, :])
    v = jnp.cross(n, u)
    # edge k runs from corner k+1 to corner k+2 (opposite corner k)
    e = jnp.roll(p, -2, axis=-2) - jnp.roll(p, -1, axis=-2)
    dn = jnp.roll(nv, -2, axis=-2) - jnp.roll(nv, -1, axis=-2)
    eu, ev = _dot(e, u[..., None, :]), _dot(e, v[..., None, :])
    du, dv = _dot(dn, u[..., None, :]), _dot(dn, v[..., None, :])
    # normal equations for S = [[a, b], [b, c]]:  a eu + b ev = du,  b eu + c ev = dv
    m = jnp.stack([
        jnp.stack([jnp.sum(eu * eu, -1), jnp.sum(eu * ev, -1), jnp.zeros_like(eu[..., 0])], -1),
        jnp.stack([jnp.sum(eu * ev, -1), jnp.sum(eu * eu + ev * ev, -1), jnp.sum(eu * ev, -1)], -1),
        jnp.stack([jnp.zeros_like(eu[..., 0]), jnp.sum(eu * ev, -1), jnp.sum(ev * ev, -1)], -1),
    ], -2)
    rhs = jnp.stack([jnp.sum(eu * du, -1), jnp.sum(ev * du + eu * dv, -1), jnp.sum(ev * dv, -1)], -1)
    det, adj = det_adjugate_3x3(m)
    abc = safe_divide(jnp.einsum("...ij,...j->...i", adj, rhs), det[..., None])
    a, b, c = abc[..., 0], abc[..., 1], abc[..., 2]
    # principal frame: tan 2θ = 2b / (a - c); atan2 guarded at (0, 0) (umbilic)
    y, x = 2 * b, a - c
    flat = (y == 0) & (x == 0)
    theta = 0.5 * jnp.arctan2(jnp.where(flat, 0, y), jnp.where(flat, 1, x))
    cs, sn = jnp.cos(theta), jnp.sin(theta)
    k1 = a * cs * cs + 2 * b * sn * cs + c * sn * sn
    k2 = a * sn * sn - 2 * b * sn * cs + c * cs * cs
    w1 = cs[..., None] * u + sn[..., None] * v
    w2 = -sn[..., None] * u + cs[..., None] * v
    return k1, k2, w1, w2


def anisotropic_stiffness(mesh: Mesh, rho) -> Float[Array, "*batch E"]:
    """Per-edge stiffness k_e = -sum_T A_T ∇φ_k^T a_T ∇φ_l (module docstring), with
    G's scale ρ = ``rho`` (an absolute curvature, 1/length).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        rho: the curvature scale ρ of G, in 1/length.

    Returns:
        per-edge stiffness, (*batch, E)."""
    k1, k2, w1, w2 = face_curvatures(mesh)
    rho = jnp.asarray(rho, mesh.dtype)[..., None]
    g1, g2 = cauchy_weight(k1, rho), cauchy_weight(k2, rho)          # G(κ) of the module docstring
    area, grad = hat_gradients(face_corners(mesh))                     # A_T, ∇φ_k
    g_w1 = _dot(grad, w1[..., None, :])                                # (*b, F, 3)
    g_w2 = _dot(grad, w2[..., None, :])
    # edge opposite corner m joins corners m+1 and m+2
    s1, s2 = jnp.roll(g_w1, -1, -1) * jnp.roll(g_w1, -2, -1), jnp.roll(g_w2, -1, -1) * jnp.roll(g_w2, -2, -1)
    k = -area[..., None] * (g1[..., None] * s1 + g2[..., None] * s2)  # (*b, F, 3)
    return segment_sum_scalars(k.reshape(*k.shape[:-2], -1), mesh.face_edges.reshape(-1),
                               mesh.num_edges)


def geometric_diffusion(mesh: Mesh, dt: Scalar = 0.3, rho: Scalar = 1.0, iterations: int = 3) -> Mesh:
    """``iterations`` semi-implicit steps of Clarenz-style anisotropic diffusion
    (module docstring); ``rho`` in units of 1/ℓ̄, ``dt`` in units of the mean vertex area.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        dt: the time step, in units of the mean vertex area.
        rho: the curvature scale, in units of 1/ℓ̄.
        iterations: the number of outer iterations (a Python int: the loop is compiled once).

    Returns:
        The smoothed mesh."""
    rho_abs = jnp.asarray(rho, mesh.dtype) / mean_edge_length(mesh)
    rho_abs = jnp.where(jnp.isfinite(rho_abs), rho_abs, 1)

    def step(x):
        w = anisotropic_stiffness(mesh.with_vertices(x), rho_abs)
        return implicit_diffusion_step(mesh, x, w, dt)

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))
