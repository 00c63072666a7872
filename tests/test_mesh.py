"""Mesh construction, host topology and validation of bad input."""

import dataclasses
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmesh
from jaxmesh import Mesh, MeshWarning
from jaxmesh.mesh import build_topology
from conftest import grid_arrays, tetrahedron_arrays


def test_tetrahedron_topology(tetra):
    assert (tetra.num_vertices, tetra.num_faces, tetra.num_edges) == (4, 4, 6)
    np.testing.assert_array_equal(tetra.degree, [3, 3, 3, 3])
    np.testing.assert_array_equal(tetra.edges, [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    # directed list sorted by (src, dst), both directions of every edge
    src, dst = np.asarray(tetra.src), np.asarray(tetra.dst)
    assert list(zip(src, dst)) == sorted(zip(src, dst))
    assert len(src) == 12
    np.testing.assert_array_equal(np.asarray(tetra.edges)[np.asarray(tetra.edge_of)],
                                  np.sort(np.stack([src, dst], 1), axis=1))


def test_face_edges_are_opposite_corners(grid):
    f, fe, e = (np.asarray(a) for a in (grid.faces, grid.face_edges, grid.edges))
    for k in range(3):
        opp = np.sort(np.stack([f[:, (k + 1) % 3], f[:, (k + 2) % 3]], 1), axis=1)
        np.testing.assert_array_equal(e[fe[:, k]], opp)


def test_from_arrays_against_trimesh_edges_and_degree(spot):
    tm = spot.to_trimesh()
    np.testing.assert_array_equal(np.asarray(spot.edges), np.unique(np.sort(tm.edges_unique, 1), axis=0))
    np.testing.assert_array_equal(np.asarray(spot.degree), tm.vertex_degree)


def test_with_vertices_keeps_topology_and_accepts_batches(tetra):
    v = np.asarray(tetra.vertices)
    batch = jnp.stack([v, v + 1.0, 2.0 * v])
    b = tetra.with_vertices(batch)
    assert b.batch_shape == (3,)
    assert b.faces is tetra.faces and b.src is tetra.src
    np.testing.assert_allclose(jaxmesh.face_areas(b)[1], jaxmesh.face_areas(tetra))
    np.testing.assert_allclose(jaxmesh.face_areas(b)[2], 4 * jaxmesh.face_areas(tetra))
    with pytest.raises(ValueError, match=r"shape \(\*batch, 4, 3\)"):
        tetra.with_vertices(np.zeros((5, 3)))


def test_mesh_is_an_immutable_pytree_and_jits_without_retracing(tetra):
    with pytest.raises(dataclasses.FrozenInstanceError):
        tetra.vertices = tetra.vertices  # type: ignore[misc]
    traces = []

    @jax.jit
    def total_area(mesh):
        traces.append(1)
        return jnp.sum(jaxmesh.face_areas(mesh))

    a = total_area(tetra)
    b = total_area(tetra.with_vertices(tetra.vertices * 2.0))
    assert len(traces) == 1
    np.testing.assert_allclose(b, 4 * a)
    leaves = jax.tree_util.tree_leaves(tetra)
    assert all(isinstance(x, jax.Array) for x in leaves)
    assert eqx.is_array(tetra.vertices)


def test_mesh_pytree_takes_any_leaves_and_compares_by_value(tetra):
    """Rebuilt from non-array leaves (vmap axes, shapes) without running ``__init__``; its key
    paths name the fields; equinox's tree tools take it; == compares shapes, dtypes and values."""
    axes = jax.tree_util.tree_map_with_path(lambda p, _: 0 if jax.tree_util.keystr(p) == ".vertices" else None, tetra)
    batch = tetra.with_vertices(jnp.stack([tetra.vertices, 2 * tetra.vertices]))
    areas = jax.vmap(lambda m: jaxmesh.face_areas(m), in_axes=(axes,))(batch)
    np.testing.assert_allclose(areas[1], 4 * areas[0])
    shapes = jax.eval_shape(lambda m: m, tetra)
    assert isinstance(shapes, jaxmesh.Mesh) and shapes.faces.shape == tetra.faces.shape
    paths = [jax.tree_util.keystr(p) for p, _ in jax.tree_util.tree_leaves_with_path(tetra)]
    assert paths == [".vertices", ".faces", ".edges", ".face_edges", ".src", ".dst", ".edge_of", ".degree"]
    moved = eqx.tree_at(lambda m: m.vertices, tetra, tetra.vertices + 1.0)
    assert isinstance(moved, jaxmesh.Mesh) and moved.same_connectivity(tetra)
    np.testing.assert_allclose(eqx.filter_jit(jaxmesh.face_areas)(moved), jaxmesh.face_areas(tetra))
    copy = jaxmesh.Mesh.from_arrays(np.asarray(tetra.vertices), np.asarray(tetra.faces))
    assert copy == tetra and copy is not tetra and not (copy != tetra)
    assert moved != tetra and tetra.astype(jnp.float32) != tetra and tetra != "a mesh"
    assert jax.tree_util.tree_map(lambda a: a.shape, copy) == jax.tree_util.tree_map(lambda a: a.shape, tetra)
    with pytest.raises(TypeError, match="unhashable"):
        hash(tetra)


def test_the_mesh_and_the_commands_that_never_train_do_not_import_equinox():
    """equinox, optimistix and lineax (about 0.27 s of import together) are for the learned model,
    the gradient tuner, the CG solves and errors raised inside jit: every command module, the
    denoisers' registry and the tuning package load without them, and a named method runs."""
    import subprocess
    import sys

    code = ("import sys, jaxmesh, jaxmesh.cli, jaxmesh.tune; mesh = jaxmesh.data.load_sample('spot'); "
            "jaxmesh.cli.build_parser(('info', 'stats', 'hash', 'compress', 'convert', 'noise', 'denoise')); "
            "from jaxmesh.denoise import METHODS; METHODS['taubin'](mesh); METHODS['bilateral_normal'](mesh); "
            "heavy = [m for m in ('equinox', 'optimistix', 'lineax') if m in sys.modules]; assert not heavy, heavy")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]


def test_dtype_follows_input(tetra):
    m32 = tetra.astype(jnp.float32)
    assert jaxmesh.face_areas(m32).dtype == jnp.float32
    assert jaxmesh.vertex_normals(m32).dtype == jnp.float32
    assert jaxmesh.face_areas(tetra).dtype == jnp.float64


# ---------------------------------------------------------------- bad input


def test_refuses_non_triangle_faces():
    v, _ = grid_arrays(1, 1)
    with pytest.raises(ValueError, match="faces must be triangles, got 4-gons"):
        Mesh.from_arrays(v, np.array([[0, 2, 3, 1]]))
    with pytest.raises(ValueError, match="ragged"):
        Mesh.from_arrays(v, np.array([[0, 1, 2], [0, 2, 3, 1]], dtype=object))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_refuses_non_finite_vertices(bad):
    v, f = tetrahedron_arrays()
    v = v.copy()
    v[2, 1] = bad
    with pytest.raises(ValueError, match="vertex 2 has a non-finite coordinate"):
        Mesh.from_arrays(v, f)


@pytest.mark.parametrize("index", [4, -1, 99])
def test_refuses_out_of_range_indices(index):
    v, f = tetrahedron_arrays()
    f = f.copy()
    f[3, 2] = index
    with pytest.raises(ValueError, match=r"face 3 = .* out of range \[0, 4\)"):
        Mesh.from_arrays(v, f)


def test_refuses_empty_meshes():
    with pytest.raises(ValueError, match="empty mesh: no vertices"):
        Mesh.from_arrays(np.zeros((0, 3)), np.zeros((0, 3), int))
    with pytest.raises(ValueError, match="empty mesh: no faces"):
        Mesh.from_arrays(np.zeros((3, 3)), np.zeros((0, 3), int))


def test_refuses_index_degenerate_faces():
    v, f = tetrahedron_arrays()
    f = np.vstack([f, [[1, 1, 2]]])
    with pytest.raises(ValueError, match=r"face 4 = \[1, 1, 2\] repeats a vertex"):
        Mesh.from_arrays(v, f)


def test_refuses_bad_shapes_and_types():
    with pytest.raises(ValueError, match=r"shape \(m, 3\)"):
        Mesh.from_arrays(np.zeros((4, 2)), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="must be integers"):
        Mesh.from_arrays(np.zeros((4, 3)), np.array([[0, 1.5, 2]]))
    with pytest.raises(ValueError, match="real numbers"):
        Mesh.from_arrays(np.zeros((4, 3), complex), np.array([[0, 1, 2]]))


def test_isolated_vertices_are_reported_and_left_in_place():
    v, f = tetrahedron_arrays()
    v = np.vstack([v, [[5.0, 5, 5]]])
    with pytest.warns(MeshWarning, match="1 isolated vertices"):
        m = Mesh.from_arrays(v, f)
    assert int(m.degree[4]) == 0
    x = m.vertices
    for op in (jaxmesh.operators.umbrella, jaxmesh.operators.laplacian,
               jaxmesh.operators.normalized_laplacian, jaxmesh.operators.vertex_laplace,
               jaxmesh.operators.laplace_beltrami):
        out = op(m, x)
        assert np.isfinite(np.asarray(out)).all()
        np.testing.assert_array_equal(out[4], 0.0)
    assert np.isfinite(np.asarray(jaxmesh.vertex_normals(m))).all()
    assert jaxmesh.mesh_info(m)["isolated_vertices"] == 1


def test_zero_area_faces_are_reported_and_get_zero_weight():
    # a sliver: vertex 3 lies on the edge (0, 1) -> face (0, 1, 3) has zero area
    v = np.array([[0.0, 0, 0], [2, 0, 0], [1, 1, 0], [1, 0, 0]])
    f = np.array([[0, 1, 2], [0, 3, 1]])
    with pytest.warns(MeshWarning, match="1 zero-area faces"):
        m = Mesh.from_arrays(v, f)
    np.testing.assert_allclose(jaxmesh.face_areas(m), [1.0, 0.0], atol=1e-15)
    np.testing.assert_array_equal(jaxmesh.face_normals(m)[1], 0.0)
    cot = jaxmesh.geometry.corner_cotangents(m)
    np.testing.assert_array_equal(cot[1], 0.0)
    for arr in (jaxmesh.operators.cotangent_weights(m), jaxmesh.vertex_normals(m),
                jaxmesh.operators.laplace_beltrami(m, m.vertices)):
        assert np.isfinite(np.asarray(arr)).all()
    g = jax.grad(lambda x: jnp.sum(jaxmesh.face_areas(m.with_vertices(x))))(m.vertices)
    assert np.isfinite(np.asarray(g)).all()
    assert jaxmesh.mesh_info(m)["degenerate_faces"] == 1


def test_no_warning_for_clean_mesh():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Mesh.from_arrays(*tetrahedron_arrays())


def test_non_manifold_input_is_accepted_and_reported():
    # three triangles share the edge (0, 1)
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]])
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    m = Mesh.from_arrays(v, f)
    info = jaxmesh.mesh_info(m)
    assert info["non_manifold_edges"] == 1 and not info["manifold"] and info["genus"] is None
    assert np.isfinite(np.asarray(jaxmesh.operators.cotangent_weights(m))).all()


