"""Eigenpairs of sparse symmetric matrices on a mesh's pattern, with exact derivatives;
Laplace–Beltrami spectra ("ShapeDNA") and spectral reconstructions differentiable in
the vertex positions.

The generalized problem A u = λ M u, A symmetric on a graph's pattern (the values of
:mod:`jaxmesh.linalg`: a diagonal and one value per edge) and M = diag(m) > 0 a lumped
mass.  :func:`eigenpairs` returns the k smallest eigenvalues, ascending, and
M-orthonormal eigenvectors (Uᵀ M U = I), computed on the host by the codec's solvers
(dense ``eigh`` up to ``dense_max``, else ARPACK shift-invert below the spectrum from a
fixed start vector) on S = M^{-1/2} A M^{-1/2}, with the codec's canonical vectors for
clusters of equal eigenvalues (:mod:`jaxmesh.compress.basis`): reproducible bit for bit.

Derivatives (``jax.custom_jvp``; reverse mode by transposition):

* eigenvalues: λ̇_i = u_iᵀ (Ȧ − λ_i Ṁ) u_i.  Within a cluster of equal eigenvalues
  (relative gap ≤ ``cluster_rtol`` of the spectrum's bound) the individual λ̇_i are not
  defined (a perturbation splits the cluster in ways that depend on its direction);
  each gets the cluster's mean, which is exact for every symmetric function of the
  cluster (its sum, its mean, any norm of it) at an exactly repeated eigenvalue;
* eigenvectors: u̇_i = y_i − ½ Σ_j u_j (u_jᵀ Ṁ u_i) over j in u_i's cluster (just
  −½ (u_iᵀ Ṁ u_i) u_i for a simple eigenvalue: what keeps Uᵀ M U = I), y_i from the
  bordered ("projected") solve

  ```text
  [A − λ_i M   M U_c] [y_i]   [−(Ȧ − λ_i Ṁ) u_i]
  [U_cᵀ M        0  ] [ μ ] = [        0        ],
  ```

  U_c the eigenvectors of u_i's cluster (u_i alone when λ_i is simple), so y_i is
  M-orthogonal to the cluster.  For a simple eigenvalue this is the eigenvector's
  derivative (sign fixed).  Within a cluster the individual eigenvectors are not
  differentiable (any rotation of them is as valid); this choice (no rotation inside the
  cluster) makes the derivative of the cluster's projector U_c U_cᵀ M exact, so every
  quantity that depends on the cluster's span only (a projection, a reconstruction
  error) has the right derivative.  ``k`` may not cut a cluster (``ValueError``): the
  span of a cut cluster is not defined.

Each bordered system is factored (SciPy SuperLU; it is indefinite) on the host, k per
derivative, cached like :mod:`jaxmesh.linalg`'s factors.
"""

from __future__ import annotations

import functools
import hashlib
import threading
from collections import OrderedDict

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from jaxtyping import Array, Float, Int

from ._private import filled_mass
from ._eigen import canonical, smallest
from .geometry import face_areas
from .linalg import sparse_matvec
from .mesh import Mesh
from .operators import cotangent_weights

__all__ = ["eigenpairs", "eigenvalues", "laplace_beltrami_system", "shape_dna", "spectral_projection",
           "spectral_reconstruction_error", "CLUSTER_RTOL"]

CLUSTER_RTOL = 1e-8
_PAD = 8
_lock = threading.Lock()


def laplace_beltrami_system(mesh: Mesh) -> tuple[Float[Array, " V"], Float[Array, " E"], Float[Array, " V"]]:
    """The cotangent Laplace–Beltrami problem of ``mesh`` as pattern values: A = −L_c
    (diagonal Σ_j c_ij, edge values −c_ij, c_ij = ½(cot α_ij + cot β_ij)) and the lumped
    (barycentric) mass m_i, a third of the area around v_i (isolated vertices get the
    mean mass, so M stays definite).  Differentiable in ``mesh.vertices``.

    Arguments:
        mesh: a single mesh.

    Returns:
        (diagonal (V,), edge values (E,), mass (V,))."""
    c = 0.5 * cotangent_weights(mesh)
    e = mesh.edges
    diag = jnp.zeros(mesh.num_vertices, c.dtype).at[e[:, 0]].add(c).at[e[:, 1]].add(c)
    area = face_areas(mesh)
    mass = jnp.zeros(mesh.num_vertices, c.dtype).at[mesh.faces.reshape(-1)].add(jnp.repeat(area / 3, 3))
    return diag, -c, filled_mass(mass, empty=0.0)       # no area at all: 0, which eigenpairs refuses


