"""Adaptive binary range coder (the LZMA family's carry-less design, 16-bit probabilities).

Every symbol the codec writes is split into binary decisions; each decision is
coded with a probability that adapts to what was coded before in the same
*context* (an index into a :class:`Model`).  Encoder and decoder update the
probabilities identically, so nothing about the statistics is transmitted.

* ``p`` is the probability of a 0 bit in units of 2**-16; after a bit it moves
  1/32 of the way towards the observed value (p += (65536 - p) >> 5, or
  p -= p >> 5), so it stays in [31, 65505] and a context never costs more than
  ~11 bits or less than ~0.0007 bits per decision.
* The interval is ``range`` (32-bit); a 0 takes the lower ``(range >> 16) * p``.
  Bytes leave the encoder once the top byte is settled, carries are handled
  with the cached-byte scheme, and the decoder reads 5 bytes ahead.

Pure Python: ~1 µs per decision, enough for a million decisions per second.
"""

from __future__ import annotations

__all__ = ["Model", "RangeEncoder", "RangeDecoder", "RangeCoderError", "MAX_DECISIONS_PER_BYTE",
           "max_decisions"]

_TOP = 1 << 24
_MASK32 = 0xFFFFFFFF
_HALF = 1 << 15


#: A decision costs at least −log2(65505/65536) ≈ 0.000683 bits, so one byte
#: holds at most 8 / 0.000683 ≈ 11 713 of them: decoders bound every count they
#: read by this before allocating or looping.
MAX_DECISIONS_PER_BYTE = 11_714


def max_decisions(nbytes: int) -> int:
    """The most binary decisions ``nbytes`` of range-coded data can hold.

    Arguments:
        nbytes: the size of the coded data.

    Returns:
        The bound, used to refuse a count no stream of that size can hold."""
    return MAX_DECISIONS_PER_BYTE * max(int(nbytes), 0) + 64


class RangeCoderError(ValueError):
    """The byte stream ended early or decoded to something impossible."""


class Model:
    """``n`` adaptive binary contexts, each starting at probability 1/2."""

    __slots__ = ("p",)

    def __init__(self, n: int):
        self.p = [_HALF] * n


class RangeEncoder:
    def __init__(self) -> None:
        self.low = 0
        self.range = _MASK32
        self.cache = 0
        self.cache_size = 1
        self.out = bytearray()

    def _shift_low(self) -> None:
        low = self.low
        if low < 0xFF000000 or low > _MASK32:
            carry = low >> 32
            temp = self.cache
            out = self.out
            while True:
                out.append((temp + carry) & 0xFF)
                temp = 0xFF
                self.cache_size -= 1
                if self.cache_size == 0:
                    break
            self.cache = (low >> 24) & 0xFF
        self.cache_size += 1
        self.low = (low << 8) & _MASK32

    def bit(self, model: Model, ctx: int, bit: int) -> None:
        """Code one binary decision ``bit`` in context ``ctx`` of ``model``."""
        probs = model.p
        p = probs[ctx]
        bound = (self.range >> 16) * p
        if bit:
            self.low += bound
            self.range -= bound
            probs[ctx] = p - (p >> 5)
        else:
            self.range = bound
            probs[ctx] = p + ((65536 - p) >> 5)
        while self.range < _TOP:
            self.range = (self.range << 8) & _MASK32
            self._shift_low()

    def direct(self, value: int, nbits: int) -> None:
        """``nbits`` equiprobable bits of ``value``, most significant first."""
        for k in range(nbits - 1, -1, -1):
            self.range >>= 1
            if (value >> k) & 1:
                self.low += self.range
            while self.range < _TOP:
                self.range = (self.range << 8) & _MASK32
                self._shift_low()

    def uint(self, model: Model, base: int, value: int, width: int = 32) -> None:
        """Adaptive Elias-gamma code of ``value >= 0``: the bit length of value + 1
        in unary (contexts ``base .. base + width``), then its lower bits raw."""
        if value < 0:
            raise ValueError(f"uint codes values >= 0, got {value}")
        v = value + 1
        n = v.bit_length() - 1
        if n > width:
            raise ValueError(f"{value} needs more than {width} bits")
        for k in range(n):
            self.bit(model, base + k, 1)
        if n < width:
            self.bit(model, base + n, 0)
        self.direct(v - (1 << n), n)

    def finish(self) -> bytes:
        for _ in range(5):
            self._shift_low()
        return bytes(self.out)


class RangeDecoder:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.pos = 5
        if len(data) < 5:
            raise RangeCoderError("entropy-coded block shorter than its 5-byte preamble")
        self.range = _MASK32
        self.code = int.from_bytes(data[1:5], "big")

    def _next(self) -> int:
        pos = self.pos
        self.pos = pos + 1
        if pos >= len(self.data):
            # the decoder reads exactly the bytes the encoder wrote: past the end is corruption
            raise RangeCoderError("entropy-coded block ended early (truncated or corrupt)")
        return self.data[pos]

    def bit(self, model: Model, ctx: int) -> int:
        probs = model.p
        p = probs[ctx]
        bound = (self.range >> 16) * p
        if self.code < bound:
            self.range = bound
            probs[ctx] = p + ((65536 - p) >> 5)
            bit = 0
        else:
            self.code -= bound
            self.range -= bound
            probs[ctx] = p - (p >> 5)
            bit = 1
        while self.range < _TOP:
            self.range = (self.range << 8) & _MASK32
            self.code = ((self.code << 8) | self._next()) & _MASK32
        return bit

    def direct(self, nbits: int) -> int:
        value = 0
        for _ in range(nbits):
            self.range >>= 1
            if self.code >= self.range:
                self.code -= self.range
                value = (value << 1) | 1
            else:
                value <<= 1
            while self.range < _TOP:
                self.range = (self.range << 8) & _MASK32
                self.code = ((self.code << 8) | self._next()) & _MASK32
        return value

    def uint(self, model: Model, base: int, width: int = 32) -> int:
        n = 0
        while n < width and self.bit(model, base + n):
            n += 1
        return (1 << n) + self.direct(n) - 1

    def exhausted(self) -> bool:
        """True when the decoder consumed exactly the encoder's output (a sanity
        check against trailing garbage or a short read)."""
        return self.pos == len(self.data)
