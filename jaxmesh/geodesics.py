"""Geodesic distances by the heat method (Crane, Weischedel & Wardetzky 2013),
differentiable in the vertex positions.

For a source s, with the lumped mass M (M_ii = a third of the area around v_i), the
cotangent weights c_ij = ½(cot α_ij + cot β_ij) and t = ℓ̄² by default:

1. heat flow for time t: (M + t L⁺) u = δ_s, L⁺ the Laplacian of the weights
   max(c_ij, 0) (negative weights of obtuse triangles clamped: M + tL⁺ is then an
   M-matrix and u > 0 decays monotonically away from s);
2. the normalised gradient X = −∇u / |∇u| on every face;
3. the Poisson problem (L + G + εM) φ = −∇·X, L the cotangent Laplacian (positive
   semidefinite) and G = diag(g) with g = 1 at one vertex of each connected component
   and 0 elsewhere: the grounding pins the constant of each component, which the
   Laplacian leaves free (φ is shifted in step 4 anyway), and ε = 10⁻¹²/ℓ̄² keeps the
   rows of vertices without area (degenerate faces) definite.  L's
   diagonal is summed from its weights in float64 on the host (``sparse_solve(laplacian=
   True)``), so the system stays definite, and φ representable, in float32.  The weak
   divergence is (∇·X)_i = −Σ_f A_f X_f · ∇ψ_i;
4. φ shifted so that φ(s) = 0.

Boundaries (``boundary``): ``"neumann"`` solves step 1 with the natural condition
(the library's statistic before this module); ``"dirichlet"`` with u = 0 on the
boundary; ``"average"`` (default) uses u = ½(u_N + u_D), as Crane et al. recommend
(§3.2): the Neumann solution bends the level sets toward the boundary, the Dirichlet
one away from it, and their average keeps them nearly orthogonal to it.  A source on
the boundary has u_D = 0 and gets the Neumann field (X does not depend on u's scale).

Both systems go through :func:`jaxmesh.linalg.mesh_solve`: factored once per mesh
(and per boundary condition), every source is one more right-hand side, and the
distances are differentiable in ``mesh.vertices`` (and ``t``) through implicit
differentiation of both solves.
"""

from __future__ import annotations

import functools
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ._private import filled_mass, safe_norm, segment_sum_scalars
from .geometry import edge_lengths, face_areas, face_corners, hat_gradients, mean_edge_length
from .intrinsic import (IntrinsicTriangulation, cotangents_from_lengths, intrinsic_delaunay, layout_from_lengths,
                        replay_flips)
from .linalg import sparse_solve
from .mesh import Mesh
from .operators import cotangent_weights

__all__ = ["heat_distances", "heat_components", "BOUNDARY_CONDITIONS", "boundary_vertices"]

#: :func:`~jaxmesh.geometry.face_areas` as one compiled program for host callers (eagerly it is a
#: dozen small programs, each compiled on first use in every process)
_face_areas = jax.jit(face_areas)

BOUNDARY_CONDITIONS = ("average", "neumann", "dirichlet")


def boundary_vertices(mesh: Mesh) -> jax.Array:
    """The vertices on a boundary edge (an edge of exactly one face).

    Arguments:
        mesh: a single mesh.

    Returns:
        A bool array, (V,)."""
    per_edge = segment_sum_scalars(jnp.ones(mesh.face_edges.size, jnp.int32), mesh.face_edges.reshape(-1),
                                   mesh.num_edges)
    on = per_edge == 1
    hit = jnp.zeros(mesh.num_vertices, bool)
    return hit.at[mesh.edges[:, 0]].max(on).at[mesh.edges[:, 1]].max(on)


