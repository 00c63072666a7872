"""The eigenvalue density of a mesh's Laplacian at any size: the kernel polynomial method.

The spectral measure of an n × n symmetric matrix A is ρ(λ) = (1/n) Σ_i δ(λ − λ_i);
its cumulative distribution F(λ) = #{λ_i ≤ λ}/n is the normalised rank, so the
thesis's plot of eigenvalue against rank is F⁻¹.  With A's spectrum inside [a, b],
x = (λ − c)/h (c = (a + b)/2, h = (b − a)/2) maps it into [−1, 1], where

    ρ(x) = [μ_0 + 2 Σ_{m≥1} g_m μ_m T_m(x)] / (π √(1 − x²)),    μ_m = tr T_m(Ã) / n,

T_m the Chebyshev polynomials and Ã = (A − cI)/h (Weiße, Wellein, Alvermann &
Fehske 2006).  The series is cut at M moments and damped by the Jackson kernel

    g_m = [(M − m + 1) cos(πm/(M + 1)) + sin(πm/(M + 1)) cot(π/(M + 1))] / (M + 1),

which keeps the density non-negative and smears each eigenvalue over about π h / M.
The moments are stochastic traces (Hutchinson): μ_m ≈ (1/(nR)) Σ_r z_rᵀ T_m(Ã) z_r
over R Rademacher probes, from M/2 products with Ã by the doubling identities
μ_{2k} = 2⟨T_k z, T_k z⟩ − μ_0 and μ_{2k+1} = 2⟨T_{k+1} z, T_k z⟩ − μ_1.  The products
gather the matrix's entries row by row: each row's first ``ROW_WIDTH`` entries from a padded
(n, K) table of columns and values, K the longest row up to that width, the rest (rows of a
vertex of higher degree) by segment sums (no dense matrix; memory O(nR + nK)).  With
x = cos θ the distribution function integrates term by term:

    F(θ) = μ_0 (π − θ)/π − (2/π) Σ_{m≥1} g_m μ_m sin(mθ)/m.

Both Laplacians are positive semi-definite, so the spectrum lies in [0, λ_max], λ_max
from Lanczos (``eigsh`` to a relative residual of 1e-5; Gershgorin's 2 max_i d_i for
L = D − A and 2 for 𝓛 = I − D^{-1/2} A D^{-1/2} where it does not converge); [a, b] is
that interval widened by ``MARGIN`` of its length so that no eigenvalue sits on ±1.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import sparse as jsparse
from .._exported import stored_jit
from .._private import seed_array
from ..mesh import Mesh, to_device
from ._graph import single

__all__ = ["SpectralDensity", "spectral_density", "density_quantiles", "spectrum_distance", "largest_eigenvalue",
           "laplacian_of_kind", "jackson", "MOMENTS", "PROBES", "MARGIN"]

#: Chebyshev moments M (the density's resolution is about π h / M)
MOMENTS = 256
#: Rademacher probes R of the stochastic traces
PROBES = 16
#: the most entries a row keeps in the padded table of the matrix products (module docstring)
ROW_WIDTH = 16
#: the spectrum's interval [a, b] is widened by this share of its length at each end
MARGIN = 1e-3


class SpectralDensity(NamedTuple):
    """The estimated eigenvalue distribution (module docstring): ``eigenvalue`` (G,) ascending
    over [a, b], the distribution function ``cdf`` (G,) there (0 at a, 1 at b) and the
    ``density`` (G,) (0 at the two ends, where it is not defined); ``moments`` (M,) the damped
    Chebyshev moments g_m μ_m; ``bounds`` (a, b), the interval mapped to [−1, 1]; ``support``
    (0, λ_max), where every eigenvalue lies."""

    eigenvalue: np.ndarray
    cdf: np.ndarray
    density: np.ndarray
    moments: np.ndarray
    bounds: tuple[float, float]
    support: tuple[float, float]


def jackson(count: int) -> np.ndarray:
    """The Jackson damping factors g_0 … g_{M−1} (module docstring).

    Arguments:
        count: M, the number of moments.

    Returns:
        (M,) float64."""
    m = np.arange(count)
    q = np.pi / (count + 1)
    return ((count - m + 1) * np.cos(q * m) + np.sin(q * m) / np.tan(q)) / (count + 1)


@stored_jit(static_argnames=("n", "count", "probes"))
def _moments(table, rest, centre, half, seed, n: int, count: int, probes: int):
    """μ_0 … μ_{count−1} of Ã = (A − centre I)/half from ``probes`` Rademacher probes (n, R) drawn
    from ``seed`` (module docstring); A given by :func:`_row_table`'s ``table`` and ``rest``.  The
    draw is part of the program: one program to keep."""
    (columns, weights), (rows, cols, vals) = table, rest

    def apply(x):                                    # Ã x
        ax = sum(weights[:, j, None] * x[columns[:, j]] for j in range(columns.shape[1]))
        ax = ax + jax.ops.segment_sum(vals[:, None] * x[cols], rows, num_segments=n)
        return (ax - centre * x) / half

    z = jax.random.rademacher(jax.random.key(seed), (n, probes), weights.dtype)
    norm = n * probes
    t0, t1 = z, apply(z)
    mu0, mu1 = jnp.sum(t0 * t0) / norm, jnp.sum(t1 * t0) / norm

    def step(carry, _):
        prev, cur = carry                            # T_{k−1} z, T_k z
        nxt = 2 * apply(cur) - prev
        return (cur, nxt), (2 * jnp.sum(cur * cur) / norm - mu0, 2 * jnp.sum(nxt * cur) / norm - mu1)

    _, (even, odd) = jax.lax.scan(step, (t0, t1), None, length=(count + 1) // 2 - 1)
    # step k = 1, 2, …: carry (T_{k−1} z, T_k z) gives μ_{2k} and μ_{2k+1}
    pairs = jnp.concatenate([jnp.stack([mu0, mu1])[None], jnp.stack([even, odd], axis=1)])
    return pairs.reshape(-1)[:count]


def _row_table(mat, width: int = ROW_WIDTH):
    """A sparse matrix as ((columns (n, K) int32, values (n, K)), (rows, cols, vals)): each row's
    first K = min(longest row, ``width``) entries in the table (padding: the row's own index,
    value 0), the entries past them as triples; A x = Σ_j values[:, j] x[columns[:, j]] plus the
    triples' segment sums."""
    csr = mat.tocsr()
    n = csr.shape[0]
    counts = np.diff(csr.indptr)
    k = max(1, min(int(counts.max(initial=0)), width))
    row = np.repeat(np.arange(n), counts)
    pos = np.arange(csr.nnz) - csr.indptr[row]
    inside = pos < k
    columns = np.repeat(np.arange(n, dtype=np.int32)[:, None], k, axis=1)
    values = np.zeros((n, k), csr.dtype)
    columns[row[inside], pos[inside]] = csr.indices[inside]
    values[row[inside], pos[inside]] = csr.data[inside]
    past = ~inside
    return (columns, values), (row[past].astype(np.int32), csr.indices[past].astype(np.int32), csr.data[past])


