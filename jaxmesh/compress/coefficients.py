"""The ``.jxm`` entropy-coded sections of numbers: the quantized spectral
coefficients of every patch and the patch ranks.

Coefficients are coded per patch and axis in order of increasing frequency:
a zero flag in the context of the previous coefficient's magnitude class, then
a sign bit and an adaptive Elias-gamma magnitude (:class:`.rangecoder.RangeEncoder`).
Decoders raise :class:`CodecError` for trailing bytes; their callers bound the
counts first (:func:`.rangecoder.max_decisions`).
"""

from __future__ import annotations

import numpy as np

from .rangecoder import Model, RangeDecoder, RangeEncoder

__all__ = ["CodecError", "encode_coefficients", "decode_coefficients", "encode_ranks", "decode_ranks"]

_CTX = 18  # magnitude classes of the previous coefficient (0..16, 17 = first)


class CodecError(ValueError):
    """A ``.jxm`` file (or byte string) that cannot be decoded; the message says why."""


def _mag_ctx(x: int) -> int:
    return min(abs(x).bit_length(), 16)


def encode_coefficients(blocks: list[np.ndarray]) -> bytes:
    """Range-code the quantized coefficient blocks (module docstring), one (rank, 3)
    int array per patch, into the section's bytes.

    Arguments:
        blocks: one (rank, 3) array of quantized integer coefficients per patch.

    Returns:
        The section's bytes."""
    enc = RangeEncoder()
    zero, mag = Model(_CTX), Model(_CTX * 40)
    for q in blocks:
        for axis in range(3):
            prev = _CTX - 1
            for x in q[:, axis].tolist():
                enc.bit(zero, prev, int(x != 0))
                if x:
                    enc.direct(int(x < 0), 1)
                    enc.uint(mag, 40 * prev, abs(x) - 1, width=39)
                prev = _mag_ctx(x)
    return enc.finish()


def decode_coefficients(data: bytes, ranks: list[int]) -> list[np.ndarray]:
    """Inverse of :func:`encode_coefficients` for patches of the given ``ranks``;
    :class:`CodecError` on truncated or trailing data.

    Arguments:
        data: the encoded bytes (untrusted: every count is checked before use).
        ranks: the number of coefficients of each patch.

    Returns:
        One (rank, 3) integer array per patch."""
    dec = RangeDecoder(data)
    zero, mag = Model(_CTX), Model(_CTX * 40)
    out = []
    for r in ranks:
        q = np.zeros((r, 3), np.int64)
        for axis in range(3):
            prev = _CTX - 1
            col = [0] * r
            for i in range(r):
                x = 0
                if dec.bit(zero, prev):
                    neg = dec.direct(1)
                    x = dec.uint(mag, 40 * prev, width=39) + 1
                    if neg:
                        x = -x
                col[i] = x
                prev = _mag_ctx(x)
            q[:, axis] = col
        out.append(q)
    if not dec.exhausted():
        raise CodecError("coefficient section has trailing bytes (corrupt)")
    return out


def encode_ranks(ranks: list[int]) -> bytes:
    """Range-code the number of coefficients kept in each patch.

    Arguments:
        ranks: the number of coefficients kept in each patch.

    Returns:
        The section's bytes."""
    enc = RangeEncoder()
    mdl = Model(40)
    for r in ranks:
        enc.uint(mdl, 0, r - 1)
    return enc.finish()


def decode_ranks(data: bytes, parts: int) -> list[int]:
    """Inverse of :func:`encode_ranks` for ``parts`` patches; :class:`CodecError` on
    truncated or trailing data.

    Arguments:
        data: the encoded bytes (untrusted: every count is checked before use).
        parts: the number of patches.

    Returns:
        The rank of each patch."""
    dec = RangeDecoder(data)
    mdl = Model(40)
    out = [dec.uint(mdl, 0) + 1 for _ in range(parts)]
    if not dec.exhausted():
        raise CodecError("rank section has trailing bytes (corrupt)")
    return out
