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
denoiser f, differentiable or not.  Σ is split along the pilot's vertex
normals n_i: Σ_i = σ² n_i n_iᵀ + σ_t² (I − n_i n_iᵀ), σ_t the noise within the
surface: 0 for noise along the normals, σ for isotropic noise
(``noise_model``), or, by default, the mesh's own reading
:func:`~jaxmesh.tune.estimate_tangential_noise`, capped at σ.  It matters
because a filter turns tangential input noise into normal output error:
recorrupting isotropic noise along the normals only chose 6.00° over 4.77° on
the fandisk at 0.3ℓ̄; the converse chose 11.41° over 10.81° on the cow at
0.1ℓ̄.  Every candidate sees the same draws (common random numbers).

**The paths.**  Some families are searched over their outer-iteration
count as well, in one compiled scan per setting: the recorrupted inputs are
denoised one iteration at a time and the estimate is read after every
iteration, so every count costs no more than the largest (:class:`SearchPath`).
Its rows in ``table`` are the best count of each setting.  Searched by
default (``PATHS``):

* *Taubin*: on smooth scans a well-tuned Taubin filter is the method to beat,
  and its best setting depends finely on the mesh and the noise (oracle
  iteration counts from 2 to 40, λ from 0.13 to 0.88 on the shared meshes):
  λ ∈ ``TAUBIN_LAMS`` × pass band k_PB ∈ ``TAUBIN_PASS_BANDS`` (μ =
  λ / (k_PB λ − 1), so μ ≤ −λ) × every count up to ``TAUBIN_MAX_ITERATIONS``.
  λ stays at or below 1/√2: a pair's gain (1 − λk)(1 − μk) at the top of the
  umbrella spectrum (k = 2, μ ≈ −λ) is 1 − 4λ², which is below −1 for larger
  λ, so those modes grow with every pass.  The estimate, which sees only
  normal components, missed that: on spot at 0.3ℓ̄ it ranked λ = 0.9 first
  (true normal error 7.85° against 6.86° for λ ≤ 0.7).
* *Bilateral normal filtering, the local iterative scheme* (Zheng et al.
  2011): each iteration is one filtering pass of the face normals and
  ``BILATERAL_PATH_FIXED["vertex_iterations"]`` vertex updates, repeated up to
  ``BILATERAL_PATH_MAX_ITERATIONS`` times, at σ_s × σ_r ∈
  ``BILATERAL_PATH_SIGMAS`` (smoothing settings); and one feature-preserving
  setting, ``BILATERAL_FEATURE_SETTING``, up to ``BILATERAL_FEATURE_MAX_ITERATIONS``
  times (why: the denoising guide).  Recomputing the normals from the positions
  after every few vertex steps is what makes it beat Taubin on
  smooth scans: oracle-tuned, it is 0.6–7% below the oracle-tuned Taubin's
  normal error on spot, maxplanck and the bunny, and on the cow at 0.1ℓ̄
  (above it on the cow at 0.3ℓ̄, 1–3%, and on the camelhead, 8–15%), where
  ten normal passes before the first vertex update (the fixed candidates) are
  up to 49% worse than it (``feature_table.py``, column *bilateral_local*).

**The decision.**  The candidate with the least estimate wins, unless a convex
blend of two leaders (the best of each path and of each fixed method) is
estimated better on fresh draws (:mod:`jaxmesh.tune.blend`, which also
measures larger blends: ``blend_size``, ``snapshots``).  It is compared
with doing nothing, whose error at the same noise level is (1 + a²) tr(AᵀAΣ):
if the choice does not beat it, ``improved`` is False and the caller must say
so.  σ comes from :func:`~jaxmesh.tune.estimate_noise` unless given.
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
from .blend import (BLEND_DRAWS, BLEND_SALT, BLEND_SIZE, SNAPSHOT_FACTORS, best_mixture, check_snapshots,
                    snapshot_rows, tilt_gram)
