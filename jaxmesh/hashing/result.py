"""The hash result object and the similarity ρ (thesis ch.4 eq.4)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

__all__ = ["MeshHash", "cosine_similarity", "scaled_vector"]


@dataclasses.dataclass(frozen=True, eq=False)
class MeshHash:
    """A mesh's hash and what it was made of.

    * ``kind``: ``"thesis"`` (:func:`jaxmesh.hashing.mesh_hash`) or ``"robust"``
      (:func:`jaxmesh.hashing.robust_hash`);
    * ``vector``: the hash h (float64); for ``"thesis"`` h = (μ_1, …, μ_s) in the
      canonical part order (which may hold ``inf`` when a μ_k overflows float64;
      ``log_vector`` = log μ_k is always finite and ρ is computed from it);
    * ``params``: the parameters that made it (so two hashes can be checked to be
      comparable);
    * ``parts``: per-part arrays in canonical order (``sizes`` m_k, ``mst_lengths``
      L*, ``entropies`` ξ_k, ``eigenvalues``), empty for ``"robust"``;
    * ``labels``: (V,) canonical part of every vertex, or ``None``.
    """

    kind: str
    vector: np.ndarray
    log_vector: np.ndarray | None = None
    params: dict[str, Any] = dataclasses.field(default_factory=dict)
    parts: dict[str, Any] = dataclasses.field(default_factory=dict)
    labels: np.ndarray | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no per-vertex labels, no eigenvalue lists); a μ_k that
        overflowed float64 is written as ``null`` (its ``log_vector`` entry is finite)."""
        out: dict[str, Any] = {"kind": self.kind, "params": dict(self.params),
                               "vector": [float(x) if np.isfinite(x) else None for x in self.vector]}
        if self.log_vector is not None:
            out["log_vector"] = [float(x) for x in self.log_vector]
        for key in ("sizes", "mst_lengths", "entropies"):
            if key in self.parts:
                out[key] = [x.item() for x in np.asarray(self.parts[key])]
        return out

    def __len__(self) -> int:
        return len(self.vector)


def cosine_similarity(h1, h2) -> float:
    """ρ = |h₁ · h₂| / (‖h₁‖ ‖h₂‖) (thesis ch.4 eq.4); 0 if either vector is zero.

    Arguments:
        h1: the first vector (or hash).
        h2: the second.

    Returns:
        ρ in [0, 1]."""
    a = np.asarray(h1, np.float64).ravel()
    b = np.asarray(h2, np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"hash vectors differ in length: {a.shape[0]} vs {b.shape[0]}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("hash vectors must be finite (compare MeshHash objects to use log μ)")
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        return 0.0
    return float(min(abs(a @ b) / (na * nb), 1.0))


def scaled_vector(h: MeshHash) -> np.ndarray:
    """μ / max μ from log μ: the same direction as h, never overflowing.

    Arguments:
        h: a thesis hash.

    Returns:
        μ / max μ, float64."""
    lv = np.asarray(h.log_vector, np.float64)
    return np.exp(lv - lv.max())
