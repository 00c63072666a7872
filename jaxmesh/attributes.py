"""What a mesh file carries besides positions and triangles, kept when the positions change.

A denoiser moves vertices; a scan's colours, texture coordinates and their per-corner
indices, materials, groups, polygons and extra PLY properties stay what they were.
:func:`read_attributes` says what an OBJ or PLY file carries beyond ``v x y z`` and
triangles (:class:`MeshAttributes`, ``None`` for a plain file); :func:`rewrite` gives the
same file with new positions, every other byte kept:

* OBJ: each ``v`` line's three coordinates are replaced (``%.17g``); whatever follows them
  on the line (vertex colours ``r g b``, a weight, a comment) and every other line are kept.
* PLY (ASCII or binary): the vertex element's ``x y z`` are replaced in the property's own
  type (a float32 file stays float32); every other property, element, comment and the
  header are kept.

Normals are recomputed from the new surface rather than kept stale: a PLY's per-vertex
``nx ny nz`` as the area-weighted vertex normals n_i ∝ Σ_{f∋i} A_f ν_f
(:func:`jaxmesh.geometry.vertex_normals`), an OBJ's ``vn`` j as n_j ∝ Σ_c A_{f(c)} ν_{f(c)}
over the face corners c that reference j, with A ν a polygon's vector area (the sum of its
fan triangles'): the area-weighted vertex normal where each ``vn`` belongs to one vertex,
the face's normal under flat shading.  A ``vn`` no corner references is kept.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _ply
from ._meshtext import only_positions_and_triangles
from .mesh import Mesh

__all__ = ["MeshAttributes", "read_attributes", "rewrite", "vertex_property"]

_COLOURS = frozenset("red green blue alpha r g b a diffuse_red diffuse_green diffuse_blue diffuse_alpha".split())
_TEXTURE = frozenset("s t u v texture_u texture_v texture_s texture_t texcoord".split())
_NORMALS = ("nx", "ny", "nz")
_FACE_LISTS = ("vertex_indices", "vertex_index")
_V_LINE = re.compile(rb"^([ \t]*v[ \t]+)(\S+)([ \t]+)(\S+)([ \t]+)(\S+)(.*)$", re.S)
_OBJ_KINDS = {b"vt": "texture coordinates", b"usemtl": "materials", b"mtllib": "materials",
              b"g": "groups", b"o": "objects", b"s": "smoothing groups"}


@dataclass(frozen=True)
class MeshAttributes:
    """A mesh file's bytes, read far enough to write them again with new positions.

    Attributes:
        format: ``"obj"`` or ``"ply"``.
        kinds: what the file carries besides positions and triangles, in words
            (``"vertex colours"``, ``"texture coordinates"``, ``"normals"``, ...).
        num_vertices: the file's vertex count (the mesh written must have as many)."""

    format: str
    kinds: tuple[str, ...]
    num_vertices: int
    _data: bytes = field(repr=False)
    _layout: dict = field(repr=False)


def read_attributes(path, data: bytes | None = None) -> MeshAttributes | None:
    """What the OBJ or PLY file at ``path`` carries besides positions and triangles.

    Arguments:
        path: the file (its suffix names the format).
        data: the file's bytes, if already read.

    Returns:
        A :class:`MeshAttributes`, or None for a file of positions and triangles only
        (and for OFF and STL, which hold nothing else jaxmesh keeps).

    Raises:
        ValueError: a file whose layout cannot be rewritten in place (a vertex element with
            list properties, integer coordinates, OBJ line continuations), naming why."""
    fmt = Path(path).suffix.lstrip(".").lower()
    if fmt not in ("obj", "ply"):
        return None
    data = Path(path).read_bytes() if data is None else data
    kinds, layout, count = (_obj_layout if fmt == "obj" else _ply_layout)(data)
    return MeshAttributes(fmt, kinds, count, data, layout) if kinds else None


def rewrite(attributes: MeshAttributes, mesh: Mesh) -> bytes:
    """The file of ``attributes`` with ``mesh``'s positions (and normals recomputed from them).

    Arguments:
        attributes: from :func:`read_attributes`.
        mesh: a single mesh with the file's vertices, in its order, and its triangles.

    Returns:
        The file's bytes."""
    if mesh.batch_shape:
        raise ValueError(f"rewrite needs a single mesh, got batch shape {mesh.batch_shape}")
    if mesh.num_vertices != attributes.num_vertices:
        raise ValueError(f"the mesh has {mesh.num_vertices} vertices, the file whose attributes are kept "
                         f"{attributes.num_vertices}")
    vertices = np.asarray(mesh.vertices, np.float64)
    if not np.isfinite(vertices).all():
        raise ValueError("refusing to save a mesh with non-finite vertex coordinates")
    return (_obj_rewrite if attributes.format == "obj" else _ply_rewrite)(attributes, mesh, vertices)


