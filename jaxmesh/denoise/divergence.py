"""Whether a denoising run blew up: :func:`diverged` (the registry's, the tuner's and the
dataset runner's one test)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from .._private import lift, safe_norm
from ..mesh import Mesh
from ..transforms import far_mask

__all__ = ["diverged"]


@functools.partial(jax.jit, static_argnames=("segments",))   # one program, not one per primitive, when eager
def diverged(before: Mesh, after: Mesh, growth: float = 10.0, far=None, segment=None, segments: int | None = None):
    """True (per batch element) where ``after`` has a non-finite coordinate or a
    bounding-box diagonal more than ``growth`` times that of ``before``: a
    smoothing flow never enlarges a mesh, so growth means the run blew up.  Both
    boxes are of the vertices that are not far in ``before``
    (:func:`~jaxmesh.transforms.far_mask`), so a corrupt coordinate smeared over
    its neighbours counts as growth.  With ``segment``, the same test for each mesh
    of a disjoint union (:func:`jaxmesh.batch.pack_batch`).

    Arguments:
        before: the input mesh.
        after: the output mesh.
        growth: the largest allowed growth of the bounding-box diagonal.
        far: :func:`~jaxmesh.transforms.far_mask` of ``before``, when the caller has it
            (required with ``segment``: each mesh's own).
        segment: the mesh each vertex of a union belongs to, (V,) (default: one mesh).
        segments: the number of segments (static), with ``segment``.

    Returns:
        A bool array, (*batch), or (segments,) with ``segment``."""
    x = after.vertices
    if segment is None:
        finite = jnp.all(jnp.isfinite(x), axis=(-2, -1))
        top = functools.partial(jnp.max, axis=-2)
        bottom = functools.partial(jnp.min, axis=-2)
    else:
        finite = jax.ops.segment_min(jnp.all(jnp.isfinite(x), axis=-1).astype(jnp.int32), segment, segments) > 0
        top = functools.partial(jax.ops.segment_max, segment_ids=segment, num_segments=segments)
        bottom = functools.partial(jax.ops.segment_min, segment_ids=segment, num_segments=segments)
    near = lift(~(far_mask(before) if far is None else far)[..., None], x.ndim)

    def diagonal(v):
        return safe_norm(top(jnp.where(near, v, -jnp.inf)) - bottom(jnp.where(near, v, jnp.inf)))

    grown = diagonal(x) > growth * diagonal(before.vertices)
    return ~finite | grown
