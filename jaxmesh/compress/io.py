"""Reading and writing ``.jxm`` files (atomic, never overwriting unless asked)."""

from __future__ import annotations

import os
from pathlib import Path

from ..io import MeshFileError, write_bytes_atomic
from ..mesh import Mesh
from .codec import CodecError, Compressed, decompress

__all__ = ["save_compressed", "load_compressed"]


def save_compressed(compressed: Compressed | bytes, path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write a :class:`Compressed` (or its bytes) to ``path`` atomically.

    Arguments:
        compressed: a :class:`Compressed` or its bytes.
        path: the file to write.
        overwrite: replace an existing file (refused by default).

    Returns:
        The path written."""
    data = compressed.data if isinstance(compressed, Compressed) else bytes(compressed)
    return write_bytes_atomic(path, data, overwrite=overwrite)


def load_compressed(path: str | os.PathLike) -> Mesh:
    """Decode a ``.jxm`` file; :class:`CodecError` names the problem with its path.

    Arguments:
        path: a ``.jxm`` file.

    Returns:
        The decoded :class:`~jaxmesh.Mesh`."""
    p = Path(path)
    if not p.is_file():
        raise MeshFileError(f"{p}: no such file")
    try:
        return decompress(p.read_bytes())
    except CodecError as err:
        raise CodecError(f"{p}: {err}") from err
