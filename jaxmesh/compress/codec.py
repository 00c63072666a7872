"""The ``.jxm`` spectral mesh codec: connectivity lossless, geometry as quantized
spectral coefficients per METIS patch (thesis ch.3 with Karni & Gotsman's patches).

Encoding (``compress``):

1. the connectivity is coded losslessly (:mod:`.connectivity`); the decoded
   vertex order is the traversal order, and everything below uses it;
2. the vertex graph is cut into patches of about ``patch_size`` vertices
   (:mod:`.patches`; one patch if the mesh is small);
3. each patch p with m_p vertices gets the basis B_p of its r_p = ⌈keep·m_p⌉
   lowest modes (:mod:`.basis`; r_p grows to the end of an eigenvalue cluster);
4. its coefficients C_p = (B_pᵀB_p)⁺B_pᵀV_p (eq.5; = B_pᵀV_p for the orthonormal
   Laplacian basis) are quantized uniformly, q = round(C / s), with step
   s = (largest bounding-box side) · 2^-bits, and range coded (context: the
   magnitude of the previous coefficient of the same patch and axis);
5. the decoder rebuilds every B_p from the connectivity and returns
   V̂_p = B_p q s.  The encoder computes the same V̂ and stores three weighted
   sums of it; the decoder checks them, so a basis that some other machine's
   LAPACK reproduced differently is an error, not a wrong mesh.

File layout (little-endian)::

    magic      8 bytes  b"\\x89JXM\\r\\n\\x1a\\n"
    version    u16      FORMAT_VERSION
    flags      u16      bit 0 fallback connectivity, bit 1 umbrella basis, bit 2 vertex order kept
    V, F       u32 u32  vertex and face counts
    parts      u32      number of patches
    bits       u8       quantization bits
    keep       f64      fraction of coefficients kept (informational)
    step       f64      quantization step s
    check      3 × f64  Σ_i g_i v̂_i, g fixed weights in [−1, 1)
    lengths    5 × u32  connectivity, labels, ranks, coefficients, order sections
    digest     u32      CRC-32 of what the sections decode to (version 2; ``_sections.content_digest``)
    sections   …
    crc32      u32      of every byte before it

Any byte changed, missing or added is reported as :class:`CodecError` with the
reason (bad magic, newer version, truncated, checksum mismatch, inconsistent
section), never decoded into a wrong mesh.  The digest covers the decoded
connectivity, patch labels, ranks and quantized coefficients, the order section, the
step and the flags, and is checked before the eigenproblems are solved: an edit whose
file checksum was recomputed (a forged or repaired file) is refused too, at a fraction
of a clean decode's cost.  Version-1 files (no digest) still decode, with the other
checks.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from .._eigen import fixed_vectors
from ..graph import adjacency_from_faces
from ..mesh import Mesh
from ..metrics import rms_vertex_error
from ..transforms import far_vertices
from . import basis as _basis
from . import connectivity as _conn
from . import patches as _patches
from ._sections import _FALLBACK, _ORDER, _UMBRELLA, SECTION_TABLE, _patch_bases, _reconstruct, content_digest
from .coefficients import CodecError
from .rangecoder import RangeCoderError

__all__ = ["MAGIC", "FORMAT_VERSION", "SECTIONS", "MAX_PATCH_SIZE", "CodecError", "Compressed", "auto_patch_size",
           "compress", "decompress", "inspect"]

MAGIC = b"\x89JXM\r\n\x1a\n"
FORMAT_VERSION = 2
#: the largest ``patch_size``: a patch's eigensolve costs about patch² × keep in time and
#: patch × keep vectors in memory (10 000 vertices at keep = 0.1: about 0.2 GB; one patch of
#: a 500k-vertex scan, about 200 GB).
MAX_PATCH_SIZE = 10_000
#: the file's sections, in file order: the header stores their byte lengths in this order
SECTIONS = tuple(sec.name for sec in SECTION_TABLE)
_HEAD = struct.Struct(f"<8sHHIIIBdd3d{len(SECTIONS)}II")
_HEAD_V1 = struct.Struct(f"<8sHHIIIBdd3d{len(SECTIONS)}I")


def _check_sums(vertices: np.ndarray) -> np.ndarray:
    g = fixed_vectors(len(vertices), 1, salt=99)[:, 0]
    return g @ vertices


@dataclass(frozen=True)
class Compressed:
    """What :func:`compress` returns.

    ``data``: the file's bytes; ``mesh``: the reconstruction exactly as
    :func:`decompress` returns it; ``order``: (V,) original index of each vertex
    of ``mesh`` (the identity when the vertex order is kept); ``stats``: sizes
    in bytes and bits per vertex per section, ranks, patches, connectivity coder.
    """

    data: bytes
    mesh: Mesh
    order: np.ndarray
    stats: dict = field(default_factory=dict)

    @property
    def bits_per_vertex(self) -> float:
        return 8 * len(self.data) / self.mesh.num_vertices

    def vertex_errors(self, original: Mesh) -> np.ndarray:
        """Distance of each reconstructed vertex to the ``original`` vertex it codes
        (matched through ``order``), in the reconstruction's vertex order."""
        recon = np.asarray(self.mesh.vertices, np.float64)
        return np.linalg.norm(recon - np.asarray(original.vertices, np.float64)[self.order], axis=-1)

    def relative_error(self, original: Mesh) -> float:
        """RMS vertex error of the reconstruction against ``original`` (matched through
        ``order``), over the bounding-box diagonal of ``original``."""
        v = np.asarray(original.vertices, np.float64)
        inv = np.empty_like(self.order)
        inv[self.order] = np.arange(len(self.order))
        recon = np.asarray(self.mesh.vertices, np.float64)[inv]
        diag = float(np.linalg.norm(v.max(0) - v.min(0)))
        err = float(rms_vertex_error(original.with_vertices(v), recon))
        return err / diag if diag > 0 else 0.0



