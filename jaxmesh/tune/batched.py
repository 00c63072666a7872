"""Tuning many meshes in one call: one setting per mesh (:func:`tune_batch`, vmapped)
or one setting shared by a training set (:func:`tune_shared`)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..batch import PaddedBatch, pad_batch, unpad
from ..mesh import Mesh
from ..metrics import visual_error
from ..transforms import to_frame
from ..transforms import unit_frame as frame
from .noise_level import checked_sigma, noise_sigma
from .objectives import noisy_visual_error_expectation
from .search import search
from .options import TuneOptions
from .tuner import (
    TuneResult,
    _check_pair,
    _Config,
    _loss_function,
    _make_config,
    _named,
    _prepare,
    _result,
    _tune_one,
)

__all__ = ["tune_batch", "tune_shared"]


def _aux_for_batch(m, noisy, singles) -> dict:
    """Host-built inputs of the method ``m`` for a batch: shared when every element has
    the same connectivity (a mesh with vertices (B, V, 3)); padded batches of different
    meshes are refused for methods that need them."""
    method = m.name
    if not m.aux:
        return {}
    if not isinstance(noisy, Mesh):
        raise ValueError(f"{method!r} needs the host-built face graph of each mesh, so tune_batch takes "
                         "one mesh with vertices (B, V, 3) for it, not a padded batch of different meshes")
    return m.prepare(singles[0])


def _shared_search(noisy: Mesh, clean: Mesh | None, sigma, key, cfg: _Config):  # methods without aux inputs
    """One u for a padded batch of meshes: the loss is the mean of the per-mesh
    relative losses (each mesh in its own frame)."""
    centre, scale = jax.vmap(frame)(noisy)
    noisy_n = jax.vmap(to_frame)(noisy, centre, scale)
    clean_n = None if clean is None else jax.vmap(to_frame)(clean, centre, scale)
    sigma_n = None if sigma is None else sigma / scale
    keys = jax.random.split(key, scale.shape[0])

    def loss(u):
        per = jax.vmap(lambda nm, cm, s, k: _loss_function(cfg, nm, cm, s, k, {})(u))(
            noisy_n, clean_n, sigma_n, keys)
        return jnp.mean(per, axis=0)

    found = search(loss, cfg, noisy.vertices.dtype, noisy.vertices.shape[0] * noisy.vertices.shape[1])
    final = loss(found.u[None])[0]
    return _named(cfg, found, final, final, None, 1)


def _as_batch(meshes):
    """(stacked Mesh, whether it is one mesh with vertices (B, V, 3) (topology shared),
    unpack(vertices) -> list[Mesh], count)."""
    if isinstance(meshes, Mesh):
        if len(meshes.batch_shape) != 1:
            raise ValueError(f"a batched mesh needs vertices (B, V, 3), got {meshes.vertices.shape}")
        b = meshes.batch_shape[0]
        return meshes, True, lambda x: [meshes.with_vertices(x[i]) for i in range(b)], b
    batch = meshes if isinstance(meshes, PaddedBatch) else pad_batch(list(meshes))
    return batch.mesh, False, lambda x: unpad(batch, x), len(batch.num_vertices)


def _axes(mesh, shared_topology: bool):
    """vmap axes of a batch: only the vertices for one mesh with vertices (B, V, 3),
    every leaf for a padded batch of different meshes."""
    if mesh is None:
        return None
    if not shared_topology:
        return 0
    return jax.tree_util.tree_map_with_path(lambda path, _: 0 if path[0].name == "vertices" else None, mesh)


@functools.partial(jax.jit, static_argnames=("cfg", "noisy_shared", "clean_shared"))
def _tune_many(noisy, clean, sigma, key, aux, cfg, noisy_shared, clean_shared):
    """:func:`_tune_one` vmapped over a batch; compiled once per configuration and shapes
    (module level, so a second batch of the same shapes does not recompile)."""
    in_axes = (_axes(noisy, noisy_shared), _axes(clean, clean_shared), None if sigma is None else 0, None, None)
    return jax.vmap(lambda n, c, sg, kk, ax: _tune_one(n, c, sg, kk, cfg, ax), in_axes=in_axes)(
        noisy, clean, sigma, key, aux)


_shared_jit = jax.jit(_shared_search, static_argnames="cfg")


def tune_batch(noisy, clean=None, method="kernel", *, iterations: int | None = None, sigma=None, key=0,
               options: TuneOptions | None = None, **keywords) -> tuple[TuneResult, list[Mesh]]:
    """One tuned setting per mesh for a whole batch, in one jitted, vmapped call.

    ``noisy`` (and ``clean``): a list of meshes of any sizes (padded with
    :func:`jaxmesh.batch.pad_batch`), a :class:`~jaxmesh.batch.PaddedBatch`, or
    one mesh with vertices (B, V, 3).  Blind when ``clean`` is None, with σ
    per mesh given (``sigma``, shape (B,)) or estimated per mesh.  Returns
    (a :class:`TuneResult` whose arrays have a leading B axis and whose ``mesh``
    is None, the list of denoised meshes).  Each element equals :func:`tune` on
    that mesh alone (tested).  One iteration count (tune the count per mesh
    with :func:`tune`).  ``method``, ``options`` and keywords as :func:`tune`.

    Arguments:
        noisy: a list of meshes, a :class:`~jaxmesh.batch.PaddedBatch`, or one mesh with vertices (B, V, 3).
        clean: the references in the same form, or None (blind).
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        iterations: the method's iteration count (default: the registry's).
        sigma: blind only: σ per mesh, (B,) (default: estimated per mesh).
        key: the probes' random key (an int or a ``jax.random`` key).
        options: the search's :class:`~jaxmesh.tune.TuneOptions` (default: its defaults).
        **keywords: the method's other parameters, fixed.

    Returns:
        (a :class:`TuneResult` with a leading B axis, the denoised meshes)."""
    if iterations is not None and not isinstance(iterations, int):
        raise ValueError("tune_batch takes one iteration count")
    stacked, shared, unpack, b = _as_batch(noisy)
    clean_stacked, clean_shared = None, False
    if clean is not None:
        clean_stacked, clean_shared, _, cb = _as_batch(clean)
        if cb != b:
            raise ValueError(f"{b} noisy meshes but {cb} clean ones")
    meth, options, fixed, key = _prepare(method, options, keywords, key)
    blind = clean is None
    cfg = _make_config(meth, iterations, options, blind, fixed)
    singles = unpack(stacked.vertices)
    if blind:
        if sigma is None:
            s = jnp.asarray([noise_sigma(m)[0] for m in singles], stacked.vertices.dtype)
        else:
            s = jnp.broadcast_to(jnp.asarray(sigma, stacked.vertices.dtype), (b,))
            for m, one in zip(singles, np.asarray(s)):
                checked_sigma(m, one)
    else:
        s = None
        for k, (m, c) in enumerate(zip(singles, unpack(clean_stacked.vertices))):
            try:
                _check_pair(m, c)
            except ValueError as err:
                raise ValueError(f"batch element {k}: {err}") from None
    aux = _aux_for_batch(meth, noisy, singles)
    out = _tune_many(stacked, clean_stacked, s, key, aux, cfg=cfg, noisy_shared=shared,
                     clean_shared=clean_shared)

    outputs = unpack(out.vertices)
    if clean is not None:   # per unpadded mesh: padding must not count in the 1/2m
        out = out._replace(error=jnp.stack([visual_error(c, o)
                                            for c, o in zip(unpack(clean_stacked.vertices), outputs)]))
    else:
        out = out._replace(error=out.loss * jnp.stack(
            [noisy_visual_error_expectation(m, s[i]) for i, m in enumerate(singles)]))
    return _result(cfg, out, s, None), outputs


def tune_shared(noisy, clean=None, method="kernel", *, iterations: int | None = None, sigma=None, key=0,
                options: TuneOptions | None = None, **keywords) -> TuneResult:
    """One setting shared by a training set of meshes: minimise the mean over
    the meshes of each one's relative loss (each in its own unit-diagonal
    frame, so meshes of any units count equally).  Use the result on unseen
    meshes with :meth:`TuneResult.apply`.  Arguments as :func:`tune_batch`;
    the result's ``error`` is the mean relative loss and ``mesh`` is None.

    Arguments:
        noisy: a list of meshes, a :class:`~jaxmesh.batch.PaddedBatch`, or one mesh with vertices (B, V, 3).
        clean: the references in the same form, or None (blind).
        method: a registry name from :data:`~jaxmesh.denoise.METHODS` or a :class:`~jaxmesh.denoise.Method`.
        iterations: the method's iteration count (default: the registry's).
        sigma: blind only: σ per mesh, (B,) (default: estimated per mesh).
        key: the probes' random key (an int or a ``jax.random`` key).
        options: the search's :class:`~jaxmesh.tune.TuneOptions` (default: its defaults).
        **keywords: the method's other parameters, fixed.

    Returns:
        A :class:`TuneResult` (``error``: the mean relative loss; ``mesh``: None)."""
    if iterations is not None and not isinstance(iterations, int):
        raise ValueError("tune_shared takes one iteration count")
    noisy = list(noisy)
    meth, options, fixed, key = _prepare(method, options, keywords, key)
    if meth.aux:
        raise ValueError(f"tune_shared pads meshes of different sizes, which {meth.name!r} (it needs the "
                         "host-built face graph of each mesh) does not support; tune each mesh with tune")
    batch = pad_batch(noisy)
    clean_batch = None
    if clean is not None:
        clean = list(clean)
        if len(clean) != len(noisy):
            raise ValueError(f"{len(noisy)} noisy meshes but {len(clean)} clean ones")
        for k, (m, c) in enumerate(zip(noisy, clean)):
            try:
                _check_pair(m, c)
            except ValueError as err:
                raise ValueError(f"training mesh {k}: {err}") from None
        clean_batch = pad_batch(clean).mesh
    blind = clean is None
    cfg = _make_config(meth, iterations, options, blind, fixed)
    s = None
    if blind:
        s = (jnp.asarray([noise_sigma(m)[0] for m in noisy], batch.mesh.vertices.dtype) if sigma is None
             else jnp.broadcast_to(jnp.asarray(sigma, batch.mesh.vertices.dtype), (len(noisy),)))
        if sigma is not None:
            for m, one in zip(noisy, np.asarray(s)):
                checked_sigma(m, one)
    out = _shared_jit(batch.mesh, clean_batch, s, key, cfg=cfg)
    return _result(cfg, out, s, None)