from .noise_level import blind_caveats, estimate_tangential_noise, noise_sigma

__all__ = ["Candidate", "CANDIDATES", "SearchPath", "PATHS", "NOISE_MODELS", "AutoResult", "edge_tilt", "choose_denoiser",
           "TAUBIN_LAMS", "TAUBIN_PASS_BANDS", "TAUBIN_MAX_ITERATIONS", "taubin_mu", "BILATERAL_PATH_SIGMAS",
           "BILATERAL_PATH_FIXED", "BILATERAL_PATH_MAX_ITERATIONS", "BILATERAL_FEATURE_SETTING",
           "BILATERAL_FEATURE_MAX_ITERATIONS"]

#: the recorruption's noise models (module docstring): σ_t estimated, 0, or σ
NOISE_MODELS = ("auto", "normal", "isotropic")
#: the Taubin path's grid (module docstring): shrinking steps λ, pass bands k_PB, and every count up to the last
TAUBIN_LAMS = (0.2, 0.35, 0.5, 0.7)
TAUBIN_PASS_BANDS = (0.0, 0.03, 0.1)
TAUBIN_MAX_ITERATIONS = 100
#: the bilateral path (module docstring): (σ_s, σ_r) settings, the statics of one iteration, the last count
BILATERAL_PATH_SIGMAS = tuple(itertools.product((1.0, 1.5), (0.6, 1.0, 2.0)))
BILATERAL_PATH_FIXED = {"normal_iterations": 1, "vertex_iterations": 5}
BILATERAL_PATH_MAX_ITERATIONS = 16
#: the feature-preserving setting of the local scheme (wide σ_s, narrow σ_r), searched up to a higher count
BILATERAL_FEATURE_SETTING = {"sigma_s": 2.5, "sigma_r": 0.35}
BILATERAL_FEATURE_MAX_ITERATIONS = 24


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


@dataclasses.dataclass(frozen=True)
class SearchPath:
    """A family :func:`choose_denoiser` searches over its outer-iteration count:
    ``method`` with the parameters ``fixed`` and each of ``settings``, read after
    every iteration 1..``max_iterations`` in one scan (module docstring).  The
    method must take ``iterations`` and satisfy method(x, iterations=k + 1) =
    method(method(x, iterations=k), iterations=1)."""

    method: str
    settings: tuple
    fixed: tuple = ()
    max_iterations: int = 100


#: the paths searched by default: Taubin, and the bilateral normal filter's local iterative scheme
#: (smoothing settings, and one feature-preserving setting)
PATHS: tuple[SearchPath, ...] = (
    SearchPath("taubin", tuple({"lam": lam, "mu": taubin_mu(lam, kpb)} for lam in TAUBIN_LAMS
                         for kpb in TAUBIN_PASS_BANDS), (), TAUBIN_MAX_ITERATIONS),
    SearchPath("bilateral_normal", tuple({"sigma_s": ss, "sigma_r": sr} for ss, sr in BILATERAL_PATH_SIGMAS),
               tuple(BILATERAL_PATH_FIXED.items()), BILATERAL_PATH_MAX_ITERATIONS),
    SearchPath("bilateral_normal", (BILATERAL_FEATURE_SETTING,), tuple(BILATERAL_PATH_FIXED.items()),
               BILATERAL_FEATURE_MAX_ITERATIONS),
)


