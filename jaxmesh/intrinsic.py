"""Intrinsic Delaunay triangulations (Bobenko & Springborn 2007; Sharp, Soliman & Crane
2019), with edge lengths differentiable in the vertex positions.

A triangle mesh defines a flat metric on its surface through its edge lengths alone.
Flipping an edge inside that metric — replacing the diagonal (a, b) of the two
triangles (a, b, c), (b, a, d) by the geodesic (c, d) across them — keeps the surface
and its metric and changes only the triangulation.  Flipping every edge whose two
opposite angles sum to more than π until none does gives the intrinsic Delaunay
triangulation, on which every interior cotangent weight ½(cot α + cot β) is ≥ 0: the
cotangent Laplacian is then an M-matrix and the finite-element operators behave as on
a well-shaped mesh, whatever the input's thin triangles.

:func:`intrinsic_delaunay` runs the flips on the host (a queue of edges, each flip
O(1)) and records them; :func:`intrinsic_lengths` replays the record in JAX
(``lax.scan``), so the lengths of the flipped triangulation are differentiable
functions of ``mesh.vertices`` (exact wherever no opposite-angle sum equals π, where
the triangulation changes).  The new length of a flipped edge is the distance between
the apices c and d once the two triangles are laid out flat on either side of (a, b)
(:func:`flipped_length`, shared by host and JAX).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import no_type_check

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from .geometry import edge_lengths
from .mesh import Mesh
from .topology import orientation_flips

__all__ = ["IntrinsicTriangulation", "intrinsic_delaunay", "intrinsic_lengths", "replay_flips",
           "flipped_length",
           "triangle_areas_from_lengths", "cotangents_from_lengths", "layout_from_lengths"]


@dataclass(frozen=True, eq=False)
class IntrinsicTriangulation:
    """The flips that make a mesh's triangulation intrinsically Delaunay.

    ``faces`` (F, 3): the triangles after the flips (vertex indices; a face may use a
    vertex twice only if the input did); ``face_edges`` (F, 3): the edge opposite each
    corner (ids into the input's ``mesh.edges`` numbering, each flip reusing the id of
    the edge it replaces); ``flips`` (K, 5): per flip in order, the flipped edge and the
    edges (b, c), (c, a), (a, d), (d, b) of its quad; ``pairs`` (P, 2): the distinct
    vertex pairs (i < j) joined by an edge, and ``edge_pair`` (E,): each edge's pair
    (−1 for an edge from a vertex to itself, which the Laplacian ignores);
    ``num_vertices``, ``num_edges``."""

    faces: np.ndarray
    face_edges: np.ndarray
    flips: np.ndarray
    pairs: np.ndarray
    edge_pair: np.ndarray
    num_vertices: int
    num_edges: int

    @property
    def num_flips(self) -> int:
        return int(self.flips.shape[0])


# The flip loop calls these per edge on host scalars: exempt from the run-time type
# checks the tests install (they cost more than the arithmetic; 8 s of a 10 s test).
@no_type_check
def _safe_sqrt(x, xp):
    """sqrt(max(x, 0)) whose gradient at x ≤ 0 is 0 instead of inf or NaN."""
    ok = x > 0
    return xp.where(ok, xp.sqrt(xp.where(ok, x, 1)), 0)


def layout_from_lengths(l, xp=jnp):
    """The corners of triangles with edge lengths ``l`` (..., 3) (``l[..., k]`` opposite
    corner k) laid out in the plane z = 0: p0 at the origin, p1 on the x axis, p2 above.

    Arguments:
        l: edge lengths, (..., 3), ``l[..., k]`` opposite corner k.
        xp: ``jax.numpy`` (default) or ``numpy``.

    Returns:
        Corner positions, (..., 3, 3)."""
    l0, l1, l2 = l[..., 0], l[..., 1], l[..., 2]
    safe2 = xp.where(l2 > 0, l2, 1)
    x = (l2 * l2 + l1 * l1 - l0 * l0) / (2 * safe2)
    y = _safe_sqrt(l1 * l1 - x * x, xp)
    zero = xp.zeros_like(l0)
    return xp.stack([xp.stack([zero, zero, zero], -1), xp.stack([l2, zero, zero], -1),
                     xp.stack([x, y, zero], -1)], -2)


def triangle_areas_from_lengths(l, xp=jnp):
    """Heron's area of triangles with edge lengths ``l`` (..., 3), in Kahan's stable form;
    0 for lengths that violate the triangle inequality.

    Arguments:
        l: edge lengths, (..., 3).
        xp: ``jax.numpy`` (default) or ``numpy``.

    Returns:
        The areas, (...)."""
    s = xp.sort(l, axis=-1)
    c, b, a = s[..., 0], s[..., 1], s[..., 2]               # a ≥ b ≥ c
    q = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return 0.25 * _safe_sqrt(q, xp)


def cotangents_from_lengths(l, xp=jnp):
    """cot of each corner of triangles with edge lengths ``l`` (..., 3) (``l[..., k]``
    opposite corner k): (l_i² + l_j² − l_k²) / 4A; 0 for a zero-area triangle.

    Arguments:
        l: edge lengths, (..., 3).
        xp: ``jax.numpy`` (default) or ``numpy``.

    Returns:
        The cotangents, (..., 3)."""
    area = triangle_areas_from_lengths(l, xp)
    sq = l * l
    num = xp.roll(sq, -1, axis=-1) + xp.roll(sq, -2, axis=-1) - sq
    ok = area > 0
    return xp.where(ok[..., None], num / (4 * xp.where(ok, area, 1))[..., None], 0)


@no_type_check
def flipped_length(l_ab, l_bc, l_ca, l_ad, l_db, xp=jnp):
    """|c − d| for triangles (a, b, c) and (b, a, d) laid out flat on either side of their
    shared edge (a, b): the length of the edge that replaces (a, b) in a flip.

    Arguments:
        l_ab: the shared edge's length.
        l_bc: |b − c|.
        l_ca: |c − a|.
        l_ad: |a − d|.
        l_db: |d − b|.
        xp: ``jax.numpy`` (default) or ``numpy``.

    Returns:
        The new edge's length, the shape of the inputs."""
    safe = xp.where(l_ab > 0, l_ab, 1)
    xc = (l_ab * l_ab + l_ca * l_ca - l_bc * l_bc) / (2 * safe)       # along a → b, from a
    xd = (l_ab * l_ab + l_ad * l_ad - l_db * l_db) / (2 * safe)
    yc = _safe_sqrt(l_ca * l_ca - xc * xc, xp)
    yd = _safe_sqrt(l_ad * l_ad - xd * xd, xp)
    return _safe_sqrt((xc - xd) ** 2 + (yc + yd) ** 2, xp)


