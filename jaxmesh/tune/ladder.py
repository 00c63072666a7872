"""The blind search's mesh padded to a size ladder, so that one set of compiled
programs serves every mesh whose sizes round alike.

:func:`~jaxmesh.tune.choose_denoiser` compiles some thirty programs (the pilot,
each family's filter on the recorrupted inputs, the search paths' loops), each
specialised to the shapes of the mesh and of its neighbourhood tables, and a
new mesh size would compile them all again.  :func:`pad_search` pads the mesh
the candidates are ranked on:

* its vertices to the rung of a geometric ladder (``SEARCH_LADDER`` apart,
  :func:`jaxmesh.dataset.plan.rung`) at or above V + 1, its faces and edges to
  twice and three times that (:func:`ladder_shape`), inertly as :func:`jaxmesh.batch.pad_batch` pads (the padding
  vertices isolated at the origin, the padding faces (d, d, d) on the first of
  them, the padding edges self-loops);
* the widths of its face rings, their patches' edges, its vertex corners and
  its vertex one-rings (:func:`~jaxmesh.denoise.face_graph`) to the next of
  ``WIDTHS``;
* the rows of the face and vertex rings into tiers (:mod:`jaxmesh.denoise.tiers`)
  of fixed widths, ``FACE_TIER_WIDTHS`` (``VERTEX_TIER_WIDTHS``) and the
  table's width, each tier but the narrowest holding a whole number of
  ``1 / TIER_FRACTION`` of the rows (the rows too wide for the next narrower
  tier, then the next widest).

The padding faces are isolated: each one's ring is itself, with no patch edges
and no corner at any vertex, so no real face or vertex sees them.  The chooser
counts only the real faces (ν_f = 0 on the others) and draws its recorruptions
on the real vertices, zero on the padding ones (:func:`jaxmesh.tune.recorrupt.recorruptions`),
so the draws are those of the unpadded search and the estimates agree with it
up to rounding.  The padding is off by default (``choose_denoiser(ladder=None)``):
it makes every search longer (more rows, wider tables), and on the dataset
benchmark's meshes too few share a shape for the saved compiles to repay it
(the denoising guide, *Many meshes*).
"""

from __future__ import annotations

import math

import jax
import numpy as np

from ..batch import pad_batch
from ..dataset.plan import rung
from ..denoise.face_graph import FaceGraph, RingTier, face_graph
from ..denoise.vertex_rings import VertexRings, neighbor_table, tiered_rings, vertex_rings
from ..host import HostMesh, aux_key
from ..mesh import Mesh, to_device

__all__ = ["SEARCH_LADDER", "check_ladder", "WIDTHS", "FACE_TIER_WIDTHS", "VERTEX_TIER_WIDTHS", "TIER_FRACTION", "table_width",
           "ladder_shape", "padded_vertex_rings", "padded_face_graph", "pad_search"]

#: the ratio between the padded sizes of the search mesh (2^¼: at most 19% padding)
SEARCH_LADDER = 2 ** 0.25
#: the widths the neighbourhood tables are padded to (beyond the last: multiples of 32)
WIDTHS = (12, 16, 24, 32, 48, 64)
#: the widths of the face rings' narrower tiers (13 faces around a face of valence-6 vertices)
FACE_TIER_WIDTHS = (13, 16)
#: the widths of the vertex one-rings' narrower tiers
VERTEX_TIER_WIDTHS = (6, 8)
#: each tier but the narrowest holds a multiple of ⌈rows / TIER_FRACTION⌉ rows
TIER_FRACTION = 8


def check_ladder(ladder) -> None:
    """Refuse a ladder that is not None or a finite number > 1 (the ``ladder`` of
    :func:`~jaxmesh.tune.choose_denoiser`), with a ValueError naming it.

    Arguments:
        ladder: the value given.

    Returns:
        None."""
    if ladder is not None and (isinstance(ladder, bool) or not isinstance(ladder, (int, float))
                               or not 1 < ladder < math.inf):
        raise ValueError(f"ladder must be None or a finite number > 1, got {ladder!r}")


