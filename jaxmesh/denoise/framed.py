"""Denoising in the library's one working frame (what ``jaxmesh denoise`` runs).

A method's parameters are lengths or squared lengths in the units of the mesh
they see (kernel λ is a squared length): run in :func:`jaxmesh.transforms.unit_frame`
(bounding box of the used vertices centred at the origin, unit diagonal) they
mean the same on every mesh.  The tuner tunes in the same frame, so a tuned
value passed back in reproduces the tuned run exactly.
"""

from __future__ import annotations

import jax
import numpy as np
from jaxtyping import Array

from .._exported import stored_jit
from ..mesh import Mesh, to_device
from ..transforms import far_mask, far_vertices, from_frame, to_frame, unit_frame
from ._compiled import compilable, split_call
from .registry import METHODS, Method, as_method, diverged

__all__ = ["denoise_in_unit_frame", "framed_run"]


def framed_run(mesh: Mesh, method: str | Method, *, far=None, **params) -> tuple[Mesh, Array]:
    """(``method`` run in ``mesh``'s unit frame and mapped back, whether it
    diverged): the jittable and vmappable core of :func:`denoise_in_unit_frame`
    (auxiliary inputs must be given).  The dataset runner vmaps it.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        far: :func:`~jaxmesh.transforms.far_mask` of ``mesh`` when the caller has it (a host
            caller passes :func:`~jaxmesh.transforms.far_vertices` as a mask: no sort in the program).
        **params: the method's parameters, auxiliary inputs included.

    Returns:
        (the denoised mesh, a bool per batch element: diverged)."""
    m = as_method(method)
    far = far_mask(mesh) if far is None else far      # the same vertices are far in the frame: computed once
    centre, scale = unit_frame(mesh, far)
    work = to_frame(mesh, centre, scale)
    out = m(work, throw=False, **params)
    return from_frame(out, centre, scale), diverged(work, out, far=far)


def denoise_in_unit_frame(mesh: Mesh, method: str | Method, **params) -> Mesh:
    """``method(mesh', **params)`` with mesh' = (mesh − c) / s (:func:`unit_frame`),
    mapped back by v = v' s + c.  Auxiliary inputs (the face graph) are built
    unless given.  Raises ``FloatingPointError`` when the run diverged
    (non-finite, or a bounding box grown tenfold: :func:`diverged`; a far vertex,
    :func:`~jaxmesh.transforms.far_vertices`, smeared over its neighbours is named).
    It runs as one compiled program per method and static parameters, the continuous
    ones traced (a new value does not compile again); a method that reads a file, or a
    call inside :func:`~jaxmesh.denoise.progress`, runs op by op.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        **params: the method's parameters.

    Returns:
        The denoised mesh, in ``mesh``'s units."""
    m = as_method(method)
    aux = {k: v for k, v in m.prepare(mesh).items() if params.get(k) is None}
    far = None if mesh.batch_shape else far_vertices(mesh)
    mask = None if far is None else to_device(np.isin(np.arange(mesh.num_vertices), far))
    out, bad = _compiled_framed_run(mesh, m, mask, {**params, **aux})
    if bool(bad):
        shown = {k: v for k, v in params.items() if k not in m.aux}
        far = () if far is None else far
        hint = (f"vertex {int(far[0])} lies far from the rest (a corrupt coordinate?) and the method spreads it "
                "over its neighbours: remove it first" if len(far)
                else "use a larger lam, fewer iterations or a smaller step")
        raise FloatingPointError(f"{m.name} diverged (non-finite or exploding coordinates) with {shown}; {hint}")
    return out


def _compiled_framed_run(mesh: Mesh, m: Method, far, params: dict) -> tuple[Mesh, Array]:
    """:func:`framed_run` as one kept program (:mod:`jaxmesh.denoise._compiled`; a registry
    method's program is also stored between processes: :mod:`jaxmesh._exported`), or run
    directly where :func:`~jaxmesh.denoise._compiled.compilable` says no."""
    if not compilable(m, mesh, {**params, "far": far}):
        return framed_run(mesh, m, far=far, **params)
    continuous, statics, inputs = split_call(m, mesh, params)
    if METHODS.get(m.name) is m:
        x, bad = _registered_program(mesh, far, continuous, inputs, m.name, statics)
    else:
        x, bad = _method_program(mesh, far, continuous, inputs, m, statics)
    return mesh.with_vertices(x), bad


def _framed_vertices(mesh: Mesh, far, continuous: dict, aux: dict, method, statics: tuple):
    out, bad = framed_run(mesh, method, far=far, **continuous, **dict(statics), **aux)
    return out.vertices, bad


#: a registry method by name (a stable key: its programs can be stored between processes)
_registered_program = stored_jit(_framed_vertices, static_argnames=("method", "statics"))
#: a method of the caller's own (static by identity: compiled for this process only)
_method_program = jax.jit(_framed_vertices, static_argnames=("method", "statics"))
