"""Detecting impulsive noise and estimating its law from the mesh alone.

Model (the literature's impulsive noise, :func:`jaxmesh.add_impulsive_noise`):
y_i = x_i + b_i ξ_i n_i with b_i ~ Bernoulli(p) and ξ_i ~ N(0, σ₁²), or, more
generally, a two-level scale mixture: each vertex's normal displacement has
variance σ₀² (b_i = 0) or σ₁² (b_i = 1).  Gaussian noise is σ₀ = σ₁.

**The residual.**  z_i = n_i · (K² y)_i / ‖row_i(K²)‖, the normalised high
pass of :mod:`jaxmesh.tune.noise_level` (K the umbrella operator, n_i the
projection normals).  With C = K², w_i = C_ii² / ‖row_i(C)‖² the share of
z_i's variance that is vertex i's own (≈ 0.74 on valence-6 meshes), and
o_i = Σ_{j≠i} C_ij² s_j² / ‖row_i(C)‖² its neighbours':

    Var(z_i | b) = w_i s_i² + o_i,    s_j² = σ₀² + b_j (σ₁² − σ₀²).

**The fit.**  First a two-component zero-mean Gaussian mixture on z by EM
(weights p̂, 1 − p̂; variances v₁ ≥ v₀); the neighbours' share is the same on
average for both components, so the noise levels are deconvolved as

    Δ = (v₁ − v₀) / w̄,   σ₀² = max(p̂ v₁ + (1 − p̂) v₀ − p̂ Δ, 0),   σ₁² = σ₀² + Δ.

Then the per-vertex posteriors π_i = P(b_i = 1 | z) are sharpened by a
mean-field pass: o_i is recomputed from the neighbours' current
E s_j² = σ₀² + π_j Δ, and π_i from the two Gaussian likelihoods of z_i with
variances w_i σ₀² + o_i and w_i σ₁² + o_i (``MEAN_FIELD_STEPS`` passes).

**The decision.**  The noise is called impulsive when σ₀ ≤ ``IMPULSIVE_RATIO``
· σ₁, σ₁ ≥ ``IMPULSIVE_FLOOR`` ℓ̄, p̂ ≥ ``IMPULSIVE_MIN_FRACTION`` and the mesh
has at least ``IMPULSIVE_MIN_VERTICES`` vertices (on a few hundred, the fit
of Gaussian noise wanders: a 386-vertex box read σ₀ = 0 under Gaussian noise
on one seed of two).  A clean
mesh's own creases and detail also read as a sparse heavy component (σ₁ up to
0.16ℓ̄ on the shared meshes), hence the floor; a handful of outlying vertices
(p̂ below the minimum) is not a noise law.  Measurements:
``experiments/denoise/impulsive_detection.py``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp

from ..geometry import mean_edge_length
from ..mesh import Mesh
from .noise_level import _normal_high_pass, _projection_normals

__all__ = ["ImpulsiveNoise", "estimate_impulsive_noise", "IMPULSIVE_RATIO", "IMPULSIVE_FLOOR", "IMPULSIVE_MIN_FRACTION", "IMPULSIVE_MIN_VERTICES", "MEAN_FIELD_STEPS",
           "scale_mixture_em"]

#: σ₀/σ₁ at or below which the noise is called impulsive (module docstring)
IMPULSIVE_RATIO = 0.35
#: σ₁ (in mean edge lengths) below which a heavy component is read as the surface's own detail
IMPULSIVE_FLOOR = 0.2
#: p̂ below which a heavy component is read as a few outliers, not a noise law
IMPULSIVE_MIN_FRACTION = 0.05
#: the fewest vertices on which the decision is made (module docstring)
IMPULSIVE_MIN_VERTICES = 1000
#: mean-field passes sharpening the per-vertex posteriors
MEAN_FIELD_STEPS = 5
_EM_STEPS, _EM_TOL = 300, 1e-7


@dataclasses.dataclass(frozen=True)
class ImpulsiveNoise:
    """The two-level noise law read from a mesh (module docstring).

    * ``fraction``: p̂, the share of vertices in the heavy component;
    * ``sigma``, ``sigma0``: σ₁ and σ₀, the normal displacement's standard
      deviation there and elsewhere (mesh units);
    * ``posterior``: π_i = P(b_i = 1 | mesh), (V,);
    * ``impulsive``: whether the law is read as impulsive (module docstring).
    """

    fraction: float
    sigma: float
    sigma0: float
    posterior: np.ndarray
    impulsive: bool

    def vertex_sigma(self) -> np.ndarray:
        """s_i = √(σ₀² + π_i (σ₁² − σ₀²)), each vertex's expected noise level, (V,).

        Returns:
            (V,) float64, mesh units."""
        return np.sqrt(self.sigma0**2 + self.posterior * (self.sigma**2 - self.sigma0**2))


def scale_mixture_em(z: np.ndarray, steps: int = _EM_STEPS, tol: float = _EM_TOL) -> tuple[float, float, float]:
    """The maximum-likelihood two-component zero-mean Gaussian mixture of ``z`` by EM:
    (p, v₀, v₁), p the weight of the component of larger variance v₁.

    Arguments:
        z: samples, (N,).
        steps: the most EM iterations.
        tol: stop when p moves by less.

    Returns:
        (p, v₀, v₁)."""
    z2 = np.asarray(z, dtype=np.float64) ** 2
    v = float(np.mean(z2))
    if not v > 0:
        return 0.0, 0.0, 0.0
    p, v0, v1 = 0.5, v / 4, 2 * v
    for _ in range(steps):
        r = _posterior(z2, p, v0, v1)
        p_new = float(np.mean(r))
        if not 0 < p_new < 1:
            return float(p_new), v, v
        v1 = max(float(np.sum(r * z2) / np.sum(r)), 1e-300)
        v0 = max(float(np.sum((1 - r) * z2) / np.sum(1 - r)), 1e-300)
        done = abs(p_new - p) < tol
        p = p_new
        if done:
            break
    return p, v0, v1


def _posterior(z2, p, v0, v1):
    """P(heavy | z) for the mixture p N(0, v₁) + (1 − p) N(0, v₀), with z² given (v may be per sample)."""
    log_ratio = np.log((1 - p) / p) + 0.5 * np.log(v1 / v0) + 0.5 * z2 * (1 / v1 - 1 / v0)
    return 1 / (1 + np.exp(np.clip(log_ratio, -700, 700)))


def estimate_impulsive_noise(mesh: Mesh) -> ImpulsiveNoise:
    """Fit the two-level noise law of the module docstring to ``mesh`` and decide
    whether it is impulsive.

    Arguments:
        mesh: a single mesh.

    Returns:
        An :class:`ImpulsiveNoise`."""
    from ..sparse import umbrella_matrix

    if mesh.batch_shape:
        raise ValueError("estimate_impulsive_noise takes one mesh; loop over a batch")
    k = umbrella_matrix(mesh)
    c2 = (k @ k).tocsr()
    sq = c2.multiply(c2).tocsr()
    g2 = np.asarray(sq.sum(axis=1)).ravel()
    ok = g2 > 0
    if not ok.any():
        raise ValueError("estimate_impulsive_noise: the mesh has no vertex with neighbours")
    own = np.where(ok, c2.diagonal() ** 2 / np.where(ok, g2, 1.0), 0.0)
    others = sp.diags(1 / np.where(ok, g2, 1.0)) @ (sq - sp.diags(sq.diagonal()))
    z = np.where(ok, _normal_high_pass(mesh, mesh.vertices, _projection_normals(mesh)) / np.sqrt(np.where(ok, g2, 1)),
                 0.0)
    p, v0, v1 = scale_mixture_em(z[ok])
    delta = max(v1 - v0, 0.0) / float(np.mean(own[ok]))
    s0 = max(p * v1 + (1 - p) * v0 - p * delta, 0.0)
    s1 = s0 + delta
    z2 = z * z
    pi = np.where(ok, _posterior(z2, min(max(p, 1e-6), 1 - 1e-6), max(v0, 1e-300), max(v1, 1e-300)), 0.0)
    floor = 1e-12 * max(s1, 1e-300)
    if 0 < p < 1 and delta > 0:
        for _ in range(MEAN_FIELD_STEPS):
            o = others @ (s0 + pi * delta)
            pi = np.where(ok, _posterior(z2, p, own * s0 + o + floor, own * s1 + o + floor), 0.0)
    ell = float(mean_edge_length(mesh))
    sigma, sigma0 = float(np.sqrt(s1)), float(np.sqrt(s0))
    impulsive = bool(IMPULSIVE_MIN_FRACTION <= p < 1 and sigma0 <= IMPULSIVE_RATIO * sigma
                     and sigma >= IMPULSIVE_FLOOR * ell and mesh.num_vertices >= IMPULSIVE_MIN_VERTICES)
    return ImpulsiveNoise(float(p), sigma, sigma0, pi, impulsive)
