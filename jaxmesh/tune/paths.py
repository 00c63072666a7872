"""The families :func:`~jaxmesh.tune.choose_denoiser` searches over their
outer-iteration count, one setting at a time in a compiled loop whose count is
a traced bound (``PATH_CAPACITY_STEP``), so the paths of one method share a
program.

The recorrupted inputs are denoised one iteration at a time and the estimate
(:mod:`jaxmesh.tune.recorrupt`) is read after every iteration, so every count
costs no more than the largest (:class:`SearchPath`).  Searched by default
(``PATHS``):

* *Taubin*: λ ∈ ``TAUBIN_LAMS`` × pass band k_PB ∈ ``TAUBIN_PASS_BANDS``
  (μ = λ / (k_PB λ − 1), so μ ≤ −λ) × every count up to
  ``TAUBIN_MAX_ITERATIONS``.  λ stays at or below 1/√2: a pair's gain
  (1 − λk)(1 − μk) at the top of the umbrella spectrum (k = 2, μ ≈ −λ) is
  1 − 4λ², below −1 for larger λ, so those modes would grow with every pass.
* *Bilateral normal filtering, the local iterative scheme* (Zheng et al.
  2011): each iteration is one filtering pass of the face normals and
  ``BILATERAL_PATH_FIXED["vertex_iterations"]`` vertex updates, repeated up to
  ``BILATERAL_PATH_MAX_ITERATIONS`` times, at σ_s × σ_r ∈
  ``BILATERAL_PATH_SIGMAS`` (smoothing settings); and one feature-preserving
  setting, ``BILATERAL_FEATURE_SETTING``, up to
  ``BILATERAL_FEATURE_MAX_ITERATIONS`` times.

**Stopping.**  A setting's risk against its count falls to one least value and
then rises (the filter starts smoothing the surface away), so a setting stops
once its risk has stayed above ``PATH_STOP_FACTOR`` times its least for more
than ``PATH_STOP_PATIENCE`` iterations; the counts not run read +inf (how often
that moves a curve's least point: the denoising guide, *Paths stop early*).

**Held vertices.**  On the patches of a large mesh (:mod:`jaxmesh.tune.patches`)
each iteration is followed by x_i ← p_i on the patches' rim (``pin``: the rim
and the pilot's positions p), so the filters see a denoised surface beyond
each patch instead of a free edge.

Why these grids, and what they were measured against: the denoising guide.
"""

from __future__ import annotations

import dataclasses
import itertools

import jax
import jax.numpy as jnp
import numpy as np

from .._exported import stored_jit
from ..mesh import Mesh
from .recorrupt import edge_tilt

__all__ = ["SearchPath", "PATHS", "TAUBIN_LAMS", "TAUBIN_PASS_BANDS", "TAUBIN_MAX_ITERATIONS", "taubin_mu",
           "BILATERAL_PATH_SIGMAS", "BILATERAL_PATH_FIXED", "BILATERAL_PATH_MAX_ITERATIONS",
           "BILATERAL_FEATURE_SETTING", "BILATERAL_FEATURE_MAX_ITERATIONS", "PATH_CAPACITY_STEP", "PATH_STOP_FACTOR",
           "PATH_STOP_PATIENCE", "one_iteration", "held", "path_risks"]

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
    """A family :func:`~jaxmesh.tune.choose_denoiser` searches over its outer-iteration count:
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


#: a path's scan is compiled for its count rounded up to a multiple of this, and runs its own count
#: (a traced bound): paths of one method whose counts round alike share one program
PATH_CAPACITY_STEP = 32


#: a path stops once its risk has been above this multiple of its least for ``PATH_STOP_PATIENCE`` iterations
PATH_STOP_FACTOR = 1.2
#: iterations past the least risk before a path may stop (module docstring, *Stopping*)
PATH_STOP_PATIENCE = 5


def one_iteration(mesh: Mesh, x, continuous: dict, aux: dict, method: str, statics: tuple):
    """One iteration of a path's method (``iterations=1``) from positions ``x``: the step both the
    paths' loops and the counted runs of :func:`~jaxmesh.tune.race.run_setting` repeat.

    Arguments:
        mesh: the mesh (single).
        x: positions, (*batch, V, 3).
        continuous: the traced parameters.
        aux: the method's prepared arrays.
        method: a registry name.
        statics: the static parameters, ``iterations`` left out.

    Returns:
        The positions after one iteration, x's shape."""
    from ..denoise import METHODS

    return METHODS[method](mesh.with_vertices(x), throw=False, **continuous, **dict(statics), iterations=1,
                           **aux).vertices


