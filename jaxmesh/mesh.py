"""The :class:`Mesh` pytree: vertex positions plus host-built topology.

A mesh M = (V, E, T) with m = |V| vertices, n = |T| triangles and |E| undirected
edges.  Everything discrete (edge lists, degrees, which edge lies opposite which
corner) is computed once on the host with numpy in :meth:`Mesh.from_arrays` and
stored as integer arrays, so that every operator is a pure function of the mesh
that ``jax.jit`` / ``jax.vmap`` / ``jax.grad`` can trace.  Counts come from array
shapes and are therefore static under ``jit``.
"""

from __future__ import annotations

import dataclasses
import warnings

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ._private import caller_stacklevel, frozen_pytree

__all__ = ["Mesh", "MeshWarning", "build_topology"]


class MeshWarning(UserWarning):
    """Emitted for inputs that are accepted but deserve attention
    (isolated vertices, zero-area faces, polygons that were triangulated)."""


def build_topology(faces: np.ndarray, num_vertices: int) -> dict[str, np.ndarray]:
    """Host-side topology of a triangle list (numpy, run once per mesh).

    Returns int32 arrays:

    * ``edges`` (E, 2): unique undirected edges with ``edges[:, 0] < edges[:, 1]``,
      sorted lexicographically;
    * ``face_edges`` (F, 3): ``face_edges[f, k]`` is the edge *opposite* corner k of
      face f, i.e. the edge (faces[f, k+1], faces[f, k+2]) (indices mod 3);
    * ``src``, ``dst``, ``edge_of`` (2E,): the directed edge list (both directions of
      every edge) sorted by ``(src, dst)``; ``edge_of`` maps a directed edge to its
      undirected edge;
    * ``degree`` (V,): number of distinct neighbours d_i.

    Arguments:
        faces: triangles, (F, 3) integer vertex indices.
        num_vertices: the vertex count V (isolated vertices included).

    Returns:
        A dict of int32 arrays (listed above)."""
    m = int(num_vertices)
    kt = np.int32 if m * m < 2**31 else np.int64          # keys i·m + j, 32-bit where they fit
    f = np.asarray(faces, dtype=kt)
    a = f[:, [1, 2, 0]]
    b = f[:, [2, 0, 1]]
    keys, inverse = _unique_inverse((np.minimum(a, b) * kt(m) + np.maximum(a, b)).ravel())
    edges = np.stack([keys // m, keys % m], axis=1)
    src, dst, edge_of = _directed(edges, m)
    as32 = lambda x: np.ascontiguousarray(x, dtype=np.int32)  # noqa: E731
    return {
        "edges": as32(edges.reshape(-1, 2)),
        "face_edges": as32(inverse.reshape(-1, 3)),
        "src": as32(src),
        "dst": as32(dst),
        "edge_of": as32(edge_of),
        "degree": as32(np.bincount(edges.ravel(), minlength=m)),
    }


def _directed(edges: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(src, dst, edge_of) of both directions of the lexicographically sorted edges i < j, sorted
    by (src, dst) without sorting them: vertex s's run is its edges j -> s (every i < s, taken
    in order of i by a stable sort of the edges on j) followed by its edges s -> j (already in
    order of j)."""
    i, j = edges[:, 0], edges[:, 1]
    by_j = radix_argsort(j)
    into, out = np.bincount(j, minlength=m), np.bincount(i, minlength=m)    # per vertex: runs j -> s, s -> j
    start = np.cumsum(into + out) - (into + out)
    at_in = start[j[by_j]] + ranks_in_runs(into)                      # j -> s runs, in by_j order
    at_out = start[i] + into[i] + ranks_in_runs(out)                  # i -> j runs, in edge order
    src, dst, edge_of = (np.empty(2 * len(edges), edges.dtype) for _ in range(3))
    src[at_in], dst[at_in], edge_of[at_in] = j[by_j], i[by_j], by_j
    src[at_out], dst[at_out], edge_of[at_out] = i, j, np.arange(len(edges))
    return src, dst, edge_of


def ranks_in_runs(counts: np.ndarray) -> np.ndarray:
    """For items laid out in consecutive runs of ``counts[r]`` items, each item's position in
    its run: 0, 1, …, counts[0] − 1, 0, 1, …, counts[1] − 1, …"""
    counts = np.asarray(counts)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def radix_argsort(keys: np.ndarray) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` of non-negative integer keys, as a least-significant-digit
    radix sort: one stable pass per 16 bits of the largest key (numpy radix-sorts 16-bit keys in
    linear time; on the bunny's 208k edge keys, two passes take a quarter of a quicksort's time)."""
    keys = np.asarray(keys)
    if keys.dtype.kind not in "iu" or (keys.size and keys.min() < 0):
        raise ValueError("radix_argsort sorts non-negative integer keys")
    order = None
    for shift in range(0, max(int(keys.max(initial=0)).bit_length(), 1), 16):
        digit = (((keys if order is None else keys[order]) >> shift) & 0xFFFF).astype(np.uint16)
        step = np.argsort(digit, kind="stable")
        order = step if order is None else order[step]
    return order


def _unique_inverse(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, return_inverse=True)`` of non-negative keys, by one radix sort."""
    perm = radix_argsort(keys)
    ordered = keys[perm]
    first = np.empty(len(ordered), bool)
    first[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    inverse = np.empty(len(ordered), np.int64)
    inverse[perm] = np.cumsum(first) - 1
    return ordered[first], inverse


def to_device(a: np.ndarray | dict[str, np.ndarray], dtype=None) -> Array | dict[str, Array]:
    """A host array (or a dict of them, moved in one call) on the default device,
    its dtype canonicalised (x64 setting).
    ``jax.device_put``, not ``jnp.asarray``: in JAX 0.10 the latter compiles a
    small program for every new shape, i.e. several per mesh size loaded."""
    if isinstance(a, dict):
        return jax.device_put({k: np.asarray(x, dtype=jax.dtypes.canonicalize_dtype(x.dtype))
                               for k, x in a.items()})
    target = jax.dtypes.canonicalize_dtype(a.dtype if dtype is None else dtype)
    if dtype is not None and np.dtype(dtype) != target:
        warnings.warn(f"dtype {np.dtype(dtype)} is not available without jax_enable_x64; using {target}",
                      UserWarning, stacklevel=caller_stacklevel())
    return jax.device_put(np.asarray(a, dtype=target))


def as_device_array(a) -> Array:
    """A numpy array by :func:`to_device`; anything else (a JAX array, a tracer, a list) by
    ``jnp.asarray``."""
    return to_device(a) if isinstance(a, np.ndarray) else jnp.asarray(a)


def _validate_vertices(vertices) -> np.ndarray:
    v = np.asarray(vertices)
    if v.dtype == object:
        raise ValueError("vertices must be a numeric array, got ragged/object data")
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must have shape (m, 3), got {v.shape}")
    if v.shape[0] == 0:
        raise ValueError("empty mesh: no vertices")
    if not np.issubdtype(v.dtype, np.number) or np.issubdtype(v.dtype, np.complexfloating):
        raise ValueError(f"vertices must be real numbers, got dtype {v.dtype}")
    if not np.issubdtype(v.dtype, np.floating):
        v = v.astype(np.float64)
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"vertex {i} has a non-finite coordinate {v[i].tolist()} "
            f"({int(bad.sum())} non-finite vertices in all)"
        )
    return v


def _validate_faces(faces, num_vertices: int) -> np.ndarray:
    f = np.asarray(faces)
    if f.dtype == object:
        raise ValueError(
            "faces are ragged (polygons with different vertex counts); "
            "only triangles are supported: triangulate first"
        )
    if f.ndim != 2:
        raise ValueError(f"faces must have shape (n, 3), got {f.shape}")
    if f.shape[0] == 0:
        raise ValueError("empty mesh: no faces")
    if f.shape[1] != 3:
        raise ValueError(
            f"faces must be triangles, got {f.shape[1]}-gons (shape {f.shape}); "
            "triangulate first (jaxmesh.load does so with a warning)"
        )
    if np.issubdtype(f.dtype, np.floating):
        if not np.all(np.isfinite(f)) or np.any(f != np.round(f)):
            raise ValueError("face indices must be integers")
        f = f.astype(np.int64)
    if not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"face indices must be integers, got dtype {f.dtype}")
    out = (f < 0) | (f >= num_vertices)
    if out.any():
        k = int(np.flatnonzero(out.any(axis=1))[0])
        raise ValueError(
            f"face {k} = {f[k].tolist()} has a vertex index out of range "
            f"[0, {num_vertices})"
        )
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    if repeated.any():
        k = int(np.flatnonzero(repeated)[0])
        raise ValueError(
            f"face {k} = {f[k].tolist()} repeats a vertex (index-degenerate; "
            f"{int(repeated.sum())} such faces); remove them before building a Mesh"
        )
    if num_vertices >= 2**31 - 1:
        raise ValueError("meshes with 2**31 or more vertices are not supported")
    return f.astype(np.int32)


def zero_area_faces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Boolean mask of faces whose area is zero up to rounding.

    A face counts as degenerate when |(b - a) x (c - a)| <= eps * (|b - a|^2 + |c - a|^2),
    eps the machine epsilon of the vertex dtype: a scale-free test.
    """
    dt = np.asarray(vertices).dtype
    eps = np.finfo(dt if np.issubdtype(dt, np.floating) else np.float64).eps
    x, y, z = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)   # component-wise: 2x faster
    i, j, k = np.asarray(faces).T
    e1x, e1y, e1z = x[j] - x[i], y[j] - y[i], z[j] - z[i]
    e2x, e2y, e2z = x[k] - x[i], y[k] - y[i], z[k] - z[i]
    n0, n1, n2 = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    cross = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    scale = (e1x * e1x + e1y * e1y + e1z * e1z) + (e2x * e2x + e2y * e2y + e2z * e2z)
    return cross <= eps * scale


@frozen_pytree
@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class Mesh:
    """An immutable triangle mesh: a frozen dataclass registered as a JAX pytree whose
    leaves are its eight arrays, in the order below (so ``jax.jit``, ``jax.vmap``,
    ``equinox``'s filters and ``eqx.tree_at`` take it as they take any pytree; rebuilding
    it from leaves does not run ``__init__``, so any leaves will do: ``vmap`` axes,
    ``ShapeDtypeStruct`` s, None).

    Attributes (all JAX arrays; leading batch dimensions are allowed on
    ``vertices`` only, e.g. ``(B, V, 3)`` for B noisy copies of one mesh):

    * ``vertices``: Float[Array, "*batch V 3"] positions v_i;
    * ``faces``: Int[Array, "F 3"] triangles (vertex indices, int32);
    * ``edges``: Int[Array, "E 2"] unique undirected edges, i < j;
    * ``face_edges``: Int[Array, "F 3"] edge opposite each corner;
    * ``src``, ``dst``, ``edge_of``: Int[Array, "H"], H = 2E, the directed edge list
      sorted by (src, dst) and the undirected edge of each directed edge;
    * ``degree``: Int[Array, "V"] vertex degrees d_i.

    A padded batch of different meshes (:func:`jaxmesh.batch.pad_batch`) stacks
    the topology too: each topology array then has a leading ``*stack`` axis (B,).

    Build with :meth:`from_arrays` (or :func:`jaxmesh.load`); move the vertices
    with :meth:`with_vertices`, which keeps the topology and costs nothing.
    """

    vertices: Float[Array, "*batch V 3"]
    faces: Int[Array, "*stack F 3"]
    edges: Int[Array, "*stack E 2"]
    face_edges: Int[Array, "*stack F 3"]
    src: Int[Array, "*stack H"]
    dst: Int[Array, "*stack H"]
    edge_of: Int[Array, "*stack H"]
    degree: Int[Array, "*stack V"]

    @classmethod
    def from_arrays(cls, vertices, faces, *, dtype=None, warn: bool = True) -> "Mesh":
        """Validate ``vertices`` (m, 3) and ``faces`` (n, 3) and build the topology.

        Raises ``ValueError`` naming the first offending vertex or face for:
        wrong shapes, non-triangle faces, non-finite coordinates, indices out
        of range, index-degenerate faces (a repeated vertex) and empty meshes.
        Accepted but reported with a :class:`MeshWarning` (when ``warn``):
        isolated vertices (degree 0; operators leave them in place) and
        zero-area faces (operators give them zero weight).  Non-manifold
        edges and vertices are accepted; :func:`jaxmesh.topology.mesh_info`
        reports them.

        ``dtype`` sets the floating dtype of the vertices (default: the input's,
        subject to JAX's x64 setting).
        """
        v = _validate_vertices(vertices)
        f = _validate_faces(faces, v.shape[0])
        topo = build_topology(f, v.shape[0])
        if warn:
            isolated = np.flatnonzero(topo["degree"] == 0)
            if isolated.size:
                warnings.warn(
                    f"{isolated.size} isolated vertices (no face uses them; first: "
                    f"{int(isolated[0])}); operators leave them in place",
                    MeshWarning,
                    stacklevel=2,
                )
            flat = zero_area_faces(v, f)
            if flat.any():
                warnings.warn(
                    f"{int(flat.sum())} zero-area faces (first: {int(np.flatnonzero(flat)[0])}); "
                    "they get zero weight in area and cotangent operators",
                    MeshWarning,
                    stacklevel=2,
                )
        target = jax.dtypes.canonicalize_dtype(dtype if dtype is not None else v.dtype)
        if jnp.issubdtype(target, jnp.floating) and v.size and np.abs(v).max() > jnp.finfo(target).max:
            i = int(np.argmax(np.abs(v).max(axis=1)))
            raise ValueError(
                f"vertex {i} {v[i].tolist()} does not fit in {target} (largest {float(jnp.finfo(target).max):.3g}); "
                "enable 64-bit floats (jax.config.update('jax_enable_x64', True)) or rescale the mesh")
        return cls(vertices=to_device(v, dtype), **to_device({"faces": f, **topo}))

    # ------------------------------------------------------------------ counts
    @property
    def num_vertices(self) -> int:
        """V (of each mesh, also when every array is stacked, as in a :class:`~jaxmesh.batch.PaddedBatch`)."""
        return self.degree.shape[-1]

    @property
    def num_faces(self) -> int:
        """F (of each mesh, also when stacked)."""
        return self.faces.shape[-2]

    @property
    def num_edges(self) -> int:
        """E, undirected (of each mesh, also when stacked)."""
        return self.edges.shape[-2]

    @property
    def batch_shape(self) -> tuple[int, ...]:
        return tuple(self.vertices.shape[:-2])

    @property
    def dtype(self):
        return self.vertices.dtype

    # ------------------------------------------------------------------ moves
    def with_vertices(self, vertices) -> "Mesh":
        """Same connectivity, new positions of shape (*batch, V, 3). O(1), jittable."""
        x = as_device_array(vertices)
        if x.ndim < 2 or x.shape[-2:] != (self.num_vertices, 3):
            raise ValueError(
                f"vertices must have shape (*batch, {self.num_vertices}, 3), got {x.shape}"
            )
        if not jnp.issubdtype(x.dtype, jnp.floating):
            raise ValueError(f"vertices must be floating point, got dtype {x.dtype}")
        return dataclasses.replace(self, vertices=x)

    def same_connectivity(self, other: "Mesh") -> bool:
        """True if ``other`` has the same vertex count and the same faces, in order."""
        return (self.num_vertices == other.num_vertices and self.faces.shape == other.faces.shape
                and bool(np.array_equal(np.asarray(self.faces), np.asarray(other.faces))))

    def astype(self, dtype) -> "Mesh":
        """The mesh with vertices cast to ``dtype`` (e.g. jnp.float32)."""
        return dataclasses.replace(self, vertices=self.vertices.astype(dtype))

    def to_trimesh(self):
        """A ``trimesh.Trimesh`` with the same vertex order (``process=False``)."""
        import trimesh

        if self.batch_shape:
            raise ValueError("to_trimesh needs a single mesh, not a batch")
        return trimesh.Trimesh(
            np.asarray(self.vertices, dtype=np.float64), np.asarray(self.faces), process=False
        )

    def __eq__(self, other: object) -> bool:
        """True if ``other`` is a Mesh of the same tree whose leaves are equal: arrays of the
        same shape, dtype and values, other leaves by ``==`` (traced arrays only to themselves)."""
        if not isinstance(other, Mesh):
            return NotImplemented
        mine, tree = jax.tree_util.tree_flatten(self)
        theirs, other_tree = jax.tree_util.tree_flatten(other)
        return tree == other_tree and all(_leaf_equal(a, b) for a, b in zip(mine, theirs))

    __hash__ = None    # unhashable, as its arrays are

    def __repr__(self) -> str:  # short: the default would print every array
        batch = f", batch={self.batch_shape}" if self.batch_shape else ""
        return (
            f"Mesh(V={self.num_vertices}, F={self.num_faces}, E={self.num_edges}, "
            f"dtype={self.dtype}{batch})"
        )


def _leaf_equal(a, b) -> bool:
    if a is b:
        return True
    if isinstance(a, jax.core.Tracer) or isinstance(b, jax.core.Tracer):
        return False
    if isinstance(a, (np.ndarray, jax.Array)) or isinstance(b, (np.ndarray, jax.Array)):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and bool(np.array_equal(a, b))
    return bool(a == b)
