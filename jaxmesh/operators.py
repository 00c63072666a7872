"""Graph and mesh operators as segment sums over the directed edge list.

Conventions: ``x`` is a vertex field of shape (*batch, V, d) (the vertex
positions, or any per-vertex signal); j ~ i runs over the neighbours of i;
d_i is the degree.  A sum over j ~ i is a gather of x at ``mesh.dst``
followed by a ``segment_sum`` over ``mesh.src``: O(E), no dense matrix, and
differentiable.  Isolated vertices (d_i = 0) get 0 from every operator.
All functions are pure and jittable; :mod:`jaxmesh.sparse` exports the same
operators as ``scipy.sparse`` matrices for host-side eigensolvers.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._private import lift, one_program, safe_divide, segment_sum_rows, segment_sum_scalars
from .geometry import corner_cotangents, vertex_areas
from .mesh import Mesh

__all__ = [
    "degree",
    "neighbor_sum",
    "laplacian",
    "normalized_laplacian",
    "umbrella",
    "taubin_pair",
    "vertex_gradient",
    "vertex_laplace",
    "gradient_magnitude",
    "cotangent_weights",
    "laplace_beltrami_weights",
    "laplace_beltrami",
    "cotangent_laplacian",
]


def degree(mesh: Mesh, dtype=None) -> Array:
    """d_i = number of neighbours of v_i (int32, or ``dtype`` if given).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        dtype: the result's dtype (default: the stored int32 degrees).

    Returns:
        The degrees, (V,)."""
    return mesh.degree if dtype is None else mesh.degree.astype(dtype)


@one_program
def neighbor_sum(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """sum_{j ~ i} x_j, i.e. (A x)_i with A the adjacency matrix.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d) array."""
    return segment_sum_rows(x[..., mesh.dst, :], mesh.src, mesh.num_vertices)


@one_program
def laplacian(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """(L x)_i = d_i x_i - sum_{j ~ i} x_j,   L = D - A   (thesis ch.1 eq.6).
    Symmetric positive semi-definite; constants are in its kernel.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d) array."""
    d = lift(degree(mesh, x.dtype)[:, None], x.ndim)
    return d * x - neighbor_sum(mesh, x)


def _inv_sqrt_degree(mesh: Mesh, dtype) -> Array:
    d = degree(mesh, dtype)
    return safe_divide(jnp.ones_like(d), jnp.sqrt(d))


@one_program
def normalized_laplacian(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """(𝓛 x)_i = x_i - sum_{j ~ i} x_j / sqrt(d_i d_j),
    𝓛 = I - D^{-1/2} A D^{-1/2}   (thesis ch.1 eq.7).

    Chung's convention for an isolated vertex: (𝓛 x)_i = 0.  Eigenvalues in [0, 2].

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d) array."""
    s = lift(_inv_sqrt_degree(mesh, x.dtype)[:, None], x.ndim)
    connected = lift((mesh.degree > 0)[:, None], x.ndim)
    return jnp.where(connected, x, 0) - s * neighbor_sum(mesh, s * x)


@one_program
def umbrella(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """(K x)_i = (1/d_i) sum_{j ~ i} x_j - x_i,   K = D^{-1} A - I   (thesis ch.3 eq.2).

    Not symmetric; rows sum to 0; eigenvalues in [-2, 0].  0 at isolated vertices.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d) array."""
    d = lift(degree(mesh, x.dtype)[:, None], x.ndim)
    mean = safe_divide(neighbor_sum(mesh, x), d)
    return jnp.where(d > 0, mean - x, 0)


@one_program
def vertex_gradient(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch H d"]:
    """grad x_i = { x_j / sqrt(d_j) - x_i / sqrt(d_i) : j ~ i }   (thesis ch.1 eq.9).

    One row per directed edge (src = i, dst = j), in ``mesh.src`` order.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, H, d) array."""
    y = lift(_inv_sqrt_degree(mesh, x.dtype)[:, None], x.ndim) * x
    return y[..., mesh.dst, :] - y[..., mesh.src, :]


@one_program
def vertex_laplace(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """Δx_i = sum_{j ~ i} (1/sqrt(d_i)) (x_j / sqrt(d_j) - x_i / sqrt(d_i))
    (thesis ch.1 eq.10) = -(𝓛 x)_i.

    Note: unlike the umbrella operator this is *not* zero on constant fields
    where neighbouring degrees differ, so a flow built on it is not
    translation invariant.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d) array."""
    s = lift(_inv_sqrt_degree(mesh, x.dtype)[:, None], x.ndim)
    return s * segment_sum_rows(vertex_gradient(mesh, x), mesh.src, mesh.num_vertices)


@one_program(static_argnames=("variant",))
def gradient_magnitude(
    mesh: Mesh, x: Float[Array, "*batch V d"], variant: str = "paper"
) -> Float[Array, "*batch V"]:
    """|grad x_i| = sqrt(sum_{j ~ i} ||x_i / sqrt(d_i) - x_j / sqrt(d_j)||^2)
    (thesis ch.2 eq.5, ch.3 eq.8).

    ``variant="paper"`` is that formula; ``variant="translation_invariant"``
    drops the degree normalisation, sqrt(sum_{j ~ i} ||x_i - x_j||^2), which is
    unchanged when the mesh is translated.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).
        variant: ``"paper"`` (the formula above) or ``"translation_invariant"``.

    Returns:
        (*batch, V) array."""
    if variant == "paper":
        g = vertex_gradient(mesh, x)
    elif variant == "translation_invariant":
        g = x[..., mesh.dst, :] - x[..., mesh.src, :]
    else:
        raise ValueError(f"variant must be 'paper' or 'translation_invariant', got {variant!r}")
    sq = segment_sum_scalars(jnp.sum(g * g, axis=-1), mesh.src, mesh.num_vertices)
    pos = sq > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1)), 0)


@one_program
def cotangent_weights(mesh: Mesh) -> Float[Array, "*batch E"]:
    """c_ij = cot α_ij + cot β_ij per undirected edge (``mesh.edges`` order), where
    α_ij, β_ij are the angles opposite edge (i, j) in its two faces.  A boundary
    edge has one face and hence one cotangent; a non-manifold edge sums over all
    its faces; degenerate faces contribute 0.  (No factor 1/2.)

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, E) array."""
    cot = corner_cotangents(mesh)
    flat = cot.reshape(*cot.shape[:-2], -1)
    return segment_sum_scalars(flat, mesh.face_edges.reshape(-1), mesh.num_edges)


@one_program
def laplace_beltrami_weights(mesh: Mesh) -> Float[Array, "*batch H"]:
    """w_ij = 3 (cot α_ij + cot β_ij) / η_i per directed edge (thesis ch.4 eq.2),
    η_i the total area of the triangles around v_i.  Row-normalised, so
    w_ij != w_ji in general.  0 where η_i = 0.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, H) array."""
    c = cotangent_weights(mesh)[..., mesh.edge_of]
    eta = vertex_areas(mesh)[..., mesh.src]
    return safe_divide(3 * c, eta)


@one_program
def laplace_beltrami(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """Δ_m x_i = sum_{j ~ i} w_ij (x_j - x_i), w from :func:`laplace_beltrami_weights`
    (thesis ch.4 eq.1).  The thesis's matrix L = D - W (eq.2) acts as -Δ_m.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d) array."""
    w = laplace_beltrami_weights(mesh)[..., None]
    diff = x[..., mesh.dst, :] - x[..., mesh.src, :]
    return segment_sum_rows(w * diff, mesh.src, mesh.num_vertices)


