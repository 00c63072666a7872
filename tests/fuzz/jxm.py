"""Fuzz suite: mutated ``.jxm`` files through :func:`jaxmesh.compress.decompress`.

Four base files (several patches; umbrella basis with the vertex order kept;
fallback connectivity; boundary loops and a non-manifold vertex) are mutated
by case index ``i``: bit flips (checksum kept or recomputed), truncations,
insertions and deletions inside a section, header fields and inner counts set
to extreme values (2^31, 2^32 − 1, NaN, ±inf, …), a section swapped in from
another file, and lzma payloads replaced by a decompression bomb.  Every
mutation but the plain flips and truncations recomputes the CRC, so it reaches
the decoder proper.

Outcomes: ``valid`` (decoded to the original mesh), ``error`` (``CodecError``),
``forged`` (a different mesh, decoded from bytes whose checksum was forged:
the format's checks are the CRC and the vertex check sums, so a consistent
different file is a different mesh, not a defect), ``silent`` (a different
mesh with the original checksum), ``traceback`` (any other exception).
"""

from __future__ import annotations

import lzma
import struct
import zlib

import numpy as np

KINDS = ("flip", "flip_crc", "truncate", "insert_crc", "delete_crc", "header_crc", "inner_crc", "splice_crc",
         "bomb_crc")
_HEAD = struct.Struct("<8sHHIIIBdd3d5II")
_INT_FIELDS = {3: "V", 4: "F", 5: "parts", 12: "len0", 13: "len1", 14: "len2", 15: "len3", 16: "len4"}
_FLOAT_FIELDS = {7: "keep", 8: "step", 9: "check0", 10: "check1", 11: "check2"}
_EXTREME_INTS = (0, 1, 2, 3, 2**31, 2**31 - 1, 2**32 - 1, 65535)
_EXTREME_FLOATS = (float("nan"), float("inf"), -float("inf"), 0.0, -1.0, 1e300, 1e-300, 5e-324)


def _sphere():
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=2)
    return np.asarray(s.vertices, np.float64), np.asarray(s.faces, np.int64)


def setup():
    import jaxmesh
    from jaxmesh.compress import codec

    v, f = _sphere()
    fin_v = np.vstack([v, [[2.0, 2.0, 2.0]]])  # a fin on an edge: non-manifold, fallback coder
    fin_f = np.vstack([f, [[f[0, 0], f[0, 1], len(v)]]])
    keep = f[:, 2] < 120  # cut a cap: boundary loop
    used = np.unique(f[keep])
    remap = -np.ones(len(v), np.int64)
    remap[used] = np.arange(len(used))
    cap_v, cap_f = v[used], remap[f[keep]]
    # a second copy sharing one vertex: a non-manifold vertex (copy list)
    m = len(cap_v)
    two_v = np.vstack([cap_v, cap_v[1:] + [3.0, 0, 0]])
    two_f = np.vstack([cap_f, np.where(cap_f == 0, 0, cap_f + m - 1)])
    meshes = [
        (v, f, dict(keep=0.4, bits=10, patch_size=50)),
        (v, f, dict(keep=0.5, bits=12, basis="umbrella", preserve_order=True)),
        (fin_v, fin_f, dict(keep=0.5, bits=8)),
        (two_v, two_f, dict(keep=0.3, bits=10, patch_size=60)),
    ]
    bases = []
    for vv, ff, kw in meshes:
        data = codec.compress(jaxmesh.Mesh.from_arrays(vv, ff, warn=False), **kw).data
        ref = codec.decompress(data)
        bases.append((data, np.asarray(ref.vertices), np.asarray(ref.faces)))
    bomb = lzma.compress(b"\0" * (64 * 2**20), preset=6)  # 64 MiB of zeros in ~10 KB
    return {"bases": bases, "bomb": bomb}


def _sections(data: bytes):
    fields = list(_HEAD.unpack_from(data, 0))
    lengths = fields[12:17]
    out, pos = [], _HEAD.size
    for ln in lengths:
        out.append(bytearray(data[pos:pos + ln]))
        pos += ln
    return fields, out


def _pack(fields, sections) -> bytes:
    fields = list(fields)
    fields[12:17] = [len(s) for s in sections]
    body = _HEAD.pack(*fields) + b"".join(bytes(s) for s in sections)
    return body + struct.pack("<I", zlib.crc32(body))


def redigest(data: bytes) -> bytes:
    """``data`` with the header's digest set to what its sections decode to (a forger who
    recomputed it too), so that a check after the digest's is what a forged file meets."""
    from types import SimpleNamespace

    from jaxmesh.compress import codec
    from jaxmesh.compress._sections import SECTION_TABLE, content_digest

    h = codec._parse(data)
    dec = SimpleNamespace(n=h["n"], nf=h["nf"], parts=h["parts"], flags=h["flags"], step=h["step"], digest=None)
    for sec, section in list(zip(SECTION_TABLE, h["sections"]))[:3]:       # connectivity, labels, ranks
        sec.decode(dec, section)
    from jaxmesh.compress.coefficients import decode_coefficients

    blocks = decode_coefficients(h["sections"][3], dec.ranks)
    fields, sections = _sections(data)
    fields[17] = content_digest(dec.faces, dec.labels, dec.ranks, blocks, bytes(sections[4]), h["step"], h["flags"])
    return _pack(fields, sections)


