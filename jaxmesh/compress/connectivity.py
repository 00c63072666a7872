"""Lossless triangle-connectivity coding: a cut-border traversal with adaptive contexts.

The coder grows the decoded region one triangle at a time, in the manner of
Gumhold & Straßer's cut-border machine (1998) and Rossignac's Edgebreaker
(1999).  The border between decoded and undecoded triangles is a set of
oriented loops of vertices; the *gate* is one border edge a→b, and the
undecoded triangle (b, a, c) across it is described by one symbol:

====  ==============================================================
N     c is a new vertex: it is inserted into the loop between a and b
L     c is the loop vertex before a: a's fan is complete, a leaves the loop
R     c is the loop vertex after b: b leaves the loop
E     the loop is the triangle (a, b, c) itself: the loop ends
S d   c lies d steps after b on the same loop: the loop splits in two
M p d c lies d steps after the gate of loop p: two loops merge (a handle)
====  ==============================================================

After N or R the gate stays at a (the traversal turns around a until its fan
closes, as valence coders do); after L it moves to c.  A split pushes the loop
(c, b, …) on a stack and works on it first.  Each component starts from a seed
triangle (three new vertices).  The symbols are coded with the adaptive range
coder of :mod:`.rangecoder`; the contexts are the numbers of triangles already
decoded around a and b, which predict when a fan closes (on a regular mesh a
vertex has six).  On manifold scans this costs about 1.5–2.5 bits per vertex.

Boundaries are closed before coding with one *dummy* vertex per boundary loop
(a fan of triangles over the hole, as Edgebreaker does); each new vertex
carries an adaptively coded flag saying whether it is a dummy, and the decoder
deletes dummies and their triangles.  The traversal needs an orientable
manifold: every edge in at most two triangles with opposite orientations and
every vertex's triangles forming a single fan.  Anything else (non-manifold
edges or vertices, inconsistent orientation, unused vertices) is coded by the
*fallback* coder instead: the face list, zig-zag delta coded and compressed by
``lzma``, vertex order kept.  :func:`encode_connectivity` says which one it used.

The decoded vertices are numbered in traversal order (the order in which the
decoder meets them), so the encoder returns that permutation; the codec stores
the geometry in the same order.  Faces keep their orientation.
"""

from __future__ import annotations

import lzma
from dataclasses import dataclass

import numpy as np

from .rangecoder import Model, RangeCoderError, RangeDecoder, RangeEncoder, max_decisions

__all__ = [
    "ConnectivityCode",
    "ConnectivityError",
    "NotManifold",
    "encode_connectivity",
    "decode_connectivity",
    "traversal_code",
    "fallback_code",
]

SYMBOLS = "NLRESM"
_N, _L, _R, _E, _S, _M = range(6)
_CAP = 8  # fan-size contexts are capped at this many triangles


class ConnectivityError(ValueError):
    """A connectivity block that cannot be decoded (corrupt or truncated)."""


class NotManifold(ValueError):
    """The mesh cannot be coded by the traversal coder (the reason is the message)."""


@dataclass(frozen=True)
class ConnectivityCode:
    """Result of :func:`encode_connectivity`.

    ``data``: the coded bytes; ``fallback``: whether the fallback coder was used
    (and ``reason`` why); ``order``: (V,) original index of each decoded vertex;
    ``faces``: (F, 3) the faces exactly as the decoder will return them, in the
    decoded numbering; ``symbols``: count of each traversal symbol.
    """

    data: bytes
    fallback: bool
    order: np.ndarray
    faces: np.ndarray
    symbols: dict
    reason: str = ""


# --------------------------------------------------------------------------- contexts
class _Models:
    """The adaptive contexts shared (by construction) by encoder and decoder."""

    def __init__(self) -> None:
        self.is_new = Model((_CAP + 1) * (_CAP + 1) * 2)
        self.is_left = Model(_CAP + 1)
        self.is_right = Model(_CAP + 1)
        self.is_split = Model(2)
        self.last = Model(2)  # loop of three: E or M
        self.dummy = Model(2)
        self.offsets = Model(3 * 34)


def _link(nxt: list, prv: list, *nodes: int) -> None:
    """Chain border nodes: nodes[0] → nodes[1] → … (next and prev pointers)."""
    for x, y in zip(nodes, nodes[1:]):
        nxt[x] = y
        prv[y] = x


def _ctx_new(fa: int, fb: int, prev_new: int) -> int:
    return ((min(fa, _CAP) * (_CAP + 1)) + min(fb, _CAP)) * 2 + prev_new