#: the fixed candidates (the paths are searched on their own, module docstring)
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
      their defaults), or ``"blend"`` and ``{}`` when two are blended;
      ``components``: (method, params, weight) of what ``mesh``, the output, is
      made of (one with weight 1, or the blend's two, :mod:`jaxmesh.tune.blend`);
    * ``sigma``: the noise σ used (mesh units) and whether it was ``estimated``;
      ``tangential_sigma``: the σ_t within the surface of the recorruption;
    * ``risk``: the winner's estimated mean squared edge tilt (radians²) at the
      recorrupted noise level (a blend's on its own draws), ``noisy_risk`` doing nothing's, and
      ``improved = risk < noisy_risk``;
    * ``table``: every candidate with its estimate, best first.
    """

    method: str
    params: dict
    mesh: Mesh
    sigma: float
    estimated: bool
    tangential_sigma: float
    risk: float
    noisy_risk: float
    improved: bool
    table: list
    components: tuple = ()

    @property
    def rms_tilt_degrees(self) -> float:
        """√risk in degrees: the estimated RMS normal error of the winner."""
        return float(np.degrees(np.sqrt(max(self.risk, 0.0))))

    def summary(self) -> dict[str, Any]:
        """A JSON-ready account of the choice."""
        return {"method": self.method, "params": self.params, "noise_sigma": self.sigma,
                "noise_sigma_estimated": self.estimated, "tangential_noise_sigma": self.tangential_sigma,
                "estimated_rms_normal_error_deg": self.rms_tilt_degrees,
                "noisy_rms_normal_error_deg": float(np.degrees(np.sqrt(max(self.noisy_risk, 0.0)))),
                "improved": self.improved,
                "components": [{"method": m, "params": p, "weight": w} for m, p, w in self.components],
                "candidates": [{"method": m, "params": p, "risk": r} for m, p, r in self.table]}


@functools.partial(jax.jit, static_argnames=("method", "statics"))
def _run(mesh: Mesh, x, continuous: dict, aux: dict, method: str, statics: tuple):
    from ..denoise import METHODS

    return METHODS[method](mesh.with_vertices(x), **continuous, **dict(statics), **aux).vertices


@functools.partial(jax.jit, static_argnames=("method", "statics", "count"))
def _path_risks(mesh: Mesh, inputs, targets, nu, ell, continuous: dict, aux: dict, method: str, statics: tuple,
                count: int):
    """Mean edge-tilt risk Σ‖A(x_t − target)‖²/F over the draws after every
    iteration t = 1..count of one setting: shape (count,).  ``inputs``,
    ``targets``: (D, V, 3)."""
    from ..denoise import METHODS

    def step(x, _):
        x = METHODS[method](mesh.with_vertices(x), **continuous, **dict(statics), iterations=1, **aux).vertices
        r = edge_tilt(mesh, nu, ell, x - targets)                                    # (D, F, 3)
        return x, jnp.mean(jnp.sum(r * r, axis=(-2, -1))) / mesh.num_faces

    return jax.lax.scan(step, inputs, None, length=count)[1]


def _path_rows(mesh: Mesh, path: SearchPath, inputs, targets, nu, ell, aux: dict, constant: float) -> list:
    """(method, params, risk) for the best count of every setting of ``path``."""
    from ..denoise import METHODS

    rows = []
    for setting in path.settings:
        cont, statics = METHODS[path.method].split(**setting, **dict(path.fixed))
        statics = tuple(kv for kv in statics if kv[0] != "iterations")
        risk = np.asarray(_path_risks(mesh, inputs, targets, nu, ell, cont, aux, path.method, statics,
                                      path.max_iterations))
        t = int(np.argmin(risk))
        rows.append((path.method, {**setting, **dict(path.fixed), "iterations": t + 1}, float(risk[t]) - constant))
    return rows


def _denoise(mesh: Mesh, x, candidate: Candidate, aux: dict):
    from ..denoise import METHODS

    cont, statics = METHODS[candidate.method].split(**candidate.params)
    return _run(mesh, x, cont, aux, candidate.method, statics)


def _check(noisy: Mesh, candidates: Sequence[Candidate], paths: Sequence[SearchPath], draws, a, noise_model,
           blend_draws=0, blend_size=2, snapshots=()) -> None:
    from ..denoise import METHODS

    if not isinstance(noisy, Mesh):
        raise TypeError(f"noisy must be a jaxmesh.Mesh, got {type(noisy).__name__}")
    if noisy.batch_shape:
        raise ValueError("choose_denoiser takes one mesh; loop over a batch")
    if not candidates and not paths:
        raise ValueError("candidates: give at least one (method, params) pair, or a path to search")
    for path in paths:
        if not isinstance(path, SearchPath) or path.method not in METHODS or "iterations" not in METHODS[path.method].params:
            raise ValueError(f"paths: each must be a SearchPath of a registered method with an 'iterations' "
                             f"parameter, got {path!r}")
        if isinstance(path.max_iterations, bool) or not isinstance(path.max_iterations, int) or path.max_iterations < 1:
            raise ValueError(f"paths: max_iterations must be a positive int, got {path.max_iterations!r}")
        for setting in path.settings:
            METHODS[path.method].resolve(**setting, **dict(path.fixed))
    for c in candidates:
        if c.method not in METHODS:
            raise ValueError(f"unknown method {c.method!r} in candidates; choose from {sorted(METHODS)}")
        METHODS[c.method].resolve(**c.params)
    for name, value, least in (("draws", draws, 1), ("blend_draws", blend_draws, 0), ("blend_size", blend_size, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
    check_snapshots(snapshots)
    if not (np.isfinite(a) and a > 0):
        raise ValueError(f"a must be a positive number, got {a!r}")
    if noise_model not in NOISE_MODELS:
        raise ValueError(f"noise_model must be one of {NOISE_MODELS}, got {noise_model!r}")


def _recorruptions(noisy: Mesh, nu, n, ell, s: float, s_t: float, draws: int, key, salt: int = 0):
    """(z, tr(AᵀAΣ)/F): ``draws`` fields z ~ N(0, Σ_i = s² n_i n_iᵀ + s_t² (I − n_i n_iᵀ)),
    (draws, V, 3), and the trace of the module docstring (each edge difference sees its two vertices);
    a nonzero ``salt`` draws an independent set."""
    y = noisy.vertices
    k = library_key(key, RECORRUPTION_STREAM)
    k = jax.random.fold_in(k, salt) if salt else k
    zs = s * jax.random.normal(k, (draws, noisy.num_vertices, 1), y.dtype) * n[None]
    if s_t > 0:
        xi = jax.random.normal(jax.random.fold_in(k, 1), (draws, noisy.num_vertices, 3), y.dtype)
        zs = zs + s_t * (xi - jnp.sum(xi * n[None], axis=-1, keepdims=True) * n[None])
    dots = jnp.sum(nu[:, None, :] * n[noisy.faces], axis=-1) ** 2                # (F, 3)
    per_vertex = s_t**2 + (s**2 - s_t**2) * dots                                # Var(ν_f · z_v)
    trace = float(jnp.sum(per_vertex[:, [1, 2, 0]] + per_vertex[:, [2, 0, 1]]) / ell**2 / noisy.num_faces)
    return zs, trace


def choose_denoiser(noisy: Mesh, sigma: float | None = None, candidates: Sequence[Candidate] = CANDIDATES,
                    *, paths: Sequence[SearchPath] = PATHS, noise_model: str = "auto", draws: int = 2,
                    blend_draws: int = BLEND_DRAWS, blend_size: int = BLEND_SIZE,
                    snapshots: Sequence[float] = SNAPSHOT_FACTORS, a: float = 0.5, key=0) -> AutoResult:
    """Pick the candidate with the least recorrupted normal-error estimate
    (module docstring) and denoise ``noisy`` with it, blind.

    Arguments:
        noisy: the mesh to denoise (single).
        sigma: the noise standard deviation in mesh units (default: estimated).
        candidates: the fixed candidates (method, parameters).
        paths: the families also searched over their iteration count (default: Taubin and
            the bilateral normal filter's local iterative scheme; ``()`` for none).
        noise_model: the recorruption's noise within the surface: ``"auto"`` (estimated,
            capped at σ), ``"normal"`` (none: noise along the normals) or ``"isotropic"`` (σ).
        draws: recorruptions per candidate.
        blend_draws: fresh recorruptions on which the blends of the leaders are fitted and judged
            (:mod:`jaxmesh.tune.blend`); 0: no blending.
        blend_size: the most denoisers one blend mixes (1: no blending; 2: pairs).
        snapshots: each search path's leader is also blended at these multiples of its
            iteration count (``()``: the leaders alone).
        a: the recorruption strength.
        key: the key (or int seed) of the recorruptions.

    Returns:
        An :class:`AutoResult`: the method and parameters chosen (or the blend), the
        denoised mesh, the table of estimated risks."""
    from ..denoise import METHODS

    _check(noisy, candidates, paths, draws, a, noise_model, blend_draws, blend_size, snapshots)
    s, estimated = noise_sigma(noisy, sigma)
    s_t = {"normal": 0.0, "isotropic": s}.get(noise_model)
    s_t = min(estimate_tangential_noise(noisy), s) if s_t is None else s_t

    y = noisy.vertices
    methods = {c.method for c in candidates} | {"guided_normal"} | {path.method for path in paths}
    auxes = {m: METHODS[m].prepare(noisy) for m in methods}
    pilot = noisy.with_vertices(_denoise(noisy, y, Candidate("guided_normal", {}), auxes["guided_normal"]))
    nu, n = face_normals(pilot), vertex_normals(pilot, "area")
    ell = mean_edge_length(noisy)
    zs, trace = _recorruptions(noisy, nu, n, ell, s, s_t, draws, key)
    constant = (1 + 1 / a**2) * trace

    def tilt(row, z):   # A(f(ŷ) − ỹ) for the (method, params, ...) row and the recorruption z
        return edge_tilt(noisy, nu, ell, _denoise(noisy, y + a * z, Candidate(*row[:2]), auxes[row[0]]) - (y - z / a))

    table = [(c.method, dict(c.params), sum(float(jnp.sum(tilt((c.method, c.params), z) ** 2)) for z in zs)
              / noisy.num_faces / draws - constant) for c in candidates]
    leaders = []
    leaders += [min((r for r in table if r[0] == m), key=lambda r: r[2]) for m in dict.fromkeys(r[0] for r in table)]
    for path in paths:
        rows = _path_rows(noisy, path, y[None] + a * zs, y[None] - zs / a, nu, ell, auxes[path.method], constant)
        table += rows
        leaders.append(min(rows, key=lambda row: row[2]))
    table.sort(key=lambda row: row[2])
    components, risk = ((table[0][0], table[0][1], 1.0),), table[0][2]
    rows = leaders + snapshot_rows(leaders[len(leaders) - len(paths):], snapshots, leaders)
    if blend_draws and blend_size > 1 and len(rows) > 1:
        gram = tilt_gram(rows, _recorruptions(noisy, nu, n, ell, s, s_t, blend_draws, key, salt=BLEND_SALT)[0], tilt)
        mix, total = best_mixture(gram, next(i for i, r in enumerate(rows) if r is table[0]), blend_size)
        if len(mix) > 1:
            components = tuple((rows[i][0], rows[i][1], w) for i, w in mix)
            risk = total / noisy.num_faces / blend_draws - constant
    out = sum(w * _denoise(noisy, y, Candidate(m, p), auxes[m]) for m, p, w in components)
    method, params = (components[0][0], components[0][1]) if len(components) == 1 else ("blend", {})
    noisy_risk = (1 + a**2) * trace
    blind_caveats(noisy, s, estimated, risk / noisy_risk)
    return AutoResult(method, params, noisy.with_vertices(out), s, estimated, s_t, risk, noisy_risk,
                      bool(risk < noisy_risk), table, components)
