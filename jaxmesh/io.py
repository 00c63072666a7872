"""Reading and writing meshes (OBJ, PLY, OFF, STL) through trimesh.

* Vertex order is kept exactly: files are read with ``process=False`` and
  ``maintain_order=True`` (no merging, no reordering, no dropped vertices).
  ``merge_duplicates=True`` merges exactly coincident vertices, keeping the
  first occurrence's position in the order.  STL stores no shared vertices, so
  for STL the default is to merge.
* Polygons are fan-triangulated by trimesh; jaxmesh notices (the file declares
  fewer faces than it yields) and warns, or refuses with ``triangulate=False``.
* Unreadable, truncated or empty files raise :class:`MeshFileError` naming the
  file and the problem.
* :func:`save` writes to a temporary file beside the target and moves it into
  place atomically; it never replaces an existing file unless ``overwrite=True``.
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np

from .mesh import Mesh, MeshWarning

__all__ = ["load", "save", "MeshFileError", "SUPPORTED_FORMATS", "merge_duplicate_vertices"]

SUPPORTED_FORMATS = ("obj", "ply", "off", "stl")


class MeshFileError(ValueError):
    """A mesh file cannot be read or written."""


def _format_of(path: Path, file_type: str | None) -> str:
    ext = (file_type or path.suffix.lstrip(".")).lower()
    if ext not in SUPPORTED_FORMATS:
        raise MeshFileError(
            f"{path}: unsupported format {ext!r}; expected one of {', '.join(SUPPORTED_FORMATS)}"
        )
    return ext


def _declared_faces(path: Path, fmt: str) -> tuple[int | None, int | None]:
    """(faces declared by the file, of which non-triangles) when cheaply known."""
    try:
        if fmt == "ply":
            with open(path, "rb") as fh:
                head = fh.read(65536).split(b"end_header")[0].decode("ascii", "replace")
            m = re.search(r"element\s+face\s+(\d+)", head)
            return (int(m.group(1)), None) if m else (None, None)
        if fmt == "off":
            with open(path, "r", errors="replace") as fh:
                lines = [ln.split("#")[0].strip() for ln in fh]
            lines = [ln for ln in lines if ln]
            first = lines[0]
            rest = first[3:].split() if first.upper().startswith("OFF") else None
            counts = rest if rest else lines[1].split()
            nv, nf = int(counts[0]), int(counts[1])
            start = 1 if rest else 2
            face_lines = lines[start + nv: start + nv + nf]
            polys = sum(1 for ln in face_lines if ln.split()[0] != "3")
            return nf, polys
        if fmt == "obj":
            nf = polys = 0
            with open(path, "r", errors="replace") as fh:
                for ln in fh:
                    if ln.startswith("f "):
                        nf += 1
                        polys += len(ln.split()) != 4
            return nf, polys
    except (OSError, ValueError, IndexError):
        return None, None
    return None, None


def merge_duplicate_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge exactly coincident vertices (first occurrence kept, order kept) and
    drop faces that become index-degenerate."""
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    keep = np.sort(first)  # survivors in original order
    new_index = np.empty(len(first), dtype=np.int64)
    new_index[np.argsort(first)] = np.arange(len(first))
    # map: old vertex -> unique id -> rank of that id's first occurrence
    remap = new_index[inverse]
    f = remap[faces]
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    if not ok.all():
        warnings.warn(
            f"merging duplicates collapsed {int((~ok).sum())} faces; they were dropped",
            MeshWarning,
            stacklevel=3,
        )
    return vertices[keep], f[ok]


