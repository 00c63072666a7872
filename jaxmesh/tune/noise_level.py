"""Estimating the noise level σ of a mesh from the mesh alone.

Model: y = x + η, x a smooth surface, η per vertex either isotropic
N(0, σ² I) (thesis ch.2 eq.1) or N(0, σ²) along the normal; both give a normal
component of standard deviation σ, and every estimator below reads the normal
component only.

**"quadric"**.  For every vertex i, in a frame with origin y_i
and axis n_i (the noisy mesh's area-weighted normal, averaged over the 1-ring),
fit a quadratic height field h(u, v) = c₀ + c₁u + c₂v + c₃u² + c₄uv + c₅v² by
least squares to its 2-ring neighbours (not to i itself).  The prediction
residual r_i = h_i − c₀ = −c₀ removes the surface up to second order, so what
is left is noise plus third-order detail; for pure noise, with M_i = ΦᵀΦ the
normal matrix of the fit, Var(r_i) = σ² (1 + (M_i⁻¹)₀₀) exactly.  Hence

    σ̂ = 1.4826 · MAD_i( r_i / √(1 + (M_i⁻¹)₀₀) ),

over the vertices with at least 8 neighbours in the 2-ring and a
well-conditioned fit; the MAD keeps creases and corners (where no quadric
fits) from counting.

**"umbrella"**.  The umbrella
operator K = D⁻¹A − I is a high-pass filter; n_i · (K²η)_i has standard
deviation σ ‖row_i(K²)‖, so σ̂ = 1.4826 · MAD_i(n_i · (K² y)_i / ‖row_i(K²)‖).
The normals n_i are those of the mesh after three umbrella steps x ← x + ½Kx:
the noisy mesh's own normals are tilted by the noise, and the projection onto
them would miss part of it.  On irregular, detailed meshes K² leaves the
surface's own curvature times the sampling irregularity in the residual, which
reads as noise at low σ; and the MAD is robust only while such vertices are a
minority (not on a CAD model whose curved and sharp parts hold half its
vertices).

**"flat"**: the flattest patches, after Liu, Tanaka & Okutomi's weak-textured
patches for images.  With z_i = n_i · (K² y)_i / ‖row_i(K²)‖ as above, take the
mean of z² over the 2-ring patch of every vertex and the 10% quantile T(y) of
those patch means: the patches where the surface's own detail adds least.
For pure noise T scales as σ², but its constant depends on the mesh's
connectivity (overlapping patches, correlated residuals), so it is calibrated
on the mesh itself: T₁ is the same statistic of unit noise along the normals
(4 fixed draws), and σ̂ = √(T(y) / T₁).  Deterministic, and exactly
equivariant (scale) and invariant (rigid motions).  It reads the noise where
the surface is smoothest, so a CAD model's flat half counts; calibrated along
the normals, it reads isotropic noise a little high.

**"min"** (the default): the smaller of "flat" and "umbrella".  Both count the
surface's own detail as noise, so each over-reads; the smaller over-reads less.

How each reads on the shared meshes (σ̂/σ at 0.02–0.3ℓ̄, both noise models,
the clean meshes' own roughness, and what did not separate roughness from
noise): the denoising guide and ``experiments/denoise/noise_estimate.py``.
"""

from __future__ import annotations

import warnings

import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp

from .._exported import stored_jit
from .._private import caller_stacklevel
from ..geometry import mean_edge_length, vertex_normals
from ..host import HostMesh, as_host
from ..mesh import Mesh
from ..operators import umbrella

__all__ = ["estimate_noise", "estimate_tangential_noise", "noise_sigma", "checked_sigma", "blind_caveats",
           "BlindTuningWarning", "LOW_NOISE", "SIGMA_RANGE", "umbrella_square_row_norms", "NOISE_ESTIMATORS"]

#: below this σ̂ (in mean edge lengths) the estimators read a surface's own detail
#: as noise (the denoising guide, *the noise estimate*)
LOW_NOISE = 0.1


class BlindTuningWarning(UserWarning):
    """Blind tuning or choice cannot vouch for its result (see the message)."""

NOISE_ESTIMATORS = ("min", "flat", "quadric", "umbrella")

#: the given noise levels blind tuning accepts, in mean edge lengths ℓ̄: below, the noise sits under
#: float32's rounding of a mesh's coordinates; above, it is larger than the mesh itself (a mesh of a
#: million vertices spans about 10³ ℓ̄), and the estimates' squares leave floating point
SIGMA_RANGE = (1e-7, 1e3)

_MAD_TO_SIGMA = 1.482602218505602  # 1 / Φ⁻¹(3/4)


