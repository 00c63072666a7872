"""One registry of denoising methods with a uniform call signature.

``METHODS[name](mesh, **params) -> Mesh``; every method accepts a batched
mesh (vertices of shape (*batch, V, 3), one parameter value per batch element
or one for all) and is jittable with its integer parameters static.  Each
:class:`Param` says whether it is continuous (and so tunable by gradient, with
the range in which tuning should search), an iteration count, or a choice.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import warnings
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._private import caller_stacklevel
from ..mesh import Mesh, MeshWarning
from .anisotropic import anisotropic_diffusion
from .bilateral import bilateral_denoising
from .curvature import cotangent_flow
from .geometric_diffusion import geometric_diffusion
from .kernel_flow import kernel_diffusion
from .laplacian import BOUNDARY_MODES, hc_smoothing, taubin_smoothing, umbrella_flow
from .bilateral_normal import bilateral_normal_filtering
from .face_graph import face_graph
from ._compiled import compilable, host_built, method_program, split_call
from .divergence import diverged
from .selection import hold
from .vertex_rings import vertex_rings
from .guided import guided_normal_filtering
from .impulse_repair import impulse_repair
from .l0 import l0_denoising
from .normal_filtering import normal_filtering

__all__ = ["Param", "Method", "METHODS", "as_method", "denoise", "diverged"]


@dataclasses.dataclass(frozen=True)
class Param:
    """A method parameter: ``kind`` is "continuous" (tunable; ``bounds`` is the
    search range, ``log`` whether to search it on a log scale), "int",
    "choice", "file" (a path read on the host, static under ``jit``), or "aux"
    (auxiliary data such as precomputed topology, made on the host by
    ``build(mesh)``; see :meth:`Method.prepare`).

    ``domain`` is where a continuous value is valid at all (``bounds`` is only
    where tuning searches): ``(lo, hi)`` with ``closed`` saying which ends are
    included ("()", "[)", "(]", "[]").  Concrete values outside it, NaN and ±inf
    are refused by :meth:`Method.resolve`; traced values (inside the tuner's
    ``jit``) are not checked."""

    default: Any
    kind: str
    help: str
    bounds: tuple[float, float] | None = None
    log: bool = False
    choices: tuple[str | bool, ...] = ()
    build: Callable[[Mesh], Any] | None = None
    domain: tuple[float, float] = (0.0, math.inf)
    closed: str = "()"

    def check(self, name: str, value) -> None:
        """Raise ``ValueError`` naming ``name`` if a concrete ``value`` is outside the domain."""
        if self.kind != "continuous" or isinstance(value, jax.core.Tracer):
            return
        try:
            a = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number, got {value!r}") from None
        lo, hi = self.domain
        ok = np.isfinite(a) & ((a >= lo) if self.closed[0] == "[" else (a > lo)) \
            & ((a <= hi) if self.closed[1] == "]" else (a < hi))
        if not ok.all():
            bad = a.reshape(-1)[~ok.reshape(-1)][0]
            raise ValueError(f"{name} must be a finite number in {self.closed[0]}{lo:g}, {hi:g}{self.closed[1]}, "
                             f"got {bad:g}")


@dataclasses.dataclass(frozen=True, eq=False)
class Method:
    """A registered denoiser: ``method(mesh, **params)`` fills in the defaults,
    refuses unknown names and calls ``function``.

    Compared and hashed by identity, so a ``Method`` (registered or not) can be a
    static argument of ``jax.jit`` (the tuner's configuration holds one)."""

    name: str
    function: Callable[..., Mesh]
    params: dict[str, Param]
    summary: str
    reference: str
    constraint: Callable[[dict], str | None] | None = None
    #: no reduction over the whole mesh: on a disjoint union of meshes (each in its own
    #: frame) it gives each mesh its own result (:func:`jaxmesh.denoise.packed_run`)
    local: bool = False
    #: the one whole-mesh quantity the method measures its parameters in, otherwise local
    #: (``"mean_edge_length"``): on a union each mesh is scaled so that its own is 1, which
    #: makes the union's 1 as well, so each mesh again gets its own result
    unit: str | None = None
    #: inputs that ``function`` builds itself from concrete connectivity when they are not
    #: given (name -> builder; the kernel flow's vertex rings): not parameters, but passed
    #: through to ``function``.  A compiled call on one mesh, where the connectivity is
    #: traced, builds them on the host first (:func:`~jaxmesh.denoise.denoise_in_unit_frame`)
    host_inputs: dict[str, Callable[[Mesh], Any]] = dataclasses.field(default_factory=dict)

    @property
    def packable(self) -> bool:
        """Whether the method runs on a packed union (``local``, or a ``unit`` to scale by)."""
        return self.local or self.unit is not None

    def defaults(self) -> dict[str, Any]:
        return {k: p.default for k, p in self.params.items()}

    @property
    def continuous(self) -> tuple[str, ...]:
        return tuple(k for k, p in self.params.items() if p.kind == "continuous")

    @property
    def aux(self) -> tuple[str, ...]:
        return tuple(k for k, p in self.params.items() if p.kind == "aux")

    def prepare(self, mesh: Mesh) -> dict[str, Any]:
        """The auxiliary inputs (host-built topology) for ``mesh``: pass them as
        keyword arguments to call the method under ``jit`` with the mesh traced.
        Empty for methods that need none.  Built once per connectivity: a later call on the same
        faces returns what was built (:func:`jaxmesh.denoise._compiled.host_built`)."""
        return {k: host_built(self.params[k].build, mesh) for k in self.aux}

    def resolve(self, **params) -> dict[str, Any]:
        unknown = sorted(set(params) - set(self.params))
        if unknown:
            raise ValueError(f"method {self.name!r} has no parameter(s) {unknown}; "
                             f"it takes {sorted(self.params)}")
        full = {**self.defaults(), **params}
        for k, p in self.params.items():
            if p.kind == "choice" and full[k] not in p.choices:
                raise ValueError(f"{self.name}: {k} must be one of {p.choices}, got {full[k]!r}")
            if p.kind == "file" and not isinstance(full[k], (str, os.PathLike)):
                raise ValueError(f"{self.name}: {k} must be a file path, got {full[k]!r}")
            if p.kind == "int" and (isinstance(full[k], bool) or not isinstance(full[k], int)
                                    or full[k] < 0):
                raise ValueError(f"{self.name}: {k} must be a non-negative int, got {full[k]!r}")
            p.check(f"{self.name}: {k}", full[k])
        problem = self.constraint(full) if self.constraint else None
        if problem:
            raise ValueError(f"{self.name}: {problem}")
        return full

    def split(self, **params) -> tuple[dict[str, Any], tuple]:
        """(continuous parameters as float arrays, the others as a sorted hashable
        tuple) of the resolved parameters, auxiliary inputs left out: the traced
        and the static arguments of one compiled call (defaults included, so every
        continuous value is traced and a new value never recompiles)."""
        cont, statics = self.parts(self.resolve(**params))
        dtype = jnp.result_type(float)     # host numbers stay on the host: jnp.asarray would compile a cast
        return {k: np.asarray(v, dtype) if isinstance(v, (int, float, np.number, np.ndarray)) else jnp.asarray(v, dtype)
                for k, v in cont.items()}, statics

    def parts(self, full: dict[str, Any]) -> tuple[dict[str, Any], tuple]:
        """(the continuous parameters as given, the others as a sorted hashable tuple) of
        resolved parameters ``full``, auxiliary inputs left out."""
        cont = {k: v for k, v in full.items() if self.params[k].kind == "continuous"}
        return cont, tuple(sorted((k, v) for k, v in full.items() if k not in cont and self.params[k].kind != "aux"))

    def __call__(self, mesh: Mesh, *, throw: bool = True, **params) -> Mesh:
        """The method on ``mesh`` with ``params`` (defaults from :attr:`params`, each checked).
        With ``throw``, a non-finite output coordinate is an error: ``FloatingPointError``
        when called eagerly, an equinox runtime error (``eqx.error_if``) under ``jit`` and
        ``vmap``; ``throw=False`` returns it for the caller to check (the tuner and the
        dataset runner do, with :func:`diverged`).  Called with concrete inputs on one
        connectivity it runs one compiled program, kept for later calls (the continuous
        parameters traced, the host-built inputs passed in: :mod:`jaxmesh.denoise._compiled`)."""
        if compilable(self, mesh, params) and mesh.faces.ndim == 2:      # one kept program (denoise._compiled)
            continuous, statics, inputs = split_call(self, mesh, params)
            out = mesh.with_vertices(method_program(mesh, continuous, inputs, self, statics))
        else:
            extra = {k: params.pop(k) for k in self.host_inputs if k in params}
            out = self.function(mesh, **self.resolve(**params), **extra)
        if not throw:
            return out
        x = out.vertices
        tail = (f"({x.dtype}); if the input was finite, a parameter is outside the range this "
                "precision supports (try float64 or a smaller step)")
        if isinstance(x, jax.core.Tracer):
            import equinox as eqx    # here: a call outside jit does not import equinox

            bad = ~jnp.all(jnp.isfinite(x), axis=(-2, -1))
            return out.with_vertices(eqx.error_if(x, bad, f"{self.name} produced non-finite coordinates {tail}"))
        if not np.isfinite(np.asarray(x)).all():      # on the host: no program of its own
            raise FloatingPointError(f"{self.name} produced non-finite coordinates with "
                                     f"{params or 'its defaults'} {tail}")
        return out


_BOUNDARY = Param("free", "choice", "boundary vertices: 'free' (all neighbours) or 'curve' (along the boundary)",
                  choices=BOUNDARY_MODES)
_GRAPH = Param(None, "aux", "face_graph(mesh), built on the host; pass it to call the method under jit",
               build=face_graph)


def _learned(mesh: Mesh, model: "str | os.PathLike" = "default", graph=None) -> Mesh:
    """:func:`jaxmesh.learn.learned_denoising` with the model in the file ``model`` (read
    once per file version; "default": the shipped one); with concrete inputs on one
    connectivity, its kept program (:func:`jaxmesh.learn.model.learned_program`)."""
    from ..learn.model import learned_denoising, learned_program
    from ..learn.modelfile import default_model

    weights = default_model(None if model == "default" else model)
    if mesh.faces.ndim == 2 and not any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(mesh)):
        return learned_program(mesh, weights, host_built(face_graph, mesh) if graph is None else graph)
    return learned_denoising(mesh, weights, graph)