def _with_crc(body: bytes) -> bytes:
    return body + struct.pack("<I", zlib.crc32(body))


def mutate(state, i: int) -> tuple[str, bytes, bool]:
    """(label, mutated bytes, whether the checksum was recomputed) for case ``i``."""
    rng = np.random.default_rng(i)
    b = i % len(state["bases"])
    data = state["bases"][b][0]
    kind = KINDS[(i // len(state["bases"])) % len(KINDS)]
    label = f"base {b} {kind}"
    if kind in ("flip", "flip_crc"):
        buf = bytearray(data if kind == "flip" else data[:-4])
        for _ in range(int(rng.integers(1, 5))):
            pos = int(rng.integers(8, len(buf)))  # magic flips are trivially refused
            buf[pos] ^= 1 << int(rng.integers(8))
        return label, (bytes(buf) if kind == "flip" else _with_crc(bytes(buf))), kind == "flip_crc"
    if kind == "truncate":
        n = int(rng.integers(0, len(data)))
        return f"{label} to {n}", data[:n], False
    fields, secs = _sections(data)
    nonempty = [k for k, s in enumerate(secs) if len(s)]
    if kind in ("insert_crc", "delete_crc"):
        k = int(rng.choice(nonempty))
        s = secs[k]
        pos = int(rng.integers(0, len(s) + 1))
        if kind == "insert_crc":
            secs[k] = s[:pos] + bytearray(rng.integers(0, 256, int(rng.integers(1, 17))).astype(np.uint8)) + s[pos:]
        else:
            secs[k] = s[:pos] + s[pos + int(rng.integers(1, 9)):]
        return f"{label} section {k} at {pos}", _pack(fields, secs), True
    if kind == "header_crc":
        keys = list(_INT_FIELDS) + list(_FLOAT_FIELDS) + [6]
        f = keys[int(rng.integers(len(keys)))]
        if f in _INT_FIELDS:
            val = int(rng.choice(_EXTREME_INTS)) if rng.random() < 0.7 else int(rng.integers(0, 2**32))
            name = _INT_FIELDS[f]
        elif f in _FLOAT_FIELDS:
            val = float(rng.choice(_EXTREME_FLOATS))
            name = _FLOAT_FIELDS[f]
        else:
            val, name = int(rng.integers(0, 256)), "bits"
        fields[f] = val
        body = _HEAD.pack(*fields) + b"".join(bytes(s) for s in secs)  # lengths as set (maybe wrong)
        return f"{label} {name}={val}", _with_crc(body), True
    if kind == "inner_crc":
        conn = secs[0]
        # traversal: [ncopy u32][pairs][components u32][total u32][nf u32]…; fallback: [n u32][nf u32][lzma]
        off = 4 * int(rng.integers(0, 5))
        val = int(rng.choice((2**31, 2**32 - 1, 2**20, 0, 1, 7)))
        if off + 4 <= len(conn):
            conn[off:off + 4] = val.to_bytes(4, "little")
        return f"{label} connectivity word {off // 4}={val}", _pack(fields, secs), True
    if kind == "splice_crc":
        other = state["bases"][(b + 1 + int(rng.integers(len(state["bases"]) - 1))) % len(state["bases"])][0]
        _, osecs = _sections(other)
        k = int(rng.integers(0, 5))
        secs[k] = osecs[k]
        return f"{label} section {k} from another file", _pack(fields, secs), True
    # bomb: an lzma payload that inflates to 64 MiB, in the order section or the fallback block
    if b == 2:
        secs[0] = secs[0][:8] + bytearray(state["bomb"])
    else:
        secs[4] = bytearray(state["bomb"])
        fields[2] |= 4
    return f"{label} lzma bomb", _pack(fields, secs), True


def case(state, i: int):
    from jaxmesh.compress.codec import CodecError, decompress

    label, data, forged = mutate(state, i)
    _, v0, f0 = state["bases"][i % len(state["bases"])]
    try:
        mesh = decompress(data)
    except MemoryError:
        raise  # the harness reports it as a blown memory budget
    except CodecError as err:
        msg = str(err)
        return label, ("error", msg) if msg else ("traceback", "CodecError without a message")
    except Exception as err:  # noqa: BLE001 - anything else is a defect
        return label, ("traceback", f"{type(err).__name__}: {err}")
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    if v.shape == v0.shape and f.shape == f0.shape and np.array_equal(v, v0) and np.array_equal(f, f0):
        return label, "valid"
    return label, ("forged" if forged else "silent", f"decoded {v.shape[0]} vertices, {f.shape[0]} faces")