def eigenpairs(
    edges: Int[Array, "E 2"], diagonal: Float[Array, " n"], edge_values: Float[Array, " E"],
    mass: Float[Array, " n"], k: int, *, dense_max: int = 1200, cluster_rtol: float = CLUSTER_RTOL,
) -> tuple[Float[Array, " k"], Float[Array, "n k"]]:
    """The k smallest eigenpairs of A u = λ M u (module docstring), differentiable in
    ``diagonal``, ``edge_values`` and ``mass``; jittable.

    Arguments:
        edges: undirected edges (i, j), (E, 2).
        diagonal: A's diagonal, (n,).
        edge_values: A's value on each edge, (E,).
        mass: M's diagonal, (n,), positive.
        k: how many eigenpairs (1 ≤ k < n; may not cut a cluster of equal eigenvalues).
        dense_max: matrices up to this size use a dense eigensolver, larger ones ARPACK.
        cluster_rtol: eigenvalues closer than this times the spectrum's bound are equal.

    Returns:
        (eigenvalues (k,) ascending, eigenvectors (n, k) with Uᵀ M U = I)."""
    k = _check_k(k, diagonal.shape[-1])
    _validate(edges, diagonal, edge_values, mass, k, dense_max, cluster_rtol)
    w, u, _ = _eig_fn(k, int(dense_max), float(cluster_rtol), True)(edges, diagonal, edge_values, mass)
    return w, u


def eigenvalues(
    edges: Int[Array, "E 2"], diagonal: Float[Array, " n"], edge_values: Float[Array, " E"],
    mass: Float[Array, " n"], k: int, *, dense_max: int = 1200, cluster_rtol: float = CLUSTER_RTOL,
) -> Float[Array, " k"]:
    """The k smallest eigenvalues of A u = λ M u with their derivatives (the cheap half of
    :func:`eigenpairs`: no bordered solves).

    Arguments:
        edges: undirected edges (i, j), (E, 2).
        diagonal: A's diagonal, (n,).
        edge_values: A's value on each edge, (E,).
        mass: M's diagonal, (n,), positive.
        k: how many eigenvalues (1 ≤ k < n; may not cut a cluster).
        dense_max: as :func:`eigenpairs`.
        cluster_rtol: as :func:`eigenpairs`.

    Returns:
        Eigenvalues, (k,), ascending."""
    k = _check_k(k, diagonal.shape[-1])
    _validate(edges, diagonal, edge_values, mass, k, dense_max, cluster_rtol)
    return _eig_fn(k, int(dense_max), float(cluster_rtol), False)(edges, diagonal, edge_values, mass)[0]


def shape_dna(mesh: Mesh, k: int = 20, *, scale_invariant: bool = True, dense_max: int = 1200) -> Float[Array, " k"]:
    """The first k nonzero Laplace–Beltrami eigenvalues (Reuter, Wolter & Peinecke 2006)
    of ``mesh`` (cotangent Laplacian, lumped mass; the zero eigenvalue of a connected
    mesh left out), differentiable in ``mesh.vertices``.

    Arguments:
        mesh: a single connected mesh.
        k: how many eigenvalues.
        scale_invariant: multiply by the surface area (so scaling the mesh leaves them unchanged).
        dense_max: as :func:`eigenpairs`.

    Returns:
        λ_1 … λ_k, (k,)."""
    d, a, m = laplace_beltrami_system(mesh)
    w = eigenvalues(mesh.edges, d, a, m, k + 1, dense_max=dense_max)[1:]
    return w * jnp.sum(m) if scale_invariant else w


def spectral_projection(mesh: Mesh, k: int, *, dense_max: int = 1200) -> Float[Array, "V 3"]:
    """x̂ = U Uᵀ M x: the positions projected onto the first k Laplace–Beltrami
    eigenvectors of ``mesh`` itself (M-orthogonal projection), differentiable in
    ``mesh.vertices`` through the positions and the basis.

    Arguments:
        mesh: a single mesh.
        k: the basis size (may not cut a cluster of equal eigenvalues).
        dense_max: as :func:`eigenpairs`.

    Returns:
        x̂, (V, 3)."""
    d, a, m = laplace_beltrami_system(mesh)
    _, u = eigenpairs(mesh.edges, d, a, m, k, dense_max=dense_max)
    return u @ (u.T @ (m[:, None] * mesh.vertices))