# --------------------------------------------------------------------------- public
def auto_patch_size(keep: float) -> int:
    """Default patch size: about 100 modes per patch, between 1 000 and 3 000 vertices.

    Bigger patches compress better (fewer seams, fewer label bits: on the bunny at
    keep = 0.02, 1.77 bits/vertex with 5 000-vertex patches against 2.02 with
    1 000) but the eigensolve grows with patch size × modes; at ~100 modes a
    patch costs ~0.1–0.3 s.

    Arguments:
        keep: the fraction of coefficients kept, in (0, 1].

    Returns:
        The target patch size in vertices, between 1 000 and 3 000."""
    return int(np.clip(round(100 / keep), 1000, 3000))


def _check_arguments(mesh: Mesh, keep, bits, basis, patch_size) -> int:
    """Refuse bad arguments with the reason; returns the patch size to use."""
    if mesh.batch_shape:
        raise ValueError(f"compress needs a single mesh, got batch shape {mesh.batch_shape}")
    if not (isinstance(keep, (int, float)) and 0 < keep <= 1):
        raise ValueError(f"keep must be in (0, 1], got {keep!r}")
    if not (isinstance(bits, (int, np.integer)) and 1 <= bits <= 30):
        raise ValueError(f"bits must be an integer in [1, 30], got {bits!r}")
    if basis not in _basis.KINDS:
        raise ValueError(f"basis must be one of {_basis.KINDS}, got {basis!r}")
    far = far_vertices(mesh)
    if far.size:
        raise ValueError(f"vertex {int(far[0])} lies far from the rest ({far.size} such: a corrupt coordinate?): the "
                         "quantization step, the largest side / 2^bits, would erase every other coordinate; "
                         "remove it first")
    if patch_size is None:
        patch_size = auto_patch_size(keep)
    if not (isinstance(patch_size, (int, np.integer)) and 16 <= patch_size <= MAX_PATCH_SIZE):
        raise ValueError(f"patch_size must be an integer in [16, {MAX_PATCH_SIZE}] (the eigensolve grows as "
                         f"patch² × keep), got {patch_size!r}")
    return int(patch_size)


