"""Mesh hashing (thesis ch.4): the thesis's spectral fingerprint and a robust variant.

* :func:`mesh_hash` — the thesis's hash: METIS parts, Euclidean-MST Tsallis
  entropy ξ_k, Laplace–Beltrami eigenvalues, μ_k (:mod:`.thesis`);
* :func:`robust_hash` — affine-normalised spherical-harmonic shell energies,
  which separate models where the thesis's hash does not (:mod:`.robust`);
* :func:`similarity` — ρ between two hashes of one kind; :func:`verdict` applies
  the documented threshold.

Building blocks: :mod:`.partition` (METIS via pymetis), :mod:`.spanning_tree`
(exact Euclidean MST, Tsallis estimate), :mod:`.spectrum` (Laplace–Beltrami
eigenvalues through scipy).  The attacks are in :mod:`jaxmesh.hashing.attacks`.
"""

from __future__ import annotations

from .partition import metis_partition, submesh
from .compare import THRESHOLDS, similarity, verdict
from .result import MeshHash, cosine_similarity
from .robust import robust_hash, robust_similarity
from .spanning_tree import euclidean_mst, euclidean_mst_length, graph_mst_length, tsallis_entropy
from .spectrum import laplace_beltrami_eigenvalues
from .thesis import mesh_hash

__all__ = [
    "MeshHash",
    "mesh_hash",
    "robust_hash",
    "similarity",
    "cosine_similarity",
    "robust_similarity",
    "verdict",
    "THRESHOLDS",
    "HASHES",
    "metis_partition",
    "submesh",
    "euclidean_mst",
    "euclidean_mst_length",
    "graph_mst_length",
    "tsallis_entropy",
    "laplace_beltrami_eigenvalues",
]

#: The hash functions by name (the CLI's ``--method``).
HASHES = {"robust": robust_hash, "thesis": mesh_hash}