def umbrella_square_row_norms(mesh: Mesh | HostMesh) -> np.ndarray:
    """‖row_i(K²)‖ for every vertex (host, scipy; 0 for isolated vertices).

    Arguments:
        mesh: a single mesh, or its :class:`~jaxmesh.host.HostMesh`.

    Returns:
        (V,) float64."""
    return as_host(mesh).umbrella_square_row_norms


#: umbrella steps (λ = ½) smoothing the mesh whose normals the residuals are projected on
PROJECTION_SMOOTHING = 3


@stored_jit
def _projection_normals(mesh: Mesh):
    """n_i: the area-weighted vertex normals of the mesh after
    :data:`PROJECTION_SMOOTHING` umbrella steps x ← x + ½ K x (module docstring)."""
    from ..denoise.laplacian import umbrella_flow

    return vertex_normals(umbrella_flow(mesh, 0.5, PROJECTION_SMOOTHING), "area")


def projection_normals(host: HostMesh):
    """The projection normals n of the module docstring, computed once per mesh.

    Arguments:
        host: the mesh's :class:`~jaxmesh.host.HostMesh`.

    Returns:
        (V, 3), the mesh's dtype."""
    return host.memo("projection_normals", lambda: _projection_normals(host.mesh))


def _normal_high_pass(mesh: Mesh, u, normals) -> np.ndarray:
    """n_i · (K² u)_i, n the projection normals (host array)."""
    return np.asarray(_k2_parts(mesh, jnp.asarray(u, mesh.dtype), normals)[0], dtype=np.float64)


@stored_jit
def _k2_parts(mesh: Mesh, u, n):
    """(n_i · (K² u)_i, (I − n_i n_iᵀ)(K² u)_i): the normal and tangential parts of K² u."""
    k2 = umbrella(mesh, umbrella(mesh, u))
    normal = jnp.sum(k2 * n, axis=-1)
    return normal, k2 - normal[:, None] * n


def _patch_statistic(z2: np.ndarray, patches: sp.csr_matrix, ok: np.ndarray, quantile: float) -> float:
    """The ``quantile`` of the patch means of z² (vertices with ``ok`` only)."""
    count = patches @ ok.astype(np.float64)
    mean = (patches @ np.where(ok, z2, 0.0))[count > 0] / count[count > 0]
    return float(np.quantile(mean, quantile)) if mean.size else 0.0


def _patches(host: HostMesh) -> sp.csr_matrix:
    """The 2-ring patches: R₂ + I, 0/1."""
    return host.memo("two_ring_patches", lambda: (host.two_ring + sp.identity(host.mesh.num_vertices, format="csr")
                                                  ).tocsr())


def _flat_patch_sigma(host: HostMesh, g: np.ndarray, high_pass: np.ndarray, n_jax, quantile: float = 0.1,
                      draws: int = 4) -> float:
    """σ̂ from the flattest patches, calibrated by simulation (module docstring);
    ``g`` = ‖row_i(K²)‖, ``high_pass`` = n · K² y, ``n_jax`` the projection normals n."""
    mesh = host.mesh
    ok = g > 0
    gs = np.where(ok, g, 1.0)
    ring = _patches(host)
    observed = _patch_statistic((high_pass / gs) ** 2, ring, ok, quantile)
    n = np.asarray(n_jax, dtype=np.float64)
    rng = np.random.default_rng(0)
    unit = np.mean([_patch_statistic((_normal_high_pass(mesh, rng.standard_normal((len(g), 1)) * n, n_jax) / gs) ** 2,
                                     ring, ok, quantile) for _ in range(draws)])
    return float(np.sqrt(observed / unit)) if unit > 0 else 0.0


def _quadric_residuals(host: HostMesh) -> np.ndarray:
    """r_i / √(1 + (M_i⁻¹)₀₀) for every vertex with a usable fit (module docstring)."""
    mesh = host.mesh
    y = np.asarray(mesh.vertices, dtype=np.float64)
    nv = y.shape[0]
    adj = host.two_ring
    rows = np.repeat(np.arange(nv), np.diff(adj.indptr))
    cols = adj.indices
    n1 = np.asarray(vertex_normals(mesh.astype(jnp.float64) if mesh.dtype != jnp.float64 else mesh, "area"),
                    dtype=np.float64)
    a1 = n1 + host.adjacency @ n1
    n = a1 / np.maximum(np.linalg.norm(a1, axis=1, keepdims=True), 1e-300)
    t1 = np.cross(n, np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-300)
    t2 = np.cross(n, t1)
    ell = float(mean_edge_length(mesh))
    d = (y[cols] - y[rows]) / ell
    u = np.sum(d * t1[rows], axis=1)
    v = np.sum(d * t2[rows], axis=1)
    h = np.sum(d * n[rows], axis=1)
    phi = np.stack([np.ones_like(u), u, v, u * u, u * v, v * v], axis=1)          # (nnz, 6)
    m = np.stack([np.bincount(rows, phi[:, a] * phi[:, b], minlength=nv)
                  for a in range(6) for b in range(6)], axis=1).reshape(nv, 6, 6)
    rhs = np.stack([np.bincount(rows, phi[:, a] * h, minlength=nv) for a in range(6)], axis=1)
    count = np.diff(adj.indptr)
    good = (count >= 8) & (np.linalg.cond(m) < 1e8)
    if not good.any():
        return np.zeros(0)
    sol = np.linalg.solve(m[good], np.stack([rhs[good], np.eye(6)[None, :, 0].repeat(good.sum(), 0)], -1))
    c0, inv00 = sol[:, 0, 0], sol[:, 0, 1]
    return ell * (-c0) / np.sqrt(1 + inv00)