def heat_distances(
    mesh: Mesh, sources, t: float | Array | None = None, *,
    boundary: Literal["average", "neumann", "dirichlet"] = "average", intrinsic: bool = True,
    triangulation: IntrinsicTriangulation | None = None, block: int = 64,
    backend: Literal["auto", "cholesky", "lu"] = "auto", components: Int[Array, " V"] | None = None,
) -> Float[Array, "S V"]:
    """Heat-method geodesic distances (S, V) from ``sources`` (module docstring),
    differentiable in ``mesh.vertices`` and ``t``; jittable given a ``triangulation``.

    Distances to a vertex in another connected component are meaningless (the
    statistic :func:`jaxmesh.stats.heat_geodesics` sets them to inf).

    Arguments:
        mesh: a single mesh.
        sources: source vertex indices, (S,) integers.
        t: the diffusion time, in squared length units (default ℓ̄², the mean edge length squared).
        boundary: ``"average"`` (default), ``"neumann"`` or ``"dirichlet"`` (module docstring).
        intrinsic: run on the intrinsic Delaunay triangulation of the mesh (default;
            :mod:`jaxmesh.intrinsic`) instead of its own triangles.
        triangulation: the intrinsic triangulation to use (default: built from ``mesh``,
            which needs concrete vertices: pass it to call this under ``jit`` or ``grad``).
        block: sources solved together (memory O(F · block)).
        backend: the sparse solver, as :func:`jaxmesh.linalg.sparse_solve`.
        components: :func:`heat_components` of ``mesh`` (default: computed; a caller that calls
            again and again on one mesh passes them once computed).

    Returns:
        Distances, (S, V), in the mesh's length units."""
    if mesh.vertices.ndim != 2:
        raise ValueError("heat_distances needs a single mesh (jax.vmap over a batch)")
    if boundary not in BOUNDARY_CONDITIONS:
        raise ValueError(f"boundary must be one of {BOUNDARY_CONDITIONS}, got {boundary!r}")
    if isinstance(block, bool) or not isinstance(block, int) or block < 1:
        raise ValueError(f"block must be a positive int, got {block!r}")
    sources = jnp.atleast_1d(jnp.asarray(sources))
    if sources.ndim != 1 or not jnp.issubdtype(sources.dtype, jnp.integer):
        raise ValueError(f"sources must be a 1-D array of vertex indices, got shape {sources.shape}")
    if not isinstance(sources, jax.core.Tracer) and sources.size and (
            int(np.asarray(sources).min()) < 0 or int(np.asarray(sources).max()) >= mesh.num_vertices):
        raise ValueError(f"sources must lie in [0, {mesh.num_vertices}), got {np.asarray(sources)}")
    if intrinsic:
        if triangulation is None:
            if isinstance(mesh.vertices, jax.core.Tracer):
                raise ValueError("heat_distances(intrinsic=True) under jit or grad needs triangulation="
                                 "jaxmesh.intrinsic.intrinsic_delaunay(mesh), built outside (or intrinsic=False)")
            triangulation = intrinsic_delaunay(mesh)
        elif triangulation.num_vertices != mesh.num_vertices or triangulation.num_edges != mesh.num_edges:
            raise ValueError("triangulation was built from another mesh (its vertex or edge count differs)")
    t = None if t is None else jnp.asarray(t, mesh.dtype)
    arrays = None if not intrinsic else tuple(jnp.asarray(z) for z in (
        triangulation.faces, triangulation.face_edges, triangulation.flips, triangulation.pairs,
        triangulation.edge_pair))
    labels = heat_components(mesh) if components is None else jnp.asarray(components)
    count = sources.shape[0]
    if count == 0:
        return jnp.zeros((0, mesh.num_vertices), mesh.dtype)
    if count <= block:
        return _checked(lambda: _heat(mesh, sources, t, arrays, labels, boundary=boundary, backend=backend), mesh)
    # one compiled block at a time (the last padded with its final source): the program is one block's,
    # whatever the count, and no two blocks' (F, block, 3) intermediates are alive at once
    padded = jnp.concatenate([sources, jnp.broadcast_to(sources[-1:], (-count % block,))])
    out = [_checked(lambda lo=lo: _heat(mesh, padded[lo:lo + block], t, arrays, labels, boundary=boundary,
                                        backend=backend), mesh)
           for lo in range(0, padded.shape[0], block)]
    return jnp.concatenate(out, axis=0)[:count]


def heat_components(mesh: Mesh) -> Int[Array, " V"]:
    """Each vertex's connected component in the graph of the faces with area (a vertex of degenerate
    faces only is its own), numbered so that the first vertex of each component holds its own index:
    the heat flow reaches exactly the vertices of the source's component (the intrinsic triangulation
    covers the same surface).  All 0 where the mesh is traced: right for a connected mesh.

    Arguments:
        mesh: a single mesh.

    Returns:
        (V,) int32 labels: each vertex's component, named by its first vertex."""
    if isinstance(mesh.vertices, jax.core.Tracer) or isinstance(mesh.faces, jax.core.Tracer):
        return jnp.zeros(mesh.num_vertices, jnp.int32)
    from scipy.sparse.csgraph import connected_components

    from .graph import adjacency_from_faces

    f = np.asarray(mesh.faces)[np.asarray(_face_areas(mesh)) > 0]
    labels = connected_components(adjacency_from_faces(f, mesh.num_vertices), directed=False)[1]
    first = np.unique(labels, return_index=True)[1]
    return jnp.asarray(first[labels], jnp.int32)


def _checked(run, mesh: Mesh):
    """The distances of one block (``run()``), after refusing (on concrete values) a heat flow that
    underflowed, and naming a system the sparse solver could not factor inside the compiled program."""
    try:
        distances, lost = run()
    except jax.errors.JaxRuntimeError as err:
        if "positive definite" not in str(err) and "singular" not in str(err):
            raise
        raise ValueError("heat_distances: the heat method's linear systems cannot be factored on this mesh "
                         "(degenerate or extreme geometry: faces without area, or coordinates far apart in "
                         "scale)") from None
    if not isinstance(lost, jax.core.Tracer) and bool(np.asarray(lost).any()):
        fix = ("use float64: jax.config.update('jax_enable_x64', True) and jaxmesh.load(..., dtype='float64')"
               if mesh.dtype != jnp.float64 else "pass a larger t (the flow reaches about 700·√t; distances get "
               "smoother)")
        raise ValueError(f"heat_distances: the heat flow underflows in {mesh.dtype} on this mesh (it decays by "
                         "exp(−d/√t) and reaches 0 before the farthest vertex of the source's component), so the "
                         f"distances there would be wrong; {fix}")
    return distances


