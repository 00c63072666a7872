"""jaxmesh.vf: libigl's conventions on (V, F) arrays — hand values, the JAX operators
they export, and libigl itself on the shared meshes."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import assert_refused, grid_arrays, octahedron_arrays, shared_mesh_path
from jax.test_util import check_grads

import jaxmesh
from jaxmesh import geometry as G
from jaxmesh import operators as O
from jaxmesh import vf

#: a right triangle with legs 1 (x) and 2 (y), and an obtuse one
RIGHT = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 2, 0]]), np.array([[0, 1, 2]]))
OBTUSE = (np.array([[0.0, 0, 0], [4, 0, 0], [2, 0.5, 0]]), np.array([[0, 1, 2]]))


def test_hand_values_on_one_triangle():
    V, F = RIGHT
    # cot at the corners (adjacent / opposite leg): 0 at the right angle (vertex 0), 1/2 at
    # vertex 1, 2 at vertex 2; L_ij = cot(the corner opposite edge ij) / 2
    L = vf.cotmatrix(V, F).toarray()
    expect = np.array([[0, 1.0, 0.25], [1.0, 0, 0], [0.25, 0, 0]])
    expect -= np.diag(expect.sum(axis=1))
    np.testing.assert_allclose(L, expect, atol=1e-15)
    np.testing.assert_allclose(vf.doublearea(V, F), [2.0])
    np.testing.assert_allclose(vf.per_face_normals(V, F), [[0, 0, 1]])
    np.testing.assert_allclose(vf.per_vertex_normals(V, F), [[0, 0, 1]] * 3)
    # Voronoi (no obtuse angle): corner i gets (|e_j|² cot_j + |e_k|² cot_k) / 8 over its two edges
    # (e_k opposite corner k): |e_0|² = 5 (cot 0), |e_1|² = 4 (cot 1/2), |e_2|² = 1 (cot 2)
    vor = vf.massmatrix(V, F).diagonal()
    np.testing.assert_allclose(vor, [(4 * 0.5 + 1 * 2) / 8, (5 * 0 + 1 * 2) / 8, (5 * 0 + 4 * 0.5) / 8])
    np.testing.assert_allclose(vor.sum(), 1.0)
    np.testing.assert_allclose(vf.massmatrix(V, F, "barycentric").diagonal(), [1 / 3] * 3)
    # obtuse at vertex 2: it gets A/2, the others A/4 (A = 1)
    np.testing.assert_allclose(vf.massmatrix(*OBTUSE).diagonal(), [0.25, 0.25, 0.5])
    A = vf.adjacency_matrix(F)
    assert A.dtype.kind == "i" and (A.toarray() == 1 - np.eye(3)).all()
    assert vf.adjacency_matrix(F, num_vertices=5).shape == (5, 5)


def test_the_matrices_are_the_jax_operators():
    V, F = grid_arrays(5, 4, jitter=0.2, seed=3)
    mesh = jaxmesh.Mesh.from_arrays(V, F)
    x = np.random.default_rng(0).standard_normal((len(V), 3))
    np.testing.assert_allclose(vf.cotmatrix(V, F) @ x, O.cotangent_laplacian(mesh, jnp.asarray(x)), atol=1e-12)
    np.testing.assert_allclose(vf.adjacency_matrix(F) @ x, O.neighbor_sum(mesh, jnp.asarray(x)), atol=1e-12)
    np.testing.assert_allclose(vf.massmatrix(V, F).diagonal(), G.vertex_voronoi_areas(mesh), atol=1e-15)
    # both masses sum to the area; the Voronoi one is differentiable in the positions
    area = float(jnp.sum(G.face_areas(mesh)))
    assert vf.massmatrix(V, F).sum() == pytest.approx(area, rel=1e-12)
    assert vf.massmatrix(V, F, "barycentric").sum() == pytest.approx(area, rel=1e-12)
    loss = lambda v: jnp.sum(G.vertex_voronoi_areas(mesh.with_vertices(v)) ** 2)  # noqa: E731
    check_grads(loss, (mesh.vertices,), order=1, modes=("fwd", "rev"), eps=1e-6, atol=1e-6, rtol=1e-6)
    # the (V, F) functions run in float64 whatever the JAX setting
    with jax.enable_x64(False):
        off = vf.cotmatrix(V, F)
    assert off.dtype == np.float64 and abs(off - vf.cotmatrix(V, F)).max() == 0
    assert vf.to_mesh(V, F).num_faces == len(F)


def test_boundary_loops_follow_the_faces():
    V, F = grid_arrays(4, 3)          # 5 x 4 vertices: a loop of 2 (4 + 3) = 14 boundary vertices
    loop = vf.boundary_loop(F)
    assert len(loop) == 14 and len(set(loop.tolist())) == 14
    # the loop runs the way the faces do: each step a -> b is a directed edge of some face
    directed = {(int(a), int(b)) for f in F for a, b in zip(f, np.roll(f, -1))}
    assert all((int(a), int(b)) in directed for a, b in zip(loop, np.roll(loop, -1)))
    # a closed mesh has none; two separate grids have two
    assert len(vf.boundary_loop(octahedron_arrays()[1])) == 0 and vf.boundary_loops(octahedron_arrays()[1]) == []
    two = np.concatenate([F, F + len(V)])
    assert [len(x) for x in vf.boundary_loops(two)] == [14, 14]


def test_bad_input_is_refused_with_a_reason():
    V, F = RIGHT
    with pytest.raises(ValueError, match=r"\(m, 3\)"):
        vf.adjacency_matrix(np.zeros((2, 4), int))
    with pytest.raises(ValueError, match="negative vertex index"):
        vf.boundary_loop(np.array([[0, 1, -1]]))
    with pytest.raises(ValueError, match="integer vertex indices"):
        vf.adjacency_matrix(np.array([[0, 1, 2.5]]))
    with pytest.raises(ValueError, match="num_vertices is 2"):
        vf.adjacency_matrix(F, num_vertices=2)
    assert_refused(vf.massmatrix, V, F, "full", param="kind", message="kind must be one of")
    assert_refused(vf.per_vertex_normals, V, F, "cotan", param="weighting", message="weighting must be one of")
    with pytest.raises(ValueError, match="out of range"):
        vf.cotmatrix(V, np.array([[0, 1, 7]]))


def _compare_with_libigl(name: str) -> dict:
    igl = pytest.importorskip("igl", reason="libigl's Python bindings (pip install libigl) are the reference")
    mesh = jaxmesh.load(shared_mesh_path(name))
    V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)

    def rel(a, b):     # largest difference relative to the largest entry (sparse stays sparse)
        if hasattr(b, "tocsr"):
            a, b = a.tocsr().astype(np.float64), b.tocsr().astype(np.float64)
            return float(abs(a - b).max() / max(abs(b).max(), 1e-300))
        return float(np.abs(np.asarray(a) - b).max() / max(np.abs(b).max(), 1e-300))

    err = {
        "cotmatrix": rel(vf.cotmatrix(V, F), igl.cotmatrix(V, F)),
        "massmatrix voronoi": rel(vf.massmatrix(V, F, "voronoi"), igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)),
        "massmatrix default": rel(vf.massmatrix(V, F), igl.massmatrix(V, F)),
        "massmatrix barycentric": rel(vf.massmatrix(V, F, "barycentric"),
                                      igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_BARYCENTRIC)),
        "adjacency_matrix": rel(vf.adjacency_matrix(F), igl.adjacency_matrix(F)),
        "per_face_normals": rel(vf.per_face_normals(V, F), igl.per_face_normals(V, F)),
        "per_vertex_normals default": rel(vf.per_vertex_normals(V, F), igl.per_vertex_normals(V, F)),
        "doublearea": rel(vf.doublearea(V, F), igl.doublearea(V, F)),
    }
    for ours, theirs in (("area", "AREA"), ("angle", "ANGLE"), ("uniform", "UNIFORM")):
        w = getattr(igl, f"PER_VERTEX_NORMALS_WEIGHTING_TYPE_{theirs}")
        err[f"per_vertex_normals {ours}"] = rel(vf.per_vertex_normals(V, F, ours), igl.per_vertex_normals(V, F, w))
    for key, e in err.items():
        assert e < 1e-10, f"{name}: {key} differs from libigl by {e:.2e} (relative to its largest entry)"
    theirs = [np.asarray(x) for x in igl.boundary_loop_all(F)]
    ours = vf.boundary_loops(F)
    assert sorted(map(len, ours)) == sorted(map(len, theirs))
    longest = igl.boundary_loop(F)
    if len(longest):     # the same cycle, the same direction (the start vertex may differ)
        loop = vf.boundary_loop(F)
        k = int(np.flatnonzero(loop == longest[0])[0])
        np.testing.assert_array_equal(np.roll(loop, -k), longest)
    return err


@pytest.mark.parametrize("name", ["eight.ply", "camelhead.ply"])
def test_equal_to_libigl(name):
    _compare_with_libigl(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cow.ply", "spot.ply", "fertility.ply", "maxplanck.ply", "fandisk.ply",
                                  "shark.ply", "human.ply", "bunny.ply", "armadillo.ply", "igea.ply"])
def test_equal_to_libigl_on_every_shared_mesh(name):
    _compare_with_libigl(name)


def test_adjacency_has_no_diagonal_even_for_a_face_with_a_repeated_index():
    """A face (0, 0, 1) joins 0 and 1 only: the adjacency (vf's, and graph.adjacency_from_faces
    behind it) stays 0/1 with a zero diagonal, as documented."""
    from jaxmesh.graph import adjacency_from_faces

    F = np.array([[0, 0, 1], [1, 2, 3]])
    want = np.array([[0, 1, 0, 0], [1, 0, 1, 1], [0, 1, 0, 1], [0, 1, 1, 0]])
    np.testing.assert_array_equal(vf.adjacency_matrix(F).toarray(), want)
    np.testing.assert_array_equal(adjacency_from_faces(F, 4).toarray(), want)