def _taubin_pass_band(p: dict) -> str | None:
    """μ > −λ is allowed (the tuner may find it best) but is not Taubin's low-pass
    filter (k_PB = 1/λ + 1/μ ≤ 0): a warning, not an error."""
    lam, mu = p["lam"], p["mu"]
    if isinstance(lam, jax.core.Tracer) or isinstance(mu, jax.core.Tracer):
        return None
    if np.any(np.asarray(mu, np.float64) > -np.asarray(lam, np.float64)):
        warnings.warn(f"taubin with μ > -λ (λ = {lam}, μ = {mu}) is not a low-pass filter: it has no "
                      "pass band and may amplify high frequencies", MeshWarning, stacklevel=caller_stacklevel())
    return None


def _it(default: int, what: str = "number of iterations") -> Param:
    return Param(default, "int", what)


def _normal_filter_params(normal_iterations: int) -> dict[str, Param]:
    """The parameters of the joint-bilateral two-step filters (bilateral and guided)."""
    return {
        "sigma_s": Param(1.0, "continuous", "spatial σ_s, in mean centroid spacings", (0.3, 4.0), True),
        "sigma_r": Param(0.35, "continuous", "range σ_r between (guidance) unit normals", (0.05, 1.5), True),
        "tangential": Param(0.1, "continuous", "tangential relaxation per vertex update (0: Sun et al.)",
                            (0.0, 0.5), domain=(0.0, 1.0), closed="[]"),
        "normal_iterations": _it(normal_iterations, "normal filter passes per round"),
        "vertex_iterations": _it(20, "vertex updates per round"),
        "iterations": _it(1, "outer rounds"),
        "graph": _GRAPH,
    }


