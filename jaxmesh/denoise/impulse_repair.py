"""Impulse repair: refit the vertices read as displaced to the others.

For impulsive noise (a fraction of the vertices moved, the rest exact) the
untouched vertices are the best data there is.  Alternate two steps, from a
thin-plate fit x⁰ = argmin ‖x − y‖² + α₀ ‖K x‖²:

* **read**: the normal residuals r_i = n_i · (y_i − x_i) (n the area-weighted
  vertex normals of the current fit) are fitted by a two-component zero-mean
  Gaussian mixture (:func:`scale_mixture`, EM); π_i = P(displaced | r_i) is the
  posterior of the wider component;
* **fit**: with w_i = 1 − π_i, x = argmin Σ_i w_i ‖x_i − y_i‖² + α ‖K x‖²,
  i.e. (W + α KᵀK) x = W y, solved by conjugate gradients (lineax, Jacobi
  preconditioned): a vertex read as untouched keeps its position, one read as
  displaced is interpolated from its neighbours by the thin-plate energy.

K = D⁻¹A − I is the umbrella operator, dimensionless, so α and α₀ are scale
free.  Differentiable in the positions and in α, α₀ (the posteriors are smooth
functions of the residuals; the solves are differentiated implicitly).  Made
for impulsive noise: under Gaussian noise every vertex is displaced, the read
has nothing to separate, and the fit is a weighted thin-plate smoothing.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import Scalar, safe_divide
from ..geometry import vertex_normals
from ..mesh import Mesh
from ..operators import degree, neighbor_sum, umbrella
from ._loop import check_iterations, iterate

__all__ = ["impulse_repair", "scale_mixture", "mixture_posterior"]

#: EM steps of the residuals' mixture fit
EM_STEPS = 100
#: the least data weight of a vertex (keeps W + α KᵀK positive definite)
MIN_WEIGHT = 1e-3


def mixture_posterior(r2: Float[Array, "*n"], p, v0, v1) -> Float[Array, "*n"]:
    """P(wide | r) for the mixture p N(0, v₁) + (1 − p) N(0, v₀), given r².

    Arguments:
        r2: squared samples.
        p: the weight of the wide component.
        v0: the narrow component's variance (scalar, or one per sample).
        v1: the wide component's variance (scalar, or one per sample).

    Returns:
        The posteriors, in [0, 1], r2's shape."""
    log_ratio = jnp.log((1 - p) / p) + 0.5 * jnp.log(v1 / v0) + 0.5 * r2 * (1 / v1 - 1 / v0)
    return jax.nn.sigmoid(-log_ratio)


def scale_mixture(r2: Float[Array, " n"], steps: int = EM_STEPS, mask=None):
    """Two-component zero-mean Gaussian mixture of samples r (given r²) by ``steps`` EM
    iterations from p = ½, v₀ = m/4, v₁ = 2m (m = mean r²): (p, v₀, v₁), p the weight
    of the wider component.  p is kept in [10⁻⁶, 1 − 10⁻⁶] and the variances above 10⁻¹² m.

    Arguments:
        r2: squared samples, (n,).
        steps: EM iterations.
        mask: which samples count, (n,) bool (default: all).

    Returns:
        (p, v₀, v₁), scalars."""
    c = jnp.ones_like(r2) if mask is None else mask.astype(r2.dtype)
    count = jnp.maximum(jnp.sum(c), 1)
    m = jnp.sum(c * r2) / count
    tiny = 1e-12 * m + jnp.finfo(r2.dtype).tiny

    def step(_, state):
        p, v0, v1 = state
        r = c * mixture_posterior(r2, p, v0, v1)
        s1, s0 = jnp.sum(r), jnp.sum(c - r)
        return (jnp.clip(s1 / count, 1e-6, 1 - 1e-6), jnp.maximum(safe_divide(jnp.sum((c - r) * r2), s0), tiny),
                jnp.maximum(safe_divide(jnp.sum(r * r2), s1), tiny))

    start = (jnp.asarray(0.5, r2.dtype), jnp.maximum(m / 4, tiny), jnp.maximum(2 * m, tiny))
    return jax.lax.fori_loop(0, steps, step, start)


def _umbrella_t(mesh: Mesh, v):
    """Kᵀ v = A D⁻¹ v − v (A symmetric; K's rows at isolated vertices are 0, so are Kᵀ's columns)."""
    d = degree(mesh, v.dtype)[:, None]
    return neighbor_sum(mesh, safe_divide(v, d)) - jnp.where(d > 0, v, 0)


