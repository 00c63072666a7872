"""Denoising a packed batch: many meshes as one disjoint union, each in its own frame.

A method with no reduction over the whole mesh (``Method.local``: the umbrella flow,
Taubin, HC, the kernel flow, the explicit cotangent flow) run on the union of meshes
(:func:`jaxmesh.batch.pack_batch`) moves each vertex by what its own mesh holds.  Run in
each mesh's unit frame (:func:`~jaxmesh.transforms.segment_unit_frame`), v' = (v − c_k) / s_k
for a vertex of mesh k, it gives every mesh the result
:func:`~jaxmesh.denoise.denoise_in_unit_frame` gives it alone, in one call over the
meshes' own vertices (no padding to the largest).

A method whose one whole-mesh quantity is the unit of its parameters (``Method.unit``:
bilateral denoising, σ in mean edge lengths ℓ̄) is scale-equivariant: mesh k is further
divided by its own ℓ̄_k (in its unit frame), so that every mesh has ℓ̄ = 1, and so does the
union (a mean over the edges of means of 1); the result, mapped back, is the mesh's own up
to rounding.  Methods with other global quantities (a mean area with ℓ̄, a mean gradient
of the moving positions, a mixture fitted to the whole mesh, a solver's tolerance) would
mix the meshes: they are refused.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from ..batch import PackedBatch, unpack
from ..geometry import segment_mean_edge_length
from ..mesh import Mesh
from ..transforms import segment_unit_frame
from .registry import METHODS, Method, as_method, diverged

__all__ = ["packed_run", "run_packed", "denoise_packed"]


_UNITS = {"mean_edge_length": segment_mean_edge_length}


def _packable(method: str | Method) -> Method:
    m = as_method(method)
    if not m.packable:
        raise ValueError(f"{m.name} reduces over the whole mesh, so it cannot run on a packed batch (packable: "
                         f"{', '.join(sorted(k for k, v in METHODS.items() if v.packable))}); pad the batch "
                         "instead (jaxmesh.batch.pad_batch)")
    if m.unit is not None and m.unit not in _UNITS:
        raise ValueError(f"{m.name}: unit {m.unit!r} is not one of {sorted(_UNITS)}")
    if m.aux:
        raise ValueError(f"{m.name} needs per-mesh auxiliary inputs; it cannot run on a packed batch")
    return m


def packed_run(mesh: Mesh, segment, far, segments: int, method: str | Method, **params) -> tuple[Mesh, Array]:
    """(``method`` run on a union of meshes, each in its own unit frame and mapped back;
    whether each mesh diverged): the jittable core of :func:`denoise_packed`, as
    :func:`~jaxmesh.denoise.framed.framed_run` is of ``denoise_in_unit_frame``.

    Arguments:
        mesh: the union (:attr:`PackedBatch.mesh`, vertices (V, 3)).
        segment: the mesh of each vertex, (V,) (:attr:`PackedBatch.segment`).
        far: each mesh's far vertices, (V,) (:attr:`PackedBatch.far`).
        segments: the number of segments (static).
        method: a registry name or :class:`~jaxmesh.denoise.Method` that is ``packable``.
        **params: the method's parameters, one value for every mesh.

    Returns:
        (the denoised union, a bool per segment: diverged)."""
    m = _packable(method)
    centre, scale = segment_unit_frame(mesh, far, segment, segments)
    c, s = centre[segment], scale[segment][:, None]
    work = mesh.with_vertices((mesh.vertices - c) / s)
    if m.unit is not None:            # each mesh's own unit in its unit frame, made 1
        unit = _UNITS[m.unit](work, segment, segments)
        u = jnp.where(unit > 0, unit, 1)[segment][:, None]
        work, s = work.with_vertices(work.vertices / u), s * u
    out = m(work, throw=False, **params)
    return mesh.with_vertices(out.vertices * s + c), diverged(work, out, far=far, segment=segment, segments=segments)


@functools.partial(jax.jit, static_argnames=("segments", "method", "statics"))
def run_packed(mesh: Mesh, segment, far, continuous: dict, segments: int, method: str | Method, statics: tuple):
    """:func:`packed_run` compiled once per union shape, segment count, method and static
    parameters (``continuous``: the traced ones, ``Method.split``)."""
    return packed_run(mesh, segment, far, segments, method, **continuous, **dict(statics))


def denoise_packed(packed: PackedBatch, method: str | Method, **params) -> list[Mesh]:
    """Every mesh of ``packed`` denoised by ``method`` in its own unit frame, in one call
    (module docstring); the same results as :func:`~jaxmesh.denoise.denoise_in_unit_frame`
    mesh by mesh.  Raises ``FloatingPointError`` naming the meshes that diverged.

    Arguments:
        packed: a :class:`~jaxmesh.batch.PackedBatch` (:func:`~jaxmesh.batch.pack_batch`).
        method: a ``packable`` method (``umbrella_flow``, ``taubin``, ``hc``, ``kernel``,
            ``cotangent``, ``bilateral``).
        **params: the method's parameters (defaults from the registry), one setting for all.

    Returns:
        The denoised meshes, in order."""
    m = _packable(method)
    cont, statics = m.split(**params)
    out, bad = run_packed(packed.mesh, packed.segment, packed.far, cont, packed.segments, m, statics)
    bad = np.flatnonzero(np.asarray(bad)[:len(packed.num_vertices)])
    if bad.size:
        raise FloatingPointError(f"{m.name} diverged (non-finite or exploding coordinates) on packed mesh(es) "
                                 f"{bad.tolist()} with {params or 'its defaults'}; use a larger lam, fewer "
                                 "iterations or a smaller step")
    return unpack(packed, out)