METHODS: dict[str, Method] = {
    m.name: m
    for m in [
        Method("kernel", kernel_diffusion, {
            "lam": Param(0.4, "continuous", "regularisation λ of H_i (squared length)", (0.05, 20.0), True,
                         domain=(0.0, 1e6), closed="(]"),
            "iterations": _it(5),
            "variant": Param("random_walk", "choice", "update rule", choices=("random_walk", "paper")),
            "safeguard": Param(True, "choice", "cap the random-walk step (never diverges)",
                               choices=(True, False)),
        }, "multivariate kernel diffusion (the thesis, ch.2)", "Tarmissi 2010, ch.2 eq.6-12", local=True,
            host_inputs={"rings": vertex_rings}),
        Method("cauchy_diffusion", anisotropic_diffusion, {
            "dt": Param(0.25, "continuous", "step size", (0.01, 0.5), True),
            "c": Param(1.0, "continuous", "Cauchy scale, relative to the mean |∇x|", (0.05, 20.0), True),
            "iterations": _it(10),
            "variant": Param("random_walk", "choice", "update rule", choices=("random_walk", "paper")),
        }, "vertex-based anisotropic diffusion, Cauchy weight", "Zhang & Ben Hamza 2006"),
        Method("umbrella_flow", umbrella_flow, {
            "lam": Param(0.5, "continuous", "umbrella step", (0.01, 1.0), True, domain=(0.0, 1.0), closed="(]"),
            "iterations": _it(10),
            "boundary": _BOUNDARY,
        }, "umbrella flow x <- x + λ K x (Laplacian smoothing)", "Taubin 1995", local=True,
            host_inputs={"rings": vertex_rings}),
        Method("taubin", taubin_smoothing, {
            "lam": Param(0.5, "continuous", "shrinking step λ ∈ (0, 1]", (0.01, 1.0), True, domain=(0.0, 1.0),
                         closed="(]"),
            "mu": Param(-0.53, "continuous",
                        "inflating step μ ∈ [-1, 0); μ ≤ -λ for a low-pass filter (else a warning)",
                        (-1.0, -0.01), domain=(-1.0, 0.0), closed="[)"),
            "iterations": _it(10),
            "boundary": _BOUNDARY,
        }, "Taubin λ|μ low-pass filter", "Taubin 1995", _taubin_pass_band, local=True,
            host_inputs={"rings": vertex_rings}),
        Method("hc", hc_smoothing, {
            "alpha": Param(0.1, "continuous", "pull towards the original positions", (0.0, 1.0),
                           domain=(0.0, 1.0), closed="[]"),
            "beta": Param(0.5, "continuous", "pull towards the previous positions", (0.0, 1.0),
                          domain=(0.0, 1.0), closed="[]"),
            "iterations": _it(10),
            "boundary": _BOUNDARY,
        }, "HC Laplacian (extra baseline, not in the thesis)", "Vollmer, Mencl & Müller 1999", local=True,
            host_inputs={"rings": vertex_rings}),
        Method("cotangent", functools.partial(cotangent_flow, implicit=False), {
            "dt": Param(0.5, "continuous", "normalised explicit step", (0.01, 1.0), True),
            "iterations": _it(5),
        }, "mean-curvature flow, cotangent weights, explicit", "Desbrun et al. 1999", local=True),
        Method("cotangent_implicit", functools.partial(cotangent_flow, implicit=True), {
            "dt": Param(0.3, "continuous", "time step in units of the mean vertex area", (0.01, 100.0), True),
            "iterations": _it(3),
            "solver": Param("cg", "choice", "linear solver of each step: matrix-free CG or a sparse Cholesky "
                            "factorization (jaxmesh.linalg)", choices=("cg", "cholesky")),
        }, "mean-curvature flow, cotangent weights, implicit", "Desbrun et al. 1999"),
        Method("normal_mean", functools.partial(normal_filtering, kind="mean"), {
            "iterations": _it(1, "outer rounds"),
            "normal_iterations": _it(5, "normal filter passes per round"),
            "vertex_iterations": _it(10, "vertex updates per round"),
            "graph": _GRAPH,
        }, "mean filtering of face normals + vertex updating", "Yagou et al. 2002"),
        Method("normal_median", functools.partial(normal_filtering, kind="median"), {
            "iterations": _it(1, "outer rounds"),
            "normal_iterations": _it(5, "normal filter passes per round"),
            "vertex_iterations": _it(10, "vertex updates per round"),
            "graph": _GRAPH,
        }, "angle-median filtering of face normals + vertex updating", "Yagou et al. 2002"),
        Method("bilateral", bilateral_denoising, {
            "sigma_c": Param(1.0, "continuous", "closeness σ_c in mean edge lengths", (0.1, 10.0), True),
            "sigma_s": Param(1.0, "continuous", "similarity σ_s in mean edge lengths", (0.01, 10.0), True),
            "iterations": _it(3),
        }, "bilateral mesh denoising", "Fleishman et al. 2003", unit="mean_edge_length"),
        Method("bilateral_normal", bilateral_normal_filtering, _normal_filter_params(10),
               "bilateral filtering of face normals + vertex update (feature preserving)",
               "Zheng et al. 2011 (local); Sun et al. 2007 update"),
        Method("guided_normal", guided_normal_filtering, _normal_filter_params(20),
               "guided (patch-consistent) normal filtering + vertex update (feature preserving)",
               "Zhang et al. 2015; Sun et al. 2007 update"),
        Method("l0", l0_denoising, {
            "lam": Param(10.0, "continuous", "L0 weight, in units of 0.02 ℓ̄² γ̄ (grid-tuned: zero gradient)",
                         (0.05, 20.0), True),
            "alpha": Param(1.0, "continuous", "regulariser weight, in units of 0.1 γ̄", (0.01, 100.0), True),
            "iterations": _it(40, "half-quadratic steps (β from 1e-3 to 1e3)"),
            "solver": Param("cholesky", "choice", "linear solver of each step: a sparse Cholesky factorization "
                            "(jaxmesh.linalg) or matrix-free CG", choices=("cholesky", "cg")),
            "graph": _GRAPH,
        }, "L0 minimization of the edge operator (feature preserving)", "He & Schaefer 2013"),
        Method("impulse_repair", impulse_repair, {
            "alpha": Param(0.3, "continuous", "thin-plate weight of the refits (dimensionless)", (0.01, 10.0), True),
            "alpha0": Param(3.0, "continuous", "thin-plate weight of the first fit", (0.1, 30.0), True),
            "iterations": _it(5, "read-and-fit rounds"),
        }, "refit the vertices read as displaced to the others (impulsive noise)",
            "two-component residual mixture + weighted thin-plate fit"),
        Method("learned", _learned, {
            "model": Param("default", "file", "model file from `jaxmesh train` ('default': the shipped model)"),
            "graph": _GRAPH,
        }, "learned stack of Taubin, joint bilateral/guided normal passes and vertex updates (no search)",
            "jaxmesh.learn: unrolled filters, parameters set by two small networks"),
        Method("geometric", geometric_diffusion, {
            "dt": Param(0.3, "continuous", "time step in units of the mean vertex area", (0.01, 100.0), True),
            "rho": Param(1.0, "continuous", "curvature scale of G, in 1/mean edge length", (0.01, 100.0), True),
            "iterations": _it(3),
        }, "anisotropic geometric diffusion (FEM, per-face tensor)", "Clarenz et al. 2000"),
    ]
}


