"""A representative part of a large mesh, on which :func:`~jaxmesh.tune.choose_denoiser`
ranks its candidates before running the winner on the whole mesh.

**The patches** (a stratified cluster sample of the surface).  The mesh is
split into ``count`` parts of near-equal size (METIS,
:func:`jaxmesh.graph.metis_labels`), the strata; each part's centre c is one of
its vertices drawn uniformly at random (from ``seed``, so the sample is
deterministic).  Around each centre the core is the smallest hop ball
B_r(c) = {i : d(c, i) ≤ r} holding ``vertices / count`` vertices; the
region is B_{r+m}(c), the core and ``margin`` rings m around it.  The search
mesh is the union of the regions (the faces whose three vertices lie in it,
:func:`jaxmesh.graph.submesh`).  Its faces with three core vertices are the
ones the ranking counts: a patch's outer rings are an artificial boundary,
where the filters behave as they do nowhere on the whole mesh.  Its *rim*, the
search-mesh vertices with a whole-mesh neighbour outside the regions, is what
the chooser holds at its pilot's positions while it runs the search paths on
the patches (:func:`~jaxmesh.tune.choose_denoiser`, ``pin_rim``): the surface
around a patch is then a denoised one, as it is around the same part of the
whole mesh, rather than a free edge that the filters shrink and curl.

Why random centres and many small patches: the candidates' errors vary over a
scanned surface (smooth flanks, detailed fur, creases), and so does the
recorrupted estimate's own bias, so the sample must look like the whole
surface.  Centres at each part's deepest vertex (the farthest from the other
parts) or spread by farthest-point sampling land on systematically unusual
places (the interiors of detailed regions; the ears and feet of an animal),
where every candidate errs more than on the whole mesh (the denoising guide,
*Ranking on patches*).

Hop balls on a roughly uniform triangulation are discs of ~3r² vertices, so a
margin of m rings costs ~2m/r of the core.  ``PATCH_COUNT`` patches,
``PATCH_MARGIN`` rings and ``SEARCH_VERTICES`` core vertices in all are the
setting measured against the search on the whole mesh; the chooser ranks on
patches when the mesh has more than ``PATCH_FACTOR × SEARCH_VERTICES`` vertices.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse.csgraph as csgraph

from ..graph import adjacency_from_faces, metis_labels, submesh
from ..mesh import Mesh

__all__ = ["Patches", "sample_patches", "SEARCH_VERTICES", "PATCH_COUNT", "PATCH_MARGIN", "PATCH_FACTOR"]

#: the core vertices the ranking sees on a large mesh, in all
SEARCH_VERTICES = 2000
#: how many patches share them (the METIS strata)
PATCH_COUNT = 32
#: the rings around each core, denoised but not counted
PATCH_MARGIN = 2
#: the chooser ranks on patches only when the mesh has more than PATCH_FACTOR × search_vertices vertices
PATCH_FACTOR = 6.0


@dataclasses.dataclass(frozen=True)
class Patches:
    """The search mesh of :func:`sample_patches`.

    * ``mesh``: the union of the regions (single mesh, the input's dtype);
    * ``vertices``: each search-mesh vertex's index in the whole mesh, (V_s,);
    * ``core_faces``: which search-mesh faces the ranking counts, (F_s,) bool;
    * ``seeds``: the patches' centres (whole-mesh indices);
    * ``rim``: which search-mesh vertices have a whole-mesh neighbour outside the regions, (V_s,) bool.
    """

    mesh: Mesh
    vertices: np.ndarray
    core_faces: np.ndarray
    seeds: np.ndarray
    rim: np.ndarray


def _hops(adjacency, source: int) -> np.ndarray:
    """Hop distances from ``source`` (inf where unreachable)."""
    return csgraph.shortest_path(adjacency, unweighted=True, indices=source, directed=False)


def _centres(mesh: Mesh, count: int, seed: int) -> np.ndarray:
    """One vertex drawn uniformly from each of ``count`` METIS parts (module docstring)."""
    used = np.asarray(mesh.degree) > 0
    count = max(min(count, int(used.sum())), 1)
    degree = np.asarray(mesh.degree, np.int64)
    labels = (np.zeros(len(degree), np.int64) if count == 1 else
              metis_labels(np.concatenate([[0], np.cumsum(degree)]), np.asarray(mesh.dst), count))
    rng = np.random.default_rng(seed)
    parts = [np.flatnonzero((labels == k) & used) for k in range(count)]
    return np.asarray([int(rng.choice(part)) for part in parts if len(part)], np.int64)


def sample_patches(mesh: Mesh, vertices: int = SEARCH_VERTICES, count: int = PATCH_COUNT,
                   margin: int = PATCH_MARGIN, seed: int = 0) -> Patches:
    """``count`` hop-ball patches spread over ``mesh`` (module docstring), their
    cores holding about ``vertices`` vertices in all.  Deterministic for a given ``seed``.

    Arguments:
        mesh: a single mesh.
        vertices: the core vertices wanted, in all (at least ``count``).
        count: the number of patches.
        margin: the rings around each core (not counted by the ranking).
        seed: the seed of the draw of the patches' centres.

    Returns:
        A :class:`Patches`."""
    for name, value, least in (("vertices", vertices, 1), ("count", count, 1), ("margin", margin, 0),
                               ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
    if mesh.batch_shape:
        raise ValueError("sample_patches takes one mesh, got batch shape " + str(mesh.batch_shape))
    x = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces, np.int64)
    adjacency = adjacency_from_faces(faces, len(x))
    centres = _centres(mesh, int(count), int(seed))
    per_patch = max(int(vertices) // len(centres), 1)
    core = np.zeros(len(x), bool)
    region = np.zeros(len(x), bool)
    for centre in centres:
        d = _hops(adjacency, int(centre))
        reach = d[np.isfinite(d)]
        k = min(per_patch, reach.size) - 1
        r = np.partition(reach, k)[k]             # the per_patch-th nearest vertex's distance
        core |= d <= r
        region |= d <= r + margin
    xs, fs, index = submesh(x, faces, region)
    sub = Mesh.from_arrays(xs, fs, warn=False)
    outside = adjacency @ (~region).astype(np.float64) > 0     # a neighbour beyond the regions
    return Patches(sub, index, core[index][fs].all(axis=1), centres, outside[index])
