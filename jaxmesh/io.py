"""Reading and writing meshes (OBJ, PLY, OFF, STL).

* OBJ, OFF and STL are read and written by jaxmesh's own strict parsers
  (:mod:`jaxmesh._meshtext`); binary PLY of the common layout (fixed-size
  vertex properties, triangles) by numpy (:mod:`jaxmesh._ply`), any other PLY
  through trimesh.
* Vertex order is kept exactly (no merging, no reordering, no dropped vertices).
  ``merge_duplicates=True`` merges exactly coincident vertices, keeping the
  first occurrence's position in the order.  STL stores no shared vertices, so
  for STL the default is to merge.
* Polygons are fan-triangulated by trimesh; jaxmesh notices (the file declares
  fewer faces than it yields) and warns, or refuses with ``triangulate=False``.
* Unreadable, truncated or empty files raise :class:`MeshFileError` naming the
  file, the line and the problem; a text file whose last line has no line end
  is taken for a truncated one.
* Text formats are written with ``%.17g`` (every float64 round-trips exactly);
  binary PLY stores doubles; STL stores float32, as its format defines.
* :func:`save` writes to a temporary file beside the target and moves it into
  place atomically; it never replaces an existing file unless ``overwrite=True``.
"""

from __future__ import annotations

import contextlib
import glob
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np

from . import _meshtext as _text
from . import _ply
from ._private import caller_stacklevel
from .attributes import MeshAttributes, rewrite
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


def _read_ply(p: Path):
    """(vertices, faces, faces declared by the header, None), after checking the
    header's counts against the file's size: the common binary layout by numpy
    (:mod:`jaxmesh._ply`), anything else through trimesh."""
    try:
        data = p.read_bytes()
        counts = _text.check_ply_header(data)
    except OSError as err:
        raise MeshFileError(f"{p}: cannot read ({err.strerror or err})") from err
    except ValueError as err:
        raise MeshFileError(f"{p}: cannot read as PLY: {err}") from err
    fast = _ply.read_binary(data)
    if fast is not None:
        return (*fast, None)
    import trimesh

    try:
        tm = trimesh.load(p, file_type="ply", process=False, maintain_order=True, force="mesh",
                          skip_materials=True, fix_texture=False)    # per-corner UVs must not split vertices
    except Exception as err:  # trimesh raises many types for bad files
        raise MeshFileError(f"{p}: cannot read as PLY ({type(err).__name__}: {err})") from err
    vertices = np.asarray(getattr(tm, "vertices", np.zeros((0, 3))), np.float64)
    faces = np.asarray(getattr(tm, "faces", np.zeros((0, 3), int)), np.int64)
    if "vertex" in counts and len(vertices) != counts["vertex"]:
        raise MeshFileError(f"{p}: the header declares {counts['vertex']} vertices, {len(vertices)} were read")
    return vertices, faces, counts.get("face"), None


def merge_duplicate_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge exactly coincident vertices (first occurrence kept, order kept) and
    drop faces that become index-degenerate.

    Arguments:
        vertices: positions, (V, 3).
        faces: triangles, (F, 3) integer vertex indices.

    Returns:
        (vertices, faces) with each position once."""
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
            stacklevel=caller_stacklevel(),
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

    Arguments:
        path: the file; its suffix names the format unless ``file_type`` does.
        merge_duplicates: merge exactly coincident vertices (default: only for STL,
            which stores no shared vertices).
        triangulate: fan-triangulate polygons with a :class:`MeshWarning` (default),
            or raise :class:`MeshFileError` if the file has any.
        file_type: ``"obj"``, ``"ply"``, ``"off"`` or ``"stl"``, overriding the suffix.
        dtype: the vertices' float dtype, passed to :meth:`Mesh.from_arrays`.

    Returns:
        The :class:`Mesh`, vertices in the file's order.

    Raises:
        MeshFileError: an unreadable, truncated or malformed file, naming the file
            (and the line)."""
    p = Path(path)
    fmt = _format_of(p, file_type)
    if p.is_dir():
        raise MeshFileError(f"{p}: is a directory, not a mesh file")
    if not p.is_file():
        raise MeshFileError(f"{p}: no such file")
    if p.stat().st_size == 0:
        raise MeshFileError(f"{p}: empty file")
    if fmt == "ply":
        vertices, faces, declared, polys = _read_ply(p)
    else:
        try:
            data = p.read_bytes()
        except OSError as err:
            raise MeshFileError(f"{p}: cannot read ({err.strerror or err})") from err
        reader = {"obj": _text.read_obj, "off": _text.read_off, "stl": _text.read_stl}[fmt]
        try:
            vertices, faces, declared, polys = reader(data)
        except (ValueError, UnicodeError) as err:
            raise MeshFileError(f"{p}: cannot read as {fmt.upper()}: {err}") from err
    if len(vertices) == 0 or len(faces) == 0:
        raise MeshFileError(f"{p}: no triangles could be read (empty or unrecognised {fmt.upper()})")
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


