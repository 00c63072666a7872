"""Batches of different meshes, and sharding a batch over devices.

Three kinds of batch:

* **one connectivity, many positions** (noisy copies of one mesh): a
  :class:`~jaxmesh.Mesh` whose ``vertices`` have shape (B, V, 3).  Every
  operator and denoiser handles the leading axis directly, no ``vmap`` needed.
* **different meshes**: :func:`pad_batch` pads them to common sizes and stacks
  every array, so ``jax.vmap(f)(batch.mesh)`` runs f on all of them at once.
  The padding is inert: padded vertices are isolated (degree 0) at the
  origin, padded edges are self-loops (d, d) and padded faces (d, d, d) on the
  first padded vertex d, so no real vertex, edge or face sees them, and
  every operator leaves them at 0.  :func:`unpad` cuts the results back.
* **different meshes, packed**: :func:`pack_batch` joins them into one disjoint
  union (no padding to the largest), padded inertly as above; a method with no
  quantity over the whole mesh but its unit (``Method.packable``) runs on it once for all
  (:func:`jaxmesh.denoise.denoise_packed`), and :func:`unpack` cuts it back.

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
from jaxtyping import Array, Bool, Int

from .mesh import Mesh, to_device

__all__ = ["PaddedBatch", "pad_batch", "batch_spec", "unpad", "PackedBatch", "pack_batch", "packed_spec",
           "unpack", "shard"]


class PaddedBatch(NamedTuple):
    """``mesh``: every array stacked along a new leading axis of size B;
    ``num_vertices``, ``num_faces``: the true sizes (host ints);
    ``vertex_mask``: True on real vertices, shape (B, V_pad)."""

    mesh: Mesh
    num_vertices: tuple[int, ...]
    num_faces: tuple[int, ...]
    vertex_mask: Bool[Array, "B V"]


_FIELDS = ("vertices", "faces", "edges", "face_edges", "src", "dst", "edge_of", "degree")


def _pad(a: np.ndarray, length: int, fill) -> np.ndarray:
    extra = length - a.shape[0]
    pad = np.broadcast_to(np.asarray(fill, a.dtype), (extra,) + a.shape[1:])
    return np.concatenate([a, pad])


def _host(mesh: Mesh) -> dict[str, np.ndarray]:
    return {k: np.asarray(getattr(mesh, k)) for k in _FIELDS}


def _layout(nv: int, nf: int, ne: int, d: int, e: int) -> tuple[dict, dict]:
    """The inert padding (module docstring): each array's padded length, and its fill when
    the first padding vertex is d and the first padding edge e."""
    lengths = dict(vertices=nv, faces=nf, face_edges=nf, edges=ne, src=2 * ne, dst=2 * ne, edge_of=2 * ne, degree=nv)
    fills = dict(vertices=0, faces=d, face_edges=e, edges=d, src=d, dst=d, edge_of=e, degree=0)
    return lengths, fills


def _padded(host: dict[str, np.ndarray], nv: int, nf: int, ne: int) -> dict[str, np.ndarray]:
    """One mesh's host arrays padded inertly to nv vertices, nf faces, ne edges."""
    lengths, fills = _layout(nv, nf, ne, len(host["vertices"]), len(host["edges"]))
    return {k: _pad(host[k], lengths[k], fills[k]) for k in _FIELDS}


