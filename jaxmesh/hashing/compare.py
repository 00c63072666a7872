"""ρ between two hashes of any kind, and the verdict "same model" (one module that
knows every kind: :mod:`.result` and :mod:`.robust` do not import each other)."""

from __future__ import annotations

from .result import MeshHash, cosine_similarity, scaled_vector
from .robust import THRESHOLD as _ROBUST_THRESHOLD
from .robust import robust_similarity

__all__ = ["similarity", "verdict", "THRESHOLDS"]

#: ρ at or above which two hashes are called the same model.  ``robust``: see
#: :mod:`.robust` (its one definition).  ``thesis``: no threshold separates models
#: (experiments/hash measures a negative margin); 0.99 is the value that errs least there.
THRESHOLDS = {"robust": _ROBUST_THRESHOLD, "thesis": 0.99}


def similarity(h1, h2) -> float:
    """ρ between two hashes, in [0, 1], 1 = identical.

    * two ``"thesis"`` hashes (or two plain vectors): the thesis's normalised
      correlation ρ (eq.4), computed from log μ so that it never overflows;
    * two ``"robust"`` hashes: :func:`jaxmesh.hashing.robust.robust_similarity`.

    Raises ``ValueError`` for hashes of different kinds or parameters.

    Arguments:
        h1: the first hash.
        h2: the second hash.

    Returns:
        ρ in [0, 1]."""
    if isinstance(h1, MeshHash) and isinstance(h2, MeshHash):
        if h1.kind != h2.kind:
            raise ValueError(f"cannot compare a {h1.kind!r} hash with a {h2.kind!r} hash")
        if h1.params != h2.params:
            raise ValueError(f"hashes made with different parameters: {h1.params} vs {h2.params}")
        if h1.kind == "robust":
            return robust_similarity(h1.vector, h2.vector)
        return cosine_similarity(scaled_vector(h1), scaled_vector(h2))
    if isinstance(h1, MeshHash) or isinstance(h2, MeshHash):
        raise ValueError("compare two MeshHash objects or two plain vectors, not one of each")
    return cosine_similarity(h1, h2)


def verdict(rho: float, kind: str) -> bool:
    """True if ``rho`` says "same model" for hashes of ``kind`` (:data:`THRESHOLDS`).

    Arguments:
        rho: a similarity from :func:`similarity`.
        kind: ``"thesis"`` or ``"robust"``.

    Returns:
        True for the same model."""
    if kind not in THRESHOLDS:
        raise ValueError(f"unknown hash kind {kind!r}; one of {sorted(THRESHOLDS)}")
    return rho >= THRESHOLDS[kind]
