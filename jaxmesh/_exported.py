"""Compiled functions whose programs are kept on disk between processes (not public API).

JAX's persistent compilation cache (:func:`jaxmesh.compiler.enable_compilation_cache`)
spares a new process XLA's compile, not the tracing of the Python function and its
lowering to StableHLO, which come first because the cache is keyed by the lowered
program.  For the large programs of the blind search these two cost more than
loading the compiled program.  :func:`stored_jit` is ``jax.jit`` for such a function,
and while a store is set (:func:`set_store`; ``enable_compilation_cache`` sets one in
its folder's ``exported/``) each program it lowers is serialised with ``jax.export``
and written there.  A later process with the same arguments' structure, shapes,
dtypes and static values deserialises the program instead of tracing and lowering
the function, and calls it (its compile then comes from JAX's cache).  The program
is the one ``jax.jit`` lowers, so the results are identical.

A stored program is found by the SHA-256 of: the function's qualified name, the
static arguments' ``repr``, the structure (tree definition) of the other arguments,
each leaf's shape, dtype and weak type, the x64 setting, the platform, the jax and
jaxlib versions, and the text of every module of this package (any change to the
code makes new keys).  The functions taken are this package's own module-level
functions (the key names a function by its qualified name and covers only this
package's source), and must see arrays only through their arguments: a closed-over
array would be baked into the stored program unkeyed.

Files are written atomically, each with the SHA-256 of its payload, checked before
``jax.export.deserialize`` sees it; a file that fails the check, or does not
deserialise, is removed and the function is traced as without a store.  Inside another
transformation (``jit``, ``vmap``, ``grad``) the function is traced with it, as ``jax.jit``'s are.  A function
that cannot be exported (a host callback, an output that is not a tuple, list,
dict or array) is traced from then on.  At most :data:`STORE_MAX_FILES` files are
kept: past it, the least recently used are removed down to three quarters of it.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import os
import tempfile
from pathlib import Path

import jax

__all__ = ["stored_jit", "set_store", "store_path", "STORE_MAX_FILES"]

#: the most programs kept in the store (least recently used removed first)
STORE_MAX_FILES = 2000
_MAGIC = b"jaxmesh-exported-1\n"
_SUFFIX = ".jaxexport"
_store: list[Path | None] = [None]


def set_store(path: str | os.PathLike | None) -> None:
    """Keep the programs of :func:`stored_jit` functions in ``path`` (created if missing), or
    nowhere (None)."""
    if path is not None:
        path = Path(path)
        path.mkdir(parents=True, exist_ok=True)
    _store[0] = path


def store_path() -> Path | None:
    """The folder programs are kept in, or None."""
    return _store[0]


@functools.cache
def _code_digest() -> str:
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    import jaxlib

    h.update(f"{jax.__version__} {jaxlib.__version__}".encode())
    return h.hexdigest()


def _leaf_spec(leaf) -> jax.ShapeDtypeStruct:
    aval = jax.typeof(leaf) if hasattr(jax, "typeof") else jax.api_util.shaped_abstractify(leaf)
    return jax.ShapeDtypeStruct(aval.shape, aval.dtype, weak_type=aval.weak_type)


def _read(path: Path):
    """The exported program in ``path``, or None (missing, damaged or unreadable: then removed)."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    head = len(_MAGIC) + 32
    if data[:len(_MAGIC)] == _MAGIC and len(data) > head and hashlib.sha256(data[head:]).digest() == data[len(_MAGIC):head]:
        try:
            exported = jax.export.deserialize(bytearray(data[head:]))
        except Exception:   # written by another jax, or damaged past the digest
            exported = None
        if exported is not None:
            with contextlib.suppress(OSError):   # recency for the eviction; a read-only store is fine
                os.utime(path)
            return exported
    with contextlib.suppress(OSError):
        path.unlink(missing_ok=True)
    return None


