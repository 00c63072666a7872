"""Automatic parameter tuning for every denoiser: supervised (a clean mesh in
hand) or blind (SURE), one mesh, a batch of meshes in one call, or one shared
setting over a training set.

The search, for continuous parameters θ in bounded coordinates u (:mod:`.space`):

1. **Frame.**  The noisy mesh is centred and scaled to a unit bounding-box
   diagonal (box of its non-isolated vertices), and the clean mesh and σ get
   the same transform.  The kernel flow is not scale-equivariant (κ is a
   density, in length⁻³), so a λ means something only in a fixed frame; in
   this one the tuned output, mapped back, is the same for any units of the
   input.  Tuned parameter values are reported in this frame (the CLI
   denoises in it too).
2. **Coarse grid.**  n points per coordinate, uniform in σ(u) (so uniform in
   log θ for a log range), evaluated in blocks of points bounded by the mesh
   size (all at once on small meshes; one by one on large ones); the loss is the
   error relative to the noisy input's, so the grid values are
   dimensionless.
3. **Start and preconditioner.**  Along each coordinate a parabola through
   the best grid point and its neighbours (fitted to log E:
   :func:`~jaxmesh.tune.search.parabola_start`) gives a start u₀ and a curvature
   h (in u); the optimiser works in y = √h (u − u₀), where the loss has unit
   curvature, so that BFGS's first (identity-Hessian) step is already a
   Newton step and its y-tolerance means the same on every mesh.
4. **BFGS** (``optimistix.BFGS``) with forward-mode gradients: with one to
   three parameters a JVP through the flow costs ~2 flow evaluations,
   reverse mode through a ``fori_loop`` of segment sums ~15 (measured on the
   bunny).  Non-finite losses are replaced by a large constant so the line
   search backs off instead of accepting NaN.

Every evaluation counts in ``evaluations`` (grid points, optimiser steps, the
final run); ``history`` holds the accepted iterates.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from .._private import PROBE_STREAM, frozen_pytree, library_key
from ..denoise import Method, as_method, denoise_in_unit_frame
from ..mesh import Mesh
from ..metrics import visual_error
from ..transforms import to_frame, unit_frame
from .objectives import (
    noisy_visual_error_expectation,
    rademacher_probes,
    relative_error,
    sure_visual_error,
)
from .noise_level import blind_caveats, checked_sigma, noise_sigma
from .options import TuneOptions
from .search import Found, search
from .space import Coordinate, search_space

__all__ = ["TuneResult", "TuneOptions", "tune", "tune_lambda"]

_BAD_LOSS = 1e6          # stands in for a non-finite loss (relative units: 1 = the noisy input)
_GRID_DEFAULT = {1: 6, 2: 4}   # points per coordinate; 3 for three or more coordinates


# --------------------------------------------------------------------------- configuration


@dataclasses.dataclass(frozen=True)
class _Config:
    """Everything static about one tuning problem (hashable: a jit static argument)."""

    method: Method
    statics: tuple[tuple[str, Any], ...]
    coords: tuple[Coordinate, ...]
    options: TuneOptions
    blind: bool

    objective = property(lambda self: self.options.objective)
    probes = property(lambda self: self.options.probes)
    max_steps = property(lambda self: self.options.max_steps)
    rtol = property(lambda self: self.options.rtol)
    atol = property(lambda self: self.options.atol)

    @property
    def grid(self) -> int:
        g = self.options.grid
        return g if g is not None else _GRID_DEFAULT.get(len(self.coords), 3)

    def run(self, mesh: Mesh, values: dict, aux: dict) -> Mesh:
        return self.method(mesh, throw=False, **dict(self.statics), **values, **aux)

    def values(self, u) -> dict:
        return {c.name: c.value(u[..., k]) for k, c in enumerate(self.coords)}


def _make_config(method, iterations, options: TuneOptions, blind: bool, fixed: dict) -> _Config:
    """The static configuration for one iteration count (``None``: the method's own)."""
    m = as_method(method)
    if blind and options.objective != "visual":
        raise ValueError("blind tuning (no clean mesh) estimates the visual error only: "
                         f"objective={options.objective!r} needs a clean mesh")
    coords = search_space(m, options.names, dict(options.bounds))
    tuned = {c.name for c in coords}
    clash = sorted(tuned & set(fixed))
    if clash:
        raise ValueError(f"{clash} are tuned; do not also fix them (pass names=... to tune fewer)")
    statics = dict(fixed)
    if iterations is not None:
        if "iterations" not in m.params:
            raise ValueError(f"method {m.name!r} has no 'iterations' parameter")
        statics["iterations"] = iterations
    full = m.resolve(**statics)    # validates names, choices and integer counts
    statics = {k: v for k, v in full.items() if k not in tuned}
    if any(m.params[k].kind == "aux" and v is not None for k, v in statics.items()):
        raise ValueError("auxiliary inputs (the face graph) are built by the tuner; do not pass them")
    statics = {k: v for k, v in statics.items() if m.params[k].kind != "aux"}
    return _Config(m, tuple(sorted(statics.items())), tuple(coords), options, blind)


def _prepare(method, options: TuneOptions | None, keywords: dict, key):
    """The one preparation step of every entry point: (Method, options, the method's
    fixed parameters, PRNG key)."""
    m = as_method(method)
    options, fixed = TuneOptions.from_keywords(options, dict(keywords))
    return m, options, fixed, library_key(key, PROBE_STREAM)


# --------------------------------------------------------------------------- the loss


def _loss_function(cfg: _Config, noisy: Mesh, clean: Mesh | None, sigma, key, aux: dict):
    """u (*g, p) -> relative loss (*g,) on one mesh already in the tuning frame."""
    probes = rademacher_probes(key, noisy, cfg.probes) if cfg.blind else None
    expected = noisy_visual_error_expectation(noisy, sigma) if cfg.blind else None

    def loss(u):
        g = u.shape[:-1]
        values = cfg.values(u)
        y = jnp.broadcast_to(noisy.vertices, g + noisy.vertices.shape)
        if cfg.blind:
            denoiser = lambda x: cfg.run(noisy.with_vertices(x), values, aux).vertices  # noqa: E731
            f = sure_visual_error(noisy.with_vertices(y), denoiser, sigma, probes) / expected
        else:
            f = relative_error(cfg.objective, clean, noisy, cfg.run(noisy.with_vertices(y), values, aux))
        return jnp.where(jnp.isfinite(f), f, _BAD_LOSS)

    return loss


# --------------------------------------------------------------------------- the search


class _Tuned(NamedTuple):
    """One tuning run's arrays, as its compiled program returns them: the parameter
    values by name (``params``, and those of the ``grid`` and the BFGS ``history``),
    the losses there, whether BFGS converged, the loss ``evaluations``, the final
    ``loss`` and ``error``, and the denoised ``vertices`` (None for a shared setting)."""

    params: dict
    grid: dict
    grid_loss: Array
    history: dict
    history_loss: Array
    converged: Array
    evaluations: Array
    loss: Array
    error: Array
    vertices: Array | None


def _tune_one(noisy: Mesh, clean: Mesh | None, sigma, key, cfg: _Config, aux: dict) -> _Tuned:
    """Tune on one mesh (any units); jittable and vmappable over meshes."""
    centre, scale = unit_frame(noisy)
    noisy_n = to_frame(noisy, centre, scale)
    clean_n = None if clean is None else to_frame(clean, centre, scale)
    sigma_n = None if sigma is None else sigma / scale
    loss = _loss_function(cfg, noisy_n, clean_n, sigma_n, key, aux)
    found = search(loss, cfg, noisy.dtype, noisy.num_vertices)
    result_n = cfg.run(noisy_n, cfg.values(found.u), aux)
    vertices = result_n.vertices * scale[..., None, None] + centre[..., None, :]
    if clean is None:   # SURE needs its own pass (a JVP); in mesh units: relative SURE x E[E(noisy)]
        final = loss(found.u[None])[0]
        return _named(cfg, found, final, final * noisy_visual_error_expectation(noisy, sigma), vertices, 2)
    final = relative_error(cfg.objective, clean_n, noisy_n, result_n)     # from the final run itself
    return _named(cfg, found, final, visual_error(clean, vertices), vertices, 1)


def _named(cfg: _Config, found: Found, loss, error, vertices, closing: int) -> _Tuned:
    """The ``_Tuned`` of a search: coordinates u -> parameter values by name (inside jit: no
    eager dispatch); evaluations = grid points + optimiser steps + ``closing`` evaluations."""
    return _Tuned(cfg.values(found.u), cfg.values(found.grid_u), found.grid_loss, cfg.values(found.history_u),
                  found.history_loss, found.converged, found.grid_loss.shape[-1] + found.steps + closing, loss,
                  error, vertices)


# --------------------------------------------------------------------------- results


@frozen_pytree(static=("method", "statics", "denoiser"))
@dataclasses.dataclass(frozen=True, eq=False)
class TuneResult:
    """What a tuning run found (a pytree: its arrays are the leaves; ``method``, ``statics`` and
    ``denoiser`` are static).

    * ``params``: the tuned continuous parameters (values in the unit-diagonal
      tuning frame; :meth:`apply` runs the method in that frame);
    * ``fixed``: the method's other parameters as used (iteration count, ...), a dict
      (kept as the hashable ``statics``, sorted (name, value) pairs);
    * ``loss``: the objective at ``params`` relative to the noisy input (E/E_noisy,
      or SURE/E[E_noisy] when blind);
    * ``error``: the visual error of ``mesh`` against the clean mesh, in the mesh's
      units (supervised), or its SURE estimate (blind);
    * ``sigma``: the noise σ used by blind tuning (mesh units), else None;
    * ``evaluations``: flow evaluations spent (grid + optimiser steps + final run);
    * ``converged``: the optimiser met its tolerance within ``max_steps``;
    * ``history``: accepted iterates {name: (S,)} and ``history_loss`` (S,),
      NaN after the last; ``grid`` / ``grid_loss`` the coarse grid;
    * ``mesh``: the denoised mesh, in the input's units;
    * ``method`` its name and ``denoiser`` the :class:`~jaxmesh.denoise.Method` itself.

    Arrays carry a leading batch axis when returned by :func:`tune_batch`.
    """

    method: str
    statics: tuple[tuple[str, Any], ...]
    denoiser: Method
    params: dict
    loss: Array
    error: Array
    sigma: Array | None
    evaluations: Array
    converged: Array
    history: dict
    history_loss: Array
    grid: dict
    grid_loss: Array
    mesh: Mesh | None

    @property
    def fixed(self) -> dict:
        """The method's other parameters as used, by name."""
        return dict(self.statics)

    def apply(self, mesh: Mesh) -> Mesh:
        """Denoise ``mesh`` (any units) with the tuned parameters, in the same
        unit-diagonal frame the tuner used.  For a shared result this is how a
        parameter learned on a training set is used on unseen meshes."""
        if jnp.ndim(next(iter(self.params.values()))) != 0:
            raise ValueError("apply needs a single result, not a batched one (index it first)")
        return denoise_in_unit_frame(mesh, self.denoiser, **self.fixed, **self.params)


def _result(cfg: _Config, out: _Tuned, sigma, mesh) -> TuneResult:
    return TuneResult(
        method=cfg.method.name, statics=tuple(cfg.statics), denoiser=cfg.method, params=out.params, loss=out.loss,
        error=out.error, sigma=sigma, evaluations=out.evaluations, converged=out.converged,
        history=out.history, history_loss=out.history_loss, grid=out.grid, grid_loss=out.grid_loss, mesh=mesh,
    )


# --------------------------------------------------------------------------- public API


def _check_pair(noisy: Mesh, clean: Mesh | None) -> None:
    if not isinstance(noisy, Mesh):
        raise TypeError(f"noisy must be a jaxmesh.Mesh, got {type(noisy).__name__}")
    if clean is None:
        return
    if not isinstance(clean, Mesh):
        raise TypeError(f"clean must be a jaxmesh.Mesh, got {type(clean).__name__}")
    if clean.num_vertices != noisy.num_vertices or clean.faces.shape != noisy.faces.shape or not (
            np.asarray(clean.faces) == np.asarray(noisy.faces)).all():
        raise ValueError("clean and noisy meshes must have the same connectivity "
                         f"(got {clean!r} and {noisy!r})")


def _sigma_for(noisy: Mesh, sigma, blind: bool):
    if not blind:
        return None
    if sigma is None:
        return jnp.asarray(noise_sigma(noisy)[0], noisy.dtype)
    return jnp.asarray(checked_sigma(noisy, sigma), noisy.dtype)


_tune_jit = jax.jit(_tune_one, static_argnames="cfg")


def tune(noisy: Mesh, clean: Mesh | None = None, method: "str | Method" = "kernel", *,
         iterations: int | Sequence[int] | None = None, sigma=None, key=0,
         options: TuneOptions | None = None, **keywords) -> TuneResult:
    """Tune ``method``'s continuous parameters on ``noisy`` (module docstring).

    Jit-compiled once per method, options, iteration count and mesh shape.

    Arguments:
        noisy: the mesh to denoise.
        clean: the clean mesh (same connectivity): minimise the objective ("visual" E,
            "nonlinear" D, or "normal" mean face-normal angle) of the output against
            it.  Without it, tune blind: minimise SURE of E.
        method: a registry name or a :class:`~jaxmesh.denoise.Method` (your own).
        iterations: an int, or several to choose from (each is tuned, the best loss
            wins); default the method's own.
        sigma: blind tuning's noise σ in mesh units (default: :func:`estimate_noise`).
        key: the key (or int seed) of blind tuning's Hutchinson probes.
        options: a :class:`TuneOptions` (which parameters, their ranges, the objective,
            grid, BFGS tolerances and budget, probes).
        **keywords: :class:`TuneOptions` fields (``names=["lam"]``, ``grid=8``), which
            override ``options``; any other keyword is a method parameter, held fixed.

    Returns:
        A :class:`TuneResult`: the tuned parameters, the denoised mesh, the loss and
        the search history."""
    _check_pair(noisy, clean)
    if noisy.batch_shape:
        raise ValueError("tune takes one mesh; use tune_batch for a batch")
    m, options, fixed, k = _prepare(method, options, keywords, key)
    blind = clean is None
    counts = [iterations] if iterations is None or isinstance(iterations, int) else list(iterations)
    if not counts:
        raise ValueError("iterations: give at least one count")
    configs = [_make_config(m, it, options, blind, fixed) for it in counts]   # every check before any work
    s = _sigma_for(noisy, sigma, blind)
    aux = m.prepare(noisy)
    best = None
    for cfg in configs:
        out = _tune_jit(noisy, clean, s, k, cfg=cfg, aux=aux)
        res = _result(cfg, out, s, noisy.with_vertices(out.vertices))
        if best is None or float(res.loss) < float(best.loss):
            best = res
    if blind:
        blind_caveats(noisy, float(s), sigma is None, float(best.loss))
    return best


def tune_lambda(noisy: Mesh, clean: Mesh | None = None, method: "str | Method" = "kernel",
                **keywords) -> TuneResult:
    """:func:`tune` of the kernel flow's λ alone (the thesis's one parameter);
    for another method, of its first continuous parameter.

    Arguments:
        noisy: the noisy mesh.
        clean: the clean reference (None: blind).
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        **keywords: as :func:`tune`.

    Returns:
        A :class:`TuneResult`."""
    m = as_method(method)
    return tune(noisy, clean, m, names=keywords.pop("names", m.continuous[:1]), **keywords)