def spectral_reconstruction_error(mesh: Mesh, k: int, *, dense_max: int = 1200) -> Float[Array, ""]:
    """‖x − x̂‖²_M / ‖x − x̄‖²_M for :func:`spectral_projection` x̂ (x̄ the area-weighted
    centroid): the fraction of the shape's variance the first k Laplace–Beltrami modes
    miss; differentiable in ``mesh.vertices``.

    Arguments:
        mesh: a single mesh.
        k: the basis size.
        dense_max: as :func:`eigenpairs`.

    Returns:
        The relative error, a scalar."""
    d, a, m = laplace_beltrami_system(mesh)
    _, u = eigenpairs(mesh.edges, d, a, m, k, dense_max=dense_max)
    x = mesh.vertices
    r = x - u @ (u.T @ (m[:, None] * x))
    centred = x - (jnp.sum(m[:, None] * x, 0) / jnp.sum(m))[None, :]
    return jnp.sum(m[:, None] * r * r) / jnp.sum(m[:, None] * centred * centred)


# --------------------------------------------------------------------------- internals
def _validate(edges, diag, vals, mass, k, dense_max, cluster_rtol) -> None:
    """Concrete inputs: solve now, so that a bad mass or a cut cluster is a plain
    ``ValueError`` here (the callback then finds the result in the cache)."""
    if not any(isinstance(z, jax.core.Tracer) for z in (edges, diag, vals, mass)):
        _host_eigh(edges, diag, vals, mass, k=k, dense_max=int(dense_max), cluster_rtol=float(cluster_rtol))


def _check_k(k, n: int) -> int:
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k < n:
        raise ValueError(f"k must be an int in [1, {n - 1}], got {k!r}")
    return int(k)


_eig_cache: OrderedDict = OrderedDict()


def _host_eigh(edges, diag, vals, mass, *, k: int, dense_max: int, cluster_rtol: float):
    """The host eigensolve, remembered for the last few inputs (a concrete call solves
    once to raise a clean error, and the callback then finds the result)."""
    edges, diag, vals, mass = (np.asarray(z) for z in (edges, diag, vals, mass))
    h = hashlib.blake2b(digest_size=16)
    for z in (edges, diag, vals, mass):
        h.update(np.ascontiguousarray(z).tobytes())
        h.update(str(z.dtype).encode())
    key = (h.hexdigest(), k, dense_max, cluster_rtol)
    with _lock:
        hit = _eig_cache.get(key)
    if hit is None:
        hit = _solve_eigh(edges, diag, vals, mass, k=k, dense_max=dense_max, cluster_rtol=cluster_rtol)
        with _lock:
            _eig_cache[key] = hit
            while len(_eig_cache) > 8:
                _eig_cache.popitem(last=False)
    return hit


def _solve_eigh(edges, diag, vals, mass, *, k: int, dense_max: int, cluster_rtol: float):
    n = len(diag)
    if not np.all(mass > 0):
        raise ValueError("eigenpairs: the mass must be positive")
    rows = np.concatenate([np.arange(n), edges[:, 0], edges[:, 1]])
    cols = np.concatenate([np.arange(n), edges[:, 1], edges[:, 0]])
    s = 1 / np.sqrt(mass.astype(np.float64))
    data = np.concatenate([diag, vals, vals]).astype(np.float64) * s[rows] * s[cols]
    mat = sp.csr_matrix((data, (rows, cols)), shape=(n, n))
    bound = float(np.abs(mat).sum(axis=1).max()) or 1.0
    tol = cluster_rtol * bound
    kk = min(n, k + _PAD)
    w, y = smallest(mat, kk, n <= dense_max, sigma=-1e-3 * bound)
    if k < len(w) and w[k] - w[k - 1] <= tol:
        ok = [j for j in range(1, len(w)) if w[j] - w[j - 1] > tol]
        raise ValueError(f"eigenpairs: k = {k} cuts a cluster of equal eigenvalues ({w[k - 1]:.6g} = {w[k]:.6g}); "
                         f"take k in {ok[:12]} (or another k that ends a cluster)")
    y = canonical(y, w, tol)
    return w[:k], s[:, None] * y[:, :k], np.float64(bound)


