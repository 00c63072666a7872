"""Per-edge, per-face and per-vertex geometry (thesis ch.1 §1.3.1–1.3.2).

Every function takes a :class:`~jaxmesh.Mesh` whose vertices may carry leading
batch dimensions, is pure and jittable, differentiable with respect to the
vertices, and returns arrays of the vertices' dtype.  Degenerate (zero-area)
faces give zero normals, zero angles' cotangents and zero weights — never NaN.
"""

from __future__ import annotations

from typing import Literal

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._private import lift, one_program, safe_norm, safe_normalize, segment_sum_rows, segment_sum_scalars
from .mesh import Mesh

__all__ = [
    "edge_vectors",
    "edge_lengths",
    "mean_edge_length",
    "segment_mean_edge_length",
    "face_corners",
    "face_areas",
    "face_normals",
    "corner_angles",
    "corner_cotangents",
    "cotangents_of_corners",
    "vertex_normals",
    "vertex_areas",
    "vertex_voronoi_areas",
    "voronoi_areas_of_corners",
    "bounding_box_diagonal",
]


@one_program
def edge_vectors(mesh: Mesh) -> Float[Array, "*batch E 3"]:
    """e_ij = v_j - v_i for every undirected edge (i, j), i < j.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, E, 3) array."""
    v = mesh.vertices
    return v[..., mesh.edges[:, 1], :] - v[..., mesh.edges[:, 0], :]


@one_program
def edge_lengths(mesh: Mesh) -> Float[Array, "*batch E"]:
    """||e_ij|| = ||v_i - v_j|| (thesis ch.1 eq.5 entries).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, E) array."""
    return safe_norm(edge_vectors(mesh))


@one_program
def mean_edge_length(mesh: Mesh) -> Float[Array, "*batch"]:
    """l_bar = (1/|E|) sum_{e_ij in E} ||e_ij||   (thesis ch.1 eq.4).

    Self-loop edges (i == j) never occur in a built mesh; they are the padding
    of :func:`jaxmesh.batch.pad_batch` and are not counted.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        One value per mesh, (*batch)."""
    real = (mesh.edges[:, 0] != mesh.edges[:, 1]).astype(mesh.dtype)
    return jnp.sum(edge_lengths(mesh) * lift(real, mesh.vertices.ndim - 1), axis=-1) / jnp.maximum(jnp.sum(real), 1)


@one_program(static_argnames=("segments",))
def segment_mean_edge_length(mesh: Mesh, segment, segments: int) -> Float[Array, " S"]:
    """:func:`mean_edge_length` of each mesh of a disjoint union (:func:`jaxmesh.batch.pack_batch`):
    l_bar_k = (1/|E_k|) sum_{e_ij in E_k} ||e_ij||, E_k the edges of segment k, self-loops
    (the padding) not counted; 0 for a segment without edges.

    Arguments:
        mesh: the union (single: vertices (V, 3)).
        segment: the mesh each vertex belongs to, (V,) ints in [0, segments).
        segments: the number of segments (static).

    Returns:
        One value per segment, (segments,)."""
    real = (mesh.edges[:, 0] != mesh.edges[:, 1]).astype(mesh.dtype)
    of = segment[mesh.edges[:, 0]]
    total = segment_sum_scalars(edge_lengths(mesh) * real, of, segments)
    return total / jnp.maximum(segment_sum_scalars(real, of, segments), 1)


@one_program
def face_corners(mesh: Mesh) -> Float[Array, "*batch F 3 3"]:
    """Positions of the three corners of each face: [..., f, k, :] = v_{faces[f, k]}.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, F, 3, 3) array."""
    return mesh.vertices[..., mesh.faces, :]


@one_program(static_argnames=("method",))
def face_areas(mesh: Mesh, method: Literal["cross", "heron"] = "cross") -> Float[Array, "*batch F"]:
    """Triangle areas.

    ``method="cross"`` (default): area = ||(v_1 - v_0) x (v_2 - v_0)|| / 2, accurate to
    rounding from the coordinates, also for needles.

    ``method="heron"``: the thesis's numerically stable Heron formula (ch.1 eq.1),
    with side lengths sorted a >= b >= c:
    area = 1/4 sqrt((a + (b + c)) (c - (a - b)) (c + (a - b)) (a + (b - c))).
    It is stable *given* the side lengths, but side lengths computed from
    coordinates have already lost a needle's height (a 1e-9-high triangle on a
    unit base has sides that round to 0.5, 0.5, 1 in float64, area 0), so it is
    not the default.  The radicand is clamped at 0 and the square root guarded,
    so zero-area faces give area 0 and a finite gradient in both methods.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        method: ``"cross"`` (half the cross-product norm, default) or ``"heron"`` (thesis ch.1 eq.1).

    Returns:
        (*batch, F) array."""
    if method == "cross":
        return 0.5 * safe_norm(_face_cross(mesh))
    if method != "heron":
        raise ValueError(f"method must be 'cross' or 'heron', got {method!r}")
    p = face_corners(mesh)
    sides = safe_norm(jnp.stack([p[..., 1, :] - p[..., 2, :],
                                 p[..., 2, :] - p[..., 0, :],
                                 p[..., 0, :] - p[..., 1, :]], axis=-2))
    s = -jnp.sort(-sides, axis=-1)
    a, b, c = s[..., 0], s[..., 1], s[..., 2]
    rad = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    pos = rad > 0
    return 0.25 * jnp.where(pos, jnp.sqrt(jnp.where(pos, rad, 1)), 0)


