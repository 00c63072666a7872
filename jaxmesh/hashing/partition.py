"""METIS partition of a mesh's vertex graph and the sub-meshes it defines (thesis 4.3.2 step 1).

METIS (Karypis & Kumar) is called through ``pymetis``.  With a fixed seed it is
deterministic for a given graph *in a given vertex order*: the labels it returns
are arbitrary integers, and relabelling or reordering the vertices can move the
cuts.  The hash functions give the parts a canonical order of their own.
"""

from __future__ import annotations

import numpy as np

from ..graph import metis_labels, submesh
from ..mesh import Mesh

__all__ = ["metis_labels", "metis_partition", "submesh"]


def metis_partition(mesh: Mesh, parts: int, seed: int = 0) -> np.ndarray:
    """Labels (V,) in 0..parts-1 from METIS's k-way partition of the edge graph.

    Minimises the number of cut edges with parts of near-equal vertex counts
    (METIS's default 3% imbalance).  Raises ``ValueError`` when the mesh has
    fewer than ``parts`` vertices.  Every label is used (checked).

    Arguments:
        mesh: a single mesh.
        parts: the number of parts (≤ V).
        seed: METIS's seed.

    Returns:
        Labels (V,) in 0..parts−1, every label used."""
    if mesh.batch_shape:
        raise ValueError(f"metis_partition needs a single mesh, got batch shape {mesh.batch_shape}")
    m = mesh.num_vertices
    if not isinstance(parts, (int, np.integer)) or parts < 1:
        raise ValueError(f"parts must be a positive integer, got {parts!r}")
    if m < parts:
        raise ValueError(f"cannot split {m} vertices into {parts} parts")
    if parts == 1:
        return np.zeros(m, np.int64)
    degree = np.asarray(mesh.degree, np.int64)
    xadj = np.concatenate([[0], np.cumsum(degree)])
    labels = metis_labels(xadj, np.asarray(mesh.dst), parts, seed)  # directed edges are sorted by source
    missing = np.setdiff1d(np.arange(parts), labels)
    if missing.size:
        raise ValueError(f"METIS left {missing.size} of {parts} parts empty "
                         f"({m} vertices); use fewer parts")
    return labels
