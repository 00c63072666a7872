"""Geometry: hand values, trimesh references, gradients, jit, batching."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import assert_refused
from jax.test_util import check_grads

import jaxmesh
from jaxmesh import geometry as G


def test_triangle_hand_values(triangle):
    np.testing.assert_allclose(G.face_areas(triangle), [6.0])
    np.testing.assert_allclose(G.face_normals(triangle), [[0, 0, 1.0]])
    np.testing.assert_allclose(G.edge_lengths(triangle), [3.0, 4.0, 5.0])  # edges (0,1),(0,2),(1,2)
    np.testing.assert_allclose(G.mean_edge_length(triangle), 4.0)
    np.testing.assert_allclose(G.corner_angles(triangle),
                               [[np.pi / 2, np.arccos(0.6), np.arccos(0.8)]])
    np.testing.assert_allclose(G.corner_cotangents(triangle), [[0.0, 0.75, 4 / 3]], atol=1e-15)
    np.testing.assert_allclose(G.vertex_areas(triangle), [6.0, 6.0, 6.0])
    np.testing.assert_allclose(G.bounding_box_diagonal(triangle), 5.0)


def test_tetrahedron_hand_values(tetra):
    np.testing.assert_allclose(G.face_areas(tetra), [0.5, 0.5, 0.5, np.sqrt(3) / 2])
    s = 1 / np.sqrt(3)
    np.testing.assert_allclose(G.face_normals(tetra), [[0, 0, -1], [0, -1, 0], [-1, 0, 0], [s, s, s]],
                               atol=1e-15)
    np.testing.assert_allclose(G.vertex_normals(tetra, "uniform")[0], [-s, -s, -s])
    # vertex 1 = (1,0,0) touches faces 0, 1, 3 (normals -z, -y, (1,1,1)/sqrt3), area weights 1/2, 1/2, sqrt3/2
    n = 0.5 * np.array([0, 0, -1.0]) + 0.5 * np.array([0, -1.0, 0]) + np.sqrt(3) / 2 * np.array([s, s, s])
    np.testing.assert_allclose(G.vertex_normals(tetra, "area")[1], n / np.linalg.norm(n), atol=1e-15)
    # angles at vertex 1: 45 deg in faces 0 and 1, 60 deg in the equilateral face 3
    n = np.pi / 4 * np.array([0, 0, -1.0]) + np.pi / 4 * np.array([0, -1.0, 0]) + np.pi / 3 * np.array([s, s, s])
    np.testing.assert_allclose(G.vertex_normals(tetra, "angle")[1], n / np.linalg.norm(n), atol=1e-15)


def test_octahedron_hand_values(octa):
    np.testing.assert_allclose(G.face_areas(octa), np.full(8, np.sqrt(3) / 2))
    np.testing.assert_allclose(G.corner_angles(octa), np.full((8, 3), np.pi / 3))
    for w in ("uniform", "angle", "area"):
        np.testing.assert_allclose(G.vertex_normals(octa, w), np.asarray(octa.vertices), atol=1e-15)


def test_heron_equals_half_cross_product():
    rng = np.random.default_rng(0)
    v = rng.standard_normal((40, 3))
    f = np.array([rng.choice(40, 3, replace=False) for _ in range(60)])
    m = jaxmesh.Mesh.from_arrays(v, f)
    cross = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    np.testing.assert_allclose(G.face_areas(m), cross, rtol=1e-12)
    np.testing.assert_allclose(G.face_areas(m, method="heron"), cross, rtol=1e-10)


def test_needles_cross_product_keeps_the_area_heron_from_lengths_cannot():
    # height 1e-9 on a unit base: the side lengths round to (1, 0.5, 0.5) in float64,
    # so the thesis's stable Heron (stable in the lengths) returns 0.
    needle = jaxmesh.Mesh.from_arrays(np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 1e-9, 0]]),
                                      np.array([[0, 1, 2]]), warn=False)
    np.testing.assert_allclose(G.face_areas(needle), [0.5e-9], rtol=1e-6)
    assert float(G.face_areas(needle, method="heron")[0]) == 0.0
    # at height 1e-5 the lengths still carry the height and the stable form recovers it
    thin = needle.with_vertices(needle.vertices.at[2, 1].set(1e-5))
    np.testing.assert_allclose(G.face_areas(thin, method="heron"), [0.5e-5], rtol=1e-5)


def test_against_trimesh(spot):
    tm = spot.to_trimesh()
    np.testing.assert_allclose(G.face_areas(spot), tm.area_faces, rtol=1e-10)
    np.testing.assert_allclose(G.face_normals(spot), tm.face_normals, atol=1e-10)
    # trimesh's vertex normals are angle-weighted face-normal averages
    np.testing.assert_allclose(G.vertex_normals(spot, "angle"), tm.vertex_normals, atol=1e-8)
    np.testing.assert_allclose(G.edge_lengths(spot),
                               np.linalg.norm(np.diff(tm.vertices[np.asarray(spot.edges)], axis=1)[:, 0], axis=1))
    np.testing.assert_allclose(G.corner_angles(spot), tm.face_angles, atol=1e-10)


FUNCS = [
    lambda m: G.face_areas(m),
    lambda m: G.face_areas(m, method="heron"),
    lambda m: G.face_normals(m),
    lambda m: G.vertex_normals(m, "angle"),
    lambda m: G.vertex_normals(m, "area"),
    lambda m: G.corner_cotangents(m),
    lambda m: G.mean_edge_length(m),
    lambda m: G.vertex_areas(m),
]


@pytest.mark.parametrize("k", range(len(FUNCS)))
def test_gradients_against_finite_differences(bumpy_grid, k):
    f = FUNCS[k]
    w = jnp.asarray(np.random.default_rng(k).standard_normal(np.shape(f(bumpy_grid))))
    loss = lambda x: jnp.sum(w * f(bumpy_grid.with_vertices(x)))  # noqa: E731
    check_grads(loss, (bumpy_grid.vertices,), order=1, modes=("rev",), eps=1e-6, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("k", range(len(FUNCS)))
def test_jit_equals_eager_and_vmap_equals_loop(bumpy_grid, k):
    f = FUNCS[k]
    with jax.disable_jit():      # the functions' bodies are jitted: eager means one primitive at a time
        eager = f(bumpy_grid)
    np.testing.assert_allclose(jax.jit(f)(bumpy_grid), eager, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(f(bumpy_grid), eager, rtol=1e-12, atol=1e-14)
    x = bumpy_grid.vertices
    batch = jnp.stack([x, 1.5 * x + 0.3, x[::-1] * 0 + x ** 2])
    batched = f(bumpy_grid.with_vertices(batch))
    vm = jax.vmap(lambda y: f(bumpy_grid.with_vertices(y)))(batch)
    for i in range(3):
        ref = f(bumpy_grid.with_vertices(batch[i]))
        np.testing.assert_allclose(batched[i], ref, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(vm[i], ref, rtol=1e-12, atol=1e-14)


def test_rejects_unknown_weighting(tetra):
    assert_refused(G.vertex_normals, tetra, "cotan", param="weighting", message="weighting must be")


def test_hat_gradients_reproduce_linear_functions_in_jax_and_numpy():
    """Σ_k u(v_k) ∇ψ_k is the exact gradient of a linear u restricted to the face's plane
    (P1 elements reproduce linear functions); the gradients sum to 0; the host (numpy)
    and JAX versions are one formula; a zero-area face gets zeros."""
    rng = np.random.default_rng(0)
    p = rng.standard_normal((50, 3, 3))
    p[7] = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]             # collinear: zero area
    a = rng.standard_normal(3)
    area_j, grad_j = G.hat_gradients(jnp.asarray(p))
    area_n, grad_n = G.hat_gradients(p, np)
    np.testing.assert_allclose(np.asarray(grad_j), grad_n, rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(area_j), area_n, rtol=1e-15)
    np.testing.assert_allclose(area_n, 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1))
    np.testing.assert_allclose(grad_n.sum(axis=1), 0, atol=1e-12)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    tangential = a - (n @ a)[:, None] * n                  # ∇u on the face's plane
    got = np.einsum("fk,fkd->fd", p @ a, grad_n)
    ok = np.arange(50) != 7
    np.testing.assert_allclose(got[ok], tangential[ok], atol=1e-10)
    assert area_n[7] == 0 and not grad_n[7].any()


@pytest.mark.parametrize("shapes", [((4, 3), (4, 3)), ((2, 5, 3, 3), (1, 5, 1, 3)), ((6, 1), (6, 4)), ((3, 7), (1, 7)),
                                    ((2,), (2,))])
def test_dot_is_the_summed_product(shapes):
    """The written-out dot product equals jnp.sum(a * b, axis=-1), broadcasting included (also past the unroll)."""
    from jaxmesh._private import dot

    a = jax.random.normal(jax.random.PRNGKey(0), shapes[0])
    b = jax.random.normal(jax.random.PRNGKey(1), shapes[1])
    np.testing.assert_allclose(dot(a, b), jnp.sum(a * b, axis=-1), rtol=1e-12, atol=1e-12)
    assert dot(a, b).shape == jnp.sum(a * b, axis=-1).shape


def test_filled_mass_one_rule_by_hand():
    """jaxmesh._private.filled_mass, the mass of vertices without area in every mass matrix
    (spectral, heat geodesics, curvature flow): the mean of the mesh's positive masses, per
    batch row; ``empty`` where a row has none."""
    from jaxmesh._private import filled_mass

    m = jnp.asarray([[2.0, 0.0, 4.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(np.asarray(filled_mass(m)), [[2, 3, 4, 3], [1, 1, 1, 1]])
    np.testing.assert_array_equal(np.asarray(filled_mass(m[1], empty=0.0)), [0, 0, 0, 0])
    np.testing.assert_array_equal(np.asarray(filled_mass(m[0])), [2, 3, 4, 3])