def compress(mesh: Mesh, keep: float = 0.1, bits: int = 12, *, basis: str = "laplacian",
             patch_size: int | None = None, preserve_order: bool = False,
             dense_max: int = 1200) -> Compressed:
    """Encode ``mesh`` to ``.jxm`` bytes (see the module doc for the format).
    Meshes with unused vertices are refused (remove them first).

    Arguments:
        mesh: the mesh (single).
        keep: fraction of each patch's spectral coefficients kept, in (0, 1].
        bits: quantization step = largest bounding-box side · 2^-bits, in [1, 30].
        basis: ``"laplacian"`` (Karni–Gotsman, default) or ``"umbrella"`` (the
            thesis's K).
        patch_size: target vertices per METIS patch, 16 to :data:`MAX_PATCH_SIZE` (:func:`auto_patch_size`).
        preserve_order: also store the vertex permutation (≈ log2 V bits per vertex)
            so that :func:`decompress` returns the original vertex order (the faces
            are the same oriented triangles, in the decoder's order).
        dense_max: patches up to this many vertices use a dense eigensolver.

    Returns:
        A :class:`Compressed`: the bytes, the reconstruction exactly as
        :func:`decompress` returns it, the vertex order and the size statistics."""
    patch_size = _check_arguments(mesh, keep, bits, basis, patch_size)
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces, np.int64)
    n = len(v)
    unused = np.setdiff1d(np.arange(n), f.reshape(-1))
    if unused.size:
        raise ValueError(f"{unused.size} vertices are used by no face (first: {int(unused[0])}); "
                         "remove them before compressing")
    code = _conn.encode_connectivity(f, n)
    order = code.order
    faces_d = code.faces
    vd = v[order]
    adjacency = adjacency_from_faces(faces_d, n)
    labels = _patches.partition(adjacency, patch_size)
    bases = _patch_bases(adjacency, labels, float(keep), basis, dense_max)
    extent = float((v.max(0) - v.min(0)).max())
    step = (extent if extent > 0 else 1.0) * 2.0 ** -int(bits)
    blocks = []
    for index, vecs in bases:
        if basis == "laplacian":
            c = vecs.T @ vd[index]
        else:
            c = np.linalg.lstsq(vecs, vd[index], rcond=None)[0]
        blocks.append(np.rint(c / step).astype(np.int64))
    recon = _reconstruct(bases, blocks, step, n)
    enc = SimpleNamespace(code=code, labels=labels, adjacency=adjacency, ranks=[b.shape[0] for b in blocks],
                          blocks=blocks, order=order, preserve_order=preserve_order)
    sections = [sec.encode(enc) for sec in SECTION_TABLE]
    ranks = enc.ranks
    out_faces, out_vertices, out_order = faces_d, recon, order
    if preserve_order:
        inv = np.empty(n, np.int64)
        inv[order] = np.arange(n)
        out_faces, out_vertices, out_order = order[faces_d], recon[inv], np.arange(n)
    flags = (_FALLBACK if code.fallback else 0) | (_UMBRELLA if basis == "umbrella" else 0)
    for sec, data in zip(SECTION_TABLE, sections):
        flags |= sec.flag if data else 0
    digest = content_digest(faces_d, labels, ranks, blocks, sections[-1], step, flags)
    head = _HEAD.pack(MAGIC, FORMAT_VERSION, flags, n, len(f), len(ranks), int(bits), float(keep),
                      step, *_check_sums(out_vertices).tolist(), *(len(s) for s in sections), digest)
    body = head + b"".join(sections)
    data = body + struct.pack("<I", zlib.crc32(body))
    out_mesh = Mesh.from_arrays(out_vertices, out_faces, warn=False)
    sizes = dict(zip(SECTIONS, map(len, sections)))
    sizes["header"] = _HEAD.size + 4
    stats = {
        "bytes": len(data),
        "bits_per_vertex": 8 * len(data) / n,
        "section_bytes": sizes,
        "section_bits_per_vertex": {k: 8 * s / n for k, s in sizes.items()},
        "connectivity_coder": "fallback" if code.fallback else "traversal",
        "connectivity_note": code.reason,
        "patches": len(ranks),
        "coefficients": int(sum(ranks)),
        "basis": basis,
        "patch_size": patch_size,
        "step": step,
    }
    return Compressed(data=data, mesh=out_mesh, order=out_order, stats=stats)