#: temporary files being written now (removed by the CLI's interrupt handler)
IN_PROGRESS: set[str] = set()


def _umask() -> int:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)  # elsewhere: read it by setting it (not thread-safe, only at a write)
    os.umask(mask)
    return mask


def _remove_stale_temporaries(parent: Path, name: str) -> None:
    """Remove ``.NAME.PID.*.tmp`` files left beside the target by a writer that
    was killed (kill -9, power loss): those whose process no longer exists."""
    for tmp in parent.glob(f".{glob.escape(name)}.*.tmp"):
        parts = tmp.name[len(name) + 2:].split(".")
        if not parts or not parts[0].isdigit():
            continue
        pid = int(parts[0])
        if pid == os.getpid():
            continue
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            with contextlib.suppress(OSError):
                tmp.unlink()
        except OSError:  # exists but not ours (EPERM): leave it
            pass


def write_bytes_atomic(path: str | os.PathLike, data: bytes, *, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same directory,
    fsynced and moved into place atomically; an existing file is an error
    (``FileExistsError``) unless ``overwrite``, also if it appears meanwhile.

    The file gets the permissions the user's umask gives a new file (0666 & ~umask,
    as ``open`` would), not ``mkstemp``'s 0600.  The temporary file is named
    ``.NAME.PID.XXXX.tmp``; ones left by a killed writer are removed by the next
    write of the same target."""
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if p.is_dir():
        raise MeshFileError(f"{p}: is a directory; refusing to replace it with a file")
    if not parent.is_dir():
        raise MeshFileError(f"{p}: directory {parent} does not exist")
    if p.exists() and not overwrite:
        raise FileExistsError(f"{p} exists; pass overwrite=True (CLI: --force) to replace it")
    _remove_stale_temporaries(parent, p.name)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.{os.getpid()}.", suffix=".tmp", dir=parent)
    IN_PROGRESS.add(tmp)
    try:
        with os.fdopen(fd, "wb") as fh:
            os.fchmod(fh.fileno(), 0o666 & ~_umask())
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
        IN_PROGRESS.discard(tmp)
    return p


def save(mesh: Mesh, path: str | os.PathLike, *, overwrite: bool = False, file_type: str | None = None,
         attributes: MeshAttributes | None = None) -> Path:
    """Write ``mesh`` (single, unbatched) to OBJ, PLY (binary), OFF or STL.

    The file is written to a temporary name in the same directory and moved into
    place atomically.  With ``attributes`` (:func:`jaxmesh.read_attributes` of the file
    the mesh was read from) the output is that file with the mesh's positions: colours,
    texture coordinates, materials and every other byte kept, normals recomputed
    (:mod:`jaxmesh.attributes`); its format must be the file's.

    Arguments:
        mesh: the mesh to write.
        path: the file; its suffix names the format unless ``file_type`` does.
        overwrite: replace an existing file (default: an existing file is an error).
        file_type: ``"obj"``, ``"ply"``, ``"off"`` or ``"stl"``, overriding the suffix.
        attributes: what to keep of the input file (default: positions and triangles only).

    Returns:
        The path written."""
    p = Path(path)
    fmt = _format_of(p, file_type)
    if mesh.batch_shape:
        raise ValueError(f"save needs a single mesh, got batch shape {mesh.batch_shape}")
    if p.is_dir():
        raise MeshFileError(f"{p}: is a directory; refusing to replace it with a file")
    if p.exists() and not overwrite:
        raise FileExistsError(f"{p} exists; pass overwrite=True (CLI: --force) to replace it")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise MeshFileError(f"{p}: directory {parent} does not exist")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.isfinite(vertices).all():
        raise ValueError("refusing to save a mesh with non-finite vertex coordinates")
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if attributes is not None:
        if attributes.format != fmt:
            raise MeshFileError(f"{p}: the attributes kept are those of a {attributes.format.upper()} file; "
                                f"{fmt.upper()} cannot hold them (write .{attributes.format})")
        try:
            data = rewrite(attributes, mesh)
        except ValueError as err:
            raise MeshFileError(f"{p}: {err}") from err
    elif fmt == "ply":
        data = _binary_ply(vertices, faces)
    else:
        try:
            data = {"obj": _text.write_obj, "off": _text.write_off, "stl": _text.write_stl}[fmt](vertices, faces)
        except ValueError as err:
            raise MeshFileError(f"{p}: {err}") from err
    write_bytes_atomic(p, data, overwrite=overwrite)
    return p