def laplacian_of_kind(mesh, kind: str):
    """L = D − A (``"combinatorial"``) or 𝓛 = I − D^{-1/2} A D^{-1/2} (``"normalized"``) as a scipy
    matrix, and the Gershgorin bound on its largest eigenvalue (2 max_i d_i, or 2).

    Arguments:
        mesh: a single mesh (or its graph view).
        kind: ``"combinatorial"`` or ``"normalized"``.

    Returns:
        (the matrix, the bound)."""
    if kind == "combinatorial":
        return jsparse.laplacian_matrix(mesh), 2.0 * float(np.max(np.asarray(mesh.degree), initial=1))
    if kind == "normalized":
        return jsparse.normalized_laplacian_matrix(mesh), 2.0
    raise ValueError(f"kind must be 'combinatorial' or 'normalized', got {kind!r}")


#: the relative residual :func:`largest_eigenvalue` asks of Lanczos: the Ritz value is then within
#: 1e-5 λ_max of an eigenvalue, a hundredth of the interval's widening (``MARGIN``)
LANCZOS_TOLERANCE = 1e-5


def largest_eigenvalue(mat, bound: float) -> float:
    """λ_max of a symmetric positive semi-definite matrix: Lanczos (``eigsh``) to a relative
    residual of ``LANCZOS_TOLERANCE``, a dense solver below 64 rows; ``bound`` (a Gershgorin
    bound) where Lanczos does not converge.

    Arguments:
        mat: a scipy sparse symmetric matrix.
        bound: an upper bound on its eigenvalues.

    Returns:
        λ_max, at most ``bound``."""
    import scipy.linalg
    import scipy.sparse.linalg as spla

    from .._eigen import start_vector

    n = mat.shape[0]
    if n < 64:
        return float(min(scipy.linalg.eigvalsh(mat.toarray())[-1], bound))
    try:
        top = spla.eigsh(mat, k=1, which="LA", tol=LANCZOS_TOLERANCE, v0=start_vector(n),
                         return_eigenvectors=False)
    except spla.ArpackNoConvergence:
        return bound
    return float(min(top[0], bound))


