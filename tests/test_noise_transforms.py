"""Noise model and normalisation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmesh


def test_noise_scale_is_relative_to_mean_edge_length(spot):
    noisy = jaxmesh.add_noise(spot, 0.1, jax.random.PRNGKey(0))
    eta = np.asarray(noisy.vertices - spot.vertices)
    ell = float(jaxmesh.mean_edge_length(spot))
    assert eta.std() == pytest.approx(0.1 * ell, rel=0.03)
    assert abs(eta.mean()) < 0.01 * ell
    again = jaxmesh.add_noise(spot, 0.1, 0)
    np.testing.assert_array_equal(again.vertices, noisy.vertices)  # int seed == PRNGKey(seed)
    other = jaxmesh.add_noise(spot, 0.1, jax.random.PRNGKey(1))
    assert not np.allclose(other.vertices, noisy.vertices)
    absolute = jaxmesh.add_noise(spot, 0.01, 0, relative=False)
    assert np.asarray(absolute.vertices - spot.vertices).std() == pytest.approx(0.01, rel=0.03)


def test_noise_along_normals(spot):
    noisy = jaxmesh.add_noise(spot, 0.1, 3, along_normals=True)
    eta = noisy.vertices - spot.vertices
    n = jaxmesh.vertex_normals(spot, "area")
    np.testing.assert_allclose(jnp.cross(eta, n), 0, atol=1e-12)
    assert float(jnp.std(jnp.sum(eta * n, -1))) == pytest.approx(0.1 * float(jaxmesh.mean_edge_length(spot)), rel=0.05)


def test_noise_on_batches_is_independent_and_scaled_per_mesh(tetra):
    b = tetra.with_vertices(jnp.stack([tetra.vertices, 1000.0 * tetra.vertices]))
    noisy = jaxmesh.add_noise(b, 0.1, 0)
    eta = np.asarray(noisy.vertices - b.vertices)
    assert eta[1].std() > 100 * eta[0].std()


def test_normalize(spot):
    big = spot.with_vertices(1000.0 * spot.vertices + 7.0)
    n, c, s = jaxmesh.normalize(big, return_transform=True)
    np.testing.assert_allclose(jaxmesh.bounding_box_diagonal(n), 1.0)
    np.testing.assert_allclose(jnp.max(n.vertices, 0) + jnp.min(n.vertices, 0), 0, atol=1e-12)
    np.testing.assert_allclose(n.vertices * s + c[None], big.vertices, rtol=1e-12)
    np.testing.assert_allclose(jaxmesh.normalize(spot).vertices, n.vertices, atol=1e-12)
    point = spot.with_vertices(jnp.zeros_like(spot.vertices) + 2.0)
    np.testing.assert_array_equal(jaxmesh.normalize(point).vertices, 0.0)  # no 0/0


def test_impulsive_noise_moves_a_fraction_along_the_normals(spot):
    ell = float(jaxmesh.mean_edge_length(spot))
    n = jaxmesh.vertex_normals(spot, "area")
    noisy = jaxmesh.add_impulsive_noise(spot, 0.5, 4, fraction=0.3)
    eta = np.asarray(noisy.vertices - spot.vertices)
    moved = np.linalg.norm(eta, axis=1) > 0
    # Bernoulli(0.3) per vertex: within 4 standard deviations of p V
    nv = spot.num_vertices
    assert abs(moved.sum() - 0.3 * nv) < 4 * np.sqrt(0.3 * 0.7 * nv)
    np.testing.assert_allclose(np.cross(eta, np.asarray(n)), 0, atol=1e-12)   # along the normals
    xi = np.sum(eta * np.asarray(n), axis=1)[moved]
    assert xi.std() == pytest.approx(0.5 * ell, rel=0.08)
    # the same key's full-fraction noise moves the chosen vertices by the same amount
    full = jaxmesh.add_noise(spot, 0.5, 4, along_normals=True)
    np.testing.assert_array_equal(noisy.vertices[moved], full.vertices[moved])
    np.testing.assert_array_equal(noisy.vertices[~moved], spot.vertices[~moved])
    # fraction 1 is the Gaussian model exactly, fraction 0 moves nothing
    np.testing.assert_array_equal(jaxmesh.add_noise(spot, 0.5, 4, along_normals=True, fraction=1.0).vertices,
                                  full.vertices)
    np.testing.assert_array_equal(jaxmesh.add_impulsive_noise(spot, 0.5, 4, fraction=0.0).vertices,
                                  spot.vertices)
    with pytest.raises(ValueError, match="fraction"):
        jaxmesh.add_noise(spot, 0.5, 4, fraction=1.5)


def test_impulsive_noise_is_jittable_in_the_fraction_and_differentiable_in_sigma(spot):
    f = jax.jit(lambda p, s: jaxmesh.add_noise(spot, s, 2, along_normals=True, fraction=p).vertices)
    np.testing.assert_allclose(f(0.4, 0.3), jaxmesh.add_impulsive_noise(spot, 0.3, 2, fraction=0.4).vertices,
                               rtol=0, atol=1e-14)
    g = jax.grad(lambda s: jnp.sum(jaxmesh.add_impulsive_noise(spot, s, 2, fraction=0.4).vertices ** 2))(0.3)
    h = 1e-6
    fd = (jnp.sum(f(0.4, 0.3 + h) ** 2) - jnp.sum(f(0.4, 0.3 - h) ** 2)) / (2 * h)
    assert float(g) == pytest.approx(float(fd), rel=1e-6)