def vertex_property(attributes: MeshAttributes, name: str) -> np.ndarray:
    """The values of one PLY vertex property (a mask or a weight stored in the file).

    Arguments:
        attributes: from :func:`read_attributes` of a PLY file.
        name: the property's name.

    Returns:
        (V,) array in the property's type."""
    dtype = attributes._layout.get("dtype")
    if attributes.format != "ply" or name not in dtype.names:
        have = ", ".join(dtype.names) if attributes.format == "ply" else "none (not a PLY file)"
        raise ValueError(f"no vertex property {name!r} (the file's vertex properties: {have})")
    layout, data = attributes._layout, attributes._data
    if not layout["ascii"]:
        return np.frombuffer(data, dtype, layout["count"], layout["start"])[name].copy()
    lines, rows = _ascii_vertex_rows(attributes)
    column = dtype.names.index(name)
    return np.array([lines[k].split()[column] for k in rows], dtype[name].newbyteorder("="))


def _ascii_vertex_rows(attributes: MeshAttributes) -> tuple[list[bytes], list[int]]:
    """An ASCII PLY's body lines and the indices of its vertex records among them (one per line)."""
    layout = attributes._layout
    lines = attributes._data[layout["head"]:].split(b"\n")
    return lines, [k for k, line in enumerate(lines) if line.strip()][layout["skip"]:][:layout["count"]]


def _vector_areas(mesh: Mesh) -> np.ndarray:
    """A_f ν_f of each triangle, (F, 3)."""
    from .geometry import face_areas, face_normals

    return np.asarray(face_areas(mesh)[:, None] * face_normals(mesh), np.float64)