def estimate_noise(mesh: Mesh | HostMesh, method: str = "min") -> float:
    """σ̂ of the module docstring, in the mesh's units (equivariant: scaling the
    mesh by s scales σ̂ by s; translation and rotation leave it unchanged).
    ``method``: "min" (default), "flat", "umbrella" or "quadric".

    Arguments:
        mesh: a single mesh, or its :class:`~jaxmesh.host.HostMesh`.
        method: ``"min"``, ``"flat"``, ``"umbrella"`` or ``"quadric"``.

    Returns:
        σ̂, in the mesh's units."""
    if isinstance(mesh, Mesh) and mesh.batch_shape:
        raise ValueError("estimate_noise takes one mesh; loop over a batch")
    if method not in NOISE_ESTIMATORS:
        raise ValueError(f"method must be one of {NOISE_ESTIMATORS}, got {method!r}")
    host = as_host(mesh)
    mesh = host.mesh
    if method == "quadric":
        r = _quadric_residuals(host)
        # too small or too irregular for a quadric: fall back
        return _mad_sigma(r) if r.size else estimate_noise(host, "umbrella")
    g = host.umbrella_square_row_norms
    ok = g > 0
    if not ok.any():
        raise ValueError("estimate_noise: the mesh has no vertex with neighbours")
    n = projection_normals(host)
    high_pass = _normal_high_pass(mesh, mesh.vertices, n)
    umbrella_sigma = _mad_sigma(high_pass[ok] / g[ok]) if method != "flat" else np.inf
    flat_sigma = _flat_patch_sigma(host, g, high_pass, n) if method != "umbrella" else np.inf
    return min(umbrella_sigma, flat_sigma)


def _tangent_frames(mesh: Mesh, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents (t1, t2) per vertex, orthogonal to ``n``, t1 along the edge to a
    neighbour fixed by the connectivity: built from the mesh alone, so they move with
    it (calibration draws in these frames keep the estimate rotation invariant)."""
    f = np.asarray(mesh.faces)
    nxt = np.zeros(mesh.num_vertices, dtype=np.int64)
    for corner in range(3):
        nxt[f[:, corner]] = f[:, (corner + 1) % 3]
    y = np.asarray(mesh.vertices, dtype=np.float64)
    e = y[nxt] - y
    t1 = e - np.sum(e * n, axis=1, keepdims=True) * n
    t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-300)
    return t1, np.cross(n, t1)


def estimate_tangential_noise(mesh: Mesh | HostMesh, quantile: float = 0.1, draws: int = 2) -> float:
    """σ̂_t, the noise's standard deviation *within* the surface (per tangential
    axis), in the mesh's units: the "flat" statistic of the module docstring on
    the tangential part t_i = (I − n_i n_iᵀ)(K² y)_i, the ``quantile`` of the
    2-ring patch means of ‖t_i‖² / ‖row_i(K²)‖², calibrated by the same
    statistic of unit noise in the tangent planes (``draws`` fixed draws).
    Isotropic noise of σ reads σ̂_t ≈ σ, noise along the normals σ̂_t ≪ σ; the
    mesh's own sampling irregularity reads as tangential noise
    (``experiments/denoise/noise_estimate.py`` measures it on clean meshes).

    Arguments:
        mesh: a single mesh, or its :class:`~jaxmesh.host.HostMesh`.
        quantile: the quantile of the patch means.
        draws: the calibration draws.

    Returns:
        σ̂_t, in the mesh's units."""
    if isinstance(mesh, Mesh) and mesh.batch_shape:
        raise ValueError("estimate_tangential_noise takes one mesh; loop over a batch")
    host = as_host(mesh)
    mesh = host.mesh
    g = host.umbrella_square_row_norms
    ok = g > 0
    if not ok.any():
        raise ValueError("estimate_tangential_noise: the mesh has no vertex with neighbours")
    gs = np.where(ok, g, 1.0)
    n = projection_normals(host)
    ring = _patches(host)

    def statistic(u) -> float:
        t = np.asarray(_k2_parts(mesh, jnp.asarray(u, mesh.dtype), n)[1], dtype=np.float64)
        return _patch_statistic(np.sum(t * t, axis=1) / gs**2, ring, ok, quantile)

    t1, t2 = _tangent_frames(mesh, np.asarray(n, dtype=np.float64))
    rng = np.random.default_rng(0)
    unit = []
    for _ in range(draws):
        xi = rng.standard_normal((mesh.num_vertices, 2, 1))
        unit.append(statistic(xi[:, 0] * t1 + xi[:, 1] * t2))
    unit = float(np.mean(unit))
    return float(np.sqrt(statistic(mesh.vertices) / unit)) if unit > 0 else 0.0


