"""XLA's CPU compiler settings for many-compile workloads.

A dataset run compiles one program per padded batch shape, and on CPU those
compiles are much of its time.  XLA's CPU backend (jaxlib 0.10) generates its
fused loops with the MLIR "fusion emitters" by default; the older elemental
emitters, selected by ``--xla_cpu_use_fusion_emitters=false``, compile jaxmesh's
programs in about half the time.  How fast the programs then run depends on
the program (``benchmarks/bench_xla_flags.py``, bunny, float64, 2 cores,
steady state, default → flag): the umbrella flow 150 → 107 ms,
Taubin 242 → 219 ms, the kernel flow 486 → 299 ms, bilateral normal filtering
1.20 → 1.00 s, a loop of 16 kernel-flow calls 647 → 419 ms, but a vmapped
batch of those 16 meshes 820 → 998 ms.  (``benchmarks/bench_denoise.py`` in
float32 with and without the flag: the umbrella step 1.06 → 1.80 ms per
iteration, slower.)  The dataset runner, which gives one mesh per call on
CPU, is 1.18× faster with it (``benchmarks/bench_dataset.py``, variant
``runner-xla-defaults``).

XLA reads ``XLA_FLAGS`` once, when JAX's first computation starts its backend,
and aborts on a flag it does not know: :func:`prefer_fast_cpu_compiles` adds the
flag only for the jaxlib versions it was measured with, and never over a setting
of the user's; it must run before that point to take effect.  The ``jaxmesh``
command calls it first thing; ``JAXMESH_XLA_DEFAULTS=1`` keeps XLA's own defaults.

**The persistent compilation cache.**  Most of a short command's time is XLA
compiling programs that then run for milliseconds, and a new process compiles
them all again.  :func:`enable_compilation_cache` turns on JAX's own persistent
cache (``jax_compilation_cache_dir``): every program whose compile took at least
:data:`CACHE_MIN_COMPILE_SECONDS` is written to disk, keyed by the program, the
compile options, the XLA flags and the jax/jaxlib versions, and later processes
load it instead of compiling.  The ``jaxmesh`` command turns it on for every run,
in :func:`default_cache_dir` (``$JAXMESH_CACHE_DIR``, else
``$XDG_CACHE_HOME/jaxmesh/jax``, else ``~/.cache/jaxmesh/jax``), at most
:data:`CACHE_MAX_BYTES` (least recently used entries are evicted).
The same call sets the folder's ``exported/`` subfolder as the store of
:mod:`jaxmesh._exported`, where the blind search's large programs are kept already
lowered: the persistent cache spares a process XLA's compile but not the tracing and
lowering that come before its lookup.  ``JAXMESH_CACHE_DIR=off`` (or ``--no-cache``)
turns both off; deleting the folder empties both.

**Releasing compiled programs.**  Every XLA executable holds some of the
process's memory mappings, and JAX keeps every program it compiled.  A process
that compiles without end (a dataset run of the blind default compiles its
search for each new mesh size) passes the kernel's ``vm.max_map_count`` (65,530
by default) and XLA's next compile fails ("Cannot allocate memory") or crashes.
:func:`release_compiled_programs` drops them all (``jax.clear_caches``) once the
process holds more than :data:`MAP_LIMIT` mappings; the dataset runner calls it
after each batch.
"""

from __future__ import annotations

import gc
import math
import os
import warnings
from pathlib import Path

from ._exported import set_store

__all__ = ["prefer_fast_cpu_compiles", "CPU_COMPILE_FLAG", "MEASURED_JAXLIB", "enable_compilation_cache",
           "default_cache_dir", "CACHE_MIN_COMPILE_SECONDS", "CACHE_MAX_BYTES", "CACHE_OFF", "EXPORTED_FOLDER",
           "MAP_LIMIT", "memory_maps", "release_compiled_programs"]

#: the flag added to XLA_FLAGS
CPU_COMPILE_FLAG = "--xla_cpu_use_fusion_emitters=false"
#: jaxlib (major, minor) versions where the flag was measured (older or newer ones are left alone)
MEASURED_JAXLIB = ((0, 10),)
#: programs that compiled faster than this are not written to the persistent cache
CACHE_MIN_COMPILE_SECONDS = 0.0
#: the persistent cache's size limit (least recently used entries are evicted past it)
CACHE_MAX_BYTES = 1 << 30
#: the subfolder of the cache where the search's lowered programs are kept (:mod:`jaxmesh._exported`)
EXPORTED_FOLDER = "exported"
#: the memory mappings past which :func:`release_compiled_programs` drops the compiled programs
#: (under half of the kernel's default ``vm.max_map_count``, 65,530)
MAP_LIMIT = 30_000
#: values of ``JAXMESH_CACHE_DIR`` that turn the persistent cache off
CACHE_OFF = ("off", "0", "none", "false", "no", "")


