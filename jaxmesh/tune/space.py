"""Bounded, unconstrained coordinates for a method's continuous parameters.

A parameter p with search range [lo, hi] (from :class:`jaxmesh.denoise.Param`)
is optimised through an unconstrained coordinate u ∈ R:

* linear range:  p(u) = lo + (hi - lo) σ(u)
* log range:     p(u) = lo (hi / lo)^σ(u)

with σ the logistic function.  Every u maps inside the range, so an optimiser
can never step into the region where a flow is unstable or meaningless
(negative λ, an explosive step), and u = 0 is the range's centre (the
geometric centre for a log range).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp

from ..denoise.registry import as_method

__all__ = ["Coordinate", "search_space"]


@dataclasses.dataclass(frozen=True)
class Coordinate:
    """One tuned parameter: ``name`` in [``lo``, ``hi``], searched on a log scale if ``log``."""

    name: str
    lo: float
    hi: float
    log: bool

    def __post_init__(self):
        if not self.lo < self.hi:
            raise ValueError(f"{self.name}: empty search range [{self.lo}, {self.hi}]")
        if self.log and self.lo <= 0:
            raise ValueError(f"{self.name}: a log range needs lo > 0, got {self.lo}")

    def value(self, u):
        """p(u), elementwise (module docstring)."""
        t = jax.nn.sigmoid(u)
        if self.log:
            return self.lo * jnp.exp(t * math.log(self.hi / self.lo))
        return self.lo + (self.hi - self.lo) * t

    def coordinate(self, value):
        """u(p), the inverse of :meth:`value`; p must lie strictly inside the range."""
        p = jnp.asarray(value)
        t = jnp.log(p / self.lo) / math.log(self.hi / self.lo) if self.log else (p - self.lo) / (self.hi - self.lo)
        return jnp.log(t) - jnp.log1p(-t)


def search_space(method, names=None, bounds: dict | None = None) -> tuple[Coordinate, ...]:
    """The coordinates of ``method``'s (a registry name or a
    :class:`~jaxmesh.denoise.Method`) continuous parameters ``names`` (default: all
    of them), with the registry's ranges unless ``bounds`` gives ``{name: (lo, hi)}``.

    Arguments:
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        names: the parameters to tune (default: all continuous ones).
        bounds: ``{name: (lo, hi)}`` replacing the registry's ranges.

    Returns:
        One :class:`Coordinate` per name."""
    m = as_method(method)
    method = m.name
    names = m.continuous if names is None else tuple(names)
    if not names:
        raise ValueError(f"method {method!r} has no continuous parameter to tune "
                         f"(its parameters: {sorted(m.params)})")
    bounds = dict(bounds or {})
    out = []
    for n in names:
        if n not in m.params or m.params[n].kind != "continuous":
            raise ValueError(f"{method}: {n!r} is not a continuous parameter; tunable: {m.continuous}")
        p = m.params[n]
        lo, hi = bounds.pop(n, p.bounds)
        out.append(Coordinate(n, float(lo), float(hi), bool(p.log)))
    if bounds:
        raise ValueError(f"bounds given for parameters that are not tuned: {sorted(bounds)}")
    return tuple(out)
