"""The iteration driver shared by the denoising flows, and its progress hook
(not public API; :func:`jaxmesh.denoise.progress` is the public face)."""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterator

import jax
from jaxtyping import Array, Float

# (callback, depth) while a progress context is active; read at trace time
_PROGRESS: contextvars.ContextVar = contextvars.ContextVar("jaxmesh_progress", default=None)
_DEPTH: contextvars.ContextVar = contextvars.ContextVar("jaxmesh_loop_depth", default=0)


def check_iterations(iterations, name: str = "iterations") -> int:
    """Iteration counts are Python ints (static): the loop compiles once."""
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 0:
        raise ValueError(f"{name} must be a non-negative int, got {iterations!r}")
    return iterations


def reporting() -> bool:
    """Whether a :func:`progress` context is active: its callback is traced into the loops, so a
    compiled program kept for later calls must not be traced (or reused) inside one."""
    return _PROGRESS.get() is not None


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
    reverse-mode differentiable), the same program called eagerly or traced.  The loop
    does not poll for Ctrl-C: the ``jaxmesh`` command runs its work in a thread it can
    abandon, and a library caller who needs to stop a long run splits it into calls of
    fewer iterations."""
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

    return jax.lax.fori_loop(0, iterations, jax.checkpoint(body), x0)