def prefer_fast_cpu_compiles() -> bool:
    """Add :data:`CPU_COMPILE_FLAG` to ``XLA_FLAGS`` where it is known to help (module
    docstring); call before JAX's first computation, when XLA reads the flags.

    Arguments:

    Returns:
        True if the flag was added; False if it was left out: ``JAXMESH_XLA_DEFAULTS=1``,
        ``XLA_FLAGS`` already names the setting, or this jaxlib version was not measured.
        (JAX has no public query for whether its backend has started: called after, the
        flag is set all the same, and only processes started later see it.)"""
    flags = os.environ.get("XLA_FLAGS", "")
    if os.environ.get("JAXMESH_XLA_DEFAULTS") == "1" or "xla_cpu_use_fusion_emitters" in flags:
        return False
    try:
        from importlib.metadata import version

        major, minor = (int(x) for x in version("jaxlib").split(".")[:2])
    except Exception:   # not installed as a distribution, or an unusual version string
        return False
    if (major, minor) not in MEASURED_JAXLIB:
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {CPU_COMPILE_FLAG}".strip()
    return True


def default_cache_dir() -> Path | None:
    """The persistent compilation cache's folder (module docstring), or None when
    ``JAXMESH_CACHE_DIR`` turns it off.

    Arguments:

    Returns:
        ``$JAXMESH_CACHE_DIR``, else ``$XDG_CACHE_HOME/jaxmesh/jax``, else
        ``~/.cache/jaxmesh/jax``; None for ``JAXMESH_CACHE_DIR=off`` (or ``0``, ``none``,
        ``false``, ``no``, or empty)."""
    env = os.environ.get("JAXMESH_CACHE_DIR")
    if env is not None:
        return None if env.strip().lower() in CACHE_OFF else Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "jaxmesh" / "jax"


def enable_compilation_cache(path: str | os.PathLike | None = None, *,
                             min_compile_seconds: float = CACHE_MIN_COMPILE_SECONDS,
                             max_bytes: int = CACHE_MAX_BYTES) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``path`` (module docstring), for
    every program compiled from then on in this process.

    Arguments:
        path: the cache folder (created if missing); None: :func:`default_cache_dir`.
        min_compile_seconds: programs that compiled faster than this are not cached.
        max_bytes: the cache's size limit; the least recently used entries are evicted past it.

    Returns:
        The folder in use, or None when the cache stays off (``path`` None and
        ``JAXMESH_CACHE_DIR=off``, or a folder that cannot be created or written, in which
        case a :class:`UserWarning` says why)."""
    import jax

    if not (min_compile_seconds >= 0 and math.isfinite(min_compile_seconds)):
        raise ValueError(f"min_compile_seconds must be a finite number >= 0, got {min_compile_seconds!r}")
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, int) or max_bytes < 1:
        raise ValueError(f"max_bytes must be a positive int, got {max_bytes!r}")
    folder = default_cache_dir() if path is None else Path(path).expanduser()
    if folder is None:
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if not os.access(folder, os.W_OK | os.X_OK):
            raise PermissionError(13, "not writable", str(folder))
    except OSError as err:
        warnings.warn(f"the compilation cache stays off: {folder}: {err.strerror or err}", UserWarning,
                      stacklevel=2)
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_seconds))
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    jax.config.update("jax_compilation_cache_max_size", int(max_bytes))
    try:
        set_store(folder / EXPORTED_FOLDER)
    except OSError as err:
        set_store(None)
        warnings.warn(f"the search's programs are not kept: {folder / EXPORTED_FOLDER}: {err.strerror or err}",
                      UserWarning, stacklevel=2)
    return folder


def memory_maps() -> int:
    """The memory mappings this process holds (lines of ``/proc/self/maps``).

    Arguments:

    Returns:
        Their count; 0 where the system has no such file (no such limit to watch)."""
    try:
        with open("/proc/self/maps", "rb") as f:
            return f.read().count(b"\n")        # one pass in C: a line generator took 5 ms per call
    except OSError:
        return 0


def release_compiled_programs(limit: int = MAP_LIMIT) -> bool:
    """Drop every compiled program JAX keeps (``jax.clear_caches``) once the process holds
    more than ``limit`` memory mappings (module docstring); below it, keep them.

    Arguments:
        limit: the mappings tolerated.

    Returns:
        True if the programs were dropped."""
    if memory_maps() <= limit:
        return False
    import jax

    jax.clear_caches()
    gc.collect()
    return True
