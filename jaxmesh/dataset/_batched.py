"""The dataset runner's batched path: meshes packed into disjoint unions (methods with
``Method.packable``) or padded into batches on the reader thread (each mesh's far vertices
found there too), one program per (padded size, batch size) compiled ahead on two
threads, each batch's outcomes; and what an input's fate is."""

from __future__ import annotations

import concurrent.futures
import dataclasses
import functools
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..batch import batch_spec, pack_batch, pad_batch, packed_spec
from ..mesh import Mesh, to_device
from ..transforms import far_vertices
from .plan import PACK_SEGMENTS, Batch, rung

__all__ = ["Outcome", "Tally", "Padded", "run_padded", "tuned_keys", "tuned_values", "pad_group", "pack_group",
           "run_batch", "precompile"]


class Outcome(NamedTuple):
    """One input's fate: the denoised ``mesh`` (with the ``params`` it was tuned to, if
    tuned), or the ``error`` that stopped it (unreadable, invalid, diverged)."""

    mesh: Mesh | None = None
    params: dict | None = None
    error: BaseException | None = None


@functools.partial(jax.jit, static_argnames=("method", "statics"))
def run_padded(mesh: Mesh, continuous: dict, far, method: str, statics: tuple):
    """The method on every mesh of a padded batch, each in its own unit frame
    (:func:`~jaxmesh.denoise.framed.framed_run`; ``far`` (B, V): each mesh's far vertices,
    found on the host): (vertices (B, V, 3), diverged (B,))."""
    from ..denoise.framed import framed_run

    def one(m, f):
        out, bad = framed_run(m, method, far=f, **continuous, **dict(statics))
        return out.vertices, bad

    return jax.vmap(one)(mesh, far)


def tuned_keys(params: dict) -> list[str]:
    """The parameters given as "auto": tuned blind, per mesh (SURE, :func:`~jaxmesh.tune.tune_batch`)."""
    return sorted(k for k, v in params.items() if isinstance(v, str) and v == "auto")


def tuned_values(params: dict, tuned: dict) -> dict:
    """The parameters as run: the fixed ones and each tuned one's value."""
    return {**{k: v for k, v in params.items() if k not in tuned}, **{k: float(v) for k, v in tuned.items()}}


@dataclasses.dataclass
class Tally:
    programs: set = dataclasses.field(default_factory=set)
    real: int = 0
    padded: int = 0


@dataclasses.dataclass(frozen=True)
class Padded:
    """A batch's readable meshes padded to their shape (built on the reader thread)."""

    good: list
    shape: tuple
    padded: Any
    far: np.ndarray


def pad_group(batch: Batch, meshes: list, ladder: float) -> Padded | None:
    """The readable meshes of ``batch`` (filled to the planned batch size with
    copies of the first) padded to the planned shape, or the next ladder size
    where a mesh outgrew its header's estimate; None when none could be read.
    A packed batch is one union instead (:func:`pack_group`)."""
    if batch.packed:
        return pack_group(batch, meshes, ladder)
    good = [(k, mesh) for k, mesh in zip(batch.items, meshes) if isinstance(mesh, Mesh)]
    if not good:
        return None
    group = [mesh for _, mesh in good]
    group += [group[0]] * (batch.fill + len(batch.items) - len(good))
    need = (max(m.num_vertices for m in group) + 1, max(m.num_faces for m in group),
            max(m.num_edges for m in group) + 1)     # the plan's sizes were estimates from the headers
    shape = _grown(batch.shape, need, ladder)
    far = np.zeros((len(group), shape[0]), bool)
    for row, mesh in zip(far, group):
        row[far_vertices(mesh)] = True
    return Padded(good, shape, pad_batch(group, shape), far)


def _grown(shape: tuple, need: tuple, ladder: float) -> tuple:
    """The planned shape, each size that is too small for ``need`` taken to its ladder size."""
    return tuple(s if s >= n else rung(n, ladder) for s, n in zip(shape, need))


def pack_group(batch: Batch, meshes: list, ladder: float) -> Padded | None:
    """The readable meshes of a packed ``batch`` as one union (:func:`~jaxmesh.batch.pack_batch`,
    :data:`~jaxmesh.dataset.plan.PACK_SEGMENTS` segments) padded to the planned shape, or the
    next ladder size where the meshes outgrew their headers' estimates; None when none
    could be read.  ``far`` is the union's (V,) mask."""
    good = [(k, mesh) for k, mesh in zip(batch.items, meshes) if isinstance(mesh, Mesh)]
    if not good:
        return None
    group = [mesh for _, mesh in good]
    need = (sum(m.num_vertices for m in group) + 1, sum(m.num_faces for m in group),
            sum(m.num_edges for m in group) + 1)
    shape = _grown(batch.shape, need, ladder)
    packed = pack_batch(group, shape, PACK_SEGMENTS)
    return Padded(good, shape, packed, np.asarray(packed.far))