def _seed_array(seed) -> np.ndarray:
    """``seed`` as the integer array ``jax.random.key`` makes of it (int64 with 64-bit types on)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be an int, got {seed!r}")
    array = seed_array(int(seed))
    if array is None:
        raise ValueError(f"seed {seed} does not fit in {'int64' if jax.config.jax_enable_x64 else 'int32'}")
    return array


def spectral_density(mesh: Mesh, kind: str = "combinatorial", moments: int = MOMENTS, probes: int = PROBES,
                     seed: int = 0, points: int = 2049) -> SpectralDensity:
    """The eigenvalue distribution of L = D − A (``kind="combinatorial"``) or
    𝓛 = I − D^{-1/2} A D^{-1/2} (``"normalized"``) by the kernel polynomial method (module
    docstring), matrix-free: memory O(V · probes).

    Arguments:
        mesh: a single mesh (or its graph view).
        kind: ``"combinatorial"`` or ``"normalized"``.
        moments: M, the Chebyshev moments (≥ 2).
        probes: R, the Rademacher probes (≥ 1).
        seed: the probes' seed.
        points: G, the grid points of the result (≥ 3), uniform in θ = arccos x.

    Returns:
        A :class:`SpectralDensity`."""
    single(mesh)
    for name, value, least in (("moments", moments, 2), ("probes", probes, 1), ("points", points, 3)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
    mat, bound = laplacian_of_kind(mesh, kind)
    n = mat.shape[0]
    if n == 0:
        raise ValueError("the mesh has no vertices")
    top = max(largest_eigenvalue(mat, bound), 1e-12)
    a, b = -MARGIN * top, top * (1 + MARGIN)
    dtype = jnp.result_type(float)
    (columns, values), (rows, cols, vals) = _row_table(mat)
    table = (to_device(columns), to_device(values, dtype))
    rest = (to_device(rows), to_device(cols), to_device(vals, dtype))
    mu = np.asarray(_moments(table, rest, (a + b) / 2, (b - a) / 2, _seed_array(seed), n=n, count=int(moments),
                             probes=int(probes)), np.float64)
    damped = jackson(int(moments)) * mu
    theta = np.linspace(np.pi, 0.0, points)                   # λ ascending
    m = np.arange(1, int(moments))
    cdf = damped[0] * (np.pi - theta) / np.pi - (2 / np.pi) * (np.sin(np.outer(theta, m)) @ (damped[1:] / m))
    cdf = np.clip(np.maximum.accumulate(cdf), 0.0, 1.0)       # monotone: stochastic moments can dip
    x = np.cos(theta)
    inner = np.sin(theta) > 0
    density = np.zeros(points)
    series = damped[0] + 2 * (np.cos(np.outer(theta[inner], m)) @ damped[1:])
    density[inner] = np.maximum(series, 0) / (np.pi * np.sin(theta[inner]) * (b - a) / 2)
    return SpectralDensity((a + b) / 2 + (b - a) / 2 * x, cdf, density, damped, (a, b), (0.0, top))


def density_quantiles(density: SpectralDensity, ranks) -> np.ndarray:
    """F⁻¹(r): the eigenvalue at each normalised rank r ∈ [0, 1] (the thesis's spectrum plot),
    within the support (the smearing of the Jackson kernel reaches a little beyond it).

    Arguments:
        density: a :class:`SpectralDensity`.
        ranks: normalised ranks in [0, 1].

    Returns:
        The eigenvalues, ``ranks``' shape."""
    r = np.asarray(ranks, np.float64)
    if np.any((r < 0) | (r > 1)):
        raise ValueError("ranks must lie in [0, 1]")
    # where F is flat its inverse is any λ of the flat stretch: take the first (np.interp on the
    # non-decreasing F, strictly increased by a ramp far below any probability step)
    ramp = np.arange(len(density.cdf)) * 1e-12
    return np.clip(np.interp(r, density.cdf + ramp, density.eigenvalue), *density.support)


def spectrum_distance(density: SpectralDensity, eigenvalues) -> float:
    """The Wasserstein-1 distance ∫ |F(λ) − F_exact(λ)| dλ between the estimated distribution
    and the spectrum ``eigenvalues`` (each of weight 1/n), on the density's grid.

    Arguments:
        density: a :class:`SpectralDensity`.
        eigenvalues: the exact eigenvalues, (n,).

    Returns:
        W₁, in eigenvalue units."""
    lam = np.sort(np.asarray(eigenvalues, np.float64))
    grid = np.unique(np.concatenate([density.eigenvalue, lam]))
    estimate = np.interp(grid, density.eigenvalue, density.cdf)
    exact = np.searchsorted(lam, grid, side="right") / len(lam)
    gap = np.abs(estimate - exact)
    return float(np.sum(gap[:-1] * np.diff(grid)))        # F_exact is right-continuous and steps at grid points