def as_method(method: "str | Method") -> Method:
    """The :class:`Method` named ``method`` in :data:`METHODS`, or ``method`` itself
    when it is a ``Method`` already (a user's own, registered or not).

    Arguments:
        method: a registry name or a :class:`Method`.

    Returns:
        The :class:`Method`."""
    if isinstance(method, Method):
        return method
    if not isinstance(method, str):
        raise TypeError(f"method must be a registry name or a Method, got {type(method).__name__}")
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {sorted(METHODS)}")
    return METHODS[method]


def denoise(mesh: Mesh, method: "str | Method" = "kernel", *, where=None, throw: bool = True, **params) -> Mesh:
    """Denoise ``mesh`` with a registered method: ``as_method(method)(mesh, **params)``,
    blended with the input by ``where`` (:mod:`jaxmesh.denoise.selection`).

    Arguments:
        mesh: the mesh (single or batched: every batch element is denoised).
        method: a registry name (``jaxmesh denoise --list-methods`` lists them; an
            unknown name is a clear error) or a :class:`Method` of your own.
        where: per-vertex weights in [0, 1] or a boolean mask, (V,): x' = y + w (x − y), so
            vertices with w = 0 keep their input positions exactly (default: all move).
        throw: a non-finite result is an error, under ``jit`` and ``vmap`` too
            (:meth:`Method.__call__`); False: return it.
        **params: the method's parameters (defaults from the registry); each is
            checked against its domain.

    Returns:
        The denoised mesh (same topology)."""
    out = as_method(method)(mesh, throw=throw, **params)
    return out if where is None else hold(mesh, out, where)
