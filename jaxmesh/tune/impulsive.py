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

**The second reading** (:func:`read_after_repair`, once the noise is called
impulsive): the same mixture fitted to the residuals against
:func:`~jaxmesh.denoise.impulse_repair`'s output, which keeps the untouched
vertices, gives much sharper posteriors; the blind chooser recorrupts with it.

**The decision.**  The noise is called impulsive when σ₀ ≤ ``IMPULSIVE_RATIO``
· σ₁, σ₁ ≥ ``IMPULSIVE_FLOOR`` ℓ̄, p̂ ≥ ``IMPULSIVE_MIN_FRACTION`` and the mesh
has at least ``IMPULSIVE_MIN_VERTICES`` vertices (on fewer, the fit of
Gaussian noise wanders: a 386-vertex box read σ₀ = 0 under Gaussian noise on
one seed of two; the 766-vertex "eight" is decided right in every cell).  A clean
mesh's own creases and detail also read as a sparse heavy component (σ₁ up to
0.16ℓ̄ on the shared meshes), hence the floor; a handful of outlying vertices
(p̂ below the minimum) is not a noise law.  Measurements:
``experiments/denoise/impulsive_detection.py``.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp

from ..denoise.impulse_repair import mixture_posterior, scale_mixture
from ..geometry import mean_edge_length, vertex_normals
from ..host import HostMesh, as_host
from ..mesh import Mesh, to_device
from .noise_level import _normal_high_pass, projection_normals

__all__ = ["ImpulsiveNoise", "estimate_impulsive_noise", "read_after_repair", "IMPULSIVE_RATIO", "IMPULSIVE_FLOOR",
           "IMPULSIVE_MIN_FRACTION", "IMPULSIVE_MIN_VERTICES", "MEAN_FIELD_STEPS", "EM_STEPS"]

#: σ₀/σ₁ at or below which the noise is called impulsive (module docstring)
IMPULSIVE_RATIO = 0.35
#: σ₁ (in mean edge lengths) below which a heavy component is read as the surface's own detail
IMPULSIVE_FLOOR = 0.2
#: p̂ below which a heavy component is read as a few outliers, not a noise law
IMPULSIVE_MIN_FRACTION = 0.05
#: the fewest vertices on which the decision is made (module docstring)
IMPULSIVE_MIN_VERTICES = 500
#: mean-field passes sharpening the per-vertex posteriors
MEAN_FIELD_STEPS = 5
#: EM iterations of the first fit
EM_STEPS = 300


#: the host-side calls of the mixture fit, each one compiled program
_posterior_jit = jax.jit(mixture_posterior)
_scale_mixture = jax.jit(scale_mixture, static_argnames=("steps",))


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


def estimate_impulsive_noise(mesh: Mesh | HostMesh) -> ImpulsiveNoise:
    """Fit the two-level noise law of the module docstring to ``mesh`` and decide
    whether it is impulsive.

    Arguments:
        mesh: a single mesh, or its :class:`~jaxmesh.host.HostMesh`.

    Returns:
        An :class:`ImpulsiveNoise`."""
    if isinstance(mesh, Mesh) and mesh.batch_shape:
        raise ValueError("estimate_impulsive_noise takes one mesh; loop over a batch")
    host = as_host(mesh)
    mesh = host.mesh
    c2 = host.umbrella_square
    sq = c2.multiply(c2).tocsr()
    g2 = np.asarray(sq.sum(axis=1)).ravel()
    ok = g2 > 0
    if not ok.any():
        raise ValueError("estimate_impulsive_noise: the mesh has no vertex with neighbours")
    own = np.where(ok, c2.diagonal() ** 2 / np.where(ok, g2, 1.0), 0.0)
    others = sp.diags(1 / np.where(ok, g2, 1.0)) @ (sq - sp.diags(sq.diagonal()))
    z = np.where(ok, _normal_high_pass(mesh, mesh.vertices, projection_normals(host)) / np.sqrt(np.where(ok, g2, 1)),
                 0.0)
    p, v0, v1 = (float(v) for v in _scale_mixture(to_device(z[ok] ** 2), EM_STEPS))
    delta = max(v1 - v0, 0.0) / float(np.mean(own[ok]))
    s0 = max(p * v1 + (1 - p) * v0 - p * delta, 0.0)
    s1 = s0 + delta
    z2 = z * z
    pi = np.where(ok, _posterior(z2, p, v0, v1), 0.0)
    floor = max(1e-6 * s1, np.finfo(np.float32).tiny)
    if delta > 0:
        for _ in range(MEAN_FIELD_STEPS):
            o = others @ (s0 + pi * delta)
            pi = np.where(ok, _posterior(z2, p, own * s0 + o + floor, own * s1 + o + floor), 0.0)
    ell = float(mean_edge_length(mesh))
    sigma, sigma0 = float(np.sqrt(s1)), float(np.sqrt(s0))
    impulsive = bool(IMPULSIVE_MIN_FRACTION <= p < 1 - 1e-5 and sigma0 <= IMPULSIVE_RATIO * sigma
                     and sigma >= IMPULSIVE_FLOOR * ell and mesh.num_vertices >= IMPULSIVE_MIN_VERTICES)
    return ImpulsiveNoise(float(p), sigma, sigma0, pi, impulsive)


def _posterior(z2, p, v0, v1) -> np.ndarray:
    """:func:`~jaxmesh.denoise.mixture_posterior` on host arrays (float64)."""
    return np.asarray(_posterior_jit(to_device(np.asarray(z2)), p, v0, v1), dtype=np.float64)



def read_after_repair(mesh: Mesh, law: ImpulsiveNoise) -> ImpulsiveNoise:
    """The law read again from the residuals of :func:`~jaxmesh.denoise.impulse_repair`
    (its defaults): r_i = n_i · (y_i − x_i), n the repaired mesh's vertex normals,
    fitted by the same two-component mixture.  Against a fit that keeps the
    untouched vertices, an untouched vertex's residual is near zero and a
    displaced one's near its displacement, so the posteriors are much sharper
    than those of the high pass (where a vertex also carries its neighbours'
    noise).  Keeps ``law.impulsive``.

    Arguments:
        mesh: the noisy mesh (single).
        law: the first reading (:func:`estimate_impulsive_noise`).

    Returns:
        An :class:`ImpulsiveNoise` with the new fraction, levels and posteriors."""
    r2 = _repair_residuals(mesh)
    if not bool(jnp.isfinite(r2).all()):
        raise FloatingPointError(f"impulse_repair produced non-finite coordinates at its defaults ({mesh.dtype}); "
                                 "the input was finite, so try float64")
    p, v0, v1 = _scale_mixture(r2, EM_STEPS)
    pi = np.asarray(_posterior_jit(r2, p, v0, v1), dtype=np.float64)
    return ImpulsiveNoise(float(p), float(np.sqrt(v1)), float(np.sqrt(v0)), pi, law.impulsive)


@jax.jit
def _repair_residuals(mesh: Mesh):
    """r_i² of :func:`read_after_repair`: (n_i · (y_i − x_i))², x the repair at its defaults."""
    from ..denoise import METHODS

    fit = METHODS["impulse_repair"](mesh, throw=False)
    return jnp.sum((mesh.vertices - fit.vertices) * vertex_normals(fit, "area"), axis=-1) ** 2