def _checked(meshes: Sequence, who: str) -> list[Mesh]:
    """``meshes`` as a list, refused unless they are one or more single meshes of one dtype."""
    meshes = list(meshes)
    if not meshes:
        raise ValueError(f"{who} needs at least one mesh")
    for k, m in enumerate(meshes):
        if not isinstance(m, Mesh):
            raise TypeError(f"meshes[{k}] is a {type(m).__name__}, not a jaxmesh.Mesh")
        if m.batch_shape:
            raise ValueError(f"meshes[{k}] is already batched {m.batch_shape}; pass single meshes")
    dtypes = {m.dtype for m in meshes}
    if len(dtypes) > 1:
        raise ValueError(f"meshes have different dtypes {sorted(map(str, dtypes))}; cast with .astype")
    return meshes


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
    meshes = _checked(meshes, "pad_batch")
    nv = max(m.num_vertices for m in meshes) + 1   # at least one padding vertex and edge each
    nf = max(m.num_faces for m in meshes)
    ne = max(m.num_edges for m in meshes) + 1
    if pad_to is not None:
        want = tuple(int(n) for n in pad_to)
        if len(want) != 3 or want[0] < nv or want[1] < nf or want[2] < ne:
            raise ValueError(f"pad_to {tuple(pad_to)} is smaller than the batch needs: at least "
                             f"({nv}, {nf}, {ne}) vertices, faces, edges (one padding vertex and edge)")
        nv, nf, ne = want
    cols = [_padded(_host(m), nv, nf, ne) for m in meshes]
    stacked = {k: to_device(np.stack([c[k] for c in cols])) for k in _FIELDS}
    stacked["vertices"] = to_device(np.stack([c["vertices"] for c in cols]), meshes[0].dtype)
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


class PackedBatch(NamedTuple):
    """``mesh``: the meshes' disjoint union, padded (a single mesh, vertices (V, 3));
    ``segment`` (V,): the mesh each vertex belongs to (padding vertices: the last segment);
    ``far`` (V,): each mesh's own far vertices (:func:`~jaxmesh.transforms.far_vertices`);
    ``segments``: the number of segments (at least the meshes plus one, static under ``jit``);
    ``num_vertices``, ``num_faces``, ``num_edges``: each mesh's true sizes (host ints)."""

    mesh: Mesh
    segment: Int[Array, " V"]
    far: Bool[Array, " V"]
    segments: int
    num_vertices: tuple[int, ...]
    num_faces: tuple[int, ...]
    num_edges: tuple[int, ...]


def pack_batch(meshes: Sequence[Mesh], pad_to: tuple[int, int, int] | None = None,
               segments: int | None = None) -> PackedBatch:
    """The disjoint union of single meshes of any sizes: mesh k's vertices, faces and
    edges follow mesh k − 1's, its indices shifted by the counts before it, so the
    union's topology is the one :meth:`Mesh.from_arrays` builds from the concatenated
    arrays (edges and directed edges stay sorted).  It is then padded inertly, as
    :func:`pad_batch` pads (one padding vertex and edge at least).  A method with no
    reduction over the whole mesh (``Method.packable``) run on the union in each mesh's own
    frame (:func:`jaxmesh.denoise.packed_run`) gives every mesh its own result, with no
    padding to the largest mesh and one call for all.

    Arguments:
        meshes: single meshes of any sizes, one dtype.
        pad_to: (vertices, faces, edges) to pad the union to, so that unions of similar
            total size share one compiled program (default: the sizes plus one vertex and edge).
        segments: the number of segments (default: the meshes plus one, for the padding);
            a fixed value lets unions of different mesh counts share one program.

    Returns:
        A :class:`PackedBatch`."""
    from .transforms import far_vertices

    meshes = _checked(meshes, "pack_batch")
    hosts = [_host(m) for m in meshes]
    nvs = [len(h["vertices"]) for h in hosts]
    nes = [len(h["edges"]) for h in hosts]
    need = (sum(nvs) + 1, sum(len(h["faces"]) for h in hosts), sum(nes) + 1)
    if pad_to is not None:
        want = tuple(int(n) for n in pad_to)
        if len(want) != 3 or any(w < n for w, n in zip(want, need)):
            raise ValueError(f"pad_to {tuple(pad_to)} is smaller than the union needs: at least {need} "
                             "vertices, faces, edges (one padding vertex and edge)")
        need = want
    count = len(meshes) + 1 if segments is None else int(segments)
    if count < len(meshes) + 1:
        raise ValueError(f"segments={segments} is too few for {len(meshes)} meshes and the padding "
                         f"(at least {len(meshes) + 1})")
    cols = _union(hosts, *need)
    arrays = to_device({k: cols[k] for k in _FIELDS if k != "vertices"})
    segment = np.full(need[0], count - 1, np.int32)
    segment[:sum(nvs)] = np.repeat(np.arange(len(meshes), dtype=np.int32), nvs)
    far = np.zeros(need[0], bool)
    for m, start in zip(meshes, np.cumsum([0] + nvs)):
        far[start + far_vertices(m)] = True
    mesh = Mesh(vertices=to_device(cols["vertices"], meshes[0].dtype), **arrays)
    return PackedBatch(mesh, to_device(segment), to_device(far), count, tuple(nvs),
                       tuple(m.num_faces for m in meshes), tuple(nes))


