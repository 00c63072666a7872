"""Weighted-Laplacian (mean-curvature) flow with cotangent weights
(Desbrun, Meyer, Schröder & Barr 1999), explicit and implicit.

With c_ij = cot α_ij + cot β_ij (``operators.cotangent_weights``), the
cotangent Laplacian (L_c x)_i = ½ sum_{j~i} c_ij (x_j - x_i) and the lumped
mass M_i = η_i / 3 (a third of the area around v_i):

* explicit:  x_i <- x_i + dt · sum_j c_ij (x_j - x_i) / sum_j c_ij
  (the normalised curvature-flow step; dt in (0, 1] is dimensionless);
* implicit (backward Euler, weights frozen at the start of each step):
  (M + τ K) x' = M x,  K = -L_c,  τ = dt · Ā with Ā = (total area) / (number of connected vertices),
  so dt is dimensionless too.  K is the P1 stiffness matrix, symmetric
  positive semi-definite whatever the angles, and M + τK is positive definite:
  the system is solved matrix-free with conjugate gradients (``lineax.CG``) on
  the edge-list segment sums, and is differentiable (lineax's implicit adjoint).

Vertices without area (isolated, or only on zero-area faces, where every
cotangent weight is 0 too) get the mean mass, so they stay in place and the
system stays definite.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import lineax as lx
from jaxtyping import Array, Float

from .._private import lift, safe_divide, segment_sum_rows, segment_sum_scalars
from ..geometry import vertex_areas
from ..mesh import Mesh
from ..operators import cotangent_weights
from ._loop import iterate

__all__ = ["cotangent_flow", "implicit_diffusion_step", "weighted_difference"]


def weighted_difference(mesh: Mesh, x: Float[Array, "*batch V 3"], w: Float[Array, "*batch E"]):
    """sum_{j~i} w_ij (x_j - x_i) for symmetric per-edge weights w (``mesh.edges`` order).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        w: symmetric per-edge weights, (*batch, E) (``mesh.edges`` order).

    Returns:
        (*batch, V, 3)."""
    diff = x[..., mesh.dst, :] - x[..., mesh.src, :]
    return segment_sum_rows(w[..., mesh.edge_of, None] * diff, mesh.src, mesh.num_vertices)


def _cg_tolerance(dtype) -> float:
    return 1e-10 if jnp.dtype(dtype) == jnp.float64 else 1e-6


def implicit_diffusion_step(
    mesh: Mesh, x: Float[Array, "*batch V 3"], stiffness: Float[Array, "*batch E"], dt,
    max_steps: int = 1000,
) -> Float[Array, "*batch V 3"]:
    """Solve (M + τ K) x' = M x for x', with K the graph operator of the
    symmetric per-edge ``stiffness`` k_ij >= 0 on average ((K x)_i = -sum_j k_ij (x_j - x_i)),
    M the lumped mass of ``x``'s geometry and τ = dt · (total area / m).

    ``stiffness`` must make K positive semi-definite (cotangent weights, or any
    FEM stiffness of a positive semi-definite per-face tensor).  All batch
    elements are solved in one CG run (the operator is block diagonal).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        stiffness: symmetric per-edge k_ij ≥ 0 on average, (*batch, E) (``mesh.edges`` order).
        dt: the time step, in units of the mean vertex area.
        max_steps: the CG iteration limit.

    Returns:
        x', (*batch, V, 3)."""
    geo = mesh.with_vertices(x)
    mass = vertex_areas(geo) / 3
    connected = jnp.maximum(jnp.sum(mesh.degree > 0), 1).astype(x.dtype)  # padding/isolated do not count
    area_per_vertex = jnp.sum(mass, axis=-1) / connected
    # a vertex with no area (isolated, or only on zero-area faces) has no stiffness either:
    # give it the mean mass so the system stays definite and the vertex stays put
    mean_mass = jnp.where(area_per_vertex > 0, area_per_vertex, 1)[..., None]
    mass = jnp.where(mass > 0, mass, mean_mass)
    tau = lift((jnp.asarray(dt, x.dtype) * area_per_vertex)[..., None, None], x.ndim)
    m = mass[..., None]

    def apply(y):
        return m * y - tau * weighted_difference(mesh, y, stiffness)

    rhs = m * x
    op = lx.FunctionLinearOperator(apply, jax.eval_shape(lambda: rhs),
                                   tags=(lx.symmetric_tag, lx.positive_semidefinite_tag))
    tol = _cg_tolerance(x.dtype)
    sol = lx.linear_solve(op, rhs, lx.CG(rtol=tol, atol=tol * 1e-3, max_steps=max_steps),
                          options={"y0": jax.lax.stop_gradient(x)}, throw=False)
    return sol.value


def cotangent_flow(mesh: Mesh, dt=0.5, iterations: int = 5, implicit: bool = False) -> Mesh:
    """Mean-curvature flow with cotangent weights (module docstring): ``implicit=False``
    is the normalised explicit step, ``implicit=True`` backward Euler with CG.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        dt: the time step, in units of the mean vertex area.
        iterations: the number of outer iterations (a Python int: the loop is compiled once).
        implicit: backward Euler with CG instead of the explicit step.

    Returns:
        The smoothed mesh."""
    if implicit:
        def step(x):
            c = 0.5 * cotangent_weights(mesh.with_vertices(x))
            return implicit_diffusion_step(mesh, x, c, dt)
    else:
        dt_ = lift(jnp.asarray(dt, mesh.dtype)[..., None, None], mesh.vertices.ndim)

        def step(x):
            c = cotangent_weights(mesh.with_vertices(x))
            total = segment_sum_scalars(c[..., mesh.edge_of], mesh.src, mesh.num_vertices)
            total = jnp.maximum(total, 0)  # a vertex whose weights sum to <= 0 stays put
            return x + dt_ * safe_divide(weighted_difference(mesh, x, c), total[..., None])

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))
