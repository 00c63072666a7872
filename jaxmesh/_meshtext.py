"""Strict readers and lossless writers for OBJ, OFF and STL (ASCII and binary).

Readers take the file's bytes and return ``(vertices (m, 3) float64, faces (n, 3)
int64, records, polygons)``: the file's face records, of which ``polygons`` have
more than three corners (they are fan-triangulated).  They raise :class:`ValueError` with the line number
and the problem for anything they cannot read exactly:

* a number that does not parse, a face with fewer than three corners, an index
  of 0 (OBJ counts from 1) or outside the vertex list;
* fewer vertices or faces than an OFF header declares, content after them;
* an ASCII STL without ``endsolid`` or a binary STL whose size does not match
  its triangle count;
* a file whose last data line has no line end: a file cut in the middle of a
  number (``v 0.5 1.25`` cut to ``v 0.5 1.2``) reads as a different, valid mesh,
  so an unterminated last line is taken for a truncation.

Text is decoded as UTF-8 after removing a byte-order mark; bytes that are not
UTF-8 (a Latin-1 comment) are kept as escapes and only matter if they are part
of a number.  Writers print ``%.17g``, which round-trips every float64 exactly;
binary STL stores float32 by definition of the format.
"""

from __future__ import annotations

import numpy as np

__all__ = ["read_obj", "read_off", "read_stl", "write_obj", "write_off", "write_stl", "check_ply_header"]

_BOMS = (b"\xef\xbb\xbf",)
# statements of the OBJ specification that carry no triangle data (ignored); any other is an error,
# since a corrupted "v" or "f" would otherwise silently drop a vertex and shift every index after it
_OBJ_IGNORED = frozenset(
    "vt vn vp l p g o s mg usemtl mtllib maplib usemap lod shadow_obj trace_obj ctech stech bevel c_interp "
    "d_interp cstype deg bmat step curv curv2 surf parm trim hole scrv sp end con call csh".split())


def _text(data: bytes) -> str:
    if data.startswith(b"\xff\xfe") or data.startswith(b"\xfe\xff"):
        return data.decode("utf-16")
    for bom in _BOMS:
        if data.startswith(bom):
            data = data[len(bom):]
    return data.decode("utf-8", errors="surrogateescape")


def _lines(text: str, comment: str = "#"):
    """(line number, content without comment, stripped) for non-empty lines, and
    whether the last data line was terminated."""
    raw = text.split("\n")
    out = []
    for k, line in enumerate(raw, 1):
        body = line.split(comment, 1)[0].strip()
        if body:
            out.append((k, body))
    terminated = not out or out[-1][0] < len(raw)  # "…\n" splits into a last empty string
    return out, terminated


def _truncated(where: str) -> ValueError:
    return ValueError(f"{where}: the last line has no line end; the file looks truncated "
                      "(if it is complete, end it with a newline)")


def _floats(tokens, k: int, what: str) -> list[float]:
    if len(tokens) < 3:
        raise ValueError(f"line {k}: {what} needs 3 coordinates, got {len(tokens)}")
    try:
        return [float(t) for t in tokens[:3]]
    except ValueError:
        raise ValueError(f"line {k}: {what} coordinate is not a number: {' '.join(tokens[:3])!r}") from None


def _fan(corners: list[int]) -> list[list[int]]:
    return [[corners[0], corners[i], corners[i + 1]] for i in range(1, len(corners) - 1)]


def _check_indices(faces: np.ndarray, n: int, base: int, lines: np.ndarray):
    bad = (faces < 0) | (faces >= n)
    if bad.any():
        row = int(np.flatnonzero(bad.any(axis=1))[0])
        idx = int(faces[row][bad[row]][0]) + base
        raise ValueError(f"line {int(lines[row])}: vertex index {idx} is out of range "
                         f"({base}..{n - 1 + base} for {n} vertices)")


def _lines_of_kind(buf: np.ndarray, starts: np.ndarray, ends: np.ndarray, chosen: np.ndarray) -> bytes:
    """The bytes of the chosen lines (line ends included), concatenated."""
    delta = np.zeros(len(buf) + 1, np.int8)
    delta[starts[chosen]] += 1
    delta[ends[chosen] + 1] -= 1
    return buf[np.cumsum(delta[:-1], dtype=np.int8) > 0].tobytes()


