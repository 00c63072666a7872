"""METIS patches for spectral coding of large meshes (Karni & Gotsman 2000, §5).

A dense eigenproblem on m vertices costs O(m³); Karni & Gotsman cut big meshes
into patches with METIS and code each patch with its own basis.  Here:

* every vertex belongs to exactly one patch (METIS's k-way vertex partition of
  the edge graph, seed 0, via ``pymetis``), patches numbered by their first
  vertex in the decoded order;
* a patch's basis is that of its *induced* subgraph (the edges with both ends in
  the patch).  Edges across a seam belong to no patch, so each patch sees a free
  boundary there; truncation error is largest along seams (measured in
  ``experiments/compress``), and the seam vertices are not otherwise treated;
* the labels are stored in the file (:func:`encode_labels`), so the decoder never
  runs METIS and METIS versions cannot disagree.  Each label is predicted from
  the labels of the vertex's already-decoded neighbours; it costs ~0.1 bits per
  vertex.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..graph import metis_labels
from .rangecoder import Model, RangeDecoder, RangeEncoder

__all__ = ["partition", "encode_labels", "decode_labels", "patch_adjacency"]


def partition(adjacency: sp.csr_matrix, patch_size: int) -> np.ndarray:
    """Labels (V,) of ~V / patch_size METIS parts, renumbered by first appearance.

    Arguments:
        adjacency: the symmetric 0/1 vertex adjacency, (V, V) CSR.
        patch_size: the target vertices per patch.

    Returns:
        Labels (V,) numbered by first appearance."""
    n = adjacency.shape[0]
    parts = max(1, int(round(n / max(int(patch_size), 1))))
    if parts == 1:
        return np.zeros(n, np.int64)
    adj = adjacency.tocsr()
    labels = metis_labels(adj.indptr, adj.indices, parts, seed=0)
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(labels.max() + 1, np.int64)
    used = labels[np.sort(first)]
    rank[used] = np.arange(len(used))
    return rank[labels]


def patch_adjacency(adjacency: sp.csr_matrix, index: np.ndarray) -> sp.csr_matrix:
    """The induced subgraph on ``index`` (sorted vertex ids).

    Arguments:
        adjacency: the symmetric 0/1 vertex adjacency, (V, V) CSR.
        index: the patch's vertex ids, sorted.

    Returns:
        The induced (len(index), len(index)) CSR adjacency."""
    return adjacency[index][:, index].tocsr()


def encode_labels(labels: np.ndarray, adjacency: sp.csr_matrix) -> bytes:
    """Range-coded labels; the context is what the decoder already knows.

    Arguments:
        labels: the patch label of every vertex, (V,).
        adjacency: the symmetric 0/1 vertex adjacency, (V, V) CSR.

    Returns:
        The range-coded bytes."""
    enc = RangeEncoder()
    hit, new, alt = Model(4), Model(2), Model(40)
    indptr, indices = adjacency.indptr.tolist(), adjacency.indices.tolist()
    lab = labels.tolist()
    top = -1
    for i, li in enumerate(lab):
        cand = _candidates(lab, indices, indptr[i], indptr[i + 1], i)
        if cand:
            ok = li == cand[0]
            enc.bit(hit, min(len(cand), 3), int(ok))
            if ok:
                continue
        is_new = li == top + 1
        enc.bit(new, int(bool(cand)), int(is_new))
        if is_new:
            top = li
            continue
        if li > top:
            raise ValueError("labels must be numbered by first appearance")
        enc.uint(alt, 0, li)
    return enc.finish()


def decode_labels(data: bytes, adjacency: sp.csr_matrix, parts: int) -> np.ndarray:
    """Inverse of :func:`encode_labels`: the patch label of every vertex, decoded in
    vertex order with the same neighbour contexts; :class:`CodecError` on bad data.

    Arguments:
        data: the encoded bytes (untrusted: every count is checked before use).
        adjacency: the decoded mesh's vertex adjacency, (V, V) CSR (the neighbour contexts).
        parts: the number of patches.

    Returns:
        The patch label of every vertex, (V,)."""
    dec = RangeDecoder(data)
    hit, new, alt = Model(4), Model(2), Model(40)
    indptr, indices = adjacency.indptr.tolist(), adjacency.indices.tolist()
    n = adjacency.shape[0]
    lab = [0] * n
    top = -1
    for i in range(n):
        cand = _candidates(lab, indices, indptr[i], indptr[i + 1], i)
        if cand and dec.bit(hit, min(len(cand), 3)):
            lab[i] = cand[0]
            continue
        if dec.bit(new, int(bool(cand))):
            top += 1
            lab[i] = top
            continue
        li = dec.uint(alt, 0)
        if li > top:
            raise ValueError("patch labels are corrupt")
        lab[i] = li
    if top + 1 != parts or not dec.exhausted():
        raise ValueError("patch labels are corrupt")
    return np.asarray(lab, np.int64)


def _candidates(lab, indices, lo, hi, i):
    """Labels of the neighbours j < i, most frequent first (ties: smaller label)."""
    counts: dict[int, int] = {}
    for t in range(lo, hi):
        j = indices[t]
        if j < i:
            counts[lab[j]] = counts.get(lab[j], 0) + 1
    if not counts:
        return []
    return sorted(counts, key=lambda x: (-counts[x], x))
