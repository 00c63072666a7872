"""The sections of a ``.jxm`` file as one declarative table: each section's name, the
header flag that marks it present, and the functions that encode it from the
encoder's state and decode it into the decoder's.  The header and the file layout
are built from :data:`SECTION_TABLE` (:mod:`.codec`); a new section is one entry
here and its two functions."""

from __future__ import annotations

import lzma
import struct
import zlib
from dataclasses import dataclass
from types import SimpleNamespace
from collections.abc import Callable

import numpy as np

from ..graph import adjacency_from_faces
from . import basis as _basis
from . import connectivity as _conn
from . import patches as _patches
from .coefficients import CodecError, decode_coefficients, decode_ranks, encode_coefficients, encode_ranks
from .rangecoder import max_decisions

__all__ = ["SECTION_TABLE", "content_digest"]

#: header flag bits: the connectivity section holds the fallback code; the basis is the
#: umbrella matrix's; the order section is present (the vertex order is kept)
_FALLBACK, _UMBRELLA, _ORDER = 1, 2, 4


@dataclass(frozen=True)
class _Section:
    """One section of the file: ``encode(enc) -> bytes`` reads the encoder's state,
    ``decode(dec, data)`` checks ``data`` and adds what it decodes to the decoder's
    state (sections are decoded in file order, each seeing the ones before).
    ``flag``: the header bit that says the section is present (0: always)."""

    name: str
    flag: int
    encode: Callable[[SimpleNamespace], bytes]
    decode: Callable[[SimpleNamespace, bytes], None]


def _sections() -> tuple[_Section, ...]:
    return (
        _Section("connectivity", 0, _encode_connectivity, _decode_connectivity),
        _Section("labels", 0, _encode_labels, _decode_labels),
        _Section("ranks", 0, _encode_ranks, _decode_ranks),
        _Section("coefficients", 0, _encode_coefficients, _decode_coefficients),
        _Section("order", _ORDER, _encode_order, _decode_order),
    )



# --------------------------------------------------------------------------- shared steps
def _patch_bases(adjacency, labels: np.ndarray, ranks_or_keep, kind: str, dense_max: int):
    """[(index, B)] per patch; ``ranks_or_keep`` is a float (encoder) or the stored ranks."""
    parts = int(labels.max()) + 1
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(parts + 1))
    out = []
    for p in range(parts):
        index = order[bounds[p]:bounds[p + 1]]
        sub = _patches.patch_adjacency(adjacency, index)
        if isinstance(ranks_or_keep, float):
            r = int(np.ceil(ranks_or_keep * len(index)))
            b = _basis.graph_basis(sub, r, kind, dense_max=dense_max)
        else:
            r = int(ranks_or_keep[p])
            if r > len(index):
                raise CodecError("a patch rank exceeds its vertex count (corrupt file)")
            b = _basis.graph_basis(sub, r, kind, dense_max=dense_max)
            if b.r != r:
                raise CodecError(
                    f"patch {p}: this machine's eigensolver put an eigenvalue cluster boundary at "
                    f"{b.r}, the file says {r}; the basis cannot be reproduced here")
        out.append((index, b.vectors))
    return out


def _reconstruct(bases, blocks, step: float, n: int) -> np.ndarray:
    out = np.zeros((n, 3))
    for (index, vecs), q in zip(bases, blocks):
        out[index] = vecs @ (q * step)
    return out


def content_digest(faces, labels, ranks, blocks, order_section: bytes, step: float, flags: int) -> int:
    """CRC-32 of what the sections decode to (the header's digest, format version 2): the faces in
    traversal order, the patch labels, the ranks, the quantized coefficients, the order section's
    bytes, the quantization step and the flags."""
    crc = 0
    for a in (faces, labels, np.asarray(ranks), *blocks):
        crc = zlib.crc32(np.ascontiguousarray(a, "<i8").tobytes(), crc)
    return zlib.crc32(order_section + struct.pack("<dH", step, flags), crc)


