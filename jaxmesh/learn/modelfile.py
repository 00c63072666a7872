"""Model files: a learned denoiser (and, for a training checkpoint, its optimiser state)
on disk.

A file is one JSON header line (``{"format": "jaxmesh-learned", "version": 1, "config":
{...}, "meta": {...}, "leaves": [[shape, dtype], ...]}``) followed by each array leaf of
the model as a NumPy ``.npy`` record, in ``jax.tree_util`` order.  The reader checks the
header's config (:meth:`~jaxmesh.learn.ModelConfig.check`) before building anything, and
every record's shape and dtype against the template the config implies, so a truncated,
edited or foreign file is a clear ``ValueError``, never a mis-shaped model.  A config
without the keys of the optional parts (``repair_rounds``, ``gated``, ``tail_features``:
files written before they existed) is the plain stack.  Files are written atomically (a
temporary file renamed over the target).
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import os
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import numpy as np

from ..io import write_bytes_atomic
from .model import LearnedDenoiser, ModelConfig, fill_weights, init_model, is_weight

__all__ = ["save_model", "load_model", "default_model", "DEFAULT_MODEL", "file_sha256"]

#: the model shipped with jaxmesh (trained by ``experiments/learn/train_default.py``)
DEFAULT_MODEL = Path(__file__).resolve().parent.parent / "data" / "learned.jxl"
_FORMAT, _VERSION = "jaxmesh-learned", 1
#: the optional parts a config without these keys lacks (files written before they existed)
_PLAIN = {"repair_rounds": 0, "gated": False, "tail_features": False}
_HEADER_LIMIT = 1 << 20


def _arrays(tree) -> list:
    return [leaf for leaf in jax.tree_util.tree_leaves(tree) if is_weight(leaf)]


def save_model(path: str | os.PathLike, model: LearnedDenoiser, meta: dict | None = None, *,
               extra: Any = None, overwrite: bool = False) -> None:
    """Write ``model`` (and ``extra``, a pytree of arrays such as an optimiser state) to ``path``.

    Arguments:
        path: the output file (by convention ``.jxl``).
        model: the denoiser.
        meta: JSON-serialisable facts kept in the header (training meshes, seed, ...).
        extra: a pytree of arrays written after the model's (a checkpoint's optimiser state).
        overwrite: replace an existing file.

    Returns:
        None."""
    leaves = [np.asarray(a) for a in _arrays(model) + _arrays(extra)]
    header = {"format": _FORMAT, "version": _VERSION, "config": vars(model.config), "meta": meta or {},
              "leaves": [[list(a.shape), a.dtype.str] for a in leaves]}
    buf = io.BytesIO()
    buf.write(json.dumps(header, sort_keys=True).encode() + b"\n")
    for a in leaves:
        np.save(buf, a, allow_pickle=False)
    write_bytes_atomic(path, buf.getvalue(), overwrite=overwrite)


def _header(f, path) -> dict:
    line = f.readline(_HEADER_LIMIT)
    try:
        header = json.loads(line)
    except (UnicodeDecodeError, json.JSONDecodeError):
        header = None
    if not isinstance(header, dict) or header.get("format") != _FORMAT:
        raise ValueError(f"{path} is not a jaxmesh model file (no {_FORMAT!r} header)")
    if header.get("version") != _VERSION:
        raise ValueError(f"{path}: model file version {header.get('version')!r}, this jaxmesh reads {_VERSION}")
    if not isinstance(header.get("config"), dict) or not isinstance(header.get("meta", {}), dict):
        raise ValueError(f"{path}: the model file's header has no config")
    return header


def _read_leaves(f, template: list, path) -> list:
    out = []
    for i, t in enumerate(template):
        try:
            a = np.load(f, allow_pickle=False)
        except (ValueError, EOFError, OSError) as e:
            raise ValueError(f"{path}: array {i} of {len(template)} is missing or damaged ({e})") from None
        if a.shape != t.shape or a.dtype.kind != np.dtype(t.dtype).kind:
            raise ValueError(f"{path}: array {i} has shape {a.shape} ({a.dtype}), the config implies {t.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"{path}: array {i} holds non-finite values")
        out.append(a.astype(t.dtype))
    return out


def load_model(path: str | os.PathLike, extra: Any = None) -> LearnedDenoiser | tuple[LearnedDenoiser, Any, dict]:
    """Read a model file written by :func:`save_model`.

    Arguments:
        path: the file.
        extra: a template pytree for the arrays after the model's (a checkpoint's
            optimiser state), or None to read the model alone.

    Returns:
        The :class:`~jaxmesh.learn.LearnedDenoiser`; with ``extra``, ``(model, extra, meta)``."""
    with open(path, "rb") as f:
        header = _header(f, path)
        try:
            config = ModelConfig(**{**_PLAIN, **header["config"]}).check()
        except TypeError as e:
            raise ValueError(f"{path}: the model file's config is not a jaxmesh model config ({e})") from None
        except ValueError as e:
            raise ValueError(f"{path}: {e}") from None
        template = eqx.filter_eval_shape(init_model, config)   # the shapes alone: no weights drawn
        arrays = _arrays(template) + _arrays(extra)
        leaves = _read_leaves(f, arrays, path)
        if f.read(1):
            raise ValueError(f"{path}: data after the last array (not a file this config wrote)")
    k = len(_arrays(template))
    with jax.ensure_compile_time_eval():
        model = fill_weights(template, leaves[:k])
    if extra is None:
        return model
    return model, fill_weights(extra, leaves[k:]), header.get("meta", {})


def file_sha256(path: str | os.PathLike) -> str:
    """The SHA-256 of a file's bytes, in hex (recorded with the shipped model).

    Arguments:
        path: the file.

    Returns:
        64 hex digits."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@functools.lru_cache(maxsize=4)
def _cached(path: str, stamp: tuple) -> LearnedDenoiser:
    return load_model(path)


def default_model(path: str | os.PathLike | None = None) -> LearnedDenoiser:
    """The model in ``path`` (the shipped model when None), read once per file version.

    Arguments:
        path: a model file, or None for :data:`DEFAULT_MODEL`.

    Returns:
        The :class:`~jaxmesh.learn.LearnedDenoiser`."""
    p = Path(DEFAULT_MODEL if path is None else path)
    try:
        st = p.stat()
    except OSError as e:
        raise ValueError(f"cannot read model file {p}: {e.strerror}") from None
    return _cached(str(p.resolve()), (st.st_mtime_ns, st.st_size))
