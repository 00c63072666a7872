"""Host-side views of a mesh's edge graph (not public API)."""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh


def single(mesh: Mesh) -> None:
    if mesh.batch_shape:
        raise ValueError("mesh statistics take a single mesh, not a batch")


def edges_and_degree(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """(edges (E, 2) int64 with i < j, degree (V,) int64) on the host."""
    single(mesh)
    return np.asarray(mesh.edges, np.int64), np.asarray(mesh.degree, np.int64)