def _unit(n: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(length > 0, n / np.where(length > 0, length, 1), 0.0)


# -- OBJ -------------------------------------------------------------------------------------------

def _obj_layout(data: bytes):
    """(kinds, layout, vertex count): the lines of ``v`` and ``vn``, and each face record's
    corner count and the ``vn`` of its corners (-1: none)."""
    if only_positions_and_triangles(data):              # the common plain file, without a Python loop
        return (), {}, 0
    if b"\\\n" in data or b"\\\r\n" in data:
        raise ValueError("OBJ line continuations: the file cannot be rewritten line by line")
    bom = b"\xef\xbb\xbf" if data.startswith(b"\xef\xbb\xbf") else b""
    lines = data[len(bom):].split(b"\n")
    kinds, v_lines, vn_lines, corners, normal_refs = set(), [], [], [], []
    for k, line in enumerate(lines):
        tok = line.split(b"#", 1)[0].split()
        if not tok:
            continue
        key = tok[0]
        if key == b"v":
            if len(tok) in (7, 8):
                kinds.add("vertex colours")
            elif len(tok) == 5:
                kinds.add("vertex weights")
            v_lines.append(k)
        elif key == b"vn":
            kinds.add("normals")
            vn_lines.append(k)
        elif key == b"f":
            refs = []
            for t in tok[1:]:
                parts = t.split(b"/")
                if len(parts) > 1:
                    kinds.add("corner indices")
                j = int(parts[2]) if len(parts) > 2 and parts[2] else 0
                refs.append(j - 1 if j > 0 else len(vn_lines) + j if j < 0 else -1)
            corners.append(len(refs))
            normal_refs.extend(refs)
            if len(refs) > 3:
                kinds.add("polygons")
        elif key in _OBJ_KINDS:
            kinds.add(_OBJ_KINDS[key])
        else:
            kinds.add(f"'{key.decode('ascii', 'replace')}' statements")
    layout = {"bom": bom, "lines": lines, "v": np.asarray(v_lines, np.int64), "vn": np.asarray(vn_lines, np.int64),
              "corners": np.asarray(corners, np.int64), "refs": np.asarray(normal_refs, np.int64)}
    return tuple(sorted(kinds)), layout, len(v_lines)


def _obj_normals(layout: dict, mesh: Mesh) -> np.ndarray:
    """The recomputed ``vn`` (module docstring), (N, 3); NaN rows where no corner references one."""
    corners, refs = layout["corners"], layout["refs"]
    triangles = np.maximum(corners - 2, 0)
    if triangles.sum() != mesh.num_faces:
        raise ValueError(f"the mesh has {mesh.num_faces} triangles, the file's faces fan into {triangles.sum()}")
    record = np.repeat(np.arange(len(corners)), triangles)
    polygon = np.zeros((len(corners), 3))
    np.add.at(polygon, record, _vector_areas(mesh))
    per_corner = np.repeat(polygon, corners, axis=0)
    use = (refs >= 0) & (refs < len(layout["vn"]))
    normals = np.zeros((len(layout["vn"]), 3))
    np.add.at(normals, refs[use], per_corner[use])
    referenced = np.zeros(len(layout["vn"]), bool)
    referenced[refs[use]] = True
    return np.where(referenced[:, None], _unit(normals), np.nan)


def _obj_rewrite(attributes: MeshAttributes, mesh: Mesh, vertices: np.ndarray) -> bytes:
    layout = attributes._layout
    lines = list(layout["lines"])
    for k, x in zip(layout["v"].tolist(), vertices.tolist()):
        m = _V_LINE.match(lines[k])
        if m is None:
            raise ValueError(f"line {k + 1}: a vertex line without three coordinates")
        lines[k] = b"".join((m[1], b"%.17g" % x[0], m[3], b"%.17g" % x[1], m[5], b"%.17g" % x[2], m[7]))
    if len(layout["vn"]):
        for k, n in zip(layout["vn"].tolist(), _obj_normals(layout, mesh).tolist()):
            if not np.isnan(n[0]):
                end = b"\r" if lines[k].endswith(b"\r") else b""
                lines[k] = b"vn %.17g %.17g %.17g" % tuple(n) + end
    return layout["bom"] + b"\n".join(lines)


# -- PLY -------------------------------------------------------------------------------------------

def _property_kind(element: str, name: str) -> str | None:
    """What a PLY property is, in words (None: a position or the face's corner list)."""
    if element == "vertex":
        if name in ("x", "y", "z"):
            return None
        if name in _COLOURS:
            return "vertex colours"
        if name in _TEXTURE:
            return "texture coordinates"
        return "normals" if name in _NORMALS else f"vertex property {name!r}"
    if name in _FACE_LISTS:
        return None
    return "texture coordinates" if "tex" in name else f"face property {name!r}"


def _ply_kinds(elements, header: bytes) -> set:
    kinds = {_property_kind(name, p[-1]) for name, _, props in elements if name in ("vertex", "face")
             for p in props}
    kinds |= {f"element {name!r}" for name, _, _ in elements if name not in ("vertex", "face")}
    if b"TextureFile" in header:
        kinds.add("texture file")
    kinds.discard(None)
    return kinds


def _ply_layout(data: bytes):
    """(kinds, layout, vertex count): the vertex records' place and dtype in the body."""
    head = _ply._header(data)
    if head is None:
        raise ValueError("a PLY header jaxmesh cannot read")
    fmt, elements, offset = head
    kinds = _ply_kinds(elements, data[:offset])
    names = [e[0] for e in elements]
    if names.count("vertex") != 1:
        raise ValueError("the file has no single vertex element")
    order = {"binary_little_endian": "<", "binary_big_endian": ">", "ascii": "<"}[fmt]
    layout = {"ascii": fmt == "ascii", "head": offset, "start": offset, "skip": 0}
    for name, count, props in elements:
        dtype = _ply._fixed_dtype(props, order)
        if name == "vertex":
            if dtype is None:
                raise ValueError("the vertex element has list properties: it cannot be rewritten in place")
            for c in "xyz":
                if c not in dtype.names or dtype[c].kind != "f":
                    raise ValueError(f"vertex coordinate {c!r} is missing or not a float property")
            layout.update(dtype=dtype, count=count)
            return tuple(sorted(kinds)), layout, count
        if dtype is None and fmt != "ascii":
            raise ValueError(f"element {name!r} before the vertices has list properties")
        if fmt == "ascii":
            layout["skip"] += count                 # one line per record
        else:
            layout["start"] += count * dtype.itemsize
    raise AssertionError("unreachable")


def _ply_values(dtype: np.dtype, mesh: Mesh, vertices: np.ndarray) -> dict:
    """New values of the rewritten properties: x, y, z and (when float) nx, ny, nz."""
    out = {c: vertices[:, i] for i, c in enumerate("xyz")}
    if all(n in dtype.names and dtype[n].kind == "f" for n in _NORMALS):
        from .geometry import vertex_normals

        out.update(zip(_NORMALS, np.asarray(vertex_normals(mesh, "area"), np.float64).T))
    for name, values in out.items():
        big = np.abs(values).max(initial=0.0)
        if big > np.finfo(dtype[name]).max:
            raise ValueError(f"a value of magnitude {big:.3g} does not fit in the file's {dtype[name]} "
                             f"property {name!r}")
    return out


def _ply_rewrite(attributes: MeshAttributes, mesh: Mesh, vertices: np.ndarray) -> bytes:
    layout, data = attributes._layout, attributes._data
    dtype, count = layout["dtype"], layout["count"]
    values = _ply_values(dtype, mesh, vertices)
    if not layout["ascii"]:
        start = layout["start"]
        records = np.frombuffer(data, dtype, count, start).copy()
        for name, v in values.items():
            records[name] = v
        return data[:start] + records.tobytes() + data[start + count * dtype.itemsize:]
    lines, rows = _ascii_vertex_rows(attributes)
    columns = {name: dtype.names.index(name) for name in values}
    text = {name: ("%.17g" if dtype[name].itemsize == 8 else "%.9g").encode() for name in values}
    for r, k in enumerate(rows):
        line = lines[k]
        end = b"\r" if line.endswith(b"\r") else b""
        tokens = line.split()
        if len(tokens) != len(dtype.names):
            raise ValueError(f"vertex {r}: {len(tokens)} values where the header declares {len(dtype.names)}")
        for name, col in columns.items():
            tokens[col] = text[name] % values[name][r]
        lines[k] = b" ".join(tokens) + end
    return data[:layout["head"]] + b"\n".join(lines)