def _mad_sigma(r: np.ndarray) -> float:
    """1.4826 · MAD(r): σ of the Gaussian part of r, robust to a minority of outliers."""
    return float(_MAD_TO_SIGMA * np.median(np.abs(r - np.median(r))))


def noise_sigma(mesh: Mesh | HostMesh, sigma=None) -> tuple[float, bool]:
    """(σ, estimated) for blind tuning: ``sigma`` checked (finite, > 0) or, when
    None, :func:`estimate_noise`, refused when it is not positive (a mesh too
    small, or too exactly smooth, for the estimator: give σ instead).

    Arguments:
        mesh: a single mesh, or its :class:`~jaxmesh.host.HostMesh`.
        sigma: a given σ, or None to estimate.

    Returns:
        (σ, estimated)."""
    host = as_host(mesh)
    mesh = host.mesh
    if sigma is not None:
        return float(checked_sigma(mesh, sigma)), False
    s = estimate_noise(host)
    if not (np.isfinite(s) and s > 0):
        raise ValueError(
            f"the noise of this mesh cannot be estimated (estimate {s:g} from {mesh.num_vertices} vertices: "
            "too few, or an exactly smooth surface); give the noise level (CLI: --noise-sigma)")
    return s, True


def checked_sigma(mesh: Mesh, sigma) -> np.ndarray:
    """A given noise level, refused unless it is a positive number within ``SIGMA_RANGE``
    mean edge lengths of ``mesh`` (of each mesh of a batch of positions).

    Arguments:
        mesh: a mesh (single, or with batched vertices (*batch, V, 3)).
        sigma: the noise standard deviation in mesh units: a number, or one per batch element.

    Returns:
        σ as a float64 array of ``sigma``'s shape."""
    s = np.asarray(sigma, np.float64)
    if not (np.all(np.isfinite(s)) and np.all(s > 0)):
        raise ValueError(f"the noise sigma must be a positive number (mesh units), got {sigma!r}")
    ell = np.asarray(mean_edge_length(mesh), np.float64)
    low, high = SIGMA_RANGE
    ratio = s / np.where(ell > 0, ell, 1.0)
    bad = (ell > 0) & ~((ratio >= low) & (ratio <= high))
    if np.any(bad):
        r, e = np.broadcast_to(ratio, bad.shape)[bad].flat[0], np.broadcast_to(ell, bad.shape)[bad].flat[0]
        raise ValueError(f"the noise sigma {r * e:g} is {r:.3g} mean edge lengths of this mesh (mean edge length "
                         f"{e:.4g}); give one between {low:g} and {high:g} mean edge lengths, in mesh units")
    return s


def blind_caveats(mesh: Mesh, sigma: float, estimated: bool, relative_risk: float) -> list[str]:
    """What a blind result cannot vouch for: ``relative_risk`` (estimated error of
    the output over the input's, ≥ 1 means no improvement is estimated) and an
    estimated σ in the range where the estimator is unreliable.  Each caveat is
    also issued as a :class:`BlindTuningWarning`.

    Arguments:
        mesh: a single mesh.
        sigma: the σ used.
        estimated: whether σ was estimated.
        relative_risk: the estimated error ratio output/input.

    Returns:
        The caveats, as sentences."""
    out = []
    if not relative_risk < 1:
        out.append(f"the result is not estimated to improve on the input (estimated error {relative_risk:.3g}x "
                   "the input's): the mesh may already be clean, or the noise overestimated")
    ratio = sigma / float(mean_edge_length(mesh))
    if estimated and ratio < LOW_NOISE:
        out.append(f"the estimated noise, {ratio:.3g} mean edge lengths, is below {LOW_NOISE:g}, where the "
                   "estimator also counts the surface's own detail (up to 3x too high): the result may be "
                   "over-smoothed; give the noise level if you know it (CLI: --noise-sigma)")
    for text in out:
        warnings.warn(text, BlindTuningWarning, stacklevel=caller_stacklevel())
    return out
