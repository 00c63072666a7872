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