@one_program
def cotangent_laplacian(mesh: Mesh, x: Float[Array, "*batch V d"]) -> Float[Array, "*batch V d"]:
    """(L_c x)_i = (1/2) sum_{j ~ i} (cot α_ij + cot β_ij)(x_j - x_i): the symmetric
    cotangent Laplacian (Pinkall–Polthier; Desbrun et al. 1999 without the mass
    matrix).  Negative semi-definite on well-shaped meshes.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: per-vertex values, (*batch, V, d).

    Returns:
        (*batch, V, d) array."""
    w = 0.5 * cotangent_weights(mesh)[..., mesh.edge_of, None]
    diff = x[..., mesh.dst, :] - x[..., mesh.src, :]
    return segment_sum_rows(w * diff, mesh.src, mesh.num_vertices)


def taubin_pair(x, k, lam, mu):
    """One Taubin λ|μ pair (Taubin 1995): x ← x + λ k(x), then x ← x + μ k(x), with
    ``k`` the smoothing operator as a function (the umbrella K x by segment sums, or
    a scipy matrix product on the host).  The one definition that Taubin smoothing
    and the robust hash's pre-smoothing share.

    Arguments:
        x: positions (or any per-vertex values).
        k: the smoothing operator, a function x -> K x.
        lam: the shrinking step λ > 0.
        mu: the inflating step μ < −λ.

    Returns:
        X after the pair, same shape."""
    x = x + lam * k(x)
    return x + mu * k(x)
