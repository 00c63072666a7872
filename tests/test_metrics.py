"""Error metrics: hand values, invariances, gradients, correspondence-free distance."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxmesh
from jaxmesh import metrics as M
from conftest import grid_arrays


def test_visual_error_hand_values(tetra):
    x = tetra.vertices
    assert float(M.visual_error(tetra, tetra)) == 0.0
    t = jnp.array([0.1, -0.2, 0.3])
    # a translation moves no Laplacian coordinate: E = |t|^2 / 2
    np.testing.assert_allclose(M.visual_error(tetra, x + t[None]), float(t @ t) / 2)
    # move vertex 0 by h along z: first term h^2, Laplacian term h^2 + 3 (h/3)^2, over 2m = 8
    h = 0.3
    np.testing.assert_allclose(M.visual_error(tetra, x.at[0, 2].add(h)), 7 * h * h / 24)


def test_nonlinear_error_reduces_to_linear_form_for_huge_c(spot):
    key = jax.random.PRNGKey(0)
    noisy = jaxmesh.add_noise(spot, 0.3, key)
    d = spot.vertices - noisy.vertices
    k = jaxmesh.operators.umbrella(spot, d)
    m = spot.num_vertices
    # g -> 1 as c -> inf, so A(v) = (2/d_i) sum_j (v_i - v_j) = -2 K v
    ref = (jnp.sum(d * d) + 4 * jnp.sum(k * k)) / (2 * m)
    np.testing.assert_allclose(M.nonlinear_visual_error(spot, noisy, c=1e12), ref, rtol=1e-10)
    assert float(M.nonlinear_visual_error(spot, spot)) == 0.0


def test_nonlinear_error_translation_defect_and_fix(spot):
    noisy = jaxmesh.add_noise(spot, 0.3, jax.random.PRNGKey(1))
    shift = jnp.array([0.5, 0.5, 0.5])
    moved_ref, moved_est = spot.with_vertices(spot.vertices + shift[None]), noisy.vertices + shift[None]
    paper = (M.nonlinear_visual_error(spot, noisy), M.nonlinear_visual_error(moved_ref, moved_est))
    fixed = [M.nonlinear_visual_error(a, b, variant="translation_invariant")
             for a, b in ((spot, noisy), (moved_ref, moved_est))]
    assert abs(float(paper[1] / paper[0]) - 1) > 1e-6  # eq.8 leaks the origin
    np.testing.assert_allclose(fixed[1], fixed[0], rtol=1e-10)


def test_rms_and_normal_angle(grid):
    x = grid.vertices
    np.testing.assert_allclose(M.rms_vertex_error(grid, x + jnp.array([[0.0, 3.0, 4.0]])), 5.0)
    th = np.radians(10.0)
    rot = jnp.array([[1, 0, 0], [0, np.cos(th), -np.sin(th)], [0, np.sin(th), np.cos(th)]])
    np.testing.assert_allclose(M.mean_normal_angle_error(grid, x @ rot.T), 10.0, rtol=1e-12)
    assert float(M.mean_normal_angle_error(grid, x)) == 0.0


def test_metrics_accept_batches_and_refuse_other_connectivity(bumpy_grid):
    mesh = bumpy_grid
    noisy = jaxmesh.add_noise(mesh, 0.2, jax.random.PRNGKey(2)).vertices
    batch = jnp.stack([noisy, mesh.vertices])
    for f in (M.visual_error, M.nonlinear_visual_error, M.rms_vertex_error, M.mean_normal_angle_error):
        out = f(mesh, batch)
        np.testing.assert_allclose(out[0], f(mesh, noisy), rtol=1e-12)
        with jax.disable_jit():      # the metrics' bodies are jitted: eager means one primitive at a time
            eager = f(mesh, noisy)
        np.testing.assert_allclose(jax.jit(f)(mesh, noisy), eager, rtol=1e-12)
        np.testing.assert_allclose(f(mesh, noisy), eager, rtol=1e-12)
        assert float(out[1]) < 1e-12
    with pytest.raises(ValueError, match="same connectivity"):
        M.visual_error(mesh, noisy[:-1])


@pytest.mark.parametrize("f", [M.visual_error, M.nonlinear_visual_error, M.rms_vertex_error,
                               M.mean_normal_angle_error])
def test_metric_gradients(bumpy_grid, f):
    est = bumpy_grid.vertices + 0.05 * jnp.asarray(np.random.default_rng(0).standard_normal((30, 3)))
    check_grads(lambda y: f(bumpy_grid, y), (est,), order=1, modes=("rev",), eps=1e-6, atol=1e-6, rtol=1e-5)


def test_point_triangle_distance_hand_cases():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    pts = np.array([[0.2, 0.2, 0.5],    # above the interior: plane distance
                    [-1.0, -1.0, 0.0],  # vertex region of a
                    [0.5, -2.0, 0.0],   # edge region of ab
                    [1.0, 1.0, 1.0]])   # edge region of bc
    expected = [0.5, np.sqrt(2), 2.0, np.sqrt(0.5 + 1.0)]
    n = len(pts)
    got = M.point_triangle_distance(pts, np.tile(a, (n, 1)), np.tile(b, (n, 1)), np.tile(c, (n, 1)))
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_point_triangle_distance_against_brute_force():
    rng = np.random.default_rng(0)
    tri = rng.standard_normal((50, 3, 3))
    p = 2 * rng.standard_normal((50, 3))
    got = M.point_triangle_distance(p, tri[:, 0], tri[:, 1], tri[:, 2])
    u, v = np.meshgrid(np.linspace(0, 1, 301), np.linspace(0, 1, 301))
    keep = u + v <= 1
    bary = np.stack([1 - u[keep] - v[keep], u[keep], v[keep]], 1)
    for k in range(50):
        pts = bary @ tri[k]
        brute = np.sqrt(((pts - p[k]) ** 2).sum(1)).min()
        assert got[k] <= brute + 1e-12
        assert brute - got[k] < 0.02 * np.abs(tri[k]).max()


def test_surface_distance_without_correspondence():
    v, f = grid_arrays(6, 6)
    a = jaxmesh.Mesh.from_arrays(v, f)
    lifted = jaxmesh.Mesh.from_arrays(v + [0, 0, 0.1], f)
    d = M.surface_distance(a, lifted, samples=3000)
    assert d["rms"] == pytest.approx(0.1, rel=1e-9) and d["hausdorff"] == pytest.approx(0.1, rel=1e-9)
    perm = np.random.default_rng(0).permutation(len(v))
    inv = np.argsort(perm)
    shuffled = jaxmesh.Mesh.from_arrays(v[perm], inv[f][:, [1, 2, 0]])
    d0 = M.surface_distance(a, shuffled, samples=3000)
    assert d0["hausdorff"] < 1e-12 and d0["diagonal"] == pytest.approx(np.sqrt(72))


def test_surface_distance_sphere_against_analytic():
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=3)
    a = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    b = jaxmesh.Mesh.from_arrays(1.05 * s.vertices, s.faces)
    d = M.surface_distance(a, b, samples=4000, seed=3)
    # every point of the inner sphere is ~0.05 from the outer one (flat facets add < 0.01)
    assert 0.045 < d["mean"] < 0.0525 and d["hausdorff"] == pytest.approx(0.05, rel=0.2)