def _parse(data: bytes):
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"decompress needs bytes, got {type(data).__name__}")
    data = bytes(data)
    if len(data) < len(MAGIC) or data[:len(MAGIC)] != MAGIC:
        raise CodecError("not a jaxmesh compressed mesh (bad magic number)")
    if len(data) < 10:
        raise CodecError("truncated file: the header is incomplete")
    version = struct.unpack_from("<H", data, 8)[0]
    if version > FORMAT_VERSION:
        raise CodecError(f"format version {version} was written by a newer jaxmesh; this one reads "
                         f"versions up to {FORMAT_VERSION}")
    if version < 1:
        raise CodecError(f"invalid format version {version}")
    head = _HEAD if version >= 2 else _HEAD_V1
    if len(data) < head.size + 4:
        raise CodecError(f"truncated file: {len(data)} bytes, shorter than the {head.size + 4}-byte header")
    fields = head.unpack_from(data, 0)
    lengths = fields[12:12 + len(SECTIONS)]
    expected = head.size + sum(lengths) + 4
    if len(data) < expected:
        raise CodecError(f"truncated file: {len(data)} bytes, the header announces {expected}")
    if len(data) > expected:
        raise CodecError(f"{len(data) - expected} unexpected bytes after the end of the compressed mesh")
    (crc,) = struct.unpack_from("<I", data, expected - 4)
    if zlib.crc32(data[:expected - 4]) != crc:
        raise CodecError("checksum mismatch: the file is corrupt")
    _, _, flags, n, nf, parts, bits, keep, step = fields[:9]
    if flags & ~(_FALLBACK | _UMBRELLA | _ORDER):
        raise CodecError(f"unknown flags {flags:#x}")
    if not 1 <= bits <= 30:
        raise CodecError(f"invalid quantization bits {bits} (corrupt header)")
    if not (np.isfinite(step) and step > 0):
        raise CodecError(f"invalid quantization step {step!r} (corrupt header)")
    if not 0 < keep <= 1:
        raise CodecError(f"invalid kept fraction {keep!r} (corrupt header)")
    if not np.isfinite(fields[9:12]).all():
        raise CodecError("non-finite reconstruction check (corrupt header)")
    if n < 3 or nf < 1:
        raise CodecError(f"invalid counts: {n} vertices, {nf} faces (corrupt header)")
    sections, pos = [], head.size
    for ln in lengths:
        sections.append(data[pos:pos + ln])
        pos += ln
    return dict(version=version, flags=flags, n=n, nf=nf, parts=parts, bits=bits, keep=keep, step=step,
                check=np.asarray(fields[9:12]), sections=sections, size=len(data),
                digest=fields[12 + len(SECTIONS)] if version >= 2 else None)


def inspect(data: bytes) -> dict:
    """Header fields and section sizes of ``.jxm`` bytes (validated, not decoded).

    Arguments:
        data: ``.jxm`` bytes.

    Returns:
        A JSON-ready dict of the header fields and section sizes."""
    h = _parse(data)
    return {
        "format_version": h["version"],
        "vertices": h["n"], "faces": h["nf"], "patches": h["parts"], "bits": h["bits"],
        "keep": h["keep"], "step": h["step"],
        "basis": "umbrella" if h["flags"] & _UMBRELLA else "laplacian",
        "connectivity_coder": "fallback" if h["flags"] & _FALLBACK else "traversal",
        "vertex_order_kept": bool(h["flags"] & _ORDER),
        "bytes": h["size"], "bits_per_vertex": 8 * h["size"] / max(h["n"], 1),
        "section_bytes": dict(zip(SECTIONS, map(len, h["sections"]))),
    }


def decompress(data: bytes, *, dense_max: int = 1200) -> Mesh:
    """The mesh coded in ``.jxm`` bytes.  Raises :class:`CodecError` naming the
    problem for foreign, truncated, corrupt or unsupported data.

    Arguments:
        data: ``.jxm`` bytes (untrusted: every count and size is checked before use).
        dense_max: matrices up to this size use a dense symmetric eigensolver, larger ones ARPACK.

    Returns:
        The decoded :class:`~jaxmesh.Mesh`."""
    h = _parse(data)
    dec = SimpleNamespace(n=h["n"], nf=h["nf"], parts=h["parts"], flags=h["flags"], step=h["step"],
                          kind="umbrella" if h["flags"] & _UMBRELLA else "laplacian", dense_max=dense_max,
                          digest=h["digest"], order_section=h["sections"][-1])
    for sec, section in zip(SECTION_TABLE, h["sections"]):
        if sec.flag and not h["flags"] & sec.flag and section:
            raise CodecError(f"the {sec.name} section has bytes but the header's flags say it is absent "
                             "(corrupt file)")
    try:
        for sec, section in zip(SECTION_TABLE, h["sections"]):
            if not sec.flag or h["flags"] & sec.flag:
                sec.decode(dec, section)
    except (_conn.ConnectivityError, RangeCoderError, ValueError) as err:
        if isinstance(err, CodecError):
            raise
        raise CodecError(f"corrupt compressed mesh: {err}") from err
    vertices, faces, n = dec.vertices, dec.faces, dec.n
    if not np.isfinite(vertices).all():
        raise CodecError("the coefficients decode to non-finite coordinates (corrupt file)")
    tol = 1e-3 * h["step"] * np.sqrt(n) + 1e-9 * np.abs(vertices).max() * np.sqrt(n)
    if not np.abs(_check_sums(vertices) - h["check"]).max() <= tol:
        raise CodecError("reconstruction check failed: this machine did not reproduce the encoder's "
                         "spectral basis (different eigensolver results)")
    try:
        return Mesh.from_arrays(vertices, faces, warn=False)
    except ValueError as err:
        raise CodecError(f"the decoded mesh is invalid (corrupt file): {err}") from err