# --------------------------------------------------------------------------- checks
def _half_edges(faces: np.ndarray, n: int):
    """twin[h] for h = 3 f + k (the half-edge faces[f, k] → faces[f, k+1]), -1 on boundaries.
    Raises NotManifold for a repeated directed edge (an edge in more than two faces,
    or two faces with inconsistent orientation)."""
    a = faces.reshape(-1).astype(np.int64)
    b = faces[:, [1, 2, 0]].reshape(-1).astype(np.int64)
    key = a * n + b
    order = np.argsort(key, kind="stable")
    sk = key[order]
    dup = np.flatnonzero(sk[1:] == sk[:-1])
    if dup.size:
        h = int(order[dup[0]])
        raise NotManifold(
            f"directed edge {int(a[h])}→{int(b[h])} occurs in two faces (an edge shared by "
            "more than two faces, or neighbouring faces with opposite orientation)")
    rkey = b * n + a
    pos = np.searchsorted(sk, rkey)
    pos_c = np.minimum(pos, len(sk) - 1)
    found = sk[pos_c] == rkey
    twin = np.where(found, order[pos_c], -1)
    return twin


def _close_boundaries(faces: np.ndarray, n: int, twin: np.ndarray):
    """Faces closing each boundary loop with a dummy vertex n, n+1, …; (faces, count)."""
    bnd = np.flatnonzero(twin < 0)
    if bnd.size == 0:
        return faces, 0
    a = faces.reshape(-1)[bnd]
    b = faces[:, [1, 2, 0]].reshape(-1)[bnd]
    nxt = np.full(n, -1, np.int64)
    starts, counts = np.unique(a, return_counts=True)
    if (counts > 1).any():
        raise NotManifold(f"vertex {int(starts[counts > 1][0])} lies on the boundary twice "
                          "(a non-manifold vertex)")
    idx_of = np.full(n, -1, np.int64)
    idx_of[a] = np.arange(len(a))
    nxt[a] = b
    loop_id = np.full(len(a), -1, np.int64)
    loops = 0
    for i in range(len(a)):
        if loop_id[i] >= 0:
            continue
        j = i
        while loop_id[j] < 0:
            loop_id[j] = loops
            j = idx_of[b[j]]
            if j < 0:
                raise NotManifold("a boundary loop does not close (non-manifold boundary)")
        loops += 1
    extra = np.stack([b, a, n + loop_id], axis=1)
    return np.concatenate([faces, extra.astype(faces.dtype)]), loops