def _write(folder: Path, path: Path, payload: bytes) -> None:
    data = _MAGIC + hashlib.sha256(payload).digest() + payload
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=_SUFFIX)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
        with os.scandir(folder) as entries:
            names = [e.name for e in entries if e.name.endswith(_SUFFIX) and not e.name.startswith(".")]
        if len(names) > STORE_MAX_FILES:   # down to three quarters, least recently used first out
            files = sorted((folder / n for n in names), key=lambda p: p.stat().st_mtime)
            for old in files[:len(files) - STORE_MAX_FILES * 3 // 4]:
                if old != path:
                    old.unlink(missing_ok=True)
    except OSError:   # a full or read-only disk, a file another process removed: not kept, or kept longer
        pass


class _StoredJit:
    """``jax.jit(fun, static_argnames=...)`` with the program store (module docstring)."""

    def __init__(self, fun, static_argnames: tuple[str, ...]):
        self._fun, self._static = fun, static_argnames
        self._jit = jax.jit(fun, static_argnames=static_argnames)
        self._signature = inspect.signature(fun)
        self._calls: dict = {}
        self._refused = False
        functools.update_wrapper(self, fun)

    def __call__(self, *args, **kwargs):
        folder = _store[0]
        if folder is None or self._refused or jax.config.jax_disable_jit:
            return self._jit(*args, **kwargs)
        bound = self._signature.bind(*args, **kwargs)
        bound.apply_defaults()
        statics = tuple((n, bound.arguments[n]) for n in self._static)
        dynamic = tuple(v for n, v in bound.arguments.items() if n not in self._static)
        leaves, tree = jax.tree.flatten(dynamic)
        if any(isinstance(x, jax.core.Tracer) for x in leaves):   # inside another transformation: traced with it
            return self._jit(*args, **kwargs)
        specs = tuple(_leaf_spec(x) for x in leaves)
        memo = (statics, tree, tuple((s.shape, s.dtype, s.weak_type) for s in specs), bool(jax.config.jax_enable_x64))
        call = self._calls.get(memo)
        if call is None:
            call = self._program(folder, statics, tree, specs, memo)
            if call is None:
                return self._jit(*args, **kwargs)
        return call(*leaves)

    def _program(self, folder: Path, statics: tuple, tree, specs: tuple, memo: tuple):
        """The program for ``memo`` (statics, tree, avals, x64): from the store, else exported and stored."""
        platform = jax.export.default_export_platform()     # "cuda", where jax.default_backend() says "gpu"
        key = repr((self._fun.__module__, self._fun.__qualname__, memo, platform, _code_digest()))
        path = folder / f"{hashlib.sha256(key.encode()).hexdigest()}{_SUFFIX}"
        exported = _read(path)
        if exported is None:
            names = [n for n in self._signature.parameters if n not in self._static]

            def flat(*leaves):
                return self._jit(**dict(zip(names, jax.tree.unflatten(tree, leaves))), **dict(statics))
            try:
                exported = jax.export.export(jax.jit(flat), platforms=(platform,))(*specs)
                payload = exported.serialize()
            except Exception:   # a callback, an output tree that cannot be serialised, ...
                self._refused = True
                return None
            _write(folder, path, bytes(payload))
        call = jax.jit(exported.call)
        self._calls[memo] = call    # one dict assignment: safe from several threads
        return call

    def __getattr__(self, name: str):
        """Everything else is ``jax.jit(fun)``'s (``lower``, ``trace``, ``eval_shape``, ...)."""
        if name.startswith("__") or name in ("_jit", "_fun", "_static", "_signature", "_calls", "_refused"):
            raise AttributeError(name)
        return getattr(self._jit, name)


def stored_jit(fun=None, *, static_argnames: tuple[str, ...] = ()):
    """``jax.jit(fun, static_argnames=static_argnames)``, its programs kept in the store
    (module docstring); usable as a decorator, with or without arguments."""
    if fun is None:
        return functools.partial(stored_jit, static_argnames=tuple(static_argnames))
    return _StoredJit(fun, tuple(static_argnames))