@functools.lru_cache(maxsize=64)
def _eig_fn(k: int, dense_max: int, cluster_rtol: float, with_vectors: bool):
    """The custom-JVP eigensolver for one static configuration."""

    def host(e, d, a, m):     # one function per configuration: an eager call's program is kept
        w, u, b = _host_eigh(e, d, a, m, k=k, dense_max=dense_max, cluster_rtol=cluster_rtol)
        dtype = np.asarray(d).dtype
        return w.astype(dtype), u.astype(dtype), np.asarray(b, dtype)

    def primal(edges, diag, vals, mass):
        n = diag.shape[0]
        dtype = diag.dtype
        out = (jax.ShapeDtypeStruct((k,), dtype), jax.ShapeDtypeStruct((n, k), dtype), jax.ShapeDtypeStruct((), dtype))
        return jax.pure_callback(host, out, edges, diag, vals, mass, vmap_method="sequential")

    f = jax.custom_jvp(primal)

    @f.defjvp
    def jvp(primals, tangents):
        edges, diag, vals, mass = primals
        _, d_dot, a_dot, m_dot = tangents
        w, u, bound = f(edges, diag, vals, mass)
        au = sparse_matvec(edges, d_dot, a_dot, u)                        # Ȧ U
        mu = m_dot[:, None] * u                                           # Ṁ U
        raw = jnp.sum(u * au, 0) - w * jnp.sum(u * mu, 0)
        cluster = jnp.concatenate([jnp.zeros(1, jnp.int32),
                                   jnp.cumsum((jnp.diff(w) > cluster_rtol * bound).astype(jnp.int32))])
        same = cluster[:, None] == cluster[None, :]                       # (k, k)
        w_dot = (same.astype(w.dtype) @ raw) / jnp.sum(same, 1).astype(w.dtype)
        if not with_vectors:
            return (w, u, bound), (w_dot, jnp.zeros_like(u), jnp.zeros_like(bound))
        rhs = -(au - w[None, :] * mu)                                     # (n, k)
        y = _bordered_solve(edges, diag, vals, mass, w, u, same, rhs)
        # keep Uᵀ M U = I: the symmetric in-cluster part −½ U_cᵀ Ṁ U_c (its antisymmetric
        # part, a rotation inside the cluster, is the gauge: 0)
        u_dot = y - 0.5 * u @ (same.astype(u.dtype) * (u.T @ mu))
        return (w, u, bound), (w_dot, u_dot, jnp.zeros_like(bound))

    return f


def _bordered_solve(edges, diag, vals, mass, w, u, same, rhs):
    """Column i of the result solves the bordered system of the module docstring for
    λ_i (border: the eigenvectors of i's cluster; the other border rows are −μ_j = 0)."""
    n, k = u.shape
    mu_ = mass[:, None] * u                                              # M U
    maskf = same.astype(u.dtype)                                          # (i, j): j in i's cluster

    def matvec(z):                                                        # z: (n + k, k), column i: system i
        y, mu = z[:n], z[n:]
        top = sparse_matvec(edges, diag, vals, y) - w[None, :] * mass[:, None] * y + mu_ @ (maskf.T * mu)
        bottom = maskf.T * (mu_.T @ y) - (1 - maskf.T) * mu
        return jnp.concatenate([top, bottom], 0)

    def solve(_, r):
        return _host_bordered(edges, diag, vals, mass, w, u, maskf, r)

    b = jnp.concatenate([rhs, jnp.zeros((k, k), rhs.dtype)], 0)
    return jax.lax.custom_linear_solve(matvec, b, solve, symmetric=True)[:n]


_cache: OrderedDict = OrderedDict()


def _host_bordered(edges, diag, vals, mass, w, u, maskf, r):
    out_type = jax.ShapeDtypeStruct(r.shape, r.dtype)

    def host(e, d, a, m, w, u, mask, r):
        e, d, a, m, w, u, mask, r = (np.asarray(z) for z in (e, d, a, m, w, u, mask, r))
        n, k = u.shape
        out = np.empty(r.shape, r.dtype)
        mu = m[:, None] * u
        for i in range(k):
            h = hashlib.blake2b(digest_size=16)
            for z in (e, d, a, m, u, mask[:, i], np.float64(w[i])):
                h.update(np.ascontiguousarray(z).tobytes())
            key = h.hexdigest()
            with _lock:
                lu = _cache.get(key)
            if lu is None:
                rows = np.concatenate([np.arange(n), e[:, 0], e[:, 1]])
                cols = np.concatenate([np.arange(n), e[:, 1], e[:, 0]])
                data = np.concatenate([d - w[i] * m, a, a]).astype(np.float64)
                top = sp.csr_matrix((data, (rows, cols)), shape=(n, n))
                border = sp.csr_matrix(mu * mask[None, :, i])
                corner = sp.diags(-(1.0 - mask[:, i]))
                mat = sp.bmat([[top, border], [border.T, corner]], format="csc")
                lu = spla.splu(mat)
                with _lock:
                    _cache[key] = lu
                    while len(_cache) > 64:
                        _cache.popitem(last=False)
            out[:, i] = lu.solve(r[:, i].astype(np.float64)).astype(r.dtype)
        return out

    return jax.pure_callback(host, out_type, edges, diag, vals, mass, w, u, maskf, r, vmap_method="sequential")
