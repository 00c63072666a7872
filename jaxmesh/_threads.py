"""Independent compiled programs run side by side on the host's cores (not public API).

XLA's CPU backend runs a program on a small mesh on one core, and the programs a
single Python thread dispatches run one after another.  Called from several
threads, they run at once: XLA releases the GIL while a program runs, so one
thread's program also overlaps another's tracing.  :func:`concurrent_map` maps a
function over independent items on one thread per available core, and returns
the results in the items' order: each item's computation is the same program on
the same inputs as in a plain loop, so the results are identical.

JAX's context managers (``jax.enable_x64``, ``jax.default_device``) act on the
calling thread only: the workers take the caller's values of both, and under
``jax.disable_jit`` the map runs in the calling thread.  ``JAXMESH_THREADS=1``
runs every map in the calling thread.
"""

from __future__ import annotations

import contextlib
import os
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Callable, Iterable
from typing import TypeVar

import jax

from ._private import x64_context

__all__ = ["concurrent_map", "worker_count"]

T = TypeVar("T")
R = TypeVar("R")


def worker_count() -> int:
    """The threads :func:`concurrent_map` uses: ``$JAXMESH_THREADS`` if set, else the cores
    this process may run on."""
    env = os.environ.get("JAXMESH_THREADS", "").strip()
    if env:
        try:
            return max(int(env), 1)
        except ValueError:
            raise ValueError(f"JAXMESH_THREADS must be a positive integer, got {env!r}") from None
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:   # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def concurrent_map(fn: Callable[[T], R], items: Iterable[T]) -> list[R]:
    """``[fn(item) for item in items]``, the calls spread over :func:`worker_count` threads
    (module docstring); the first exception raised by a call is raised here."""
    items = list(items)
    workers = min(worker_count(), len(items))
    if workers <= 1 or jax.config.jax_disable_jit:
        return [fn(item) for item in items]
    x64, device = bool(jax.config.jax_enable_x64), jax.config.jax_default_device

    def call(item: T) -> R:
        with x64_context(x64), (jax.default_device(device) if device is not None else contextlib.nullcontext()):
            return fn(item)

    with ThreadPoolExecutor(workers, thread_name_prefix="jaxmesh-map") as pool:
        return list(pool.map(call, items))
