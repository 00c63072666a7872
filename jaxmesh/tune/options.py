"""The options of a tuning run as one immutable object, in the style of optimistix's
solvers: build it once, pass it to :func:`~jaxmesh.tune.tune`,
:func:`~jaxmesh.tune.tune_batch` or :func:`~jaxmesh.tune.tune_shared`, reuse it.
It is hashable, so it is part of the jit-static configuration of a run."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from .objectives import OBJECTIVES

__all__ = ["TuneOptions"]


@dataclasses.dataclass(frozen=True)
class TuneOptions:
    """How to search (see :mod:`jaxmesh.tune.tuner` for the search itself).

    * ``names``: the continuous parameters to tune (default: all of the method's);
    * ``bounds``: ``{name: (lo, hi)}`` replacing the registry's search ranges;
    * ``objective``: "visual" (E), "nonlinear" (D) or "normal" (mean face-normal
      angle) against the clean mesh; blind tuning estimates "visual" only;
    * ``grid``: coarse-grid points per coordinate (default 6 for one parameter,
      4 for two, 3 for more; at least 3);
    * ``max_steps``, ``rtol``, ``atol``: BFGS's step budget and tolerances (in the
      preconditioned coordinates, so they mean the same on every mesh);
    * ``probes``: Hutchinson probes of the blind (SURE) estimate.
    """

    names: str | Sequence[str] | None = None
    bounds: Mapping[str, tuple[float, float]] | tuple[tuple[str, tuple[float, float]], ...] = ()
    objective: str = "visual"
    grid: int | None = None
    max_steps: int = 20
    rtol: float = 1e-2
    atol: float = 1e-2
    probes: int = 1

    def __post_init__(self):
        if self.names is not None:
            names = (self.names,) if isinstance(self.names, str) else tuple(self.names)
            object.__setattr__(self, "names", names)
        bounds = self.bounds.items() if isinstance(self.bounds, Mapping) else (self.bounds or ())
        object.__setattr__(self, "bounds", tuple(sorted((str(k), (float(lo), float(hi))) for k, (lo, hi) in bounds)))
        if self.objective not in OBJECTIVES:
            raise ValueError(f"objective must be one of {OBJECTIVES}, got {self.objective!r}")
        if self.grid is not None and (not isinstance(self.grid, int) or self.grid < 3):
            raise ValueError(f"grid needs at least 3 points per coordinate, got {self.grid!r}")
        if not isinstance(self.max_steps, int) or self.max_steps < 1:
            raise ValueError(f"max_steps must be an int >= 1, got {self.max_steps!r}")
        if not isinstance(self.probes, int) or self.probes < 1:
            raise ValueError(f"probes must be an int >= 1, got {self.probes!r}")
        for name in ("rtol", "atol"):
            if not float(getattr(self, name)) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")

    @classmethod
    def from_keywords(cls, options: "TuneOptions | None", keywords: dict) -> tuple["TuneOptions", dict[str, Any]]:
        """(options, the other keywords): the keywords naming an option (``grid=4``,
        ...) override ``options``; the rest are the method's fixed parameters."""
        fields = {f.name for f in dataclasses.fields(cls)}
        given = {k: keywords.pop(k) for k in list(keywords) if k in fields}
        base = options if options is not None else cls()
        if not isinstance(base, cls):
            raise TypeError(f"options must be a TuneOptions, got {type(base).__name__}")
        return (dataclasses.replace(base, **given) if given else base), keywords
