"""Batches of different meshes, and sharding a batch over devices.

Two kinds of batch:

* **one connectivity, many positions** (noisy copies of one mesh): a
  :class:`~jaxmesh.Mesh` whose ``vertices`` have shape (B, V, 3).  Every
  operator and denoiser handles the leading axis directly, no ``vmap`` needed.
* **different meshes**: :func:`pad_batch` pads them to common sizes and stacks
  every array, so ``jax.vmap(f)(batch.mesh)`` runs f on all of them at once.
  The padding is inert: padded vertices are isolated (degree 0) at the
  origin, padded edges are self-loops (d, d) and padded faces (d, d, d) on the
  first padded vertex d, so no real vertex, edge or face sees them, and
  every operator leaves them at 0.  :func:`unpad` cuts the results back.

:func:`shard` lays a batch's leading axis over the local devices with
``jax.sharding``; jitted functions then run data-parallel without further
change.  On several hosts, call ``jax.distributed.initialize()`` first and the
same code shards over every process's devices.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh as DeviceMesh
from jax.sharding import NamedSharding, PartitionSpec
from jaxtyping import Array, Bool

from .mesh import Mesh, to_device

__all__ = ["PaddedBatch", "pad_batch", "batch_spec", "unpad", "shard"]


class PaddedBatch(NamedTuple):
    """``mesh``: every array stacked along a new leading axis of size B;
    ``num_vertices``, ``num_faces``: the true sizes (host ints);
    ``vertex_mask``: True on real vertices, shape (B, V_pad)."""

    mesh: Mesh
    num_vertices: tuple[int, ...]
    num_faces: tuple[int, ...]
    vertex_mask: Bool[Array, "B V"]


def _pad(a: np.ndarray, length: int, fill) -> np.ndarray:
    extra = length - a.shape[0]
    pad = np.broadcast_to(np.asarray(fill, a.dtype), (extra,) + a.shape[1:])
    return np.concatenate([a, pad])


def pad_batch(meshes: Sequence[Mesh], pad_to: tuple[int, int, int] | None = None) -> PaddedBatch:
    """Stack single meshes of any sizes into one padded batch (module docstring).
    All meshes must share a dtype; batched meshes are refused.  ``pad_to``:
    (vertices, faces, edges) to pad to, so that batches of similar meshes share
    one shape (and one compiled program); it must leave at least one padding
    vertex and edge (default: the largest sizes plus one).

    Arguments:
        meshes: single meshes of any sizes, one dtype.
        pad_to: (vertices, faces, edges) to pad to (default: the largest sizes plus one).

    Returns:
        A :class:`PaddedBatch`: the padded mesh with vertices (B, V, 3) and the true sizes."""
    meshes = list(meshes)
    if not meshes:
        raise ValueError("pad_batch needs at least one mesh")
    for k, m in enumerate(meshes):
        if not isinstance(m, Mesh):
            raise TypeError(f"meshes[{k}] is a {type(m).__name__}, not a jaxmesh.Mesh")
        if m.batch_shape:
            raise ValueError(f"meshes[{k}] is already batched {m.batch_shape}; pass single meshes")
    dtypes = {m.dtype for m in meshes}
    if len(dtypes) > 1:
        raise ValueError(f"meshes have different dtypes {sorted(map(str, dtypes))}; cast with .astype")
    nv = max(m.num_vertices for m in meshes) + 1   # at least one padding vertex and edge each
    nf = max(m.num_faces for m in meshes)
    ne = max(m.num_edges for m in meshes) + 1
    if pad_to is not None:
        want = tuple(int(n) for n in pad_to)
        if len(want) != 3 or want[0] < nv or want[1] < nf or want[2] < ne:
            raise ValueError(f"pad_to {tuple(pad_to)} is smaller than the batch needs: at least "
                             f"({nv}, {nf}, {ne}) vertices, faces, edges (one padding vertex and edge)")
        nv, nf, ne = want
    cols = {k: [] for k in ("vertices", "faces", "edges", "face_edges", "src", "dst", "edge_of", "degree")}
    for m in meshes:
        d, e = m.num_vertices, m.num_edges      # first padding vertex / edge
        cols["vertices"].append(_pad(np.asarray(m.vertices), nv, 0))
        cols["faces"].append(_pad(np.asarray(m.faces), nf, d))
        cols["face_edges"].append(_pad(np.asarray(m.face_edges), nf, e))
        cols["edges"].append(_pad(np.asarray(m.edges), ne, d))
        cols["src"].append(_pad(np.asarray(m.src), 2 * ne, d))
        cols["dst"].append(_pad(np.asarray(m.dst), 2 * ne, d))
        cols["edge_of"].append(_pad(np.asarray(m.edge_of), 2 * ne, e))
        cols["degree"].append(_pad(np.asarray(m.degree), nv, 0))
    stacked = {k: to_device(np.stack(v)) for k, v in cols.items()}
    stacked["vertices"] = to_device(np.stack(cols["vertices"]), meshes[0].dtype)
    sizes = tuple(m.num_vertices for m in meshes)
    mask = to_device(np.arange(nv)[None, :] < np.asarray(sizes)[:, None])
    return PaddedBatch(Mesh(**stacked), sizes, tuple(m.num_faces for m in meshes), mask)


def batch_spec(pad_to: tuple[int, int, int], count: int, dtype) -> Mesh:
    """The abstract mesh (leaves ``jax.ShapeDtypeStruct``) of a padded batch of
    ``count`` meshes padded to ``pad_to`` = (vertices, faces, edges): what
    :func:`pad_batch` builds, for ahead-of-time lowering (``jit(f).lower(spec)``).
    Derived from padding one triangle, so it cannot drift from :func:`pad_batch`.

    Arguments:
        pad_to: (vertices, faces, edges) every mesh is padded to.
        count: the batch size B.
        dtype: the positions' dtype.

    Returns:
        A :class:`~jaxmesh.Mesh` whose leaves are ``jax.ShapeDtypeStruct`` (vertices (B, V, 3))."""
    tri = Mesh.from_arrays(np.eye(3), np.array([[0, 1, 2]]), dtype=dtype, warn=False)
    one = pad_batch([tri], pad_to=pad_to).mesh
    return jax.tree.map(lambda a: jax.ShapeDtypeStruct((int(count),) + a.shape[1:], a.dtype), one)


def unpad(batch: PaddedBatch, result=None) -> list[Mesh]:
    """The batch's meshes cut back to their true sizes.  ``result`` (a Mesh as
    returned by a vmapped denoiser, or a vertex array (B, V_pad, 3)) replaces
    the positions; without it the input positions are returned.

    Arguments:
        batch: the padded batch.
        result: a denoised batched mesh or vertex array (B, V_pad, 3) (default: the input positions).

    Returns:
        One single mesh per batch element, at its true size."""
    x = batch.mesh.vertices if result is None else (
        result.vertices if isinstance(result, Mesh) else jnp.asarray(result))
    host = {k: np.asarray(getattr(batch.mesh, k)) for k in ("faces", "edges", "face_edges", "src", "dst",
                                                             "edge_of", "degree")}
    host["vertices"] = np.asarray(x)      # sliced on the host: eager slicing compiles once per mesh size
    out = []
    for k, (v, f) in enumerate(zip(batch.num_vertices, batch.num_faces)):
        e = int(np.sum(host["edges"][k, :, 0] != host["edges"][k, :, 1]))
        cut = dict(vertices=v, faces=f, edges=e, face_edges=f, src=2 * e, dst=2 * e, edge_of=2 * e, degree=v)
        out.append(Mesh(**{name: to_device(host[name][k, :n]) for name, n in cut.items()}))
    return out


def shard(batch, devices=None):
    """Lay the leading (batch) axis over ``devices`` (default: all of
    ``jax.devices()``) with a ``NamedSharding``; other axes are not split.

    ``batch`` is a batched :class:`~jaxmesh.Mesh` (only the vertices are
    split; the shared topology is replicated), a :class:`PaddedBatch` (every
    array is split) or any array.  The batch size must be a multiple of the
    device count.

    Arguments:
        batch: a batched mesh, a :class:`PaddedBatch` or an array with a leading batch axis.
        devices: the devices to lay the batch over (default: ``jax.devices()``).

    Returns:
        The same structure, placed with a ``NamedSharding`` over the batch axis."""
    devices = list(jax.devices() if devices is None else devices)
    grid = DeviceMesh(np.array(devices), ("batch",))
    split = NamedSharding(grid, PartitionSpec("batch"))
    whole = NamedSharding(grid, PartitionSpec())

    def check(a):
        if a.ndim == 0 or a.shape[0] % len(devices):
            raise ValueError(f"batch size {a.shape[0] if a.ndim else 'of a scalar'} is not a multiple "
                             f"of the {len(devices)} devices; pad the batch (e.g. repeat an element)")
        return jax.device_put(a, split)

    if isinstance(batch, PaddedBatch):
        return batch._replace(mesh=jax.tree.map(check, batch.mesh),
                              vertex_mask=check(batch.vertex_mask))
    if isinstance(batch, Mesh):
        if not batch.batch_shape:
            raise ValueError("shard needs a batched mesh (vertices of shape (B, V, 3))")
        replicated = jax.tree.map(lambda a: jax.device_put(a, whole), batch)
        return replicated.with_vertices(check(batch.vertices))
    return check(jnp.asarray(batch))
