"""The held-out estimate that ranks denoisers under impulsive noise.

Under impulsive noise (a share p of the vertices displaced along their normals,
the others exact, :func:`jaxmesh.add_impulsive_noise`) the vertices left
untouched *are* the clean surface, so a denoiser can be scored against them
directly.  The recorrupted estimate of :mod:`jaxmesh.tune.recorrupt` cannot do
this: it needs the recorrupted input's noise independent of the target's,
which the two-level law breaks vertex by vertex, and it ranked impulse repair's
settings in reverse (the denoising guide, *Impulsive noise*).

**Untouched and displaced.**  With r_i = |n_i · (y_i − x_i)| / ℓ̄ the normal
residual of vertex i against a reference fit x (n its area-weighted vertex
normals), and r_i = min over the fits, a vertex is read as *untouched* (U) when
r_i < τ = ``HELD_OUT_TOLERANCE`` and as *displaced* (D) when r_i >
``DISPLACED_FACTOR`` τ.  The fits are impulse repair at its defaults (exact on
smooth regions, but it rounds creases off, so an untouched crease vertex reads
far from it) and the pilot, guided normal filtering (it keeps the creases):
with the repair alone the crease vertices would be missing from U, and the
measured faces below would avoid the creases, exactly where impulse repair
fails (the denoising guide, *Impulsive noise*).

**A draw.**  Each vertex of U is displaced with probability p̂ along the
pilot's normal n_i by ξ_i ~ N(0, σ̂₁²); so that the share of displaced vertices
stays p̂, each vertex of D is put back at the repair's position with
probability min(1, p̂ |U| / |D|):

    ŷ_i = y_i + h_i ξ_i n_i (i ∈ U),    ŷ_i = x_i^repair (i ∈ D, put back),    ŷ_i = y_i otherwise.

**The estimate.**  On the *measured* faces M, those whose three vertices are
in U (their noisy normals ν_f are exact), with the edge tilt A of
:mod:`jaxmesh.tune.recorrupt`,

    R(f) = Σ_d ‖A(f(ŷ_d) − y)‖² / (D |M|),

the mean squared edge tilt of f's output on faces whose vertices were each
displaced with probability p̂ (the law's), among neighbours displaced as often.
No constant is subtracted: the target y is exact on M.  A vertex of U that was
in fact displaced by less than τℓ̄ is a small error in the target.

**Creases, reweighted.**  Crease vertices still reach U less often than the
others (an untouched one is near the pilot, but not always within τ), so the
faces are split into two strata, *feature* faces (a vertex where two of the
pilot's adjacent face normals part by more than ``FEATURE_ANGLE``) and the
rest, and each measured face is weighted by w_s = (N_s / N) / (M_s / |M|),
its stratum's share of the counted faces over its share of the measured ones
(post-stratification; the weights sum to |M|).  A stratum with fewer than
``STRATUM_MIN_FACES`` measured faces is not reweighted (w = 1 throughout).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._private import HELD_OUT_STREAM, library_key
from ..geometry import face_normals, vertex_normals
from ..mesh import Mesh

__all__ = ["HELD_OUT_TOLERANCE", "DISPLACED_FACTOR", "HELD_OUT_MIN_FACES", "FEATURE_ANGLE", "STRATUM_MIN_FACES",
           "normal_residuals", "held_out_split", "measured_faces", "feature_faces", "stratum_weights",
           "held_out_inputs", "held_out_estimate"]

#: τ, in mean edge lengths: a vertex this close to a reference fit along its normal is read as untouched
HELD_OUT_TOLERANCE = 0.05
#: a vertex farther than this many τ from every reference fit is read as displaced
DISPLACED_FACTOR = 3.0
#: the fewest measured faces on which the held-out estimate is used (fewer: the recorrupted one)
HELD_OUT_MIN_FACES = 100
#: degrees between adjacent pilot face normals beyond which their vertices are read as on a crease
FEATURE_ANGLE = 30.0
#: the fewest measured faces of a stratum for the reweighting (module docstring)
STRATUM_MIN_FACES = 50


@jax.jit
def _residuals(y, fit: Mesh, ell):
    return jnp.abs(jnp.sum((y - fit.vertices) * vertex_normals(fit, "area"), axis=-1)) / ell


def normal_residuals(y, fit: Mesh, ell: float) -> np.ndarray:
    """r_i = |n_i · (y_i − x_i)| / ℓ̄ against the fit x, n its area-weighted vertex normals.

    Arguments:
        y: the noisy positions, (V, 3).
        fit: the reference fit (a single mesh on the same faces).
        ell: the mean edge length ℓ̄.

    Returns:
        (V,) float64."""
    return np.asarray(_residuals(y, fit, ell), np.float64)


def held_out_split(noisy: Mesh, fits: Sequence[Mesh], ell: float,
                   tolerance: float = HELD_OUT_TOLERANCE) -> tuple[np.ndarray, np.ndarray]:
    """The vertices read as untouched (r_i < τ) and as displaced (r_i > ``DISPLACED_FACTOR`` τ),
    r_i the least normal residual over ``fits`` (module docstring).

    Arguments:
        noisy: the noisy mesh (single).
        fits: the reference fits (the repair and the pilot).
        ell: the mean edge length ℓ̄.
        tolerance: τ in mean edge lengths.

    Returns:
        (untouched, displaced), two (V,) bool arrays."""
    if not fits:
        raise ValueError("held_out_split: give at least one reference fit")
    r = np.min([normal_residuals(noisy.vertices, f, ell) for f in fits], axis=0)
    return r < tolerance, r > DISPLACED_FACTOR * tolerance


def measured_faces(noisy: Mesh, untouched: np.ndarray) -> np.ndarray:
    """The faces whose three vertices are read as untouched.

    Arguments:
        noisy: the mesh (single).
        untouched: (V,) bool, the vertices read as untouched.

    Returns:
        (F,) bool."""
    return np.asarray(untouched)[np.asarray(noisy.faces)].all(axis=1)


def feature_faces(mesh: Mesh, nu) -> np.ndarray:
    """The faces with a vertex where two adjacent faces' normals ``nu`` part by more than
    ``FEATURE_ANGLE``, (F,) bool.

    Arguments:
        mesh: a single mesh.
        nu: unit face normals (the pilot's), (F, 3).

    Returns:
        (F,) bool."""
    from ..topology import face_adjacency

    pairs = face_adjacency(mesh)
    nu = np.asarray(nu, np.float64)
    sharp = pairs[np.sum(nu[pairs[:, 0]] * nu[pairs[:, 1]], axis=1) < np.cos(np.radians(FEATURE_ANGLE))]
    faces = np.asarray(mesh.faces)
    a, b = faces[sharp[:, 0]], faces[sharp[:, 1]]
    on_crease = np.zeros(mesh.num_vertices, bool)
    on_crease[a[(a[:, :, None] == b[:, None, :]).any(axis=2)]] = True        # the shared edge's two vertices
    return on_crease[faces].any(axis=1)


def stratum_weights(feature: np.ndarray, measured: np.ndarray, counted: np.ndarray) -> np.ndarray:
    """w_f of the module docstring on the measured faces (0 elsewhere): each stratum's share of the
    ``counted`` faces over its share of the ``measured`` ones; 1 throughout where a stratum has fewer
    than ``STRATUM_MIN_FACES`` measured faces.

    Arguments:
        feature: (F,) bool, the feature stratum.
        measured: (F,) bool, the measured faces (a subset of ``counted``).
        counted: (F,) bool, the faces the estimate stands for.

    Returns:
        (F,) float64."""
    w = np.asarray(measured, np.float64)
    m, n = int(np.sum(measured)), int(np.sum(counted))
    strata = [np.asarray(feature, bool), ~np.asarray(feature, bool)]
    if m == 0 or any(np.sum(measured & s) < STRATUM_MIN_FACES for s in strata):
        return w
    for s in strata:
        w[measured & s] = (np.sum(counted & s) / n) / (np.sum(measured & s) / m)
    return w


def held_out_inputs(noisy: Mesh, untouched, displaced, repaired, n, sigma: float, fraction: float, draws: int,
                    key, salt: int = 0):
    """``draws`` inputs ŷ_d of the module docstring: untouched vertices displaced with probability
    p̂ by N(0, σ̂₁²) along n, displaced ones put back at the repair's position with probability
    min(1, p̂ |U| / |D|).

    Arguments:
        noisy: the noisy mesh (single).
        untouched: (V,) bool, U.
        displaced: (V,) bool, D.
        repaired: the repair's positions, (V, 3).
        n: unit vertex normals along which to displace (the pilot's), (V, 3).
        sigma: σ̂₁, the displaced vertices' level (mesh units).
        fraction: p̂.
        draws: how many inputs.
        key: the key (or int seed) of the draws.
        salt: nonzero draws an independent set.

    Returns:
        (draws, V, 3)."""
    k = library_key(key, HELD_OUT_STREAM)
    k = jax.random.fold_in(k, salt) if salt else k
    u = np.asarray(untouched, bool)
    back = min(1.0, fraction * u.sum() / max(int(np.sum(displaced)), 1))
    dtype = noisy.dtype
    return _inputs(k, noisy.vertices, jnp.asarray(u), jnp.asarray(displaced, bool), jnp.asarray(repaired, dtype),
                   jnp.asarray(n, dtype), jnp.asarray(sigma, dtype), jnp.asarray(fraction, dtype),
                   jnp.asarray(back, dtype), draws)


@functools.partial(jax.jit, static_argnames=("draws",))
def _inputs(k, y, untouched, displaced, repaired, n, sigma, fraction, back, draws: int):
    """The inputs of :func:`held_out_inputs`, (draws, V, 3), in one program."""
    k_hit, k_xi, k_back = jax.random.split(k, 3)
    shape = (draws, y.shape[0])
    hit = untouched[None] & jax.random.bernoulli(k_hit, fraction, shape)
    xi = sigma * jax.random.normal(k_xi, shape, y.dtype)
    put_back = displaced[None] & jax.random.bernoulli(k_back, back, shape)
    moved = y[None] + jnp.where(hit, xi, 0.0)[..., None] * n[None]
    return jnp.where(put_back[..., None], repaired[None], moved)


def held_out_estimate(noisy: Mesh, pilot: Mesh, nu_pilot, n, ell, core, auxes: dict, impulsive: tuple, key):
    """What :func:`~jaxmesh.tune.choose_denoiser` ranks by under impulsive noise: the face normals
    (zero off the measured faces, ‖A_f‖² weighted by the strata's w_f), a function of (count, salt)
    giving that many draws (inputs, targets), and the measured faces' count; None where fewer than
    ``HELD_OUT_MIN_FACES`` faces are measured.

    Arguments:
        noisy: the mesh ranked on (single).
        pilot: the pilot's denoised mesh.
        nu_pilot: the pilot's face normals, (F, 3).
        n: the pilot's vertex normals, (V, 3).
        ell: the mean edge length ℓ̄.
        core: the faces that count, (F,) bool.
        auxes: the methods' prepared arrays (``impulse_repair``'s among them).
        impulsive: (p̂, σ̂₁), the law read.
        key: the key (or int seed) of the draws.

    Returns:
        (ν, draw, count) or None."""
    from .race import run_setting

    y = noisy.vertices
    repaired = run_setting(noisy, y, "impulse_repair", {}, auxes["impulse_repair"])
    untouched, displaced = held_out_split(noisy, (noisy.with_vertices(repaired), pilot), float(ell))
    measured = measured_faces(noisy, untouched) & core
    if measured.sum() < HELD_OUT_MIN_FACES:
        return None
    weights = stratum_weights(feature_faces(noisy, nu_pilot), measured, core)
    nu = face_normals(noisy) * jnp.asarray(np.sqrt(weights), noisy.dtype)[:, None]
    fraction, sigma = impulsive

    def draw(count: int, salt: int = 0):
        inputs = held_out_inputs(noisy, untouched, displaced, repaired, n, sigma, fraction, count, key, salt)
        return inputs, jnp.broadcast_to(y, inputs.shape)
    return nu, draw, int(measured.sum())