@pytest.mark.parametrize("num_vertices", [40, 50_000])     # 32-bit and 64-bit edge keys
def test_build_topology_against_a_plain_reference(num_vertices):
    """Edges, the opposite-edge table, the directed edges sorted by (src, dst) and the degrees,
    against a dictionary and lexsort written from their definitions."""
    rng = np.random.default_rng(num_vertices)
    faces = np.array([rng.choice(num_vertices, 3, replace=False) for _ in range(300)])
    topo = build_topology(faces, num_vertices)
    pairs = sorted({tuple(sorted((int(f[k]), int(f[(k + 1) % 3])))) for f in faces for k in range(3)})
    index = {p: i for i, p in enumerate(pairs)}
    np.testing.assert_array_equal(topo["edges"], np.array(pairs))
    opposite = [[index[tuple(sorted((int(f[(k + 1) % 3]), int(f[(k + 2) % 3]))))] for k in range(3)] for f in faces]
    np.testing.assert_array_equal(topo["face_edges"], opposite)
    src = np.array([p[0] for p in pairs] + [p[1] for p in pairs])
    dst = np.array([p[1] for p in pairs] + [p[0] for p in pairs])
    order = np.lexsort((dst, src))
    np.testing.assert_array_equal(topo["src"], src[order])
    np.testing.assert_array_equal(topo["dst"], dst[order])
    np.testing.assert_array_equal(topo["edge_of"], np.r_[np.arange(len(pairs)), np.arange(len(pairs))][order])
    np.testing.assert_array_equal(topo["degree"], np.bincount(src, minlength=num_vertices))
    assert all(a.dtype == np.int32 for a in topo.values())


def test_radix_argsort_is_numpys_stable_argsort():
    """(And the positions of items in their runs, by hand.)  Duplicates kept in input order, keys of 1 to 63 bits, int32 and uint64, empty; negative or
    float keys refused."""
    from jaxmesh.mesh import radix_argsort, ranks_in_runs

    rng = np.random.default_rng(0)
    for top in (1, 2**16, 2**31 - 1, 2**40, 2**62):
        keys = rng.integers(0, top, 5000, dtype=np.int64, endpoint=True)
        keys[::7] = keys[0]                                  # ties
        for k in (keys, keys.astype(np.uint64)) + ((keys.astype(np.int32),) if top < 2**31 else ()):
            np.testing.assert_array_equal(radix_argsort(k), np.argsort(k, kind="stable"))
    assert radix_argsort(np.zeros(0, np.int32)).shape == (0,)
    np.testing.assert_array_equal(ranks_in_runs(np.array([2, 0, 3, 1])), [0, 1, 0, 1, 2, 0])     # by hand
    for bad in (np.array([3, -1]), np.array([0.5, 1.0])):
        with pytest.raises(ValueError, match="non-negative integer keys"):
            radix_argsort(bad)
