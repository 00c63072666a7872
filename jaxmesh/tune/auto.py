"""Blind choice of the denoiser and its parameters (``--method auto``).

The tuner's blind objective, SURE of the visual error E, favours low-pass
filters (E is a squared position error), and SURE needs the divergence of the
denoiser, which for the feature-preserving filters is nearly discontinuous: a
JVP-based SURE of the face-normal error read 18–36° for a guided filter whose
true error was 3° (fandisk, noise 0.3ℓ̄).  This module instead ranks
candidate (method, parameters) pairs by a *recorrupted* estimate of a
normal error, which needs no derivative at all.

**The error.**  For a displacement field u (V, 3) and fixed unit face normals
ν_f, let

    (A u)_{f,e} = ν_f · (u_b − u_c) / ℓ̄     for the three edges e = (b, c) of f,

the tilt of face f's edges out of the plane ν_f, in radians for small u.  With
u = f(y) − x, ‖A u‖²/F approximates the mean squared face-normal angle error
(A is linear in u and does not depend on triangle shapes, unlike the
hat-function gradient, whose 1/height blows up on the slivers a filter can
leave).  ν_f are the face normals of a pilot estimate (guided normal filtering
with its defaults), held fixed.

**The estimate** (recorrupted-to-recorrupted, Pang et al. 2021).  With noise
y = x + η, η ~ N(0, Σ), draw z ~ N(0, Σ) and set ŷ = y + a z, ỹ = y − z / a.
ŷ − x and ỹ − x are independent Gaussians (their covariance is Σ − Σ = 0), so

    E ‖A(f(ŷ) − ỹ)‖² = E ‖A(f(ŷ) − x)‖² + (1 + 1/a²) tr(AᵀAΣ):

the left side, computed from the noisy mesh alone, minus a known constant is
an unbiased estimate of the error of f at the noise level σ√(1 + a²), for any
denoiser f, differentiable or not.  Σ is taken along the pilot's vertex normals
(Σ_i = σ² n_i n_iᵀ), which is the "along the normals" noise model and, since A
sees only normal components, nearly the same estimate under isotropic noise.
The same draws are used for every candidate (common random numbers), so the
ranking is much less noisy than each estimate.

**The Taubin path.**  On smooth scans a well-tuned Taubin filter is the
method to beat, and its best setting depends finely on the mesh and the noise
(oracle iteration counts from 2 to 40, λ from 0.13 to 0.88 on the shared
meshes).  So besides the fixed candidates, the Taubin family is searched on a
grid: λ ∈ ``TAUBIN_LAMS`` × pass band k_PB ∈ ``TAUBIN_PASS_BANDS`` (μ =
λ / (k_PB λ − 1), so μ ≤ −λ) × *every* iteration count up to
``TAUBIN_MAX_ITERATIONS``, in one compiled pass: the recorrupted inputs are
smoothed step by step, and the estimate is read after every step (a scan),
for all (λ, μ) at once.  Its rows in ``table`` are the best count of each
(λ, μ).  λ stays at or below 1/√2: a pair's gain (1 − λk)(1 − μk) at the top
of the umbrella spectrum (k = 2, μ ≈ −λ) is 1 − 4λ², which is below −1 for
larger λ, so those modes grow with every pass.  The estimate, which sees only
normal components, missed that: on spot at 0.3ℓ̄ it ranked λ = 0.9 first
(true normal error 7.85° against 6.86° for λ ≤ 0.7).

**The decision.**  The candidate with the least estimate wins.  It is compared
with doing nothing, whose error at the same noise level is (1 + a²) tr(AᵀAΣ):
if no candidate beats it, ``improved`` is False and the caller must say so.
σ comes from :func:`~jaxmesh.tune.estimate_noise` unless given.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._private import RECORRUPTION_STREAM, library_key, lift
from ..geometry import face_normals, mean_edge_length, vertex_normals
from ..mesh import Mesh
from ..operators import taubin_pair, umbrella
from .noise_level import blind_caveats, noise_sigma

__all__ = ["Candidate", "CANDIDATES", "AutoResult", "edge_tilt", "choose_denoiser", "TAUBIN_LAMS",
           "TAUBIN_PASS_BANDS", "TAUBIN_MAX_ITERATIONS", "taubin_mu"]

#: the Taubin path's grid (module docstring): shrinking steps λ, pass bands k_PB, and every count up to the last
TAUBIN_LAMS = (0.2, 0.35, 0.5, 0.7)
TAUBIN_PASS_BANDS = (0.0, 0.03, 0.1)
TAUBIN_MAX_ITERATIONS = 100


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One (method, parameters) pair that :func:`choose_denoiser` may pick."""

    method: str
    params: dict


