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

Both systems go through :func:`jaxmesh.linalg.sparse_solve`: factored once per mesh
(and per boundary condition), every source is one more right-hand side, and the
distances are differentiable in ``mesh.vertices`` (and ``t``) through implicit
differentiation of both solves.  On concrete inputs the matrices are built once for
every block of sources, each factored once for all of them, and the solves are called from
the host (:func:`jaxmesh.linalg.host_factor`) between compiled stages, the same functions: a
program with a host callback inside is compiled again in every process, these are
kept in the persistent compilation cache.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ._exported import stored_jit
from ._private import filled_mass, one_program, safe_norm, segment_sum_scalars
from .geometry import edge_lengths, face_areas, face_corners, hat_gradients, mean_edge_length
from .intrinsic import (IntrinsicTriangulation, cotangents_from_lengths, intrinsic_delaunay, layout_from_lengths,
                        replay_flips)
from .linalg import host_factor, sparse_solve
from .mesh import Mesh, as_device_array, to_device
from .operators import cotangent_weights

__all__ = ["heat_distances", "heat_solver", "heat_components", "BOUNDARY_CONDITIONS", "boundary_vertices"]

#: :func:`~jaxmesh.geometry.face_areas` as one compiled program for host callers (eagerly it is a
#: dozen small programs, each compiled on first use in every process)
_face_areas = jax.jit(face_areas)

BOUNDARY_CONDITIONS = ("average", "neumann", "dirichlet")


@one_program
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
    Many calls on one mesh: :func:`heat_solver` builds the set-up once.

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
    _check_block(block)
    _check_boundary(boundary)
    return heat_solver(mesh, t, boundary=boundary, intrinsic=intrinsic, triangulation=triangulation,
                       backend=backend, components=components)(sources, block=block)


def heat_solver(
    mesh: Mesh, t: float | Array | None = None, *,
    boundary: Literal["average", "neumann", "dirichlet"] = "average", intrinsic: bool = True,
    triangulation: IntrinsicTriangulation | None = None,
    backend: Literal["auto", "cholesky", "lu"] = "auto", components: Int[Array, " V"] | None = None,
) -> Callable[..., Float[Array, "S V"]]:
    """:func:`heat_distances` on one mesh for source after source: the intrinsic triangulation,
    the components and (on concrete inputs) both steps' matrices are built here once, and each
    call of the returned ``distances(sources, block=64)`` costs its solves (the factors are
    cached by :mod:`jaxmesh.linalg`).  The arguments are :func:`heat_distances`'s.

    Arguments:
        mesh: a single mesh.
        t: the diffusion time (default ℓ̄²).
        boundary: ``"average"`` (default), ``"neumann"`` or ``"dirichlet"``.
        intrinsic: run on the intrinsic Delaunay triangulation (default).
        triangulation: the intrinsic triangulation to use (default: built from ``mesh``).
        backend: the sparse solver, as :func:`jaxmesh.linalg.sparse_solve`.
        components: :func:`heat_components` of ``mesh`` (default: computed).

    Returns:
        ``distances(sources, block=64)``: distances (S, V) from the (S,) source indices."""
    if mesh.vertices.ndim != 2:
        raise ValueError("heat_distances needs a single mesh (jax.vmap over a batch)")
    _check_boundary(boundary)
    if intrinsic:
        if triangulation is None:
            if isinstance(mesh.vertices, jax.core.Tracer):
                raise ValueError("heat_distances(intrinsic=True) under jit or grad needs triangulation="
                                 "jaxmesh.intrinsic.intrinsic_delaunay(mesh), built outside (or intrinsic=False)")
            triangulation = intrinsic_delaunay(mesh)
        elif triangulation.num_vertices != mesh.num_vertices or triangulation.num_edges != mesh.num_edges:
            raise ValueError("triangulation was built from another mesh (its vertex or edge count differs)")
    t = None if t is None else jnp.asarray(t, mesh.dtype)
    arrays = None if not intrinsic else tuple(as_device_array(z) for z in (
        triangulation.faces, triangulation.face_edges, triangulation.flips, triangulation.pairs,
        triangulation.edge_pair))
    labels = heat_components(mesh) if components is None else as_device_array(components)
    traced = any(isinstance(z, jax.core.Tracer) for z in (mesh.vertices, t))
    # concrete: the matrices once, the solves called from the host
    systems = None if traced else _Systems(*_systems_program(mesh, t, arrays, boundary=boundary))
    poisson = None if traced else _poisson_program(systems, labels)
    solve = None if traced else _host_solver(systems, backend)

    def run(part):
        if systems is None or isinstance(part, jax.core.Tracer):
            return _heat(mesh, part, t, arrays, labels, boundary=boundary, backend=backend)
        return _steps(systems, poisson, part, labels, boundary=boundary, solve=solve, stages=_STAGE_PROGRAMS)

    def distances(sources, block: int = 64) -> Float[Array, "S V"]:
        _check_block(block)
        xp = jnp if isinstance(sources, jax.core.Tracer) else np      # concrete: no eager programs
        sources = xp.atleast_1d(xp.asarray(sources))
        if sources.ndim != 1 or not xp.issubdtype(sources.dtype, xp.integer):
            raise ValueError(f"sources must be a 1-D array of vertex indices, got shape {sources.shape}")
        if xp is np and sources.size and (sources.min() < 0 or sources.max() >= mesh.num_vertices):
            raise ValueError(f"sources must lie in [0, {mesh.num_vertices}), got {sources}")
        count = sources.shape[0]
        if count == 0:
            return jnp.zeros((0, mesh.num_vertices), mesh.dtype)
        if count <= block:
            return _checked(lambda: run(sources), mesh)
        # one block at a time (the last padded with its final source): the programs are one block's,
        # whatever the count, and no two blocks' (F, block, 3) intermediates are alive at once
        padded = xp.concatenate([sources, xp.broadcast_to(sources[-1:], (-count % block,))])
        out = [_checked(lambda lo=lo: run(padded[lo:lo + block]), mesh) for lo in range(0, padded.shape[0], block)]
        return jnp.concatenate(out, axis=0)[:count]

    return distances