def run_batch(batch: Batch, meshes: list, prepared: Padded | None, method: str, params: dict, tally: Tally,
              compiled: dict) -> dict:
    """{item: its :class:`Outcome`} for one padded batch (the reader gives a mesh or the exception)."""
    results = {k: Outcome(error=mesh) for k, mesh in zip(batch.items, meshes) if not isinstance(mesh, Mesh)}
    if prepared is None:
        return results
    if batch.packed:
        return _run_packed_batch(prepared, method, params, tally, compiled, results)
    good, shape, pb = prepared.good, prepared.shape, prepared.padded
    tally.programs.add((shape, pb.mesh.vertices.shape[0]))
    names = tuned_keys(params)
    if names:
        from ..tune import tune_batch

        res, outs = tune_batch(pb, method=method, names=names, **{k: params[k] for k in params if k not in names})
        for j, (k, mesh) in enumerate(good):
            values = tuned_values(params, {n: res.params[n][j] for n in names})
            ok = bool(np.all(np.isfinite(np.asarray(outs[j].vertices))))
            results[k] = (Outcome(mesh.with_vertices(outs[j].vertices), values) if ok else
                          Outcome(error=FloatingPointError(f"{method} tuned to a non-finite result ({values})")))
    else:
        from ..denoise import METHODS

        cont, statics = METHODS[method].split(**params)
        ahead = compiled.get((shape, pb.mesh.vertices.shape[0]))
        far = jnp.asarray(prepared.far)
        x, bad = (ahead.result()(pb.mesh, cont, far) if ahead is not None
                  else run_padded(pb.mesh, cont, far, method, statics))
        x, bad = np.asarray(x), np.asarray(bad)     # cut on the host: only the positions come back
        for j, (k, mesh) in enumerate(good):
            results[k] = _fate(mesh, x[j, :mesh.num_vertices], bad[j], prepared.far[j], method, params)
    tally.real += sum(mesh.num_vertices for _, mesh in good)
    tally.padded += shape[0] * pb.mesh.vertices.shape[0]
    return results


def _fate(mesh: Mesh, x: np.ndarray, diverged, far: np.ndarray, method: str, params: dict) -> Outcome:
    """One mesh's outcome from its denoised positions ``x`` and whether it ``diverged``
    (naming its first ``far`` vertex, a (V,) mask, as the likely cause)."""
    if not diverged:
        return Outcome(mesh.with_vertices(to_device(x)))
    far = np.flatnonzero(far)
    why = f" (vertex {far[0]} lies far from the rest: a corrupt coordinate?)" if far.size else ""
    return Outcome(error=FloatingPointError(f"{method} diverged on this mesh with {params}{why}"))


def _run_packed_batch(prepared: Padded, method: str, params: dict, tally: Tally, compiled: dict,
                      results: dict) -> dict:
    """The outcomes of one packed union (:func:`jaxmesh.denoise.run_packed`), added to ``results``."""
    from ..denoise import METHODS, run_packed

    good, shape, pb = prepared.good, prepared.shape, prepared.padded
    tally.programs.add((shape, "packed"))
    cont, statics = METHODS[method].split(**params)
    ahead = compiled.get((shape, "packed"))
    out, bad = (ahead.result()(pb.mesh, pb.segment, pb.far, cont) if ahead is not None
                else run_packed(pb.mesh, pb.segment, pb.far, cont, pb.segments, method, statics))
    x, bad = np.asarray(out.vertices), np.asarray(bad)     # only the positions come back
    start = 0
    for j, (k, mesh) in enumerate(good):
        end = start + mesh.num_vertices
        results[k] = _fate(mesh, x[start:end], bad[j], prepared.far[start:end], method, params)
        start = end
    tally.real += start
    tally.padded += shape[0]
    return results


def precompile(plan: list[Batch], method: str, params: dict, dtype, workers: int = 2) -> dict:
    """Compile every planned (shape, batch size) on ``workers`` threads, ahead of
    the stream (XLA compiles without the GIL, so this overlaps reading):
    {(shape, count): future of the compiled program}."""
    from ..denoise import METHODS

    cont, statics = METHODS[method].split(**params)
    pool = concurrent.futures.ThreadPoolExecutor(workers, thread_name_prefix="jaxmesh-compile")
    jobs = {}
    for b in plan:
        if b.packed:
            key = (b.shape, "packed")
            if key not in jobs:
                jobs[key] = pool.submit(lambda k=key: _lower_packed(k[0], cont, method, statics, dtype).compile())
            continue
        key = (b.shape, len(b.items) + b.fill)
        if key not in jobs:
            jobs[key] = pool.submit(lambda k=key: run_padded.lower(
                batch_spec(k[0], k[1], dtype), cont, jax.ShapeDtypeStruct((k[1], k[0][0]), bool), method=method,
                statics=statics).compile())
    pool.shutdown(wait=False)
    return jobs


def _lower_packed(shape: tuple, cont: dict, method: str, statics: tuple, dtype):
    """:func:`jaxmesh.denoise.run_packed` lowered for unions padded to ``shape``."""
    from ..denoise import run_packed

    vector = functools.partial(jax.ShapeDtypeStruct, (shape[0],))
    return run_packed.lower(packed_spec(shape, dtype), vector(jnp.int32), vector(bool), cont, segments=PACK_SEGMENTS,
                            method=method, statics=statics)