def _grid(method: str, **axes) -> list[Candidate]:
    keys = list(axes)
    return [Candidate(method, dict(zip(keys, vals))) for vals in itertools.product(*axes.values())]


def taubin_mu(lam: float, pass_band: float) -> float:
    """μ with pass-band frequency k_PB = 1/λ + 1/μ (Taubin 1995): μ = λ / (k_PB λ − 1).

    Arguments:
        lam: λ > 0.
        pass_band: k_PB ≥ 0.

    Returns:
        μ < −λ."""
    return lam / (pass_band * lam - 1)


#: the fixed candidates (the Taubin family is searched on its own path, module docstring)
CANDIDATES: tuple[Candidate, ...] = tuple(
    _grid("bilateral_normal", sigma_r=(0.2, 0.35, 0.6), sigma_s=(1.0, 2.0))
    + _grid("guided_normal", sigma_r=(0.15, 0.3, 0.45), sigma_s=(1.0, 2.0))
)


def edge_tilt(mesh: Mesh, nu: Float[Array, "F 3"], ell, u: Float[Array, "*batch V 3"]) -> Float[Array, "*batch F 3"]:
    """(A u)_{f,e} = ν_f · (u_b − u_c) / ℓ̄ for the edges (b, c) opposite each corner (module docstring).

    Arguments:
        mesh: a single mesh.
        nu: unit face normals, (F, 3).
        ell: the mean edge length ℓ̄.
        u: a displacement field, (*batch, V, 3).

    Returns:
        (*batch, F, 3)."""
    h = jnp.sum(u[..., mesh.faces, :] * lift(nu[:, None, :], u.ndim + 1), axis=-1)       # (*b, F, 3)
    return (h[..., [1, 2, 0]] - h[..., [2, 0, 1]]) / ell


@dataclasses.dataclass(frozen=True)
class AutoResult:
    """What :func:`choose_denoiser` chose and why.

    * ``method``, ``params``: the winner (the method's other parameters at
      their defaults); ``mesh``: the input denoised with it;
    * ``sigma``: the noise σ used (mesh units) and whether it was ``estimated``;
    * ``risk``: the winner's estimated mean squared edge tilt (radians²) at the
      recorrupted noise level, ``noisy_risk`` doing nothing's, and
      ``improved = risk < noisy_risk``;
    * ``table``: every candidate with its estimate, best first.
    """

    method: str
    params: dict
    mesh: Mesh
    sigma: float
    estimated: bool
    risk: float
    noisy_risk: float
    improved: bool
    table: list

    @property
    def rms_tilt_degrees(self) -> float:
        """√risk in degrees: the estimated RMS normal error of the winner."""
        return float(np.degrees(np.sqrt(max(self.risk, 0.0))))

    def summary(self) -> dict[str, Any]:
        """A JSON-ready account of the choice."""
        return {"method": self.method, "params": self.params, "noise_sigma": self.sigma,
                "noise_sigma_estimated": self.estimated, "estimated_rms_normal_error_deg": self.rms_tilt_degrees,
                "noisy_rms_normal_error_deg": float(np.degrees(np.sqrt(max(self.noisy_risk, 0.0)))),
                "improved": self.improved,
                "candidates": [{"method": m, "params": p, "risk": r} for m, p, r in self.table]}


@functools.partial(jax.jit, static_argnames=("method", "statics"))
def _run(mesh: Mesh, x, continuous: dict, aux: dict, method: str, statics: tuple):
    from ..denoise import METHODS

    return METHODS[method](mesh.with_vertices(x), **continuous, **dict(statics), **aux).vertices


@functools.partial(jax.jit, static_argnames=("count",))
def _taubin_path(mesh: Mesh, inputs, targets, nu, ell, lam, mu, count: int):
    """Mean edge-tilt risk Σ‖A(x_t − target)‖²/F over the draws after every Taubin
    pair t = 1..count, for every (λ, μ): shape (count, P).  ``inputs``,
    ``targets``: (D, V, 3); ``lam``, ``mu``: (P,)."""
    lam_b, mu_b = lam[:, None, None, None], mu[:, None, None, None]

    def step(x, _):
        x = taubin_pair(x, lambda u: umbrella(mesh, u), lam_b, mu_b)
        r = edge_tilt(mesh, nu, ell, x - targets[None])                           # (P, D, F, 3)
        return x, jnp.mean(jnp.sum(r * r, axis=(-2, -1)), axis=-1) / mesh.num_faces

    x0 = jnp.broadcast_to(inputs, (lam.shape[0],) + inputs.shape)
    return jax.lax.scan(step, x0, None, length=count)[1]