def _check_boundary(boundary) -> None:
    if boundary not in BOUNDARY_CONDITIONS:
        raise ValueError(f"boundary must be one of {BOUNDARY_CONDITIONS}, got {boundary!r}")


def _check_block(block) -> None:
    if isinstance(block, bool) or not isinstance(block, int) or block < 1:
        raise ValueError(f"block must be a positive int, got {block!r}")


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
    return to_device(first[labels].astype(np.int32))


def _checked(run, mesh: Mesh):
    """The distances of one block (``run()``), after refusing (on concrete values) a heat flow that
    underflowed, and naming a system the sparse solver could not factor inside the compiled program."""
    try:
        distances, lost = run()
    except (jax.errors.JaxRuntimeError, ValueError) as err:
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


class _Systems(NamedTuple):
    """What every block of sources shares (:func:`_systems`): the triangles, their areas and
    hat gradients, the Laplacian's pairs and weights, where the lumped mass is positive, the
    boundary vertices, step 1's matrices as diagonals and off-diagonal values on those pairs
    (Neumann, and Dirichlet: the same under ``boundary="neumann"``) and step 3's εM."""
    faces: Array
    area: Array
    grad: Array
    pairs: Array
    weights: Array
    positive: Array
    on: Array
    heat_diag: Array
    heat_off: Array
    dir_diag: Array
    dir_off: Array
    poisson_diag: Array