def _union(hosts: list[dict], nv: int, nf: int, ne: int) -> dict[str, np.ndarray]:
    """The meshes' host arrays joined (each mesh's vertex and edge indices shifted by the
    counts before it) and padded inertly to nv vertices, nf faces, ne edges, written in place."""
    lengths, fills = _layout(nv, nf, ne, sum(len(h["vertices"]) for h in hosts), sum(len(h["edges"]) for h in hosts))
    cols = {k: np.full((lengths[k],) + hosts[0][k].shape[1:], fills[k], hosts[0][k].dtype) for k in _FIELDS}
    at = dict.fromkeys(_FIELDS, 0)
    v0 = e0 = 0
    for h in hosts:
        shift = dict(vertices=0, degree=0, faces=v0, edges=v0, src=v0, dst=v0, face_edges=e0, edge_of=e0)
        for k in _FIELDS:
            n = len(h[k])
            np.add(h[k], shift[k], out=cols[k][at[k]:at[k] + n], casting="unsafe")
            at[k] += n
        v0, e0 = v0 + len(h["vertices"]), e0 + len(h["edges"])
    return cols


def packed_spec(pad_to: tuple[int, int, int], dtype) -> Mesh:
    """The abstract mesh (leaves ``jax.ShapeDtypeStruct``) of a :class:`PackedBatch`'s
    union padded to ``pad_to``, for ahead-of-time lowering; derived from packing one
    triangle, so it cannot drift from :func:`pack_batch`.

    Arguments:
        pad_to: (vertices, faces, edges) the union is padded to.
        dtype: the positions' dtype.

    Returns:
        A :class:`~jaxmesh.Mesh` whose leaves are ``jax.ShapeDtypeStruct`` (vertices (V, 3))."""
    tri = Mesh.from_arrays(np.eye(3), np.array([[0, 1, 2]]), dtype=dtype, warn=False)
    return jax.tree.map(lambda a: jax.ShapeDtypeStruct(a.shape, a.dtype), pack_batch([tri], pad_to=pad_to).mesh)


def unpack(packed: PackedBatch, result=None) -> list[Mesh]:
    """The union's meshes, each cut out with its own indices.  ``result`` (a Mesh, or a
    vertex array (V, 3)) replaces the positions; without it the input positions are returned.

    Arguments:
        packed: the packed batch.
        result: the denoised union or its vertex array (V, 3) (default: the input positions).

    Returns:
        One single mesh per packed mesh, in order."""
    x = packed.mesh.vertices if result is None else (
        result.vertices if isinstance(result, Mesh) else jnp.asarray(result))
    host = _host(packed.mesh.with_vertices(x))
    out, v0, f0, e0 = [], 0, 0, 0
    for v, f, e in zip(packed.num_vertices, packed.num_faces, packed.num_edges):
        cut = dict(vertices=(v0, v, 0), degree=(v0, v, 0), faces=(f0, f, v0), face_edges=(f0, f, e0),
                   edges=(e0, e, v0), src=(2 * e0, 2 * e, v0), dst=(2 * e0, 2 * e, v0), edge_of=(2 * e0, 2 * e, e0))
        parts = {k: host[k][a:a + n] - (shift if k != "vertices" else 0) for k, (a, n, shift) in cut.items()}
        out.append(Mesh(vertices=to_device(parts.pop("vertices"), x.dtype), **to_device(parts)))
        v0, f0, e0 = v0 + v, f0 + f, e0 + e
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