def _taubin_rows(mesh: Mesh, inputs, targets, nu, ell, constant: float) -> list:
    """(method, params, risk) for the best count of every (λ, μ) of the grid."""
    pairs = [(lam, taubin_mu(lam, kpb)) for lam in TAUBIN_LAMS for kpb in TAUBIN_PASS_BANDS]
    lam = jnp.asarray([p[0] for p in pairs], inputs.dtype)
    mu = jnp.asarray([p[1] for p in pairs], inputs.dtype)
    risk = np.asarray(_taubin_path(mesh, inputs, targets, nu, ell, lam, mu, TAUBIN_MAX_ITERATIONS))
    rows = []
    for j, (la, m) in enumerate(pairs):
        t = int(np.argmin(risk[:, j]))
        rows.append(("taubin", {"lam": la, "mu": m, "iterations": t + 1}, float(risk[t, j]) - constant))
    return rows


def _denoise(mesh: Mesh, x, candidate: Candidate, aux: dict):
    from ..denoise import METHODS

    cont, statics = METHODS[candidate.method].split(**candidate.params)
    return _run(mesh, x, cont, aux, candidate.method, statics)


def choose_denoiser(noisy: Mesh, sigma: float | None = None, candidates: Sequence[Candidate] = CANDIDATES,
                    *, taubin_path: bool = True, draws: int = 2, a: float = 0.5, key=0) -> AutoResult:
    """Pick the candidate with the least recorrupted normal-error estimate
    (module docstring) and denoise ``noisy`` with it, blind.

    Arguments:
        noisy: the mesh to denoise (single).
        sigma: the noise standard deviation in mesh units (default: estimated).
        candidates: the fixed candidates (method, parameters).
        taubin_path: also search the Taubin family's grid (λ, pass band, count).
        draws: recorruptions per candidate.
        a: the recorruption strength.
        key: the key (or int seed) of the recorruptions.

    Returns:
        An :class:`AutoResult`: the method and parameters chosen, the denoised mesh,
        the table of estimated risks."""
    from ..denoise import METHODS

    if not isinstance(noisy, Mesh):
        raise TypeError(f"noisy must be a jaxmesh.Mesh, got {type(noisy).__name__}")
    if noisy.batch_shape:
        raise ValueError("choose_denoiser takes one mesh; loop over a batch")
    if not candidates and not taubin_path:
        raise ValueError("candidates: give at least one (method, params) pair, or search the Taubin path")
    for c in candidates:
        if c.method not in METHODS:
            raise ValueError(f"unknown method {c.method!r} in candidates; choose from {sorted(METHODS)}")
        METHODS[c.method].resolve(**c.params)
    if isinstance(draws, bool) or not isinstance(draws, int) or draws < 1:
        raise ValueError(f"draws must be a positive int, got {draws!r}")
    if not (np.isfinite(a) and a > 0):
        raise ValueError(f"a must be a positive number, got {a!r}")
    s, estimated = noise_sigma(noisy, sigma)

    y = noisy.vertices
    methods = {c.method for c in candidates} | {"guided_normal"} | ({"taubin"} if taubin_path else set())
    auxes = {m: METHODS[m].prepare(noisy) for m in methods}
    pilot = noisy.with_vertices(_denoise(noisy, y, Candidate("guided_normal", {}), auxes["guided_normal"]))
    nu, n = face_normals(pilot), vertex_normals(pilot, "area")
    ell = mean_edge_length(noisy)
    k = library_key(key, RECORRUPTION_STREAM)
    zs = s * jax.random.normal(k, (draws, noisy.num_vertices, 1), y.dtype) * n[None]

    # tr(AᵀAΣ)/F with Σ_i = σ² n_i n_iᵀ: each edge difference sees its two vertices
    dots = jnp.sum(nu[:, None, :] * n[noisy.faces], axis=-1) ** 2                # (F, 3)
    trace = float(s**2 * jnp.sum(dots[:, [1, 2, 0]] + dots[:, [2, 0, 1]]) / ell**2 / noisy.num_faces)
    constant = (1 + 1 / a**2) * trace

    table = []
    for c in candidates:
        est = 0.0
        for z in zs:
            out = _denoise(noisy, y + a * z, c, auxes[c.method])
            r = edge_tilt(noisy, nu, ell, out - (y - z / a))
            est += float(jnp.sum(r * r)) / noisy.num_faces / draws
        table.append((c.method, dict(c.params), est - constant))
    if taubin_path:
        table += _taubin_rows(noisy, y[None] + a * zs, y[None] - zs / a, nu, ell, constant)
    table.sort(key=lambda row: row[2])
    method, params, risk = table[0]
    best = noisy.with_vertices(_denoise(noisy, y, Candidate(method, params), auxes[method]))
    noisy_risk = (1 + a**2) * trace
    blind_caveats(noisy, s, estimated, risk / noisy_risk)
    return AutoResult(method, params, best, s, estimated, risk, noisy_risk, bool(risk < noisy_risk), table)
