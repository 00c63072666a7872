"""A numpy reader for the common binary PLY layout.

Most binary PLY files in circulation (every scanner export, trimesh's, Open3D's,
jaxmesh's own) store a ``vertex`` element of fixed-size properties and a ``face``
element whose only list is ``vertex_indices`` with three corners per face.  Such
a body is two fixed-size record arrays, which :func:`numpy.frombuffer` views in
place: no per-face Python work.  :func:`read_binary` reads exactly that layout
and returns ``None`` for anything else (ASCII, polygons, other lists, elements
of variable size before the faces), which the caller then hands to a general
reader (trimesh).

The header's counts are checked against the file's size before anything is
allocated (:func:`jaxmesh._meshtext.check_ply_header` runs first), and the face
records' corner counts are all checked to be 3: a count read from the file is
never trusted to size anything by itself.
"""

from __future__ import annotations

import numpy as np

__all__ = ["read_binary"]

_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
          "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
          "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_FACE_LISTS = ("vertex_indices", "vertex_index")


def _header(data: bytes):
    """(format, [(element, count, [property tokens])], offset of the body), or None."""
    end = data.find(b"end_header")
    nl = data.find(b"\n", end)
    if not data.startswith(b"ply") or end < 0 or nl < 0:
        return None
    fmt, elements = None, []
    for line in data[:end].decode("ascii", "replace").splitlines():
        tok = line.split()
        if not tok or tok[0] in ("ply", "comment", "obj_info"):
            continue
        if tok[0] == "format" and len(tok) >= 2:
            fmt = tok[1]
        elif tok[0] == "element" and len(tok) == 3 and tok[2].isdigit():
            elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property" and elements:
            elements[-1][2].append(tok[1:])
        else:
            return None
    return fmt, elements, nl + 1


def _fixed_dtype(props, order: str) -> np.dtype | None:
    """The record dtype of an element of fixed-size properties, or None."""
    fields = []
    for p in props:
        if len(p) != 2 or p[0] not in _TYPES:
            return None
        fields.append((p[1], order + _TYPES[p[0]]))
    return np.dtype(fields)


def _face_dtype(props, order: str) -> np.dtype | None:
    """The record dtype of a face element whose one list holds three corners."""
    fields, lists = [], 0
    for p in props:
        if p[0] == "list":
            if len(p) != 4 or p[3] not in _FACE_LISTS or p[1] not in _TYPES or p[2] not in _TYPES:
                return None
            if _TYPES[p[1]][0] == "f" or _TYPES[p[2]][0] == "f":
                return None
            fields += [("__n", order + _TYPES[p[1]]), ("__idx", order + _TYPES[p[2]], (3,))]
            lists += 1
        elif len(p) == 2 and p[0] in _TYPES:
            fields.append((p[1], order + _TYPES[p[0]]))
        else:
            return None
    return np.dtype(fields) if lists == 1 else None


def read_binary(data: bytes) -> tuple[np.ndarray, np.ndarray, int] | None:
    """Read a binary PLY triangle mesh of the common layout.

    Arguments:
        data: the file's bytes (header already checked against the size).

    Returns:
        (vertices (V, 3) float64, faces (F, 3) int64, declared face count), or
        None when the file is not of that layout (the caller falls back)."""
    head = _header(data)
    if head is None:
        return None
    fmt, elements, offset = head
    order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt)
    names = [e[0] for e in elements]
    if order is None or names.count("vertex") != 1 or names.count("face") != 1:
        return None
    out = {}
    for name, count, props in elements:
        dtype = _face_dtype(props, order) if name == "face" else _fixed_dtype(props, order)
        if dtype is None or dtype.itemsize == 0:
            return None
        size = count * dtype.itemsize
        if offset + size > len(data):
            return None
        out[name] = np.frombuffer(data, dtype, count, offset)
        offset += size
        if "vertex" in out and "face" in out:
            break
    v, f = out["vertex"], out["face"]
    if not {"x", "y", "z"} <= set(v.dtype.names) or not (f["__n"] == 3).all():
        return None
    vertices = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
    return vertices, f["__idx"].astype(np.int64), len(f)