# --------------------------------------------------------------------------- encoder
def traversal_code(faces: np.ndarray, num_vertices: int) -> ConnectivityCode:
    """Code a manifold, orientable triangle mesh with the cut-border traversal.
    Raises :class:`NotManifold` when the mesh is not one."""
    faces = np.asarray(faces, np.int64)
    n = int(num_vertices)
    used = np.zeros(n, bool)
    used[faces.reshape(-1)] = True
    if not used.all():
        raise NotManifold(f"{int((~used).sum())} vertices are used by no face")
    twin0 = _half_edges(faces, n)
    closed, n_dummy = _close_boundaries(faces, n, twin0)
    total = n + n_dummy
    twin = _half_edges(closed, total) if n_dummy else twin0
    if (twin < 0).any():  # pragma: no cover - closing leaves no boundary by construction
        raise NotManifold("boundary closing failed")
    fv = closed.reshape(-1).tolist()
    tw = twin.tolist()
    nf = len(closed)

    processed = [False] * nf
    new_id = [-1] * total
    order: list[int] = []
    fan = [0] * total  # decoded triangles around each vertex (the contexts)
    out_faces: list[int] = []
    node_v: list[int] = []
    node_next: list[int] = []
    node_prev: list[int] = []
    node_he: list[int] = []
    node_loop: list[int] = []
    node_of_he = [-1] * (3 * nf)
    loop_gate: list[int] = []
    counts = [0] * 6

    enc = RangeEncoder()
    mdl = _Models()

    def new_vertex(v: int) -> None:
        new_id[v] = len(order)
        order.append(v)
        enc.bit(mdl.dummy, 0, int(v >= n))

    def emit(x: int, y: int, z: int) -> None:
        out_faces.extend((new_id[x], new_id[y], new_id[z]))
        fan[x] += 1
        fan[y] += 1
        fan[z] += 1

    def add_node(v: int, he: int, loop: int) -> int:
        k = len(node_v)
        node_v.append(v)
        node_next.append(-1)
        node_prev.append(-1)
        node_he.append(he)
        node_loop.append(loop)
        node_of_he[he] = k
        return k

    def set_he(k: int, he: int) -> None:
        node_of_he[node_he[k]] = -1
        node_he[k] = he
        node_of_he[he] = k

    components = 0
    seed_cursor = 0
    prev_new = 0
    while True:
        while seed_cursor < nf and processed[seed_cursor]:
            seed_cursor += 1
        if seed_cursor == nf:
            break
        s = seed_cursor
        components += 1
        processed[s] = True
        v0, v1, v2 = fv[3 * s], fv[3 * s + 1], fv[3 * s + 2]
        for v in (v0, v1, v2):
            if new_id[v] >= 0:
                raise NotManifold(f"vertex {v} is shared by two components (a non-manifold vertex)")
            new_vertex(v)
        emit(v0, v1, v2)
        loop = len(loop_gate)
        k0 = add_node(v0, 3 * s, loop)
        k1 = add_node(v1, 3 * s + 1, loop)
        k2 = add_node(v2, 3 * s + 2, loop)
        _link(node_next, node_prev, k0, k1, k2, k0)
        loop_gate.append(k0)
        loop_len = {loop: 3}
        stack = [loop]
        while stack:
            lp = stack[-1]
            g = loop_gate[lp]
            a = node_v[g]
            m = node_next[g]
            b = node_v[m]
            t = tw[node_he[g]]
            f = t // 3
            if processed[f]:  # pragma: no cover - the border never holds a closed edge
                raise NotManifold("traversal reached a decoded face across the gate")
            processed[f] = True
            r = t % 3
            h_ac = 3 * f + (r + 1) % 3
            h_cb = 3 * f + (r + 2) % 3
            c = fv[h_cb]
            fa, fb = fan[a], fan[b]
            if new_id[c] < 0:
                enc.bit(mdl.is_new, _ctx_new(fa, fb, prev_new), 1)
                counts[_N] += 1
                prev_new = 1
                new_vertex(c)
                emit(b, a, c)
                k = add_node(c, h_cb, lp)
                set_he(g, h_ac)
                _link(node_next, node_prev, g, k, m)
                loop_len[lp] += 1
                continue
            enc.bit(mdl.is_new, _ctx_new(fa, fb, prev_new), 0)
            prev_new = 0
            # which border node of c: turn around c from (c, b) over undecoded faces
            h = h_cb
            while True:
                t2 = tw[h]
                f2 = t2 // 3
                if f2 == f:
                    raise NotManifold(f"vertex {c if c < n else 'dummy'} has more than one fan "
                                      "of triangles (a non-manifold vertex)")
                if processed[f2]:
                    j = node_of_he[t2]
                    break
                h = 3 * f2 + (t2 % 3 + 1) % 3
            if j < 0:  # pragma: no cover
                raise NotManifold("border bookkeeping failed")
            k = node_next[j]
            emit(b, a, c)
            length = loop_len[lp]
            if length == 3 and node_loop[k] == lp:
                enc.bit(mdl.last, 0, 0)
                counts[_E] += 1
                stack.pop()
                for x in (g, m, k):
                    node_of_he[node_he[x]] = -1
                del loop_len[lp]
                continue
            if length == 3:
                enc.bit(mdl.last, 0, 1)
            elif k == node_prev[g]:
                enc.bit(mdl.is_left, min(fa, _CAP), 1)
                counts[_L] += 1
                node_of_he[node_he[g]] = -1
                set_he(k, h_cb)
                _link(node_next, node_prev, k, m)
                loop_gate[lp] = k
                loop_len[lp] -= 1
                continue
            else:
                enc.bit(mdl.is_left, min(fa, _CAP), 0)
                if k == node_next[m]:
                    enc.bit(mdl.is_right, min(fb, _CAP), 1)
                    counts[_R] += 1
                    node_of_he[node_he[m]] = -1
                    set_he(g, h_ac)
                    _link(node_next, node_prev, g, k)
                    loop_len[lp] -= 1
                    continue
                enc.bit(mdl.is_right, min(fb, _CAP), 0)
            if node_loop[k] == lp:
                # split: (a, c, …) and (c, b, …, y); c is coded by its distance e behind a
                enc.bit(mdl.is_split, 0, 1)
                counts[_S] += 1
                e = 1
                x = node_prev[g]
                while x != k:
                    x = node_prev[x]
                    e += 1
                enc.uint(mdl.offsets, 0, e - 2)
                k2 = add_node(c, h_cb, lp)
                set_he(g, h_ac)
                _link(node_next, node_prev, j, k2, m)
                _link(node_next, node_prev, g, k)
                new_loop = len(loop_gate)
                size_a, size_b = e + 1, length - e
                # relabel the smaller part (the decoder needs no labels)
                start, stop = (g, g) if size_a <= size_b else (k2, k2)
                x = start
                while True:
                    node_loop[x] = new_loop
                    x = node_next[x]
                    if x == stop:
                        break
                loop_a, loop_b = (new_loop, lp) if size_a <= size_b else (lp, new_loop)
                loop_gate.append(-1)
                loop_gate[loop_a] = g
                loop_gate[loop_b] = k2
                loop_len[loop_a] = size_a
                loop_len[loop_b] = size_b
                stack[-1] = loop_b
                stack.append(loop_a)
                continue
            # merge with another loop (only on surfaces with handles)
            if length > 3:
                enc.bit(mdl.is_split, 0, 0)
            counts[_M] += 1
            other = node_loop[k]
            p = stack.index(other)
            d = 0
            x = loop_gate[other]
            while x != k:
                x = node_next[x]
                d += 1
            enc.uint(mdl.offsets, 34, len(stack) - 2 - p)
            enc.uint(mdl.offsets, 68, d)
            x = k
            while True:
                node_loop[x] = lp
                x = node_next[x]
                if x == k:
                    break
            k2 = add_node(c, h_cb, lp)
            set_he(g, h_ac)
            _link(node_next, node_prev, j, k2, m)
            _link(node_next, node_prev, g, k)
            loop_len[lp] = length + loop_len.pop(other) + 1
            stack.remove(other)
    head = components.to_bytes(4, "little") + total.to_bytes(4, "little") + nf.to_bytes(4, "little")
    data = head + enc.finish()
    order_a = np.asarray(order, np.int64)
    faces_a = np.asarray(out_faces, np.int64).reshape(-1, 3)
    keep_v = order_a < n
    if n_dummy:
        remap = np.cumsum(keep_v) - 1
        faces_a = remap[faces_a[keep_v[faces_a].all(axis=1)]]
        order_a = order_a[keep_v]
    return ConnectivityCode(data=data, fallback=False, order=order_a, faces=faces_a,
                            symbols=dict(zip(SYMBOLS, counts)))