def _systems(mesh: Mesh, t, triangulation, *, boundary: str) -> _Systems:
    """Steps 1 and 3's matrices (module docstring), on the intrinsic triangulation's arrays
    (``triangulation``) or the mesh's own triangles (None)."""
    n, dtype = mesh.num_vertices, mesh.dtype
    if triangulation is not None:
        faces, face_edges, flips, pairs, edge_pair = triangulation
        lengths = replay_flips(edge_lengths(mesh), flips)[face_edges]       # (F, 3)
        area, grad = hat_gradients(layout_from_lengths(lengths))
        cot_edges = segment_sum_scalars(0.5 * cotangents_from_lengths(lengths).reshape(-1),
                                        face_edges.reshape(-1), mesh.num_edges)
        c = segment_sum_scalars(jnp.where(edge_pair >= 0, cot_edges, 0), jnp.maximum(edge_pair, 0),
                                pairs.shape[0])
    else:
        faces = mesh.faces
        area, grad = hat_gradients(face_corners(mesh))                   # (F,), (F, 3, 3)
        pairs, c = mesh.edges, 0.5 * cotangent_weights(mesh)             # (E, 2), (E,)
    ell = mean_edge_length(mesh)
    t = ell ** 2 if t is None else t
    mass = segment_sum_scalars(jnp.repeat(area / 3, 3), faces.reshape(-1), n)
    positive = mass > 0
    mass = filled_mass(mass)                                          # vertices without area: the mean
    e0, e1 = pairs[:, 0], pairs[:, 1]
    # step 1's clamp: on the intrinsic Delaunay triangulation only the edges it cannot flip can be
    # negative (boundary and non-manifold edges, and edges whose two faces run them the same way);
    # a negative weight there can make u negative, which reads as an underflow
    heat_w = jnp.maximum(c, 0)
    heat_diag = mass + t * jnp.zeros(n, dtype).at[e0].add(heat_w).at[e1].add(heat_w)
    heat_off = -t * heat_w
    if boundary == "neumann":
        on, dir_diag, dir_off = jnp.zeros(n, bool), heat_diag, heat_off
    else:
        on = boundary_vertices(mesh)
        dir_diag = jnp.where(on, 1.0, heat_diag)
        dir_off = jnp.where(on[e0] | on[e1], 0.0, heat_off)
    # (L + G + εM) φ = b, step 3; εM = 10⁻¹² M/ℓ̄² keeps it definite where L has zero rows (zero-area faces)
    return _Systems(faces, area, grad, pairs, c, positive, on, heat_diag, heat_off, dir_diag, dir_off,
                    1e-12 * mass / ell ** 2)


def _deltas(n: int, sources, dtype, on):
    """Step 1's right-hand sides: δ_s per column (n, k), and the same with 0 on the boundary."""
    k = sources.shape[0]
    delta = jnp.zeros((n, k), dtype).at[sources, jnp.arange(k)].set(1.0)
    return delta, jnp.where(on[:, None], 0.0, delta)


def _divergence(s: _Systems, u, u_n, sources, labels, *, boundary: str):
    """Steps 2 and 3's right-hand side from step 1's fields: ``u`` (Dirichlet, or Neumann under
    ``boundary="neumann"``) and ``u_n`` (Neumann, for ``"average"``); the grounded right-hand
    side b (n, k) and which sources' flow underflowed (k,)."""
    n, dtype, k = s.heat_diag.shape[0], s.heat_diag.dtype, sources.shape[0]
    if boundary == "average":
        # a boundary source has u_D = 0: its field is the Neumann one
        u = jnp.where(s.on[sources][None, :], u_n, 0.5 * (u + u_n))
    # u ≤ 0 where the flow reaches in exact arithmetic: a vertex with area, in the source's component
    # (not on a Dirichlet boundary, where u_D = 0; not a vertex of degenerate faces only, with no weights)
    reach = s.positive if boundary != "dirichlet" else s.positive & ~s.on
    lost = jnp.any((labels[:, None] == labels[sources][None, :]) & (u <= 0) & reach[:, None], axis=0)   # (k,)
    gu = jnp.einsum("fks,fkd->fsd", u[s.faces], s.grad)                   # ∇u per face, (F, k, 3)
    # scaled before normalising: far from the source u is ~1e-21 and |∇u|² underflows in float32
    # (X does not depend on the scale, so the scale carries no gradient)
    scale = jax.lax.stop_gradient(jnp.max(jnp.abs(gu), axis=-1, keepdims=True))
    gu = gu / jnp.where(scale > 0, scale, 1)
    x = -gu / jnp.maximum(safe_norm(gu), jnp.finfo(dtype).tiny)[..., None]
    contrib = s.area[:, None, None] * jnp.einsum("fkd,fsd->fks", s.grad, x)   # A_f X_f · ∇ψ_k
    b = jnp.zeros((n, k), dtype).at[s.faces.reshape(-1)].add(contrib.reshape(-1, k))
    return b, lost