@no_type_check
def _cot_opposite(l_ab: float, l_x1: float, l_x2: float) -> float:
    """cot of the angle opposite edge ab in a triangle with the other sides l_x1, l_x2
    (scalar host twin of :func:`cotangents_from_lengths`, for the flip loop)."""
    c, b, a = sorted((l_ab, l_x1, l_x2))
    q = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return (l_x1 * l_x1 + l_x2 * l_x2 - l_ab * l_ab) / q ** 0.5 if q > 0 else 0.0


class _Scalars:
    """The ``xp`` of :func:`flipped_length` for the flip loop's host floats: one edge at a
    time, ``math`` costs a fraction of numpy's dispatch on a scalar."""
    sqrt = staticmethod(math.sqrt)

    @staticmethod
    @no_type_check
    def where(condition, a, b):
        return a if condition else b


class _HalfEdges:
    """Mutable half-edge lists of a triangle list (Python lists: the flip loop reads and writes
    them one entry at a time): half-edge h = 3f + j runs ``origin[h]`` → ``origin[next(h)]``
    in face f, lies on edge ``edge[h]`` and has the opposite half-edge ``twin[h]`` (−1 on
    boundary and non-manifold edges, and on an edge whose two faces run it the same way);
    ``of_edge[e]`` is one half-edge of edge e."""

    def __init__(self, faces: np.ndarray, face_edges: np.ndarray, num_vertices: int, num_edges: int):
        nf = faces.shape[0]
        edge = face_edges[:, [2, 0, 1]].ravel()      # the edge of h = 3f + j is opposite corner j + 2
        origin = faces.ravel()
        target = faces[:, [1, 2, 0]].ravel()
        key = origin * num_vertices + target
        rev = target * num_vertices + origin
        order = np.argsort(key, kind="stable")
        pos = np.minimum(np.searchsorted(key[order], rev), len(key) - 1)
        twin = np.where(key[order][pos] == rev, order[pos], -1)
        twin[np.bincount(edge, minlength=num_edges)[edge] != 2] = -1
        _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
        twin[counts[inverse] > 1] = -1                # a directed edge two faces share: they disagree
        of_edge = np.empty(num_edges, np.int64)
        of_edge[edge] = np.arange(3 * nf)
        self.edge, self.origin, self.twin, self.of_edge = (x.tolist() for x in (edge, origin, twin, of_edge))

    @staticmethod
    @no_type_check
    def next(h):
        return h - h % 3 + (h % 3 + 1) % 3

    @no_type_check
    def quad(self, e: int):
        """(h, t, h1, h2, t1, t2) around interior edge e, or None when it cannot flip."""
        h = self.of_edge[e]
        t = self.twin[h]
        if t < 0 or h // 3 == t // 3:
            return None
        h1, t1 = self.next(h), self.next(t)
        h2, t2 = self.next(h1), self.next(t1)
        if self.origin[h2] == self.origin[t2]:               # the flip would join a vertex to itself
            return None
        return h, t, h1, h2, t1, t2

    @no_type_check
    def flip(self, e: int, quad) -> None:
        """Faces (a, b, c), (b, a, d) on edge e = (a, b) become (c, a, d), (d, b, c)."""
        h, t, h1, h2, t1, t2 = quad
        origin, edge, twin = self.origin, self.edge, self.twin
        a, b, c, d = origin[h], origin[t], origin[h2], origin[t2]
        f, g = 3 * (h // 3), 3 * (t // 3)
        new = ((f, c, edge[h2], twin[h2]), (f + 1, a, edge[t1], twin[t1]), (f + 2, d, e, g + 2),
               (g, d, edge[t2], twin[t2]), (g + 1, b, edge[h1], twin[h1]), (g + 2, c, e, f + 2))
        for slot, o, ed, tw in new:
            origin[slot], edge[slot], twin[slot] = o, ed, tw
            if tw >= 0:
                twin[tw] = slot
        for slot, _, ed, _ in new:
            self.of_edge[ed] = slot

    def pairs(self, num_vertices: int) -> tuple[np.ndarray, np.ndarray]:
        """(distinct vertex pairs (P, 2) with i < j, each edge's pair or −1 for a loop)."""
        origin, of_edge = np.asarray(self.origin, np.int64), np.asarray(self.of_edge, np.int64)
        ends = np.stack([origin[of_edge], origin[self.next(of_edge)]], 1)
        lo, hi = ends.min(1), ends.max(1)
        loop = lo == hi
        uniq, inverse = np.unique((lo * num_vertices + hi)[~loop], return_inverse=True)
        edge_pair = np.full(len(lo), -1, np.int64)
        edge_pair[~loop] = inverse
        return np.stack([uniq // num_vertices, uniq % num_vertices], 1), edge_pair


def intrinsic_delaunay(mesh: Mesh, *, tolerance: float = 1e-10, max_flips: int | None = None
                       ) -> IntrinsicTriangulation:
    """Flip ``mesh``'s edges, in its own metric, until every interior edge is Delaunay
    (its opposite angles sum to at most π: cot α + cot β ≥ −``tolerance``).  Boundary
    and non-manifold edges are never flipped.  Faces wound against their neighbours are
    reversed first (:func:`~jaxmesh.topology.orientation_flips`; the returned ``faces`` keep
    those windings), so an inconsistently oriented mesh flips as its oriented copy does; on a
    non-orientable surface the edges whose faces still disagree are not flipped either.
    Host numpy; needs concrete positions.

    Arguments:
        mesh: a single mesh.
        tolerance: how far below 0 cot α + cot β may be before an edge is flipped.
        max_flips: a bound on the flips (default 100 E); exceeding it raises ``RuntimeError``.

    Returns:
        The :class:`IntrinsicTriangulation` (the flip record and the final triangles)."""
    if mesh.vertices.ndim != 2:
        raise ValueError("intrinsic_delaunay needs a single mesh")
    faces = np.array(mesh.faces, np.int64)
    face_edges = np.array(mesh.face_edges, np.int64)
    nf, ne = faces.shape[0], mesh.num_edges
    # faces wound against their neighbours are reversed first (the flips need each edge's two
    # faces to run it opposite ways; the metric does not depend on the winding)
    reverse = orientation_flips(faces, face_edges, ne)
    faces[reverse], face_edges[reverse] = faces[reverse][:, [0, 2, 1]], face_edges[reverse][:, [0, 2, 1]]
    # the lengths in float64 from the positions as stored, whatever the mesh's dtype: a float32 mesh
    # then flips as its float64 copy does (near-ties are not decided by float32 rounding)
    v, e = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.edges)
    length = np.sqrt(np.sum((v[e[:, 1]] - v[e[:, 0]]) ** 2, axis=-1))
    he = _HalfEdges(faces, face_edges, mesh.num_vertices, ne)
    # the first pass, vectorised: only edges that are not Delaunay start in the queue
    cot = cotangents_from_lengths(length[face_edges], np)              # (F, 3), corner k opposite edge k
    sums = np.bincount(face_edges.ravel(), cot.ravel(), minlength=ne)
    flippable = np.zeros(ne, bool)
    edge_of_half = np.asarray(he.edge, np.int64)
    flippable[edge_of_half[np.asarray(he.twin) >= 0]] = True
    start = flippable & (sums < -tolerance)
    stack = np.flatnonzero(start)[::-1].tolist()
    queued, length = start.tolist(), length.tolist()           # Python scalars: the loop is per edge
    flips: list[tuple[int, int, int, int, int]] = []
    limit = 100 * max(ne, 1) if max_flips is None else int(max_flips)
    while stack:
        e = stack.pop()
        queued[e] = False
        quad = he.quad(e)
        if quad is None:
            continue
        _, _, h1, h2, t1, t2 = quad
        bc, ca, ad, db = he.edge[h1], he.edge[h2], he.edge[t1], he.edge[t2]
        if _cot_opposite(length[e], length[bc], length[ca]) + _cot_opposite(length[e], length[ad], length[db]) \
                >= -tolerance:
            continue
        if len(flips) >= limit:
            raise RuntimeError(f"intrinsic_delaunay: more than {limit} flips (max_flips)")
        length[e] = flipped_length(length[e], length[bc], length[ca], length[ad], length[db], _Scalars)
        flips.append((e, bc, ca, ad, db))
        he.flip(e, quad)
        for x in (bc, ca, ad, db):
            if not queued[x]:
                queued[x] = True
                stack.append(x)
    pairs, edge_pair = he.pairs(mesh.num_vertices)
    return IntrinsicTriangulation(
        faces=np.asarray(he.origin, np.int32).reshape(nf, 3),
        face_edges=np.asarray(he.edge, np.int32).reshape(nf, 3)[:, [1, 2, 0]],   # opposite corner k: half-edge k + 1
        flips=np.array(flips, np.int32).reshape(-1, 5), pairs=pairs.astype(np.int32),
        edge_pair=edge_pair.astype(np.int32), num_vertices=mesh.num_vertices, num_edges=ne)


def replay_flips(lengths: Float[Array, " E"], flips: Int[Array, "K 5"]) -> Float[Array, " E"]:
    """Apply a flip record to edge lengths: for each row (e, bc, ca, ad, db) in order,
    lengths[e] ← :func:`flipped_length` of the five current lengths (``lax.scan``).

    Arguments:
        lengths: the edge lengths before the flips, (E,).
        flips: the record of :func:`intrinsic_delaunay`, (K, 5).

    Returns:
        The lengths after the flips, (E,)."""
    if flips.shape[0] == 0:
        return lengths

    def step(current, rec):
        e, bc, ca, ad, db = rec[0], rec[1], rec[2], rec[3], rec[4]
        new = flipped_length(current[e], current[bc], current[ca], current[ad], current[db])
        return current.at[e].set(new), None

    return jax.lax.scan(step, lengths, flips)[0]


def intrinsic_lengths(mesh: Mesh, triangulation: IntrinsicTriangulation) -> Float[Array, " E"]:
    """The edge lengths of ``triangulation`` as functions of ``mesh.vertices``: the input
    edges' Euclidean lengths, then every recorded flip replayed (:func:`replay_flips`).

    Arguments:
        mesh: the single mesh the triangulation was built from (its vertices may be traced).
        triangulation: from :func:`intrinsic_delaunay`.

    Returns:
        Lengths, (E,), in the ``triangulation``'s edge numbering."""
    return replay_flips(edge_lengths(mesh), jnp.asarray(triangulation.flips))