def _face_cross(mesh: Mesh) -> Float[Array, "*batch F 3"]:
    """(v_1 - v_0) x (v_2 - v_0): direction n(t), length 2 area(t)."""
    p = face_corners(mesh)
    return jnp.cross(p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 0, :])


@one_program
def face_normals(mesh: Mesh) -> Float[Array, "*batch F 3"]:
    """Unit normal n(t) = (v_1 - v_0) x (v_2 - v_0) / ||.||, counter-clockwise
    orientation; zero for a zero-area face.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, F, 3) array."""
    return safe_normalize(_face_cross(mesh))


@one_program
def corner_angles(mesh: Mesh) -> Float[Array, "*batch F 3"]:
    """Interior angle at each corner, atan2(||e1 x e2||, e1 . e2) with e1, e2 the
    two edges leaving the corner (stable for tiny and obtuse angles).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, F, 3) array."""
    p = face_corners(mesh)
    e1 = jnp.roll(p, -1, axis=-2) - p
    e2 = jnp.roll(p, -2, axis=-2) - p
    return jnp.arctan2(safe_norm(jnp.cross(e1, e2)), jnp.sum(e1 * e2, axis=-1))


@one_program
def corner_cotangents(mesh: Mesh) -> Float[Array, "*batch F 3"]:
    """cot of the interior angle at each corner: (e1 . e2) / ||e1 x e2||.

    A corner of a degenerate face, ||e1 x e2|| <= eps (||e1||^2 + ||e2||^2) with eps
    the dtype's machine epsilon, gets cotangent 0 (scale-free guard).  The formula
    is :func:`cotangents_of_corners`, which host (numpy) code calls too.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, F, 3) array."""
    return cotangents_of_corners(face_corners(mesh))


def cotangents_of_corners(p, xp=jnp):
    """cot at each corner of triangles given by their corner positions p
    (..., 3, 3), with the degenerate-corner guard of :func:`corner_cotangents`.
    ``xp`` is ``jax.numpy`` (default; gradient-safe norm) or ``numpy`` (host
    code: the same rule, in float64, without JAX).

    Arguments:
        p: corner positions of triangles, (..., 3, 3).
        xp: ``jax.numpy`` (default) or ``numpy`` (host code, float64, no JAX).

    Returns:
        The cotangent at each corner, (..., 3)."""
    e1 = xp.roll(p, -1, axis=-2) - p
    e2 = xp.roll(p, -2, axis=-2) - p
    c = xp.cross(e1, e2)
    cross = safe_norm(c) if xp is jnp else xp.sqrt(xp.sum(c * c, axis=-1))
    scale = xp.sum(e1 * e1, axis=-1) + xp.sum(e2 * e2, axis=-1)
    eps = xp.finfo(p.dtype).eps
    ok = cross > eps * scale
    return xp.where(ok, xp.sum(e1 * e2, axis=-1) / xp.where(ok, cross, 1), 0)


def voronoi_areas_of_corners(p, xp=jnp):
    """Mixed Voronoi area of each corner of triangles given by their corners p
    (..., 3, 3) (Meyer, Desbrun, Schröder & Barr 2003, the mass of libigl's
    ``massmatrix(..., VORONOI)``): for a triangle with no obtuse angle, corner i gets
    (|e_j|² cot θ_j + |e_k|² cot θ_k) / 8 over the two edges e_j, e_k that meet at
    it (e_j opposite corner j); in an obtuse triangle the obtuse corner gets A/2 and
    the others A/4.  The three sum to the area A.  Cotangents (with their
    degenerate-corner guard) from :func:`cotangents_of_corners`; ``xp`` as there.

    Arguments:
        p: corner positions of triangles, (..., 3, 3).
        xp: ``jax.numpy`` (default) or ``numpy`` (host code, float64, no JAX).

    Returns:
        The mixed Voronoi area of each corner, (..., 3)."""
    cot = cotangents_of_corners(p, xp)
    e = xp.roll(p, -2, axis=-2) - xp.roll(p, -1, axis=-2)            # edge opposite each corner
    l2 = xp.sum(e * e, axis=-1)
    term = l2 * cot                                                  # per opposite edge
    voronoi = (xp.roll(term, -1, axis=-1) + xp.roll(term, -2, axis=-1)) / 8
    c = xp.cross(p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 0, :])
    area = 0.5 * (safe_norm(c) if xp is jnp else xp.sqrt(xp.sum(c * c, axis=-1)))
    obtuse = cot < 0
    split = xp.where(obtuse, 0.5, 0.25) * area[..., None]
    return xp.where(xp.any(obtuse, axis=-1, keepdims=True), split, voronoi)


