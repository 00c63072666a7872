"""The iteration driver shared by the denoising flows (not public API)."""

from __future__ import annotations

from typing import Callable

import jax
from jaxtyping import Array, Float


def check_iterations(iterations, name: str = "iterations") -> int:
    """Iteration counts are Python ints (static): the loop compiles once."""
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 0:
        raise ValueError(f"{name} must be a non-negative int, got {iterations!r}")
    return iterations


def iterate(step: Callable[[Float[Array, "*batch V 3"]], Float[Array, "*batch V 3"]],
            x0: Float[Array, "*batch V 3"], iterations: int) -> Float[Array, "*batch V 3"]:
    """x_{k+1} = step(x_k), ``iterations`` times, as a ``lax.fori_loop`` (compile
    time independent of the count; reverse-mode differentiable)."""
    return jax.lax.fori_loop(0, check_iterations(iterations), lambda _, x: step(x), x0)
