"""Host-side views of a mesh's edge graph (not public API).

:func:`graph_view` copies the edge arrays off the device once; every statistic
accepts the view in place of the mesh, so :func:`~jaxmesh.stats.mesh_statistics`
builds it once for all of them."""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh


def single(mesh) -> None:
    if mesh.batch_shape:
        raise ValueError("mesh statistics take a single mesh, not a batch")


class GraphView:
    """The edge graph of one mesh as numpy arrays: ``edges`` (E, 2) with i < j,
    ``degree`` (V,), ``src`` / ``dst`` (H,) directed edges grouped by source.  Any
    other attribute is the mesh's (``num_vertices``, ``vertices``, ...)."""

    def __init__(self, mesh: Mesh):
        single(mesh)
        self.mesh = mesh
        self.edges = np.asarray(mesh.edges, np.int64)
        self.degree = np.asarray(mesh.degree, np.int64)
        self.src = np.asarray(mesh.src)
        self.dst = np.asarray(mesh.dst)

    def __getattr__(self, name):
        return getattr(self.mesh, name)


MeshOrView = Mesh | GraphView
"""What the statistics accept: a single mesh, or its :class:`GraphView`."""


def graph_view(mesh: MeshOrView) -> GraphView:
    """``mesh``'s :class:`GraphView` (``mesh`` itself if it is one already)."""
    return mesh if isinstance(mesh, GraphView) else GraphView(mesh)


def mesh_of(mesh) -> Mesh:
    """The mesh behind a view (or the mesh itself)."""
    return mesh.mesh if isinstance(mesh, GraphView) else mesh


def edges_and_degree(mesh) -> tuple[np.ndarray, np.ndarray]:
    """(edges (E, 2) int64 with i < j, degree (V,) int64) on the host."""
    g = graph_view(mesh)
    return g.edges, g.degree