def _only_ignored(buf: np.ndarray, starts: np.ndarray, ends: np.ndarray, other: np.ndarray) -> bool:
    """Whether every other line is blank, a comment or an ignored statement, read as :func:`read_obj`
    reads it (the part before ``#``, stripped, up to its first space), on each line's first 16 bytes;
    False where those do not settle it."""
    if not other.any():
        return True
    heads = np.minimum(starts[other][:, None] + np.arange(16), ends[other][:, None])
    for row in np.unique(buf[heads], axis=0):
        raw = row.tobytes()
        head = raw.split(b"\n", 1)[0]
        if any(c >= 0x80 or 0x1C <= c <= 0x1F for c in head):
            return False
        body = head.split(b"#", 1)[0].strip()
        complete = b"\n" in raw or b"#" in head
        if not body and complete:
            continue
        key, space, _ = body.partition(b" ")
        if not (space or complete) or key.decode("ascii") not in _OBJ_IGNORED:
            return False
    return True


def _obj_lines(data: bytes):
    """(bytes as uint8, line starts, line ends, ``v`` lines, ``f`` lines) of an OBJ without a
    byte-order mark's encodings, tabs or line continuations that ends with a line end; else None."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if (not data.endswith(b"\n") or b"\\" in data or b"\t" in data or data.startswith((b"\xff\xfe", b"\xfe\xff"))):
        return None
    buf = np.frombuffer(data, np.uint8)
    ends = np.flatnonzero(buf == ord("\n"))
    starts = np.concatenate(([0], ends[:-1] + 1))
    key = np.where(buf[np.minimum(starts + 1, len(buf) - 1)] == ord(" "), buf[starts], 0)
    key[starts == ends] = 0
    return buf, starts, ends, key == ord("v"), key == ord("f")


def only_positions_and_triangles(data: bytes) -> bool:
    """Whether an OBJ holds ``v x y z`` and ``f a b c`` lines (plain indices), comments and blank
    lines, and nothing else (vectorised; False where that is not certain)."""
    lines = _obj_lines(data)
    if lines is None or b"/" in data:
        return False
    buf, starts, ends, is_v, is_f = lines
    other = ~(is_v | is_f)
    if not np.all((starts[other] == ends[other]) | (buf[np.minimum(starts[other], len(buf) - 1)] == ord("#"))):
        return False
    word = (buf != ord(" ")) & (buf != ord("\n")) & (buf != ord("\r"))
    begins = word & ~np.concatenate(([False], word[:-1]))             # the first byte of each token
    tokens = np.add.reduceat(begins.astype(np.int64), starts) if len(starts) else starts
    return bool(np.all(tokens[is_v | is_f] == 4))


def _plain_obj(data: bytes):
    """The fast reading of a plain OBJ, or None where the file is not one: every vertex line
    ``v x y z`` and every face line ``f a b c`` (positive indices, ``a/t/n`` corners allowed) with
    nothing else on it, no tabs or line continuations, every other line blank, a comment or an
    ignored statement, the file ending with a line end.  The lines are sorted with numpy and each
    number goes through the same ``float`` and ``int`` as in :func:`read_obj`, so a plain file reads
    the same either way; anything else (and every error) is left to :func:`read_obj`."""
    lines = _obj_lines(data)
    if lines is None:
        return None
    buf, starts, ends, is_v, is_f = lines
    if not _only_ignored(buf, starts, ends, ~(is_v | is_f)):
        return None
    nv, nf = int(is_v.sum()), int(is_f.sum())
    v_tokens = _lines_of_kind(buf, starts, ends, is_v).split()
    f_tokens = _lines_of_kind(buf, starts, ends, is_f).split()
    if (len(v_tokens) != 4 * nv or len(f_tokens) != 4 * nf
            or v_tokens[::4].count(b"v") != nv or f_tokens[::4].count(b"f") != nf):
        return None           # a line with other than three numbers, or a comment after them
    del v_tokens[::4], f_tokens[::4]
    try:
        vertices = np.array(list(map(float, v_tokens)), np.float64).reshape(-1, 3)
        corners = f_tokens if b"/" not in data else [t.partition(b"/")[0] for t in f_tokens]
        faces = np.array(list(map(int, corners)), np.int64).reshape(-1, 3)
    except ValueError:
        return None
    if faces.size and (faces.min() < 1 or faces.max() > len(vertices)):
        return None           # 0, relative or out-of-range indices: read_obj says which line
    return vertices, faces - 1, len(faces), 0


def read_obj(data: bytes):
    plain = _plain_obj(data)
    if plain is not None:
        return plain
    text = _text(data).replace("\\\n", " ")  # line continuations
    lines, terminated = _lines(text)
    verts, faces, face_line, polys = [], [], [], 0
    for k, body in lines:
        key, _, rest = body.replace("\t", " ").partition(" ")
        if key == "v":
            verts.append(_floats(rest.split(), k, "vertex"))
        elif key == "f":
            corners = []
            for tok in rest.split():
                head = tok.split("/", 1)[0]
                try:
                    i = int(head)
                except ValueError:
                    raise ValueError(f"line {k}: face index {tok!r} is not an integer") from None
                if i == 0:
                    raise ValueError(f"line {k}: face index 0 (OBJ indices start at 1)")
                if i < 0 and len(verts) + i < 0:
                    raise ValueError(f"line {k}: relative index {i} points before the first vertex "
                                     f"({len(verts)} read so far)")
                corners.append(i - 1 if i > 0 else len(verts) + i)
            if len(corners) < 3:
                raise ValueError(f"line {k}: a face needs at least 3 vertices, got {len(corners)}")
            polys += len(corners) > 3
            tri = _fan(corners)
            faces += tri
            face_line += [k] * len(tri)
        elif key not in _OBJ_IGNORED:
            raise ValueError(f"line {k}: unknown OBJ statement {key[:20]!r}")
    if not terminated and lines and lines[-1][1].split(None, 1)[0] in ("v", "f"):
        raise _truncated(f"line {lines[-1][0]}")
    v = np.asarray(verts, np.float64).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    _check_indices(f, len(v), 1, np.asarray(face_line))
    return v, f, len(set(face_line)), polys


def read_off(data: bytes):
    lines, terminated = _lines(_text(data))
    if not lines:
        raise ValueError("no OFF header")
    k0, first = lines[0]
    head = first.split()
    if not head[0].upper().endswith("OFF"):
        raise ValueError(f"line {k0}: expected an OFF header, got {first[:40]!r}")
    counts, pos = head[1:], 1
    if not counts:
        if len(lines) < 2:
            raise ValueError("the OFF header has no vertex and face counts")
        k0, second = lines[1]
        counts, pos = second.split(), 2
    try:
        nv, nf = int(counts[0]), int(counts[1])
    except (ValueError, IndexError):
        raise ValueError(f"line {k0}: expected 'vertices faces edges' counts, got {' '.join(counts)!r}") from None
    if nv < 0 or nf < 0:
        raise ValueError(f"line {k0}: negative counts {nv} {nf}")
    if len(lines) - pos < nv + nf:
        raise ValueError(f"the header declares {nv} vertices and {nf} faces; the file has only "
                         f"{len(lines) - pos} data lines (truncated?)")
    if len(lines) - pos > nv + nf:
        k, extra = lines[pos + nv + nf]
        raise ValueError(f"line {k}: content after the {nv} vertices and {nf} faces the header declares: "
                         f"{extra[:40]!r}")
    verts = [_floats(body.split(), k, "vertex") for k, body in lines[pos:pos + nv]]
    faces, face_line, polys = [], [], 0
    for k, body in lines[pos + nv:]:
        tok = body.split()
        try:
            m = int(tok[0])
            corners = [int(t) for t in tok[1:1 + m]]
        except ValueError:
            raise ValueError(f"line {k}: face is not a list of integers: {body[:40]!r}") from None
        if m < 3 or len(corners) < m:
            raise ValueError(f"line {k}: face declares {m} vertices and lists {len(corners)} (need >= 3)")
        polys += m > 3
        tri = _fan(corners)
        faces += tri
        face_line += [k] * len(tri)
    if not terminated:
        raise _truncated(f"line {lines[-1][0]}")
    v = np.asarray(verts, np.float64).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    _check_indices(f, len(v), 0, np.asarray(face_line))
    return v, f, nf, polys


def _binary_stl(data: bytes):
    n = int.from_bytes(data[80:84], "little")
    if len(data) != 84 + 50 * n:
        raise ValueError(f"binary STL of {n} triangles should be {84 + 50 * n} bytes, the file has "
                         f"{len(data)} (truncated or corrupt)")
    rec = np.frombuffer(data, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")], count=n, offset=84)
    v = rec["v"].reshape(-1, 3).astype(np.float64)
    return v, np.arange(3 * n, dtype=np.int64).reshape(-1, 3), n, 0


def read_stl(data: bytes):
    """Triangles as 3 separate vertices each (merge duplicates afterwards)."""
    if len(data) >= 84 and len(data) == 84 + 50 * int.from_bytes(data[80:84], "little"):
        return _binary_stl(data)
    if data.startswith((b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff")):  # a byte-order mark: text?
        text = _text(data).encode("utf-8", errors="surrogateescape")
        if text.lstrip()[:5].lower() == b"solid":
            data = text
    if data.lstrip()[:5].lower() != b"solid":
        if len(data) < 84:
            raise ValueError(f"{len(data)} bytes: too short for a binary STL and not an ASCII one")
        return _binary_stl(data)
    lines, terminated = _lines(_text(data), comment="\0")
    verts, facets, ended = [], 0, False
    for k, body in lines:
        key = body.split(None, 1)[0].lower()
        if key == "vertex":
            verts.append(_floats(body.split()[1:], k, "vertex"))
        elif key == "endfacet":
            facets += 1
            if len(verts) != 3 * facets:
                raise ValueError(f"line {k}: facet {facets} has {len(verts) - 3 * (facets - 1)} vertices, not 3")
        elif key == "endsolid":
            ended = True
    if not ended:
        raise ValueError("ASCII STL without 'endsolid' (truncated?)")
    if len(verts) != 3 * facets:
        raise ValueError("ASCII STL ends inside a facet (truncated?)")
    v = np.asarray(verts, np.float64).reshape(-1, 3)
    return v, np.arange(len(v), dtype=np.int64).reshape(-1, 3), facets, 0


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def check_ply_header(data: bytes) -> dict[str, int]:
    """Element counts of a PLY header, checked against the bytes that follow it
    (before a reader allocates anything): binary elements need at least their
    fixed-size part, ASCII ones a line each.  Returns {element: count}."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError("not a PLY file (no 'ply' magic or no 'end_header')")
    nl = data.find(b"\n", end)
    body = len(data) - (nl + 1 if nl >= 0 else len(data))
    fmt, elements = None, []
    for k, line in enumerate(data[:end].decode("ascii", "replace").splitlines(), 1):
        tok = line.split()
        if not tok or tok[0] in ("ply", "comment", "obj_info"):
            continue
        if tok[0] == "format" and len(tok) >= 2:
            fmt = tok[1]
        elif tok[0] == "element" and len(tok) == 3:
            try:
                count = int(tok[2])
            except ValueError:
                raise ValueError(f"header line {k}: element count {tok[2]!r} is not an integer") from None
            if count < 0:
                raise ValueError(f"header line {k}: negative element count {count}")
            elements.append([tok[1], count, 0])
        elif tok[0] == "property" and elements and len(tok) >= 3:
            if tok[1] == "list":
                if len(tok) != 5 or tok[2] not in _PLY_SIZES or tok[3] not in _PLY_SIZES:
                    raise ValueError(f"header line {k}: bad list property {line!r}")
                elements[-1][2] += _PLY_SIZES[tok[2]]
            elif tok[1] in _PLY_SIZES:
                elements[-1][2] += _PLY_SIZES[tok[1]]
            else:
                raise ValueError(f"header line {k}: unknown property type {tok[1]!r}")
        else:
            raise ValueError(f"header line {k}: cannot parse {line[:40]!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ValueError(f"unknown PLY format {fmt!r}")
    if fmt == "ascii":
        need = sum(c for _, c, _ in elements)
        have = data[nl + 1:].count(b"\n") + 1 if nl >= 0 else 0
        unit = "lines"
    else:
        need = sum(c * size for _, c, size in elements)
        have, unit = body, "bytes"
    if need > have:
        counts = ", ".join(f"{c} {name}" for name, c, _ in elements)
        raise ValueError(f"the header declares {counts}, which need at least {need} {unit}; the file has "
                         f"{have} after the header (truncated or corrupt)")
    return {name: c for name, c, _ in elements}


def _rows(fmt: str, a: np.ndarray) -> str:
    return "".join(fmt % tuple(r) for r in a.tolist())


def write_obj(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    return ("# written by jaxmesh\n" + _rows("v %.17g %.17g %.17g\n", vertices)
            + _rows("f %d %d %d\n", faces + 1)).encode("ascii")


def write_off(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    return (f"OFF\n{len(vertices)} {len(faces)} 0\n" + _rows("%.17g %.17g %.17g\n", vertices)
            + _rows("3 %d %d %d\n", faces)).encode("ascii")


def write_stl(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """Binary STL (float32 by the format's definition); raises if a coordinate
    does not fit in float32."""
    big = np.abs(vertices).max(initial=0.0)
    if big > np.finfo(np.float32).max:
        raise ValueError(f"a coordinate of magnitude {big:.3g} does not fit in STL's float32; "
                         "use PLY, OBJ or OFF")
    tri = vertices[faces].astype(np.float32)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 0, n / np.where(length > 0, length, 1), 0).astype(np.float32)
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tri
    head = b"binary STL written by jaxmesh".ljust(80, b" ")
    return head + len(faces).to_bytes(4, "little") + rec.tobytes()