def _topology(mesh: Mesh, dtype):
    """(connected (V,) bool, diag(KᵀK) (V,)): what every fit of one mesh shares."""
    d = degree(mesh, dtype)
    return d > 0, (d > 0).astype(dtype) + neighbor_sum(mesh, safe_divide(jnp.ones_like(d), d * d)[:, None])[:, 0]


def _fit(mesh: Mesh, y, w, alpha, x0, topology=None):
    """argmin Σ w_i ‖x_i − y_i‖² + α ‖K x‖²: (W + α KᵀK) x = W y by preconditioned CG, on
    positions centred and scaled to unit RMS (the solution moves and scales with y, since
    K c = 0 for constants; lineax's tolerance is per entry, and zero entries of W y, as at
    padding vertices, need an absolute one).  ``topology``: :func:`_topology` of the mesh."""
    is_connected, kk_diag = _topology(mesh, y.dtype) if topology is None else topology
    connected = is_connected.astype(y.dtype)[:, None]
    count = jnp.maximum(jnp.sum(connected), 1)
    centre = jax.lax.stop_gradient(jnp.sum(connected * y, axis=0, keepdims=True) / count)
    scale = jax.lax.stop_gradient(jnp.sqrt(jnp.sum(connected * (y - centre) ** 2) / count) + jnp.finfo(y.dtype).tiny)

    def matvec(x):
        return w[:, None] * x + alpha * _umbrella_t(mesh, umbrella(mesh, x))

    diag = jax.lax.stop_gradient(w + alpha * kk_diag)                                  # diag(W + α KᵀK)
    import lineax as lx  # here, not at the top: the commands that never solve with it do not import lineax

    op = lx.FunctionLinearOperator(matvec, jax.ShapeDtypeStruct(y.shape, y.dtype), tags=lx.positive_semidefinite_tag)
    pre = lx.TaggedLinearOperator(lx.DiagonalLinearOperator(jnp.broadcast_to(1 / diag[:, None], y.shape)),
                                  lx.positive_semidefinite_tag)
    tol = 1e-10 if y.dtype == jnp.float64 else 1e-5
    solver = lx.CG(rtol=tol, atol=tol, max_steps=4000)
    options = {"y0": jax.lax.stop_gradient((x0 - centre) / scale), "preconditioner": pre}
    unit = lx.linear_solve(op, w[:, None] * (y - centre) / scale, solver, options=options, throw=False).value
    return jnp.where(connected > 0, centre + scale * unit, y)       # isolated vertices keep their positions


def _repair_single(mesh: Mesh, y, alpha, alpha0, iterations: int):
    ones = jnp.ones(y.shape[0], y.dtype)
    topology = _topology(mesh, y.dtype)
    connected = topology[0]                      # isolated (and padding) vertices keep their positions
    x0 = _fit(mesh, y, ones, alpha0, y, topology)

    def step(x):
        n = vertex_normals(mesh.with_vertices(x), "area")
        r2 = jnp.sum((y - x) * n, axis=-1) ** 2
        p, v0, v1 = scale_mixture(r2, mask=connected)
        w = jnp.where(connected, jnp.maximum(1 - mixture_posterior(r2, p, v0, v1), MIN_WEIGHT), 1.0)
        return _fit(mesh, y, w, alpha, x, topology)

    return iterate(step, x0, iterations)


def impulse_repair(mesh: Mesh, alpha: Scalar = 0.3, alpha0: Scalar = 3.0, iterations: int = 5) -> Mesh:
    """The read-and-fit alternation of the module docstring: a thin-plate fit with
    weight ``alpha0``, then ``iterations`` rounds of reading the displaced vertices
    from the residuals and refitting them with weight ``alpha``.  Batched over
    leading vertex dimensions (one parameter value per batch element, or one for all).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        alpha: the thin-plate weight α of the refits (dimensionless).
        alpha0: the thin-plate weight α₀ of the first fit.
        iterations: read-and-fit rounds.

    Returns:
        The repaired mesh."""
    check_iterations(iterations)
    x = mesh.vertices
    batch = x.shape[:-2]
    alpha = jnp.broadcast_to(jnp.asarray(alpha, x.dtype), batch)
    alpha0 = jnp.broadcast_to(jnp.asarray(alpha0, x.dtype), batch)
    fn = lambda y, a, a0: _repair_single(mesh, y, a, a0, iterations)  # noqa: E731
    for _ in batch:
        fn = jax.vmap(fn)
    return mesh.with_vertices(fn(x, alpha, alpha0))
