"""Every single-bit edit of a ``.jxm`` header, its checksum recomputed: how long the
decoder works on it, against the clean file's decode time.

    .venv/bin/python experiments/compress/header_edits.py [--mesh fandisk] [--keep 0.1]

The header (after the magic number, before the sections) is edited one bit at a time,
the file's CRC-32 recomputed so that the edit is not caught by it, and the result
decoded.  Reported: how many edits are refused, how many decode (to the same mesh or to
another one), and the slowest decode (or refusal) as a multiple of the clean file's
decode time, with the field it came from.  The target: at most 2×, and no edit decoding
to another mesh.

Writes experiments/results/compress/header_edits.md.
"""

from __future__ import annotations

import argparse
import struct
import sys
import time
import zlib
from collections import Counter
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from jaxmesh.compress import CodecError, compress, decompress  # noqa: E402
from jaxmesh.compress.codec import _HEAD, MAGIC  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "results" / "compress" / "header_edits.md"
#: the header's fields after the magic number, in order, with their struct codes
FIELDS = (("version", "H"), ("flags", "H"), ("vertices", "I"), ("faces", "I"), ("patches", "I"), ("bits", "B"),
          ("keep", "d"), ("step", "d"), ("check", "3d"), ("lengths", "5I"), ("digest", "I"))


def field_of(byte: int) -> str:
    at = len(MAGIC)
    for name, code in FIELDS:
        size = struct.calcsize("<" + code)
        if at <= byte < at + size:
            return name
        at += size
    return "?"


def decode_time(data: bytes):
    start = time.perf_counter()
    try:
        mesh = decompress(data)
    except CodecError as err:
        return time.perf_counter() - start, None, str(err)
    return time.perf_counter() - start, mesh, None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", default="fandisk")
    ap.add_argument("--keep", type=float, default=0.1)
    args = ap.parse_args()
    clean = compress(load(args.mesh), keep=args.keep).data
    base = min(decode_time(clean)[0] for _ in range(3))
    reference = decompress(clean)
    outcomes, slowest = Counter(), (0.0, "", "")
    for byte in range(len(MAGIC), _HEAD.size):
        for bit in range(8):
            data = bytearray(clean)
            data[byte] ^= 1 << bit
            body = bytes(data[:-4])
            data[-4:] = struct.pack("<I", zlib.crc32(body))
            seconds, mesh, error = decode_time(bytes(data))
            if mesh is None:
                kind = "refused"
            elif (np.array_equal(mesh.faces, reference.faces)
                  and np.array_equal(mesh.vertices, reference.vertices)):
                kind = "same mesh"
            else:
                kind = "another mesh"
            outcomes[(field_of(byte), kind)] += 1
            if seconds > slowest[0]:
                slowest = (seconds, field_of(byte), (error or kind)[:80])
    rows = ["# `.jxm` header edits with the checksum recomputed", "",
            "Regenerate: `.venv/bin/python experiments/compress/header_edits.py` (needs ../shared/meshes).", "",
            f"{args.mesh}, keep {args.keep}: {len(clean)} bytes, clean decode {base:.3f} s (best of 3). Every bit of "
            f"the header after the magic number ({8 * (_HEAD.size - len(MAGIC))} edits) flipped in turn, the CRC-32 "
            "recomputed, the file decoded.", "",
            "| field | refused | decodes to the same mesh | decodes to another mesh |", "|---|---|---|---|"]
    for name, _ in FIELDS:
        rows.append(f"| {name} | {outcomes[(name, 'refused')]} | {outcomes[(name, 'same mesh')]} | "
                    f"{outcomes[(name, 'another mesh')]} |")
    rows += ["", f"- slowest: {slowest[0]:.3f} s, **{slowest[0] / base:.2f}×** the clean decode (field "
                 f"`{slowest[1]}`: {slowest[2]})",
             f"- edits decoding to another mesh: **{sum(v for (f, k), v in outcomes.items() if k == 'another mesh')}**"]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(rows) + "\n")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
