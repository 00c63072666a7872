"""A representative part of a large mesh, on which :func:`~jaxmesh.tune.choose_denoiser`
ranks its candidates before running the winner on the whole mesh.

**The patches.**  The mesh is split into ``count`` parts of near-equal size
(METIS, :func:`jaxmesh.graph.metis_labels`), one stratum of the surface each;
each part's seed is its deepest vertex, the farthest in edges from the other
parts.  Around each seed the core is the smallest hop ball
B_r(seed) = {i : d(seed, i) ≤ r} holding ``vertices / count`` vertices; the
region is B_{r+m}(seed), the core and ``margin`` rings m around it.  The search
mesh is the union of the regions (the faces whose three vertices lie in it,
:func:`jaxmesh.graph.submesh`).  Its faces with three core vertices are the
ones the ranking counts: a patch's outer rings are an artificial boundary,
where the filters behave as they do nowhere on the whole mesh.  (Seeds spread
by farthest-point sampling instead land on the extremities, the ears and feet of
an animal, where every filter errs most: not a sample of the surface.)

Hop balls on a roughly uniform triangulation are discs of ~3r² vertices, so a
margin of m rings costs ~2m/r of the core.  ``PATCH_COUNT`` patches,
``PATCH_MARGIN`` rings and ``SEARCH_VERTICES`` core vertices in all are the
setting measured against the search on the whole mesh (the denoising guide); the
chooser ranks on the whole mesh unless asked (``search_vertices=``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph

from ..graph import adjacency_from_faces, metis_labels, submesh
from ..mesh import Mesh

__all__ = ["Patches", "sample_patches", "SEARCH_VERTICES", "PATCH_COUNT", "PATCH_MARGIN", "PATCH_FACTOR"]

#: the core vertices the ranking sees on a large mesh, in all
SEARCH_VERTICES = 2000
#: how many patches share them
PATCH_COUNT = 8
#: the rings around each core, denoised but not counted
PATCH_MARGIN = 3
#: the chooser ranks on patches only when the mesh has more than PATCH_FACTOR × search_vertices vertices
PATCH_FACTOR = 6.0


@dataclasses.dataclass(frozen=True)
class Patches:
    """The search mesh of :func:`sample_patches`.

    * ``mesh``: the union of the regions (single mesh, the input's dtype);
    * ``vertices``: each search-mesh vertex's index in the whole mesh, (V_s,);
    * ``core_faces``: which search-mesh faces the ranking counts, (F_s,) bool;
    * ``seeds``: the patches' seed vertices (whole-mesh indices).
    """

    mesh: Mesh
    vertices: np.ndarray
    core_faces: np.ndarray
    seeds: np.ndarray


def _hops(adjacency, seed: int) -> np.ndarray:
    """Hop distances from ``seed`` (inf where unreachable)."""
    return csgraph.shortest_path(adjacency, unweighted=True, indices=seed, directed=False)


def _seeds(mesh: Mesh, adjacency, count: int) -> np.ndarray:
    """Each METIS part's deepest vertex: the farthest in hops from the vertices with a
    neighbour in another part (module docstring)."""
    used = np.asarray(mesh.degree) > 0
    count = max(min(count, int(used.sum())), 1)
    degree = np.asarray(mesh.degree, np.int64)
    labels = (np.zeros(len(degree), np.int64) if count == 1 else
              metis_labels(np.concatenate([[0], np.cumsum(degree)]), np.asarray(mesh.dst), count))
    cut = np.zeros(len(degree), bool)
    src, dst = np.asarray(mesh.src), np.asarray(mesh.dst)
    cut[src[labels[src] != labels[dst]]] = True
    # one BFS from a virtual vertex joined to every cut vertex (or to all, with one part)
    sources = np.flatnonzero(cut if cut.any() else used)
    n = len(degree)
    joined = sp.bmat([[adjacency, sp.csr_matrix((np.ones(len(sources)), (sources, np.zeros(len(sources), int))),
                                                 shape=(n, 1))], [None, sp.csr_matrix((1, 1))]], format="csr")
    depth = np.where(used, _hops(joined, n)[:n], -1.0)
    depth = np.where(np.isfinite(depth), depth, 0.0)    # a component with no cut vertex
    seeds = [int(np.flatnonzero(labels == k)[np.argmax(depth[labels == k])]) for k in range(count)
             if np.any((labels == k) & used)]
    return np.asarray(seeds, np.int64)


def sample_patches(mesh: Mesh, vertices: int = SEARCH_VERTICES, count: int = PATCH_COUNT,
                   margin: int = PATCH_MARGIN) -> Patches:
    """``count`` hop-ball patches spread over ``mesh`` (module docstring), their
    cores holding about ``vertices`` vertices in all.  Deterministic.

    Arguments:
        mesh: a single mesh.
        vertices: the core vertices wanted, in all (at least ``count``).
        count: the number of patches.
        margin: the rings around each core (not counted by the ranking).

    Returns:
        A :class:`Patches`."""
    for name, value, least in (("vertices", vertices, 1), ("count", count, 1), ("margin", margin, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
    if mesh.batch_shape:
        raise ValueError("sample_patches takes one mesh, got batch shape " + str(mesh.batch_shape))
    x = np.asarray(mesh.vertices)
    faces = np.asarray(mesh.faces, np.int64)
    adjacency = adjacency_from_faces(faces, len(x))
    seeds = _seeds(mesh, adjacency, int(count))
    per_patch = max(int(vertices) // len(seeds), 1)
    core = np.zeros(len(x), bool)
    region = np.zeros(len(x), bool)
    for seed in seeds:
        d = _hops(adjacency, int(seed))
        r = np.sort(d[np.isfinite(d)])[min(per_patch, int(np.isfinite(d).sum())) - 1]
        core |= d <= r
        region |= d <= r + margin
    xs, fs, index = submesh(x, faces, region)
    sub = Mesh.from_arrays(xs, fs, warn=False)
    return Patches(sub, index, core[index][fs].all(axis=1), seeds)
