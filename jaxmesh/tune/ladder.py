"""The blind search's mesh padded to a size ladder, so that meshes of similar
sizes share the search's compiled programs.

:func:`~jaxmesh.tune.choose_denoiser` compiles some sixty programs for the mesh
it ranks on (each candidate family's filter, its tilt, the recorruption's
fields), and a program is compiled for each array shape it sees: ranking a new
mesh means compiling them all again, most of the time of a blind call on a mesh
of a few thousand vertices.  :func:`pad_search` pads the search mesh's
vertices, faces and edges to one rung of a geometric ladder (``SEARCH_LADDER``
apart, :func:`jaxmesh.dataset.plan.rung`), as :func:`jaxmesh.batch.pad_batch`
pads (inert: isolated padded vertices, padded faces and edges on the first of
them), and the face graphs of the methods that take one
(:func:`jaxmesh.denoise.face_graph.pad_face_graph`: widths from
:func:`padded_width`, at least ``RING_WIDTH``, ``PATCH_WIDTH`` and
``TIER_WIDTHS``).  Later meshes on the same rung, with rings of the usual widths,
reuse the compiled programs, in one process and, through the persistent
compilation cache, across processes.

What stays exact: the padded faces count for nothing (their pilot normals are
zeroed, so their tilts are 0), every risk is a sum over the counted faces, and
the recorruptions are drawn at the real size and padded with zeros, so a padded
search ranks on the same numbers as the unpadded one (up to the order of
floating-point sums).

What it costs: the padded search runs on up to 19% more vertices, and guided
filtering's tiers (cut at fixed fractions, on the ladder's widths) hold more
pairs than the real mesh's own tiers.  A warm blind call took 1.2× as long padded
on a 1.2k-vertex mesh and 1.4× on a 5.6k-vertex one (guided filtering alone
1.4×), where a compile costs several seconds; on the 111 meshes of the dataset
benchmark that rank on the whole mesh the 111 searches fall on 21 shapes.  So
the chooser pads only when asked (``search_ladder``), which the dataset runner
does, and only where it ranks on the whole mesh: the patches of a large mesh
are ranked unpadded, as is held-out ranking.
"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np

from ..dataset.plan import rung
from ..denoise.face_graph import FaceGraph, pad_face_graph
from ..host import HostMesh
from ..mesh import Mesh, to_device

__all__ = ["SEARCH_LADDER", "RING_WIDTH", "PATCH_WIDTH", "TIER_WIDTHS", "padded_width", "SearchMesh", "pad_search"]

#: the ratio between padded search sizes (padding at most 19%, about 9% on average)
SEARCH_LADDER = 2 ** 0.25
#: the least padded widths of a face graph's rings, patch edges and tiers (the faces with the
#: smallest 5/8, next 2/8 and widest 1/8 rings): what most meshes need (the mean ring holds 13
#: faces, the widest 23 to 46), so that the widest, set by a few high-valence vertices, does not
#: give every mesh its own program
RING_WIDTH, PATCH_WIDTH, TIER_WIDTHS = 32, 48, (16, 24, 32)


def padded_width(n: int) -> int:
    """The padded width of n entries: the least 2^j or 3 · 2^j ≥ n (8, 12, 16, 24, 32, 48, …).

    Arguments:
        n: a width (≥ 1).

    Returns:
        The padded width."""
    j = max(int(n) - 1, 1).bit_length()         # 2^(j-1) < n ≤ 2^j
    return 3 << (j - 2) if j >= 2 and 3 << (j - 2) >= n else 1 << j


@dataclasses.dataclass(frozen=True, eq=False)
class SearchMesh:
    """The mesh the search ranks on: ``host``, the real one, and ``mesh``, it padded
    (or ``host.mesh`` itself when ``ratio`` is None), with its methods' auxiliary
    inputs padded alike (:meth:`aux`)."""

    host: HostMesh
    mesh: Mesh
    ratio: float | None
    _auxes: dict = dataclasses.field(default_factory=dict, init=False, repr=False)

    @property
    def num_vertices(self) -> int:
        """The real mesh's vertex count."""
        return self.host.mesh.num_vertices

    @property
    def num_faces(self) -> int:
        """The real mesh's face count."""
        return self.host.mesh.num_faces

    def aux(self, method: str) -> dict:
        """The registry method's auxiliary inputs for :attr:`mesh` (built once per method)."""
        if method not in self._auxes:
            aux = self.host.aux(method)
            if self.ratio is not None:
                aux = {k: self._pad(k, v) for k, v in aux.items()}
            self._auxes[method] = aux
        return self._auxes[method]

    def _pad(self, name: str, value):
        if not isinstance(value, FaceGraph):
            raise TypeError(f"the search cannot pad the auxiliary input {name!r} ({type(value).__name__})")
        return pad_face_graph(value, self.mesh.num_faces, self.mesh.num_edges, padded_width, ring_least=RING_WIDTH,
                              patch_least=PATCH_WIDTH, tier_least=TIER_WIDTHS)

    def counted(self, core) -> np.ndarray:
        """The faces whose error counts, (F_padded,) bool: ``core`` (a mask over the real
        faces; None: all of them), and none of the padded faces."""
        out = np.zeros(self.mesh.num_faces, bool)
        out[:self.num_faces] = True if core is None else np.asarray(core, bool)
        return out


def pad_search(host: HostMesh, ratio: float | None = SEARCH_LADDER) -> SearchMesh:
    """The search mesh of ``host``'s mesh: padded to the next ladder sizes (module
    docstring), or as it is with ``ratio=None``.

    Arguments:
        host: the real search mesh's host mirror.
        ratio: the ladder's step (> 1), or None for no padding.

    Returns:
        The :class:`SearchMesh`."""
    mesh = host.mesh
    if ratio is None:
        return SearchMesh(host, mesh, None)
    from ..batch import pad_batch

    base = rung(max(mesh.num_vertices + 1, -(-mesh.num_faces // 2), -(-(mesh.num_edges + 1) // 3)), ratio)
    shape = (base, 2 * base, 3 * base)      # one rung for all three: F ≈ 2V and E ≈ 3V on a closed surface
    padded = jax.tree.map(lambda a: to_device(np.asarray(a)[0]), pad_batch([mesh], pad_to=shape).mesh)
    return SearchMesh(host, padded, ratio)
