"""Denoising with some parameters given and others to tune: what ``jaxmesh denoise``
does with ``--lam auto`` or ``--tune``, as one library call.

A tuned value is re-run through :func:`jaxmesh.denoise.denoise_in_unit_frame`,
the same call as a given value, so passing the reported value back in writes
the same mesh, bit for bit.
"""

from __future__ import annotations

import dataclasses

from ..denoise import Method, as_method, denoise_in_unit_frame, diverged
from ..mesh import Mesh
from .tuner import TuneResult, tune

__all__ = ["AUTO", "DenoiseRun", "split_auto", "denoise_with_tuning"]

#: the value that marks a continuous parameter to tune
AUTO = "auto"


@dataclasses.dataclass(frozen=True)
class DenoiseRun:
    """``mesh``: the result (input units); ``params``: every parameter as used (tuned
    ones as Python floats); ``tuned``: the names tuned; ``tuning``: the tuner's
    :class:`TuneResult`, or None."""

    mesh: Mesh
    method: str
    params: dict
    tuned: tuple[str, ...]
    tuning: TuneResult | None


def split_auto(method: "str | Method", given: dict, tune_all: bool = False) -> tuple[dict, list[str]]:
    """(fixed values, names to tune) from ``given``, where :data:`AUTO` marks a
    continuous parameter to tune; ``tune_all`` adds every continuous one not given.

    Arguments:
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        given: parameter values, :data:`AUTO` for those to tune.
        tune_all: add every continuous parameter not given.

    Returns:
        (fixed values, names to tune)."""
    m = as_method(method)
    method = m.name
    names = [k for k, v in given.items() if v == AUTO]
    if tune_all:
        names += [k for k in m.continuous if k not in given]
    for k in names:
        if k not in m.params:
            raise ValueError(f"method {method!r} has no parameter {k!r}; it takes {sorted(m.params)}")
        if m.params[k].kind != "continuous":
            raise ValueError(f"{method}: {k} cannot be {AUTO!r} (not continuous)")
    fixed = {k: v for k, v in given.items() if k not in names}
    m.resolve(**fixed, **{k: m.params[k].default for k in names})  # validate everything up front
    return fixed, names


def denoise_with_tuning(mesh: Mesh, method: "str | Method", given: dict | None = None, *, tune_all: bool = False,
                        reference: Mesh | None = None, sigma=None, unit_frame: bool = True) -> DenoiseRun:
    """Denoise ``mesh`` with ``method``: parameters in ``given`` fixed, those given as
    :data:`AUTO` (or all continuous ones with ``tune_all``) tuned — against
    ``reference`` if given, else blind (noise ``sigma`` or estimated).  Runs in
    the unit frame (``unit_frame=False``: in the mesh's units, no tuning).

    Arguments:
        mesh: a single mesh.
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        given: parameter values; :data:`AUTO` marks one to tune.
        tune_all: also tune every continuous parameter not given.
        reference: a clean mesh to tune against (None: blind).
        sigma: blind: the noise σ (None: estimated).
        unit_frame: run in the unit frame (False: in the mesh's units, no tuning).

    Returns:
        A :class:`DenoiseRun` (the mesh, the method, every parameter as used, the names tuned, the tuner's result)."""
    m = as_method(method)
    fixed, names = split_auto(m, dict(given or {}), tune_all)
    if names and not unit_frame:
        raise ValueError("tuning runs in the unit-diagonal frame; it cannot run in the mesh's units")
    tuning = None
    params = dict(fixed)
    if names:
        tuning = tune(mesh, reference, m, names=names, sigma=sigma, **fixed)
        params.update({k: float(v) for k, v in tuning.params.items()})
    full = m.resolve(**params)
    if unit_frame:
        out = denoise_in_unit_frame(mesh, m, **full)
    else:
        out = m(mesh, **full)
        if bool(diverged(mesh, out)):
            raise FloatingPointError(f"{m.name} diverged (a bounding box grown tenfold) with {fixed}; "
                                     "use a larger lam, fewer iterations or a smaller step")
    shown = {k: v for k, v in full.items() if m.params[k].kind != "aux"}
    return DenoiseRun(out, m.name, shown, tuple(names), tuning)
