"""The decoder of the cut-border traversal (:mod:`.traversal` describes the
symbols): the same :class:`._border.Border` operations as the encoder, driven by
the symbols read, every count checked against the block's header."""

from __future__ import annotations

import numpy as np

from ._border import Border
from ._codes import ConnectivityError
from .rangecoder import RangeDecoder, max_decisions
from .traversal import _CAP, _ctx_new, _Models

__all__ = ["traversal_decode"]


class _Decoder:
    """State of one :func:`traversal_decode` run: the same border operations as the
    encoder, driven by the symbols read; every count checked against the header."""

    def __init__(self, payload: bytes, total: int, nf: int) -> None:
        self.dec = RangeDecoder(payload)
        self.mdl = _Models()
        self.total, self.nf = total, nf
        self.fan = [0] * total
        self.dummy: list[int] = []
        self.out: list[int] = []
        self.nv = 0
        self.prev_new = 0
        self.border = Border()

    def new_vertex(self) -> int:
        if self.nv >= self.total:
            raise ConnectivityError("connectivity block decodes more vertices than its header states")
        self.dummy.append(self.dec.bit(self.mdl.dummy, 0))
        self.nv += 1
        return self.nv - 1

    def emit(self, x: int, y: int, z: int) -> None:
        if len(self.out) >= 3 * self.nf:
            raise ConnectivityError("connectivity block decodes more faces than its header states")
        self.out.extend((x, y, z))
        for v in (x, y, z):
            self.fan[v] += 1

    def seed(self) -> None:
        bd = self.border
        v0, v1, v2 = self.new_vertex(), self.new_vertex(), self.new_vertex()
        self.emit(v0, v1, v2)
        bd.open_loop(bd.add_node(v0), bd.add_node(v1), bd.add_node(v2))

    def step(self) -> None:
        """Read one symbol and apply it to the border."""
        bd, dec, mdl = self.border, self.dec, self.mdl
        lp, g, m = bd.current()
        a, b = bd.vertex[g], bd.vertex[m]
        fa, fb = self.fan[a], self.fan[b]
        if dec.bit(mdl.is_new, _ctx_new(fa, fb, self.prev_new)):
            self.prev_new = 1
            c = self.new_vertex()
            self.emit(b, a, c)
            bd.insert(lp, g, bd.add_node(c), m)
            return
        self.prev_new = 0
        length = bd.length[lp]
        if length == 3:
            if not dec.bit(mdl.last, 0):
                self.emit(b, a, bd.vertex[bd.prev[g]])
                bd.close(lp)
                return
            self.merge(lp, g, m, a, b, length)
        elif dec.bit(mdl.is_left, min(fa, _CAP)):
            k = bd.prev[g]
            self.emit(b, a, bd.vertex[k])
            bd.cut_left(lp, k, m)
        elif dec.bit(mdl.is_right, min(fb, _CAP)):
            k = bd.next[m]
            self.emit(b, a, bd.vertex[k])
            bd.cut_right(lp, g, k)
        elif dec.bit(mdl.is_split, 0):
            self.split(lp, g, m, a, b, length)
        else:
            self.merge(lp, g, m, a, b, length)

    def _join(self, g: int, m: int, a: int, b: int, k: int) -> None:
        c = self.border.vertex[k]
        self.emit(b, a, c)
        self.border.splice(self.border.prev[k], self.border.add_node(c), m, g, k)

    def split(self, lp, g, m, a, b, length) -> None:
        e = self.dec.uint(self.mdl.offsets, 0) + 2
        if e > length - 3:
            raise ConnectivityError("split offset beyond the loop (corrupt block)")
        bd, k = self.border, g
        for _ in range(e):
            k = bd.prev[k]
        self._join(g, m, a, b, k)
        bd.split(lp, g, len(bd.vertex) - 1, e + 1, length - e, new_is_a=False)

    def merge(self, lp, g, m, a, b, length) -> None:
        bd = self.border
        q = self.dec.uint(self.mdl.offsets, 34)
        if q > len(bd.stack) - 2:
            raise ConnectivityError("merge names a loop that does not exist (corrupt block)")
        other = bd.stack[len(bd.stack) - 2 - q]
        d = self.dec.uint(self.mdl.offsets, 68)
        if d >= bd.length[other]:
            raise ConnectivityError("split/merge offset beyond the loop (corrupt block)")
        k = bd.gate[other]
        for _ in range(d):
            k = bd.next[k]
        self._join(g, m, a, b, k)
        bd.merge(lp, other)


def traversal_decode(data: bytes) -> np.ndarray:
    """Faces (F, 3) from a :func:`traversal_code` block, in the decoded numbering.

    Arguments:
        data: a traversal block (untrusted).

    Returns:
        The faces, (F, 3), in the decoded vertex numbering."""
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
    d = _Decoder(data[12:], total, nf)
    for _ in range(components):
        d.seed()
        while d.border.stack:
            d.step()
    nv, out, dummy, dec = d.nv, d.out, d.dummy, d.dec
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