def hat_gradients(p, xp=jnp):
    """P1 finite elements on triangles given by their corners p (..., 3, 3): the area
    A_f and the gradients of the three hat functions,
    ∇ψ_k = (n × e_k) / (2 A_f), e_k the edge opposite corner k, n the unit normal.
    A zero-area face gets area 0 and gradients 0.  ``xp`` is ``jax.numpy``
    (default; gradient-safe norm) or ``numpy`` (host code: the same rule, in
    float64).  Returns (A (...,), ∇ψ (..., 3, 3))."""
    e = xp.roll(p, -2, axis=-2) - xp.roll(p, -1, axis=-2)
    c = xp.cross(p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 0, :])
    twice = safe_norm(c) if xp is jnp else xp.sqrt(xp.sum(c * c, axis=-1))
    ok = twice > 0
    safe = xp.where(ok, twice, 1)
    n = xp.where(ok[..., None], c / safe[..., None], 0)
    grad = xp.where(ok[..., None, None], xp.cross(n[..., None, :], e) / safe[..., None, None], 0)
    return 0.5 * twice, grad


@one_program(static_argnames=("weighting",))
def vertex_normals(
    mesh: Mesh, weighting: Literal["uniform", "angle", "area"] = "area"
) -> Float[Array, "*batch V 3"]:
    """Vertex normal n_i = normalize(sum_{t_j ~ v_i} w_ij n(t_j))  (thesis ch.1 eq.2–3).

    ``weighting``: ``"uniform"`` (w = 1, eq.2 — the 1/d_i factor vanishes in the
    normalisation), ``"angle"`` (w = interior angle of t_j at v_i) or ``"area"``
    (w = area(t_j)).  Isolated vertices get the zero vector.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        weighting: face weights: ``"area"`` (default), ``"angle"`` or ``"uniform"``.

    Returns:
        (*batch, V, 3) array."""
    n = face_normals(mesh)
    if weighting == "uniform":
        w = jnp.ones(n.shape[:-1], n.dtype)
        per_corner = jnp.stack([w, w, w], axis=-1)
    elif weighting == "area":
        a = face_areas(mesh)
        per_corner = jnp.stack([a, a, a], axis=-1)
    elif weighting == "angle":
        per_corner = corner_angles(mesh)
    else:
        raise ValueError(f"weighting must be 'uniform', 'angle' or 'area', got {weighting!r}")
    contrib = per_corner[..., :, :, None] * n[..., :, None, :]  # (*b, F, 3, 3)
    flat = contrib.reshape(*contrib.shape[:-3], -1, 3)
    summed = segment_sum_rows(flat, mesh.faces.reshape(-1), mesh.num_vertices)
    return safe_normalize(summed)


@one_program
def vertex_areas(mesh: Mesh) -> Float[Array, "*batch V"]:
    """eta_i = sum of the areas of the triangles incident to v_i (thesis ch.4 eq.1).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, V) array."""
    a = face_areas(mesh)
    per_corner = jnp.stack([a, a, a], axis=-1)
    flat = per_corner.reshape(*per_corner.shape[:-2], -1)
    return segment_sum_scalars(flat, mesh.faces.reshape(-1), mesh.num_vertices)


@one_program
def vertex_voronoi_areas(mesh: Mesh) -> Float[Array, "*batch V"]:
    """Mixed Voronoi area of each vertex, the sum of :func:`voronoi_areas_of_corners`
    over its corners (the diagonal of libigl's Voronoi mass matrix).  Sums to the
    surface area, like ``vertex_areas(mesh) / 3`` (the barycentric mass).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        (*batch, V) array."""
    per_corner = voronoi_areas_of_corners(face_corners(mesh))
    flat = per_corner.reshape(*per_corner.shape[:-2], -1)
    return segment_sum_scalars(flat, mesh.faces.reshape(-1), mesh.num_vertices)


@one_program
def bounding_box_diagonal(mesh: Mesh) -> Float[Array, "*batch"]:
    """Length of the diagonal of the axis-aligned bounding box.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).

    Returns:
        One value per mesh, (*batch)."""
    v = mesh.vertices
    return safe_norm(jnp.max(v, axis=-2) - jnp.min(v, axis=-2))

