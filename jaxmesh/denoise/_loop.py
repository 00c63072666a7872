"""The iteration driver shared by the denoising flows, and its progress hook
(not public API; :func:`jaxmesh.denoise.progress` is the public face)."""

from __future__ import annotations

import contextlib
import contextvars
import signal
import threading
import time
from collections.abc import Callable, Iterator

import jax
from jaxtyping import Array, Float

try:  # no public equivalent: "is anything being traced right now?"
    from jax._src.core import trace_state_clean as _trace_state_clean
except ImportError:
    _trace_state_clean = None

# (callback, depth) while a progress context is active; read at trace time
_PROGRESS: contextvars.ContextVar = contextvars.ContextVar("jaxmesh_progress", default=None)
_DEPTH: contextvars.ContextVar = contextvars.ContextVar("jaxmesh_loop_depth", default=0)


def check_iterations(iterations, name: str = "iterations") -> int:
    """Iteration counts are Python ints (static): the loop compiles once."""
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 0:
        raise ValueError(f"{name} must be a non-negative int, got {iterations!r}")
    return iterations


@contextlib.contextmanager
def progress(callback: Callable[[int], None]) -> Iterator[None]:
    """Call ``callback(i)`` after outer iteration i of every denoiser traced
    inside this context (a host callback inside the loop, so it works under
    jit; nested loops are not reported).  Used by the CLI's progress bar.

    Arguments:
        callback: called with the iteration index i (from a host callback).

    Returns:
        A context manager."""
    token = _PROGRESS.set(callback)
    try:
        yield
    finally:
        _PROGRESS.reset(token)


def iterate(step: Callable[..., Float[Array, "*batch V 3"]],
            x0: Float[Array, "*batch V 3"], iterations: int, *, indexed: bool = False
            ) -> Float[Array, "*batch V 3"]:
    """x_{k+1} = step(x_k) (or step(k, x_k) when ``indexed``), ``iterations``
    times, as a ``lax.fori_loop`` (compile time independent of the count;
    reverse-mode differentiable).

    Called eagerly (``x0`` a concrete array, not under ``jit``, ``vmap`` or
    ``grad``), the loop runs as a sequence of compiled chunks of growing length,
    each well under a second, so that Ctrl-C (``KeyboardInterrupt``) stops a
    long run between two chunks; the steps and their order are the same."""
    check_iterations(iterations)
    report = _PROGRESS.get() if _DEPTH.get() == 0 else None

    def body(i, x):
        token = _DEPTH.set(_DEPTH.get() + 1)
        try:
            y = step(i, x) if indexed else step(x)
        finally:
            _DEPTH.reset(token)
        if report is not None:
            jax.debug.callback(lambda i, _: report(int(i)), i, y[..., :1, :1])
        return y

    if iterations <= 1 or not _eager(x0):
        return jax.lax.fori_loop(0, iterations, jax.checkpoint(body), x0)
    return _chunked(body, x0, iterations)


def _eager(x0) -> bool:
    """True outside every transformation (no jit, vmap, grad tracing anything the
    step might close over, such as a differentiated parameter)."""
    if _trace_state_clean is None:  # another JAX: never chunk (the loop stays one call)
        return False
    return _trace_state_clean() and not isinstance(x0, jax.core.Tracer)


def _chunked(body, x0, iterations: int, seconds: float = 0.25):
    """``fori_loop(0, iterations, body, x0)`` as one compiled program called on
    chunks [lo, hi) whose length doubles while a chunk takes under ``seconds``.

    In the main thread with Python's default SIGINT handler, Ctrl-C is caught by a
    handler of ours for the duration and raised as ``KeyboardInterrupt`` between two
    chunks (a signal landing inside JAX's own Python code could otherwise be
    swallowed there)."""
    run = jax.jit(lambda x, lo, hi: jax.lax.fori_loop(lo, hi, body, x))
    hit: list[int] = []
    previous = None
    if threading.current_thread() is threading.main_thread() \
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous = signal.signal(signal.SIGINT, lambda signum, frame: hit.append(signum))
    try:
        x, done, chunk = x0, 0, 1
        while done < iterations:
            if hit:
                raise KeyboardInterrupt
            n = min(chunk, iterations - done)
            start = time.perf_counter()
            x = run(x, done, done + n)
            jax.block_until_ready(x)
            done += n
            if time.perf_counter() - start < seconds:
                chunk *= 2
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if hit:
        raise KeyboardInterrupt
    return x