def table_width(k: int) -> int:
    """The width a table of rows of up to ``k`` entries is padded to.

    Arguments:
        k: the widest row.

    Returns:
        The next of ``WIDTHS`` at or above ``k`` (beyond the last, the next multiple of 32)."""
    return next((w for w in WIDTHS if k <= w), 32 * math.ceil(k / 32))


def ladder_shape(mesh: Mesh, ratio: float = SEARCH_LADDER) -> tuple[int, int, int]:
    """The padded sizes of the search mesh: V_p the ladder's rung at or above V + 1, F_p = 2 V_p and
    E_p = 3 V_p, which hold a closed mesh of genus 0 or an open one (F < 2V, E < 3V), so that the three
    sizes change together; a mesh with more faces or edges (a high genus) takes their own rungs.

    Arguments:
        mesh: a single mesh.
        ratio: the ladder's step.

    Returns:
        (V_p, F_p, E_p)."""
    nv = rung(mesh.num_vertices + 1, ratio)
    nf = 2 * nv if mesh.num_faces <= 2 * nv else rung(mesh.num_faces, ratio)
    ne = 3 * nv if mesh.num_edges < 3 * nv else rung(mesh.num_edges + 1, ratio)
    return nv, nf, ne


def _tiers(counts: np.ndarray, narrow: tuple[int, ...], width: int) -> tuple[list[np.ndarray], list[int]]:
    """The rows of each tier and its width (module docstring): the widths ``narrow`` below ``width``,
    then ``width``; from the widest down, each tier holds the rows too wide for the next narrower one
    (after those the wider tiers took), at least one, in a multiple of ⌈n / TIER_FRACTION⌉ rows, the
    widest rows first; the narrowest tier holds the rest.  One tier where no row is wider than the
    narrowest width."""
    n = counts.size
    widths = [w for w in narrow if w < width] + [width]
    if n == 0 or counts.max() <= widths[0]:
        return [np.arange(n)], [width]
    step = -(-n // TIER_FRACTION)
    by = np.argsort(-counts, kind="stable")
    groups, taken = [], 0
    for t in range(len(widths) - 1, 0, -1):
        need = max(int(np.sum(counts > widths[t - 1])) - taken, 1)
        rows = min(n - taken, step * -(-need // step))
        groups.append(np.sort(by[taken:taken + rows]))
        taken += rows
    groups.append(np.sort(by[taken:]))
    return groups[::-1], widths


def _widened(table: np.ndarray, rows: int, width: int, fill: np.ndarray) -> np.ndarray:
    """``table`` (R, k) as (rows, width): the new entries ``fill[row]``."""
    out = np.repeat(np.asarray(fill)[:rows, None], width, axis=1).astype(table.dtype)
    out[:table.shape[0], :table.shape[1]] = table
    return out


def padded_vertex_rings(mesh: Mesh, nv: int) -> VertexRings:
    """The one-rings of ``mesh`` padded to ``nv`` vertices (the padding ones isolated) and to the
    widths and tiers of the module docstring.

    Arguments:
        mesh: a single mesh with concrete connectivity.
        nv: the padded vertex count, > V.

    Returns:
        :class:`~jaxmesh.denoise.VertexRings` for the padded mesh."""
    table, mask, degree = neighbor_table(mesh)
    width = table_width(table.shape[1])
    table = _widened(table, nv, width, np.arange(nv))
    mask = _widened(mask, nv, width, np.zeros(nv, bool))
    counts = np.maximum(np.bincount(np.arange(degree.size), degree, nv), 1)
    groups, widths = _tiers(counts, VERTEX_TIER_WIDTHS, width)
    return tiered_rings(table, mask, groups, widths)


def padded_face_graph(mesh: Mesh, shape: tuple[int, int, int], graph: FaceGraph | None = None,
                      rings: VertexRings | None = None) -> FaceGraph:
    """The :class:`~jaxmesh.denoise.FaceGraph` of ``mesh`` padded to ``shape`` = (V_p, F_p, E_p)
    (module docstring): the padding faces each their own ring, without patch edges or corners.

    Arguments:
        mesh: a single mesh with concrete connectivity.
        shape: the padded sizes, each at least the mesh's (V_p > V, E_p > E).
        graph: the mesh's own face graph (default: built here).
        rings: the padded one-rings (default: :func:`padded_vertex_rings`, built here).

    Returns:
        The padded face graph."""
    nv, nf, ne = shape
    graph = face_graph(mesh) if graph is None else graph
    host = {k: np.asarray(v) for k, v in graph._asdict().items() if k not in ("tiers", "vertex_rings")}
    f, e = host["ring"].shape[0], host["edge_faces"].shape[0]
    k = table_width(host["ring"].shape[1])
    ring = _widened(host["ring"], nf, k, np.arange(nf))
    ring_mask = _widened(host["ring_mask"], nf, k, np.zeros(nf, bool))
    ring_mask[f:, 0] = True                                               # a padding face: itself alone
    width = table_width(host["patch_edges"].shape[1])
    patch_edges = _widened(host["patch_edges"], nf, width, np.zeros(nf, np.int64))
    patch_edge_mask = _widened(host["patch_edge_mask"], nf, width, np.zeros(nf, bool))
    corners = np.where(host["vertex_corners"] == 3 * f, 3 * nf, host["vertex_corners"])
    corners = _widened(corners, nv, table_width(corners.shape[1]), np.full(nv, 3 * nf))
    groups, widths = _tiers(ring_mask.sum(axis=1), FACE_TIER_WIDTHS, k)
    order = np.empty(nf, np.int64)
    order[np.concatenate(groups)] = np.arange(nf)
    as32 = lambda a: to_device(np.ascontiguousarray(a, dtype=np.int32))  # noqa: E731
    tiers = tuple(RingTier(as32(g), as32(ring[g, :w]), to_device(np.ascontiguousarray(ring_mask[g, :w])))
                  for g, w in zip(groups, widths))
    edge_rows = lambda a: np.concatenate([a, np.zeros((ne - e, *a.shape[1:]), a.dtype)])  # noqa: E731
    return FaceGraph(as32(ring), to_device(ring_mask), as32(patch_edges), to_device(patch_edge_mask),
                     as32(edge_rows(host["edge_faces"])), as32(edge_rows(host["edge_apex"])),
                     to_device(edge_rows(host["edge_mask"])), tiers, as32(order), as32(corners),
                     padded_vertex_rings(mesh, nv) if rings is None else rings)


def pad_search(host: HostMesh, core, rim, ratio: float = SEARCH_LADDER) -> tuple[HostMesh, np.ndarray, np.ndarray | None]:
    """The search mesh padded to the ladder (module docstring), its methods' tables already padded.

    Arguments:
        host: the search mesh's host mirror (the whole mesh or its patches).
        core: the faces that count (F,) bool, or None for all.
        rim: the vertices held through the search paths' iterations (V,) bool, or None.
        ratio: the ladder's step.

    Returns:
        (the padded mesh's host mirror, the faces that count (F_p,) bool, the rim (V_p,) bool or None)."""
    mesh = host.mesh
    shape = ladder_shape(mesh, ratio)
    padded = HostMesh(jax.tree.map(lambda a: a[0], pad_batch([mesh], shape).mesh))
    rings = padded.memo(aux_key(vertex_rings), lambda: padded_vertex_rings(mesh, shape[0]))
    padded.memo(aux_key(face_graph), lambda: padded_face_graph(mesh, shape, host.aux("guided_normal")["graph"], rings))
    counted = np.zeros(shape[1], bool)
    counted[:mesh.num_faces] = True if core is None else np.asarray(core, bool)
    if rim is not None:
        rim = np.concatenate([np.asarray(rim, bool), np.zeros(shape[0] - mesh.num_vertices, bool)])
    return padded, counted, rim