def load(
    path: str | os.PathLike,
    *,
    merge_duplicates: bool | None = None,
    triangulate: bool = True,
    file_type: str | None = None,
    dtype=None,
) -> Mesh:
    """Read a triangle mesh from OBJ, PLY, OFF or STL.

    ``merge_duplicates``: merge exactly coincident vertices (default: only for STL).
    ``triangulate``: fan-triangulate polygons with a :class:`MeshWarning`
    (default), or raise :class:`MeshFileError` if the file has any.
    ``file_type`` overrides the suffix; ``dtype`` is passed to
    :meth:`Mesh.from_arrays`.
    """
    import trimesh

    p = Path(path)
    fmt = _format_of(p, file_type)
    if not p.is_file():
        raise MeshFileError(f"{p}: no such file")
    if p.stat().st_size == 0:
        raise MeshFileError(f"{p}: empty file")
    try:
        tm = trimesh.load(
            p, file_type=fmt, process=False, maintain_order=True, force="mesh",
            skip_materials=True,
        )
    except Exception as err:  # trimesh raises many types for bad files
        raise MeshFileError(f"{p}: cannot read as {fmt.upper()} ({type(err).__name__}: {err})") from err
    vertices = np.asarray(getattr(tm, "vertices", np.zeros((0, 3))))
    faces = np.asarray(getattr(tm, "faces", np.zeros((0, 3), int)))
    if len(vertices) == 0 or len(faces) == 0:
        raise MeshFileError(f"{p}: no triangles could be read (empty or unrecognised {fmt.upper()})")
    declared, polys = _declared_faces(p, fmt)
    if declared is not None and (declared != len(faces) or polys):
        n_poly = polys if polys else "some"
        msg = (f"{p}: {n_poly} of {declared} faces are polygons; "
               f"fan-triangulated into {len(faces)} triangles")
        if not triangulate:
            raise MeshFileError(msg.replace("fan-triangulated", "would be fan-triangulated")
                                + " (triangulate=False)")
        warnings.warn(msg, MeshWarning, stacklevel=2)
    if merge_duplicates is None:
        merge_duplicates = fmt == "stl"
    if merge_duplicates:
        vertices, faces = merge_duplicate_vertices(vertices, faces)
    try:
        return Mesh.from_arrays(vertices, faces, dtype=dtype)
    except ValueError as err:
        raise MeshFileError(f"{p}: {err}") from err


def _binary_ply(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """Binary little-endian PLY with double coordinates and int32 indices
    (trimesh's exporter writes float32 coordinates, which loses precision)."""
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment written by jaxmesh\n"
        f"element vertex {len(vertices)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {len(faces)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    ).encode("ascii")
    face_rec = np.empty(len(faces), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    face_rec["n"] = 3
    face_rec["idx"] = faces
    return header + np.ascontiguousarray(vertices, dtype="<f8").tobytes() + face_rec.tobytes()


def write_bytes_atomic(path: str | os.PathLike, data: bytes, *, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same directory,
    fsynced and moved into place atomically; an existing file is an error
    (``FileExistsError``) unless ``overwrite``, also if it appears meanwhile."""
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise MeshFileError(f"{p}: directory {parent} does not exist")
    if p.exists() and not overwrite:
        raise FileExistsError(f"{p} exists; pass overwrite=True (CLI: --force) to replace it")
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        if overwrite:
            os.replace(tmp, p)
        else:
            try:
                os.link(tmp, p)  # fails if p appeared meanwhile: no clobbering race
            except FileExistsError:
                raise FileExistsError(f"{p} exists; pass overwrite=True (CLI: --force) to replace it")
            except OSError:
                if p.exists():
                    raise FileExistsError(f"{p} exists; pass overwrite=True to replace it")
                os.replace(tmp, p)  # filesystem without hard links
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return p


def save(mesh: Mesh, path: str | os.PathLike, *, overwrite: bool = False, file_type: str | None = None) -> Path:
    """Write ``mesh`` (single, unbatched) to OBJ, PLY (binary), OFF or STL.

    The file is written to a temporary name in the same directory and moved
    into place atomically; an existing file is an error unless ``overwrite``.
    Returns the path written.
    """
    p = Path(path)
    fmt = _format_of(p, file_type)
    if mesh.batch_shape:
        raise ValueError(f"save needs a single mesh, got batch shape {mesh.batch_shape}")
    if p.exists() and not overwrite:
        raise FileExistsError(f"{p} exists; pass overwrite=True (CLI: --force) to replace it")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise MeshFileError(f"{p}: directory {parent} does not exist")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.isfinite(vertices).all():
        raise ValueError("refusing to save a mesh with non-finite vertex coordinates")
    if fmt == "ply":
        data = _binary_ply(vertices, np.asarray(mesh.faces))
    elif fmt == "obj":
        data = mesh.to_trimesh().export(file_type="obj", include_normals=False,
                                        include_texture=False, digits=17)
    else:
        data = mesh.to_trimesh().export(file_type=fmt)
    if isinstance(data, str):
        data = data.encode()
    write_bytes_atomic(p, data, overwrite=overwrite)
    return p
