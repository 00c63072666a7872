"""Racing the blind chooser's settings over the recorruptions, and running one
setting on them.

Every setting (each fixed candidate, each setting of a search path with its
iteration count searched, :mod:`jaxmesh.tune.paths`) is first estimated on one
recorruption; then only the ``RACE_KEEP`` best of each *family* (each method
among the fixed candidates, each path) go on to the other draws, and
:func:`~jaxmesh.tune.choose_denoiser` takes its winner and its leaders among
those.  The draws are common to every setting, so the first draw's order within
a family is already close to the final one.  A setting's estimate is
Σ_d ‖A(f(ŷ_d) − ỹ_d)‖²/F over the draws d less a constant: the recorrupted
estimate of :mod:`jaxmesh.tune.recorrupt` (its noise constant), or the held-out
one of :mod:`jaxmesh.tune.heldout` (ỹ the noisy mesh, no constant).
"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np

from .._exported import stored_jit
from .._threads import concurrent_map
from ..mesh import Mesh
from .auto_result import Ranked
from .paths import SearchPath, held, one_iteration, path_risks
from .recorrupt import edge_tilt

__all__ = ["RACE_KEEP", "race", "run_setting", "setting_tilt"]

#: after the first recorruption, the settings of each family that go on to the other draws
RACE_KEEP = 2


def _apply(mesh: Mesh, x, continuous: dict, aux: dict, count, pin, method: str, statics: tuple):
    """f(x), or, with a traced ``count``, ``count`` single iterations of f in a loop (one program for
    every count: the search paths' methods, :class:`~jaxmesh.tune.SearchPath`), each followed by
    :func:`~jaxmesh.tune.paths.held` with ``pin``."""
    from ..denoise import METHODS

    if count is None:
        return METHODS[method](mesh.with_vertices(x), throw=False, **continuous, **dict(statics), **aux).vertices
    return jax.lax.fori_loop(0, count, lambda _, x: held(one_iteration(mesh, x, continuous, aux, method, statics),
                                                         pin), x)


@stored_jit(static_argnames=("method", "statics"))
def _run(mesh: Mesh, x, continuous: dict, aux: dict, count, pin, method: str, statics: tuple):
    return _apply(mesh, x, continuous, aux, count, pin, method, statics)


def _split(method: str, params: dict, counted: bool) -> tuple:
    """(continuous, statics, count): the traced and static arguments of one compiled call; with
    ``counted``, the iteration count taken out of the statics and traced (None otherwise)."""
    from ..denoise import METHODS

    cont, statics = METHODS[method].split(**params)
    if not counted:
        return cont, statics, None
    count = dict(statics)["iterations"]
    return cont, tuple(kv for kv in statics if kv[0] != "iterations"), np.int32(count)


def run_setting(mesh: Mesh, x, method: str, params: dict, aux: dict, counted: bool = False, pin=None):
    """f(x): the registry method ``method`` with ``params`` on positions ``x`` of ``mesh``, compiled
    once per method and static parameters (the continuous ones are traced).

    Arguments:
        mesh: the mesh (single).
        x: positions, (V, 3).
        method: a registry name.
        params: its parameters (the others at their defaults).
        aux: its prepared arrays (``METHODS[method].prepare(mesh)``).
        counted: run the ``iterations`` as a traced count of single iterations (one program for
            every count; only for methods whose iterations compose, those of the search paths).
        pin: with ``counted``, None or (mask (V,) bool, positions (V, 3)) held after every iteration
            (:func:`~jaxmesh.tune.paths.held`); ignored without (a fixed candidate runs as a whole).

    Returns:
        The denoised positions, (V, 3)."""
    cont, statics, count = _split(method, params, counted)
    return _run(mesh, x, cont, aux, count, pin if counted else None, method, statics)


@stored_jit
def _tilt(mesh: Mesh, denoised, target, nu, ell):
    """A(f(ŷ) − ỹ), one program for every method (the filter's own is :func:`run_setting`'s)."""
    return edge_tilt(mesh, nu, ell, denoised - target)


def setting_tilt(mesh: Mesh, noisy_input, target, nu, ell, method: str, params: dict, aux: dict,
                 counted: bool = False, pin=None):
    """T = A(f(ŷ) − ỹ) of one setting on one recorruption (ŷ, ỹ): the filter's program
    (:func:`run_setting`, the one that also runs the setting) and the tilt's, shared by every method,
    so that each filter is compiled once for the search.

    Arguments:
        mesh: the mesh (single).
        noisy_input: ŷ, (V, 3).
        target: ỹ, (V, 3).
        nu: the pilot's unit face normals, (F, 3).
        ell: the mean edge length ℓ̄.
        method: a registry name.
        params: its parameters.
        aux: its prepared arrays.
        counted: as for :func:`run_setting`.
        pin: as for :func:`run_setting`.

    Returns:
        (F, 3)."""
    return _tilt(mesh, run_setting(mesh, noisy_input, method, params, aux, counted, pin), target, nu, ell)


@dataclasses.dataclass(frozen=True)
class _Entry:
    """One setting in the race: a fixed candidate, or one setting of a search path (its count searched)."""

    family: tuple
    method: str
    params: dict
    path: SearchPath | None = None


def _entry_sums(noisy: Mesh, entry: _Entry, inputs, targets, nu, ell, auxes: dict, pin=None) -> np.ndarray:
    """Σ_d ‖A(f(ŷ_d) − ỹ_d)‖²/F over the draws given: (1,) for a fixed candidate, one per
    iteration count for a path setting (:func:`~jaxmesh.tune.paths.path_risks`, ``pin`` held)."""
    aux = auxes[entry.method]
    if entry.path is not None:
        return path_risks(noisy, entry.path, entry.params, inputs, targets, nu, ell, aux, pin=pin)
    total = sum(float(np.sum(np.asarray(setting_tilt(noisy, x, t, nu, ell, entry.method, entry.params, aux)) ** 2))
                for x, t in zip(inputs, targets))
    return np.array([total / noisy.num_faces])


def race(noisy: Mesh, candidates, paths, inputs, targets, nu, ell, auxes: dict, constant: float,
         race_keep: int | None, pin=None) -> tuple[list, list]:
    """The ranking of :func:`~jaxmesh.tune.choose_denoiser` (module docstring).

    Arguments:
        noisy: the mesh ranked on (single; the whole mesh or its patches).
        candidates: the fixed candidates (each with ``method`` and ``params``).
        paths: the search paths.
        inputs: the recorrupted inputs ŷ_d, (D, V, 3).
        targets: the targets ỹ_d, (D, V, 3).
        nu: the pilot's unit face normals, (F, 3) (zero rows: faces that do not count).
        ell: the mean edge length ℓ̄.
        auxes: each method's prepared arrays.
        constant: the noise constant subtracted from every estimate.
        race_keep: the settings of each family run on the draws after the first (None: all).
        pin: None, or (mask, positions) held after every iteration of the search paths
            (:func:`~jaxmesh.tune.paths.held`).

    Returns:
        (table, leaders): :class:`~jaxmesh.tune.auto_result.Ranked` rows, those raced to the end first, best
        first, then those dropped after the first draw (estimated on it alone), best first;
        and the best row of each family among the first, families in order."""
    entries = [_Entry(("fixed", c.method), c.method, dict(c.params)) for c in candidates]
    entries += [_Entry(("path", i), path.method, dict(setting), path)
                for i, path in enumerate(paths) for setting in path.settings]
    draws = len(inputs)
    first = draws if race_keep is None else 1

    def sums_on(indices, draws_of: slice) -> list:
        return concurrent_map(lambda i: _entry_sums(noisy, entries[i], inputs[draws_of], targets[draws_of], nu, ell,
                                                    auxes, pin), indices)
    sums = sums_on(range(len(entries)), slice(None, first))
    families = list(dict.fromkeys(e.family for e in entries))
    finished = set(range(len(entries)))
    if first < draws:
        finished = {i for family in families
                    for i in sorted((i for i, e in enumerate(entries) if e.family == family),
                                    key=lambda i: float(np.min(sums[i])))[:race_keep]}
        rest = sorted(finished)
        for i, extra in zip(rest, sums_on(rest, slice(first, None))):
            sums[i] = sums[i] + extra

    def row(i: int) -> Ranked:
        e, t = entries[i], int(np.argmin(sums[i]))
        params = dict(e.params) if e.path is None else {**e.params, **dict(e.path.fixed), "iterations": t + 1}
        return Ranked(e.method, params, float(sums[i][t]) / (draws if i in finished else first) - constant)

    rows = {i: row(i) for i in range(len(entries))}
    leaders = [min((rows[i] for i in finished if entries[i].family == family), key=lambda r: r.risk)
               for family in families]
    table = (sorted((rows[i] for i in finished), key=lambda r: r.risk)
             + sorted((rows[i] for i in rows if i not in finished), key=lambda r: r.risk))
    return table, leaders
