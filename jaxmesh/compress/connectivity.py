"""Lossless triangle-connectivity coding: the cut-border traversal
(:mod:`.traversal`) for orientable manifolds, non-manifold vertices split first
and merged back after decoding, and a *fallback* coder (zig-zag deltas of the
face list, ``lzma``) for everything else.  :func:`encode_connectivity` says
which one it used; the decoded vertex order is the traversal order.
"""

from __future__ import annotations

import lzma

import numpy as np

from ._codes import SYMBOLS, ConnectivityCode, ConnectivityError, NotManifold
from .rangecoder import RangeCoderError
from .traversal import half_edges, traversal_code
from .traversal_decoder import traversal_decode

__all__ = [
    "SYMBOLS",
    "ConnectivityCode",
    "ConnectivityError",
    "NotManifold",
    "encode_connectivity",
    "decode_connectivity",
    "lzma_exact",
    "MAX_LZMA_RATIO",
    "split_nonmanifold_vertices",
]


# --------------------------------------------------------------------------- fallback
#: lzma's largest compression ratio is about 7 000 : 1 (a run of zeros: 6 814 at
#: 100 MB); a payload that claims to inflate beyond this many bytes per byte is refused
#: before any decompression.
MAX_LZMA_RATIO = 16_384


def lzma_exact(payload: bytes, size: int, what: str) -> bytes:
    """Decompress one lzma stream that must inflate to exactly ``size`` bytes,
    never producing more than ``size + 1`` bytes (a bounded decompression: a
    corrupt or hostile stream cannot claim memory the header did not announce).

    Arguments:
        payload: one lzma stream.
        size: the exact size it must inflate to.
        what: the section's name, for the error message.

    Returns:
        Exactly ``size`` bytes (else :class:`CodecError`)."""
    if size > MAX_LZMA_RATIO * len(payload) + 4096:
        raise ConnectivityError(f"{what}: {len(payload)} compressed bytes cannot hold the announced "
                                f"{size} bytes (corrupt)")
    dec = lzma.LZMADecompressor()
    try:
        raw = dec.decompress(payload, max_length=size + 1)
    except lzma.LZMAError as err:
        raise ConnectivityError(f"{what} is corrupt ({err})") from err
    if len(raw) != size or not dec.eof or dec.unused_data:
        raise ConnectivityError(f"{what} does not inflate to the announced {size} bytes (corrupt)")
    return raw


def _zigzag(x: np.ndarray) -> np.ndarray:
    return ((x << 1) ^ (x >> 63)).astype(np.uint64)


def fallback_code(faces: np.ndarray, num_vertices: int, reason: str = "") -> ConnectivityCode:
    """Any triangle list: zig-zag deltas of the flattened face indices, lzma-compressed.
    Vertex order is kept (``order`` is the identity)."""
    f = np.asarray(faces, np.int64)
    flat = f.reshape(-1)
    delta = np.diff(flat, prepend=0)
    payload = _zigzag(delta).astype("<u8").tobytes()
    head = int(num_vertices).to_bytes(4, "little") + len(f).to_bytes(4, "little")
    data = head + lzma.compress(payload, preset=9 | lzma.PRESET_EXTREME)
    return ConnectivityCode(data=data, fallback=True, order=np.arange(num_vertices), faces=f,
                            symbols={}, reason=reason)


def fallback_decode(data: bytes) -> tuple[np.ndarray, int]:
    if len(data) < 8:
        raise ConnectivityError("fallback connectivity block too short")
    n = int.from_bytes(data[0:4], "little")
    nf = int.from_bytes(data[4:8], "little")
    raw = lzma_exact(data[8:], 24 * nf, "fallback connectivity block")
    z = np.frombuffer(raw, "<u8")
    delta = (z >> np.uint64(1)).astype(np.int64) ^ -(z & np.uint64(1)).astype(np.int64)
    flat = np.cumsum(delta)
    if flat.size and (flat.min() < 0 or flat.max() >= n):
        raise ConnectivityError("fallback connectivity block has out-of-range indices")
    return flat.reshape(-1, 3), n