def held(x, pin):
    """x with the vertices of ``pin`` = (mask (V,) bool, positions p (V, 3)) set to p (module
    docstring, *Held vertices*); x itself where ``pin`` is None.

    Arguments:
        x: positions, (*batch, V, 3).
        pin: None, or (mask, p).

    Returns:
        x's shape."""
    if pin is None:
        return x
    mask, p = pin
    return jnp.where(mask[:, None], p.astype(x.dtype), x)


@stored_jit(static_argnames=("method", "statics", "capacity"))
def _path_risks(mesh: Mesh, inputs, targets, nu, ell, continuous: dict, aux: dict, count, factor, patience, pin,
                method: str, statics: tuple, capacity: int):
    """Mean edge-tilt risk Σ‖A(x_t − target)‖²/F over the draws after every
    iteration t = 1..count of one setting, stopped early (module docstring, *Stopping*):
    shape (capacity,), +inf past the last iteration run.  ``inputs``, ``targets``: (D, V, 3) or (V, 3); ``pin``:
    as for :func:`held`."""

    def going(state):
        t, _, risks, best_t = state
        last = risks[jnp.maximum(t - 1, 0)]
        spent = (t > best_t + patience) & (last > factor * risks[best_t])
        return (t < count) & ~spent

    def step(state):
        t, x, risks, best_t = state
        x = held(one_iteration(mesh, x, continuous, aux, method, statics), pin)
        r = edge_tilt(mesh, nu, ell, x - targets)                                    # (D, F, 3)
        risks = risks.at[t].set(jnp.mean(jnp.sum(r * r, axis=(-2, -1))) / mesh.num_faces)
        return t + 1, x, risks, jnp.where(risks[t] < risks[best_t], t, best_t)

    risks = jnp.full((capacity,), jnp.inf, inputs.dtype)
    return jax.lax.while_loop(going, step, (jnp.asarray(0, jnp.int32), inputs, risks, jnp.asarray(0, jnp.int32)))[2]


def path_risks(mesh: Mesh, path: SearchPath, setting: dict, inputs, targets, nu, ell, aux: dict,
               stop: tuple[float, int] | None = (PATH_STOP_FACTOR, PATH_STOP_PATIENCE), pin=None) -> np.ndarray:
    """Σ‖A(x_t − ỹ)‖²/F summed over the draws, after every iteration t = 1..``path.max_iterations``
    of one setting of ``path`` (x_0 = ŷ).

    Arguments:
        mesh: the noisy mesh (single).
        path: the family.
        setting: one of ``path.settings``.
        inputs: the recorrupted inputs ŷ, (D, V, 3).
        targets: the targets ỹ, (D, V, 3).
        nu: the pilot's unit face normals, (F, 3).
        ell: the mean edge length ℓ̄.
        aux: the method's prepared arrays.
        stop: (factor, patience) of the early stop (module docstring, *Stopping*); None: every count.
        pin: None, or (mask (V,) bool, positions (V, 3)) held after every iteration (:func:`held`).

    Returns:
        (max_iterations,) float64, the sum over the D draws; +inf past the last count run."""
    from ..denoise import METHODS

    cont, statics = METHODS[path.method].split(**setting, **dict(path.fixed))
    statics = tuple(kv for kv in statics if kv[0] != "iterations")
    capacity = -(-path.max_iterations // PATH_CAPACITY_STEP) * PATH_CAPACITY_STEP
    factor, patience = (np.inf, 0) if stop is None else stop
    if len(inputs) == 1:        # one draw, no draw axis: the blind chooser ran 10-15% faster on 2 cores
        inputs, targets = inputs[0], targets[0]
    risk = _path_risks(mesh, inputs, targets, nu, ell, cont, aux, np.int32(path.max_iterations),
                       np.asarray(factor, inputs.dtype), np.int32(patience), pin, path.method, statics, capacity)
    return np.asarray(risk, np.float64)[:path.max_iterations] * (1 if inputs.ndim == 2 else len(inputs))
