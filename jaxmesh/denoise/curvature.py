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

from typing import Literal

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import Scalar, filled_mass, lift, safe_divide, segment_sum_rows, segment_sum_scalars
from ..geometry import vertex_areas
from ..linalg import sparse_solve
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
    max_steps: int = 1000, solver: Literal["cg", "cholesky"] = "cg",
) -> Float[Array, "*batch V 3"]:
    """Solve (M + τ K) x' = M x for x', with K the graph operator of the
    symmetric per-edge ``stiffness`` k_ij >= 0 on average ((K x)_i = -sum_j k_ij (x_j - x_i)),
    M the lumped mass of ``x``'s geometry and τ = dt · (total area / m).

    ``stiffness`` must make K positive semi-definite (cotangent weights, or any
    FEM stiffness of a positive semi-definite per-face tensor).  ``solver="cg"``:
    all batch elements in one matrix-free CG run (the operator is block diagonal);
    ``"cholesky"``: :func:`jaxmesh.linalg.sparse_solve` per batch element (a sparse
    factorization on the host, exact to rounding; both differentiable).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        stiffness: symmetric per-edge k_ij ≥ 0 on average, (*batch, E) (``mesh.edges`` order).
        dt: the time step, in units of the mean vertex area.
        max_steps: the CG iteration limit.
        solver: ``"cg"`` (default) or ``"cholesky"``.

    Returns:
        x', (*batch, V, 3)."""
    geo = mesh.with_vertices(x)
    mass = vertex_areas(geo) / 3
    connected = jnp.maximum(jnp.sum(mesh.degree > 0), 1).astype(x.dtype)  # padding/isolated do not count
    area_per_vertex = jnp.sum(mass, axis=-1) / connected
    mass = filled_mass(mass)    # a vertex without area has no stiffness either: it stays put
    tau = lift((jnp.asarray(dt, x.dtype) * area_per_vertex)[..., None, None], x.ndim)
    m = mass[..., None]

    def apply(y):
        return m * y - tau * weighted_difference(mesh, y, stiffness)

    rhs = m * x
    if solver == "cholesky":
        return _direct_solve(mesh, mass, stiffness, tau[..., 0, 0], rhs)
    if solver != "cg":
        raise ValueError(f"solver must be 'cg' or 'cholesky', got {solver!r}")
    import lineax as lx  # here, not at the top: the commands that never solve with it do not import lineax

    op = lx.FunctionLinearOperator(apply, jax.eval_shape(lambda: rhs),
                                   tags=(lx.symmetric_tag, lx.positive_semidefinite_tag))
    tol = _cg_tolerance(x.dtype)
    sol = lx.linear_solve(op, rhs, lx.CG(rtol=tol, atol=tol * 1e-3, max_steps=max_steps),
                          options={"y0": jax.lax.stop_gradient(x)}, throw=False)
    return sol.value


def _direct_solve(mesh: Mesh, mass, stiffness, tau, rhs):
    """(M + τK) x' = rhs through the sparse factorization, one matrix per batch element:
    diagonal m_i + τ Σ_j k_ij, off-diagonal −τ k_ij."""
    lead = rhs.shape[:-2]
    edges = jnp.broadcast_to(mesh.edges, lead + mesh.edges.shape[-2:])

    def one(e, m, k, t, b):
        diag = m + t * (jnp.zeros_like(m).at[e[:, 0]].add(k).at[e[:, 1]].add(k))
        return sparse_solve(e, diag, -t * k, b, backend="cholesky")

    for _ in lead:
        one = jax.vmap(one)
    return one(edges, jnp.broadcast_to(mass, lead + mass.shape[-1:]),
               jnp.broadcast_to(stiffness, lead + stiffness.shape[-1:]), jnp.broadcast_to(tau, lead), rhs)


def cotangent_flow(mesh: Mesh, dt: Scalar = 0.5, iterations: int = 5, implicit: bool = False,
                   solver: Literal["cg", "cholesky"] = "cg") -> Mesh:
    """Mean-curvature flow with cotangent weights (module docstring): ``implicit=False``
    is the normalised explicit step, ``implicit=True`` backward Euler, each step solved
    by CG (``solver="cg"``) or a sparse Cholesky factorization (``"cholesky"``).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        dt: the time step, in units of the mean vertex area.
        iterations: the number of outer iterations (a Python int: the loop is compiled once).
        implicit: backward Euler instead of the explicit step.
        solver: the implicit step's linear solver, ``"cg"`` (default) or ``"cholesky"``.

    Returns:
        The smoothed mesh."""
    if implicit:
        def step(x):
            c = 0.5 * cotangent_weights(mesh.with_vertices(x))
            return implicit_diffusion_step(mesh, x, c, dt, solver=solver)
    else:
        dt_ = lift(jnp.asarray(dt, mesh.dtype)[..., None, None], mesh.vertices.ndim)

        def step(x):
            c = cotangent_weights(mesh.with_vertices(x))
            total = segment_sum_scalars(c[..., mesh.edge_of], mesh.src, mesh.num_vertices)
            total = jnp.maximum(total, 0)  # a vertex whose weights sum to <= 0 stays put
            return x + dt_ * safe_divide(weighted_difference(mesh, x, c), total[..., None])

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))