# --------------------------------------------------------------------------- vertex splitting
def split_nonmanifold_vertices(faces: np.ndarray, num_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Give each extra fan of a non-manifold vertex a vertex of its own.

    A vertex whose triangles form k > 1 fans (connected through shared edges
    around it) keeps the first fan; the others get new vertices n, n+1, ….
    Returns ``(faces, copy_of)``, ``copy_of[i]`` the original of vertex n + i.
    Needs every directed edge at most once (else :class:`NotManifold`).

    Arguments:
        faces: triangles, (F, 3) integer vertex indices.
        num_vertices: the vertex count n.

    Returns:
        ``(faces, copy_of)``: the faces with the new vertices, and the original of each new vertex."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(faces, np.int64)
    n = int(num_vertices)
    twin = half_edges(faces, n)
    corners = np.arange(faces.size)
    has = twin >= 0
    # corner c of v (outgoing half-edge c) meets v's corner in the face across that edge
    other = 3 * (twin[has] // 3) + (twin[has] % 3 + 1) % 3
    g = sp.coo_matrix((np.ones(int(has.sum())), (corners[has], other)), shape=(faces.size, faces.size))
    _, fan = connected_components(g, directed=False)
    vert = faces.reshape(-1)
    pairs = np.unique(np.stack([vert, fan], axis=1), axis=0)  # sorted by vertex, then fan label
    first = np.r_[True, pairs[1:, 0] != pairs[:-1, 0]]
    extra = pairs[~first]
    if extra.size == 0:
        return faces, np.zeros(0, np.int64)
    new_of_fan = np.full(fan.max() + 1, -1, np.int64)
    new_of_fan[extra[:, 1]] = n + np.arange(len(extra))
    remapped = np.where(new_of_fan[fan] >= 0, new_of_fan[fan], vert)
    return remapped.reshape(-1, 3), extra[:, 0]


# --------------------------------------------------------------------------- public
def encode_connectivity(faces: np.ndarray, num_vertices: int, *, allow_fallback: bool = True) -> ConnectivityCode:
    """Code ``faces`` losslessly: the traversal coder when the mesh is an orientable
    manifold (with or without boundary, any genus, any number of components),
    else the fallback coder (or :class:`NotManifold` if ``allow_fallback`` is False).

    Arguments:
        faces: triangles, (F, 3) integer vertex indices.
        num_vertices: the vertex count V.
        allow_fallback: use the fallback coder for non-manifold input instead of raising.

    Returns:
        A :class:`ConnectivityCode` (the bytes, whether it fell back, the decoded vertex order and faces)."""
    n = int(num_vertices)
    try:
        split, copy_of = split_nonmanifold_vertices(faces, n)
        code = traversal_code(split, n + len(copy_of))
    except NotManifold as err:
        if not allow_fallback:
            raise
        return fallback_code(faces, n, reason=str(err))
    order, faces_d = code.order, code.faces
    pairs = np.zeros((0, 2), np.int64)
    if len(copy_of):
        pos = np.empty(len(order), np.int64)
        pos[order] = np.arange(len(order))
        pairs = np.stack([pos[n + np.arange(len(copy_of))], pos[copy_of]], axis=1)
        faces_d, keep = _merge_copies(faces_d, len(order), pairs)
        order = order[keep]
    head = len(pairs).to_bytes(4, "little") + pairs.astype("<u4").tobytes()
    return ConnectivityCode(data=head + code.data, fallback=False, order=order, faces=faces_d,
                            symbols=code.symbols, reason=f"non-manifold vertices split into {len(copy_of)} extra copies"
                            if len(copy_of) else "")


def _merge_copies(faces: np.ndarray, total: int, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Replace each copy pairs[:, 0] by its original pairs[:, 1] and drop the copies."""
    target = np.arange(total)
    target[pairs[:, 0]] = pairs[:, 1]
    keep = np.ones(total, bool)
    keep[pairs[:, 0]] = False
    remap = np.cumsum(keep) - 1
    return remap[target[faces]], keep


def decode_connectivity(data: bytes, fallback: bool, num_vertices: int | None = None) -> np.ndarray:
    """Faces from a block written by :func:`encode_connectivity`.

    ``num_vertices``, when known (the codec's header), bounds the counts the
    block announces before anything is allocated.

    Arguments:
        data: the encoded bytes (untrusted: every count is checked before use).
        fallback: whether the block was written by the fallback coder (the header says).
        num_vertices: the vertex count from the codec's header, which bounds the block's counts (None: unbounded).

    Returns:
        The faces, (F, 3) int array."""
    try:
        if fallback:
            faces, n = fallback_decode(data)
            if num_vertices is not None and n != num_vertices:
                raise ConnectivityError(f"fallback block is for {n} vertices, the header says {num_vertices}")
            return faces
        if len(data) < 4:
            raise ConnectivityError("connectivity block too short")
        ncopy = int.from_bytes(data[0:4], "little")
        end = 4 + 8 * ncopy
        if len(data) < end:
            raise ConnectivityError("connectivity block too short for its vertex-copy list")
        if num_vertices is not None and len(data) >= end + 12:
            total = int.from_bytes(data[end + 4:end + 8], "little")
            # decoded vertices: the real ones, one copy per extra fan, one dummy per boundary loop (≥ 3 vertices)
            split = num_vertices + ncopy
            if total < num_vertices or total > split + split // 3 + 1:
                raise ConnectivityError(f"connectivity block announces {total} decoded vertices; the header "
                                        f"says the mesh has {num_vertices} (corrupt)")
        pairs = np.frombuffer(data[4:end], "<u4").astype(np.int64).reshape(-1, 2)
        faces = traversal_decode(data[end:])
        if ncopy:
            total = int(faces.max()) + 1
            if pairs.max() >= total or len(np.unique(pairs[:, 0])) != ncopy or np.isin(pairs[:, 1], pairs[:, 0]).any():
                raise ConnectivityError("connectivity block has an invalid vertex-copy list")
            faces = _merge_copies(faces, total, pairs)[0]
        return faces
    except RangeCoderError as err:
        raise ConnectivityError(str(err)) from err