def _check_digest(dec, blocks) -> None:
    """Refuse, before any eigenproblem is solved, content that does not match the header's digest."""
    if getattr(dec, "digest", None) is not None and content_digest(
            dec.faces, dec.labels, dec.ranks, blocks, dec.order_section, dec.step, dec.flags) != dec.digest:
        raise CodecError("the decoded content does not match the header's digest: the file was edited and its "
                         "checksum recomputed (corrupt or forged file)")


# --------------------------------------------------------------------------- the sections
def _encode_connectivity(enc) -> bytes:
    return enc.code.data


def _decode_connectivity(dec, data: bytes) -> None:
    n = dec.n
    if n > max_decisions(len(data)) and n > len(data) * _conn.MAX_LZMA_RATIO // 12:
        raise CodecError(f"the header claims {n} vertices, more than the {len(data)}-byte "
                         "connectivity section can describe (corrupt file)")
    faces = _conn.decode_connectivity(data, bool(dec.flags & _FALLBACK), n)
    if len(faces) != dec.nf or (faces.size and faces.max() + 1 != n):
        raise CodecError("connectivity does not match the header's counts (corrupt file)")
    dec.faces = faces
    dec.adjacency = adjacency_from_faces(faces, n)


def _encode_labels(enc) -> bytes:
    return _patches.encode_labels(enc.labels, enc.adjacency) if len(enc.ranks) > 1 else b""


def _decode_labels(dec, data: bytes) -> None:
    if dec.parts < 1 or dec.parts > dec.n:
        raise CodecError("invalid patch count (corrupt file)")
    dec.labels = (_patches.decode_labels(data, dec.adjacency, dec.parts) if dec.parts > 1
                  else np.zeros(dec.n, np.int64))


def _encode_ranks(enc) -> bytes:
    return encode_ranks(enc.ranks)


def _decode_ranks(dec, data: bytes) -> None:
    if dec.parts > max_decisions(len(data)):
        raise CodecError(f"{dec.parts} patches cannot be described by a {len(data)}-byte rank section")
    ranks = decode_ranks(data, dec.parts)
    sizes = np.bincount(dec.labels, minlength=dec.parts)
    if any(r > s for r, s in zip(ranks, sizes.tolist())):
        raise CodecError("a patch rank exceeds its vertex count (corrupt file)")
    dec.ranks = ranks


def _encode_coefficients(enc) -> bytes:
    return encode_coefficients(enc.blocks)


def _decode_coefficients(dec, data: bytes) -> None:
    if 3 * sum(dec.ranks) > max_decisions(len(data)):
        raise CodecError(f"{sum(dec.ranks)} coefficients per axis cannot be described by a "
                         f"{len(data)}-byte coefficient section (corrupt file)")
    blocks = decode_coefficients(data, dec.ranks)
    _check_digest(dec, blocks)
    bases = _patch_bases(dec.adjacency, dec.labels, dec.ranks, dec.kind, dec.dense_max)
    dec.blocks, dec.vertices = blocks, _reconstruct(bases, blocks, dec.step, dec.n)


def _encode_order(enc) -> bytes:
    return lzma.compress(enc.order.astype("<u4").tobytes(), preset=9) if enc.preserve_order else b""


def _decode_order(dec, data: bytes) -> None:
    n = dec.n
    raw = _conn.lzma_exact(data, 4 * n, "vertex order section")
    perm = np.frombuffer(raw, "<u4").astype(np.int64)
    if not np.array_equal(np.sort(perm), np.arange(n)):
        raise CodecError("stored vertex order is not a permutation (corrupt file)")
    inv = np.empty(n, np.int64)
    inv[perm] = np.arange(n)
    dec.faces, dec.vertices = perm[dec.faces], dec.vertices[inv]


SECTION_TABLE = _sections()