@functools.partial(jax.jit, static_argnames=("boundary", "backend"))
def _heat(mesh: Mesh, sources, t, triangulation, labels, *, boundary: str, backend: str):
    """The numerical part of :func:`heat_distances` for one block of sources (all solved
    together), compiled once per shape (the triangulation's arrays are arguments, so a new
    one of the same sizes reuses it): the distances, NaN for a source whose heat flow
    underflowed (u = 0 somewhere in its component), and which did."""
    n, dtype = mesh.num_vertices, mesh.dtype
    if triangulation is not None:
        faces, face_edges, flips, pairs, edge_pair = triangulation
        lengths = replay_flips(edge_lengths(mesh), flips)[face_edges]       # (F, 3)
        area, grad = hat_gradients(layout_from_lengths(lengths))
        cot_edges = segment_sum_scalars(0.5 * cotangents_from_lengths(lengths).reshape(-1),
                                        face_edges.reshape(-1), mesh.num_edges)
        c = segment_sum_scalars(jnp.where(edge_pair >= 0, cot_edges, 0), jnp.maximum(edge_pair, 0),
                                pairs.shape[0])
        clamp = False                  # interior weights are ≥ 0 on the Delaunay triangulation
    else:
        faces = mesh.faces
        area, grad = hat_gradients(face_corners(mesh))                   # (F,), (F, 3, 3)
        pairs, c = mesh.edges, 0.5 * cotangent_weights(mesh)             # (E, 2), (E,)
        clamp = True                   # see step 1 of the module docstring
    ell = mean_edge_length(mesh)
    t = ell ** 2 if t is None else t
    flat = faces.reshape(-1)
    mass = segment_sum_scalars(jnp.repeat(area / 3, 3), flat, n)
    positive = mass > 0
    mass = filled_mass(mass)                                          # vertices without area: the mean
    e0, e1 = pairs[:, 0], pairs[:, 1]

    def row_sums(w):
        return jnp.zeros(n, dtype).at[e0].add(w).at[e1].add(w)

    def solve(diag, off, rhs, laplacian=False):
        return sparse_solve(pairs, diag, off, rhs, backend=backend, laplacian=laplacian)

    heat_w = jnp.maximum(c, 0) if clamp else c
    heat_diag, heat_off = mass + t * row_sums(heat_w), -t * heat_w
    if boundary != "neumann":
        on = boundary_vertices(mesh)
        dir_diag = jnp.where(on, 1.0, heat_diag)
        dir_off = jnp.where(on[e0] | on[e1], 0.0, heat_off)

    src, k = sources, sources.shape[0]
    delta = jnp.zeros((n, k), dtype).at[src, jnp.arange(k)].set(1.0)
    if boundary == "neumann":
        u = solve(heat_diag, heat_off, delta)
    else:
        u = solve(dir_diag, dir_off, jnp.where(on[:, None], 0.0, delta))
        if boundary == "average":
            u_n = solve(heat_diag, heat_off, delta)
            # a boundary source has u_D = 0: its field is the Neumann one
            u = jnp.where(on[src][None, :], u_n, 0.5 * (u + u_n))
    # u ≤ 0 where the flow reaches in exact arithmetic: a vertex with area, in the source's component
    # (not on a Dirichlet boundary, where u_D = 0; not a vertex of degenerate faces only, with no weights)
    zero = (u <= 0) & positive[:, None] if boundary != "dirichlet" else (u <= 0) & (positive & ~on)[:, None]
    lost = jnp.any((labels[:, None] == labels[src][None, :]) & zero, axis=0)          # (k,)
    gu = jnp.einsum("fks,fkd->fsd", u[faces], grad)                   # ∇u per face, (F, k, 3)
    # scaled before normalising: far from the source u is ~1e-21 and |∇u|² underflows in float32
    # (X does not depend on the scale, so the scale carries no gradient)
    scale = jax.lax.stop_gradient(jnp.max(jnp.abs(gu), axis=-1, keepdims=True))
    gu = gu / jnp.where(scale > 0, scale, 1)
    x = -gu / jnp.maximum(safe_norm(gu), jnp.finfo(dtype).tiny)[..., None]
    contrib = area[:, None, None] * jnp.einsum("fkd,fsd->fks", grad, x)   # A_f X_f · ∇ψ_k
    b = jnp.zeros((n, k), dtype).at[flat].add(contrib.reshape(-1, k))
    ground = (labels == jnp.arange(n, dtype=labels.dtype)).astype(dtype)
    # (L + G + εM) φ = b, step 3; εM = 10⁻¹² M/ℓ̄² keeps it definite where L has zero rows (zero-area faces)
    phi = solve(ground + 1e-12 * mass / ell ** 2, -c, b, laplacian=True)
    return jnp.where(lost[:, None], jnp.nan, (phi - phi[src, jnp.arange(k)][None, :]).T), lost
