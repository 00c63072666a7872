"""Splitting padded rows into tiers by width, built once on the host.

A padded table (the face rings of :mod:`.face_graph`, the vertex one-rings of
:mod:`.vertex_rings`) is as wide as its widest row, and a few high-valence
vertices make every row that wide.  Its rows are therefore split into at most
``RING_TIERS`` tiers, each holding the rows whose size fits its width, cut to
it: :func:`ring_tiers` picks the widths that minimise the work of the rows plus
``_TIER_COST`` per tier (a tier is one more loop over its rows).
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["RING_TIERS", "ring_tiers"]

#: the most tiers the rows are split into (module docstring)
RING_TIERS = 3
#: the cost of one more tier, in pairs (a tier is one more loop over its rows)
_TIER_COST = 4096


def ring_tiers(counts: np.ndarray, most: int = RING_TIERS, pairs: bool = True) -> list[int]:
    """The tiers' widths k_1 < … < k_T (T ≤ ``most``, k_T the widest ring) minimising
    Σ_t n_t · w(k_t) + T · c, n_t the rows whose ring size lies in (k_{t−1}, k_t], w(k) the
    work per row (k(k + 1)/2 pairs, or k entries with ``pairs=False``) and c the cost of a
    tier (module docstring).  Exhaustive over the ring sizes present.

    Arguments:
        counts: each row's ring size, (F,) (at least 1).
        most: the most tiers.
        pairs: the work is quadratic in the ring (pairs) rather than linear (entries).

    Returns:
        The widths, increasing."""
    sizes, freq = np.unique(np.asarray(counts, np.int64), return_counts=True)
    if sizes.size == 0:
        return [1]
    below = np.concatenate([[0], np.cumsum(freq)])           # faces with size < sizes[i]: below[i]

    def cost(widths) -> float:
        total, start = len(widths) * _TIER_COST, 0
        for i in widths:                                       # widths as indices into sizes
            total += float((below[i + 1] - below[start]) * (sizes[i] * (sizes[i] + 1) / 2 if pairs else sizes[i]))
            start = i + 1
        return total
    last = sizes.size - 1
    options = [(*inner, last) for t in range(most) for inner in itertools.combinations(range(last), t)]
    return [int(sizes[i]) for i in min(options, key=cost)]
