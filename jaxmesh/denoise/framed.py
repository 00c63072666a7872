"""Denoising in the library's one working frame (what ``jaxmesh denoise`` runs).

A method's parameters are lengths or squared lengths in the units of the mesh
they see (kernel λ is a squared length): run in :func:`jaxmesh.transforms.unit_frame`
(bounding box of the used vertices centred at the origin, unit diagonal) they
mean the same on every mesh.  The tuner tunes in the same frame, so a tuned
value passed back in reproduces the tuned run exactly.
"""

from __future__ import annotations

from jaxtyping import Array

from ..mesh import Mesh
from ..transforms import from_frame, to_frame, unit_frame
from .registry import Method, as_method, diverged

__all__ = ["denoise_in_unit_frame", "framed_run"]


def framed_run(mesh: Mesh, method: str | Method, **params) -> tuple[Mesh, Array]:
    """(``method`` run in ``mesh``'s unit frame and mapped back, whether it
    diverged): the jittable and vmappable core of :func:`denoise_in_unit_frame`
    (auxiliary inputs must be given).  The dataset runner vmaps it.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        **params: the method's parameters, auxiliary inputs included.

    Returns:
        (the denoised mesh, a bool per batch element: diverged)."""
    m = as_method(method)
    centre, scale = unit_frame(mesh)
    work = to_frame(mesh, centre, scale)
    out = m(work, throw=False, **params)
    return from_frame(out, centre, scale), diverged(work, out)


def denoise_in_unit_frame(mesh: Mesh, method: str | Method, **params) -> Mesh:
    """``method(mesh', **params)`` with mesh' = (mesh − c) / s (:func:`unit_frame`),
    mapped back by v = v' s + c.  Auxiliary inputs (the face graph) are built
    unless given.  Raises ``FloatingPointError`` when the run diverged
    (non-finite, or a bounding box grown tenfold: :func:`diverged`).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        **params: the method's parameters.

    Returns:
        The denoised mesh, in ``mesh``'s units."""
    m = as_method(method)
    aux = {k: v for k, v in m.prepare(mesh).items() if params.get(k) is None}
    out, bad = framed_run(mesh, m, **{**params, **aux})
    if bool(bad):
        shown = {k: v for k, v in params.items() if k not in m.aux}
        raise FloatingPointError(f"{m.name} diverged (non-finite or exploding coordinates) with {shown}; "
                                 "use a larger lam, fewer iterations or a smaller step")
    return out