def traversal_decode(data: bytes) -> np.ndarray:
    """Faces (F, 3) from a :func:`traversal_code` block, in the decoded numbering."""
    if len(data) < 12:
        raise ConnectivityError("connectivity block too short")
    components = int.from_bytes(data[0:4], "little")
    total = int.from_bytes(data[4:8], "little")
    nf = int.from_bytes(data[8:12], "little")
    if components > nf or 3 * components > total:
        raise ConnectivityError("connectivity header is inconsistent")
    cap = max_decisions(len(data) - 12)  # each vertex and each face costs a decision or more
    if total > cap or nf > cap:
        raise ConnectivityError(f"connectivity header claims {total} vertices and {nf} faces, more than "
                                f"its {len(data) - 12} coded bytes can hold (corrupt)")
    dec = RangeDecoder(data[12:])
    mdl = _Models()
    fan = [0] * total
    dummy: list[int] = []
    out: list[int] = []
    node_v: list[int] = []
    node_next: list[int] = []
    node_prev: list[int] = []
    loop_gate: list[int] = []
    nv = 0

    def new_vertex() -> int:
        nonlocal nv
        if nv >= total:
            raise ConnectivityError("connectivity block decodes more vertices than its header states")
        dummy.append(dec.bit(mdl.dummy, 0))
        nv += 1
        return nv - 1

    def emit(x: int, y: int, z: int) -> None:
        if len(out) >= 3 * nf:
            raise ConnectivityError("connectivity block decodes more faces than its header states")
        out.extend((x, y, z))
        fan[x] += 1
        fan[y] += 1
        fan[z] += 1

    def add_node(v: int) -> int:
        node_v.append(v)
        node_next.append(-1)
        node_prev.append(-1)
        return len(node_v) - 1

    def walk(x: int, d: int, limit: int) -> int:
        if d >= limit:
            raise ConnectivityError("split/merge offset beyond the loop (corrupt block)")
        for _ in range(d):
            x = node_next[x]
        return x

    prev_new = 0
    for _ in range(components):
        v0, v1, v2 = new_vertex(), new_vertex(), new_vertex()
        emit(v0, v1, v2)
        loop = len(loop_gate)
        k0, k1, k2 = add_node(v0), add_node(v1), add_node(v2)
        _link(node_next, node_prev, k0, k1, k2, k0)
        loop_gate.append(k0)
        loop_len = {loop: 3}
        stack = [loop]
        while stack:
            lp = stack[-1]
            g = loop_gate[lp]
            a = node_v[g]
            m = node_next[g]
            b = node_v[m]
            fa, fb = fan[a], fan[b]
            if dec.bit(mdl.is_new, _ctx_new(fa, fb, prev_new)):
                prev_new = 1
                c = new_vertex()
                emit(b, a, c)
                k = add_node(c)
                _link(node_next, node_prev, g, k, m)
                loop_len[lp] += 1
                continue
            prev_new = 0
            length = loop_len[lp]
            if length == 3:
                if not dec.bit(mdl.last, 0):
                    emit(b, a, node_v[node_prev[g]])
                    stack.pop()
                    del loop_len[lp]
                    continue
                sym = _M
            elif dec.bit(mdl.is_left, min(fa, _CAP)):
                k = node_prev[g]
                emit(b, a, node_v[k])
                _link(node_next, node_prev, k, m)
                loop_gate[lp] = k
                loop_len[lp] -= 1
                continue
            elif dec.bit(mdl.is_right, min(fb, _CAP)):
                k = node_next[m]
                emit(b, a, node_v[k])
                _link(node_next, node_prev, g, k)
                loop_len[lp] -= 1
                continue
            else:
                sym = _S if dec.bit(mdl.is_split, 0) else _M
            if sym == _S:
                e = dec.uint(mdl.offsets, 0) + 2
                if e > length - 3:
                    raise ConnectivityError("split offset beyond the loop (corrupt block)")
                k = g
                for _ in range(e):
                    k = node_prev[k]
                c = node_v[k]
                emit(b, a, c)
                j = node_prev[k]
                k2 = add_node(c)
                _link(node_next, node_prev, j, k2, m)
                _link(node_next, node_prev, g, k)
                loop_b = len(loop_gate)
                loop_gate.append(k2)
                loop_len[loop_b] = length - e
                loop_len[lp] = e + 1
                stack[-1] = loop_b
                stack.append(lp)
                continue
            q = dec.uint(mdl.offsets, 34)
            if q > len(stack) - 2:
                raise ConnectivityError("merge names a loop that does not exist (corrupt block)")
            other = stack[len(stack) - 2 - q]
            d = dec.uint(mdl.offsets, 68)
            k = walk(loop_gate[other], d, loop_len[other])
            c = node_v[k]
            emit(b, a, c)
            j = node_prev[k]
            k2 = add_node(c)
            _link(node_next, node_prev, j, k2, m)
            _link(node_next, node_prev, g, k)
            loop_len[lp] = length + loop_len.pop(other) + 1
            stack.remove(other)
    if nv != total or len(out) != 3 * nf:
        raise ConnectivityError(f"connectivity block decoded {nv} vertices and {len(out) // 3} faces; "
                                f"its header states {total} and {nf}")
    if not dec.exhausted():
        raise ConnectivityError("connectivity block has trailing bytes (corrupt)")
    faces = np.asarray(out, np.int64).reshape(-1, 3)
    is_dummy = np.asarray(dummy, bool)
    if is_dummy.any():
        keep = ~is_dummy
        remap = np.cumsum(keep) - 1
        faces = remap[faces[keep[faces].all(axis=1)]]
    return faces


# --------------------------------------------------------------------------- fallback
#: lzma's largest compression ratio is about 7 000 : 1 (a run of zeros: 6 814 at
#: 100 MB); a payload that claims to inflate beyond this many bytes per byte is refused
#: before any decompression.
MAX_LZMA_RATIO = 16_384


def lzma_exact(payload: bytes, size: int, what: str) -> bytes:
    """Decompress one lzma stream that must inflate to exactly ``size`` bytes,
    never producing more than ``size + 1`` bytes (a bounded decompression: a
    corrupt or hostile stream cannot claim memory the header did not announce)."""
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
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(faces, np.int64)
    n = int(num_vertices)
    twin = _half_edges(faces, n)
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
    else the fallback coder (or :class:`NotManifold` if ``allow_fallback`` is False)."""
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
    block announces before anything is allocated."""
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
