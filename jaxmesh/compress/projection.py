"""Spectral projection in JAX (thesis ch.3 eq.5), with the host eigensolver behind
``jax.pure_callback``.

The bases depend on the connectivity only, so they are constants of a mesh:
:func:`basis_callback` computes one on the host (scipy, :mod:`.basis`) from
inside jitted code, and everything downstream — the projection, the visual
errors — is ordinary differentiable JAX in the vertex positions.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ..graph import adjacency_from_faces
from ..mesh import Mesh
from . import basis as _basis

__all__ = ["project", "project_orthonormal", "spectral_coefficients", "basis_callback", "spectral_reconstruction"]


def spectral_coefficients(basis: Float[Array, "V r"], x: Float[Array, "*batch V 3"]) -> Float[Array, "*batch r 3"]:
    """Ĉ = (B_rᵀB_r)⁺ B_rᵀ V: the least-squares coefficients of eq.5.

    Arguments:
        basis: the basis B_r, (V, r).
        x: positions, (*batch, V, 3).

    Returns:
        Ĉ, (*batch, r, 3)."""
    gram = basis.T @ basis
    return jnp.linalg.pinv(gram, hermitian=True) @ (basis.T @ x)


def project(basis: Float[Array, "V r"], x: Float[Array, "*batch V 3"]) -> Float[Array, "*batch V 3"]:
    """V̂ = B_r (B_rᵀB_r)⁺ B_rᵀ V   (thesis ch.3 eq.5): the orthogonal projection of
    each coordinate column onto span(B_r), for any (not necessarily orthonormal)
    basis.  r = V with an invertible basis gives V back.

    Arguments:
        basis: the basis B_r, (V, r).
        x: positions, (*batch, V, 3).

    Returns:
        V̂, the shape of ``x``."""
    return basis @ spectral_coefficients(basis, x)


def project_orthonormal(basis: Float[Array, "V r"], x: Float[Array, "*batch V 3"]) -> Float[Array, "*batch V 3"]:
    """V̂ = B_r B_rᵀ V (Karni & Gotsman), valid when B_rᵀB_r = I.

    Arguments:
        basis: the basis B_r, (V, r).
        x: positions, (*batch, V, 3).

    Returns:
        V̂, the shape of ``x``."""
    return basis @ (basis.T @ x)


def _host_basis(faces: np.ndarray, num_vertices: int, r: int, kind: str, dtype) -> np.ndarray:
    adj = adjacency_from_faces(np.asarray(faces), num_vertices)
    b = _basis.graph_basis(adj, r, kind, extend_clusters=False)
    return np.asarray(b.vectors, dtype=dtype)


def basis_callback(mesh: Mesh, r: int, kind: str = "umbrella") -> Float[Array, "V r"]:
    """The basis of :func:`jaxmesh.compress.spectral_basis` (exactly ``r`` columns,
    clusters not extended) computed on the host through ``jax.pure_callback``,
    so it can be called inside ``jit``; a constant for differentiation.

    Arguments:
        mesh: a single mesh.
        r: the number of basis vectors, clipped to [1, V].
        kind: ``"umbrella"`` (the thesis's K, default) or ``"laplacian"`` (Karni–Gotsman's L = D − A).

    Returns:
        The basis, (V, r), a constant under differentiation."""
    if kind not in _basis.KINDS:
        raise ValueError(f"kind must be one of {_basis.KINDS}, got {kind!r}")
    m = mesh.num_vertices
    if not (isinstance(r, (int, np.integer)) and 1 <= r <= m):
        raise ValueError(f"r must be an integer in [1, {m}], got {r!r}")
    dtype = mesh.vertices.dtype
    shape = jax.ShapeDtypeStruct((m, int(r)), dtype)

    def host(faces: Int[np.ndarray, "F 3"] | Int[Array, "F 3"]) -> np.ndarray:
        return _host_basis(np.asarray(faces), m, int(r), kind, np.dtype(dtype))

    out = jax.pure_callback(host, shape, mesh.faces, vmap_method="sequential")
    return jax.lax.stop_gradient(out)


def spectral_reconstruction(mesh: Mesh, r: int, kind: str = "umbrella") -> Float[Array, "*batch V 3"]:
    """V̂ for the r-vector ``kind`` basis: eq.5 for the umbrella basis, B Bᵀ V for
    the orthonormal Laplacian one; differentiable in ``mesh.vertices``.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        r: the number of basis vectors, clipped to [1, V].
        kind: ``"umbrella"`` (the thesis's K, default) or ``"laplacian"`` (Karni–Gotsman's L = D − A).

    Returns:
        V̂, (*batch, V, 3)."""
    b = basis_callback(mesh, r, kind)
    if kind == "laplacian":
        return project_orthonormal(b, mesh.vertices)
    return project(b, mesh.vertices)