def _shifted(phi, sources, lost):
    """Step 4: φ − φ(s) per source, (k, n); NaN rows for the sources whose flow underflowed."""
    k = sources.shape[0]
    return jnp.where(lost[:, None], jnp.nan, (phi - phi[sources, jnp.arange(k)][None, :]).T)


def _poisson(s: _Systems, labels):
    """Step 3's matrix L + G + εM as (diagonal, edge values) in the Laplacian form: G is 1 at the
    first vertex of each component (``labels`` name it)."""
    ground = (labels == jnp.arange(labels.shape[0], dtype=labels.dtype)).astype(s.poisson_diag.dtype)
    return ground + s.poisson_diag, -s.weights


def _steps(s: _Systems, poisson: tuple, sources, labels, *, boundary: str, solve, stages: tuple):
    """Steps 1–4 for one block of sources, given the shared systems ``s``, step 3's matrix
    ``poisson`` (:func:`_poisson`), the sparse ``solve`` and the ``stages`` (:func:`_deltas`,
    :func:`_divergence`, :func:`_shifted`, or their stored programs): the distances, NaN for
    a source whose heat flow underflowed (u = 0 somewhere in its component), and which did."""
    deltas, divergence, shifted = stages
    delta, delta_d = deltas(s.heat_diag.shape[0], sources, s.heat_diag.dtype, s.on)
    u_n = solve(s.heat_diag, s.heat_off, delta) if boundary != "dirichlet" else None
    u = u_n if boundary == "neumann" else solve(s.dir_diag, s.dir_off, delta_d)
    b, lost = divergence(s, u, u_n, sources, labels, boundary=boundary)
    return shifted(solve(*poisson, b, laplacian=True), sources, lost), lost


@functools.partial(jax.jit, static_argnames=("boundary", "backend"))
def _heat(mesh: Mesh, sources, t, triangulation, labels, *, boundary: str, backend: str):
    """:func:`_steps` for one block of sources as one program, differentiable (the solves
    are :func:`sparse_solve`'s host callbacks).  It runs where the positions (or t) are
    traced; concrete inputs run the same steps with the host solves of :func:`_host_solver`."""
    s = _systems(mesh, t, triangulation, boundary=boundary)

    def solve(diag, off, rhs, laplacian=False):
        return sparse_solve(s.pairs, diag, off, rhs, backend=backend, laplacian=laplacian)

    return _steps(s, _poisson(s, labels), sources, labels, boundary=boundary, solve=solve,
                  stages=(_deltas, _divergence, _shifted))


def _systems_arrays(mesh: Mesh, t, triangulation, *, boundary: str) -> tuple:
    """:func:`_systems` as a plain tuple (a stored program's outputs are plain containers)."""
    return tuple(_systems(mesh, t, triangulation, boundary=boundary))


#: the stages of :func:`_heat` as programs of their own for concrete inputs: without a host
#: callback inside, each is kept between processes (:mod:`jaxmesh._exported` and the persistent
#: compilation cache), where a program with one is traced and compiled again in every process
_systems_program = stored_jit(_systems_arrays, static_argnames=("boundary",))
_poisson_program = stored_jit(_poisson)
_STAGE_PROGRAMS = (stored_jit(_deltas, static_argnames=("n", "dtype")),
                   stored_jit(_divergence, static_argnames=("boundary",)), stored_jit(_shifted))


def _host_solver(s: _Systems, backend: str):
    """``solve(diag, off, rhs, laplacian)`` from the host for the systems of ``s``: each matrix
    factored (:func:`~jaxmesh.linalg.host_factor`) at its first solve and kept for the next
    blocks, found by the identity of its arrays (those of ``s`` and of the Poisson system, which
    :func:`heat_solver`'s closure holds as long as this solver)."""
    factors: dict = {}

    def solve(diag, off, rhs, laplacian=False):
        key = (id(diag), id(off), laplacian)
        factor = factors.get(key)
        if factor is None:
            factor = factors[key] = host_factor(s.pairs, diag, off, backend=backend, laplacian=laplacian)
        return jnp.asarray(factor(rhs), s.heat_diag.dtype)

    return solve

